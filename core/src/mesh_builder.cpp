#include <progiso/core/detail/mesh_builder.hpp>

#include <algorithm>
#include <bit>
#include <utility>

#include <progiso/core/assert.hpp>
#include <progiso/core/marching.hpp>

namespace progiso::detail {

mesh_builder::mesh_builder(const hierarchy& hier, const volume& vol, double w, std::size_t expected)
    : hier_(hier), vol_(vol), w_(w), keys_(expected) {
  for (std::size_t q = 0; q < 3; ++q) box_[q] = static_cast<double>(hier.data_max()[q]);
  // A closed surface has about half as many vertices as triangles; clipping at the data box
  // (padded hierarchies only) adds some of both. Reserving for them saves a copy of each array.
  const bool padded = hier.grid_max() != hier.data_max();
  const std::size_t slack = padded ? expected / 8 + 64 : 0;
  grid_.reserve(expected + slack);
  mesh_.triangles.reserve(2 * (expected + slack));
}

triangle_mesh mesh_builder::finish() {
  const auto& sp = vol_.spacing();
  const auto& org = vol_.origin();
  // In place: the grid positions are not needed after this (no second array to fault in).
  mesh_.vertices = std::move(grid_);
  for (vec3& v : mesh_.vertices) {
    for (std::size_t q = 0; q < 3; ++q) v[q] = org[q] + v[q] * sp[q];
  }
  // Every vertex is used (in order of first use) unless clipping left one of its triangles'
  // inside corners out (a corner on the box's face with the rest of the piece beyond it) and
  // no other triangle uses it: then the unused ones are dropped.
  if (suspects_.empty()) return std::move(mesh_);
  const std::size_t count = mesh_.vertices.size();
  {
    std::vector<bool> used(count, false);
    for (const auto& t : mesh_.triangles) {
      for (const std::uint32_t v : t) used[v] = true;
    }
    if (std::all_of(suspects_.begin(), suspects_.end(),
                    [&used](std::uint32_t v) { return used[v]; })) {
      return std::move(mesh_);
    }
  }
  std::vector<std::uint32_t> remap(count, ~std::uint32_t{0});
  std::uint32_t n = 0;
  for (auto& t : mesh_.triangles) {
    for (auto& v : t) {
      if (remap[v] == ~std::uint32_t{0}) remap[v] = n++;
      v = remap[v];
    }
  }
  if (n != count) {
    std::vector<vec3> kept(n);
    for (std::size_t i = 0; i < count; ++i) {
      if (remap[i] != ~std::uint32_t{0}) kept[remap[i]] = mesh_.vertices[i];
    }
    mesh_.vertices = std::move(kept);
  } else {
    std::vector<vec3> ordered(n);
    for (std::size_t i = 0; i < count; ++i) ordered[remap[i]] = mesh_.vertices[i];
    mesh_.vertices = std::move(ordered);
  }
  return std::move(mesh_);
}

std::uint32_t mesh_builder::new_vertex(std::uint64_t key) {
  const auto ends = hier_.edge_ends(key);
  const double fa = vol_.value(ends[0][0], ends[0][1], ends[0][2]);
  const double fb = vol_.value(ends[1][0], ends[1][1], ends[1][2]);
  const vec3 p = interpolate(ends[0], fa, ends[1], fb, w_);
  if (p[0] <= box_[0] && p[1] <= box_[1] && p[2] <= box_[2]) {
    PROGISO_ASSERT(grid_.size() < outside_bit);
    grid_.push_back(p);
    return static_cast<std::uint32_t>(grid_.size() - 1);
  }
  PROGISO_ASSERT(outside_.size() < outside_bit);
  outside_.push_back(p);
  return static_cast<std::uint32_t>(outside_.size() - 1) | outside_bit;
}

std::uint32_t mesh_builder::clip_vertex(const vec3& p) {
  const auto [it, inserted] = clipped_.try_emplace(p, static_cast<std::uint32_t>(grid_.size()));
  if (inserted) grid_.push_back(p);
  return it->second;
}

// Sutherland–Hodgman against x_q ≤ box_q, on positions. Each crossing point is computed from
// the segment's ends in lexicographic order, so the two triangles sharing a segment get the same
// point; crossing points get vertex ids (one per position) only when a kept triangle uses them.
void mesh_builder::clip(const std::array<std::uint32_t, 3>& ids) {
  struct corner {
    vec3 p;
    std::uint32_t id;  // a vertex id, or none for a crossing point
  };
  constexpr std::uint32_t none = ~std::uint32_t{0};
  // Clipping a convex polygon by a plane adds at most one corner: at most 6 after 3 planes.
  std::array<corner, 8> poly{};
  std::array<corner, 8> next{};
  for (std::size_t i = 0; i < 3; ++i) poly[i] = {position(ids[i]), ids[i]};
  std::size_t size = 3;
  for (std::size_t q = 0; q < 3 && size >= 3; ++q) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < size; ++i) {
      const corner& a = poly[i];
      const corner& b = poly[i + 1 == size ? 0 : i + 1];
      const bool ain = a.p[q] <= box_[q];
      const bool bin = b.p[q] <= box_[q];
      if (ain) next[kept++] = a;
      // A crossing whose inside end lies on the plane is that end itself, already emitted.
      const bool on_plane = ain ? a.p[q] == box_[q] : b.p[q] == box_[q];
      if (ain != bin && !on_plane) {
        vec3 p = a.p;
        vec3 r = b.p;
        if (r < p) std::swap(p, r);
        const double s = (box_[q] - p[q]) / (r[q] - p[q]);
        vec3 x{};
        for (std::size_t k = 0; k < 3; ++k) x[k] = p[k] + s * (r[k] - p[k]);
        x[q] = box_[q];
        next[kept++] = {x, none};
      }
    }
    PROGISO_ASSERT(kept <= 6);
    poly = next;
    size = kept;
  }
  // Each of the input's inside vertices should end up in a kept triangle; one that does not may
  // be unused (finish() checks).
  std::array<bool, 3> used{};
  for (std::size_t i = 1; i + 1 < size; ++i) {
    const std::array<corner*, 3> t{&poly[0], &poly[i], &poly[i + 1]};
    if (t[0]->p == t[1]->p || t[1]->p == t[2]->p || t[0]->p == t[2]->p) continue;
    std::array<std::uint32_t, 3> tri{};
    for (std::size_t k = 0; k < 3; ++k) {
      if (t[k]->id == none) {
        t[k]->id = clip_vertex(t[k]->p);
      } else {
        for (std::size_t j = 0; j < 3; ++j) used[j] = used[j] || ids[j] == t[k]->id;
      }
      tri[k] = t[k]->id;
    }
    mesh_.triangles.push_back(tri);
  }
  for (std::size_t j = 0; j < 3; ++j) {
    if ((ids[j] & outside_bit) == 0 && !used[j]) suspects_.push_back(ids[j]);
  }
}

std::size_t mesh_builder::position_hash::operator()(const vec3& p) const noexcept {
  std::uint64_t h = 0;
  for (const double v : p) {
    // + 0.0 makes -0.0 hash as 0.0 (they compare equal).
    h = (h ^ std::bit_cast<std::uint64_t>(v + 0.0)) * 0x9E3779B97F4A7C15ULL;
  }
  return static_cast<std::size_t>(h ^ (h >> 29));
}

}  // namespace progiso::detail
