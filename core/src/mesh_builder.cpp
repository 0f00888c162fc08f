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

void mesh_builder::clip_any(const std::array<std::uint32_t, 3>& flagged) {
  clipped_any_ = true;
  clip({flagged[0] & ~outside_bit, flagged[1] & ~outside_bit, flagged[2] & ~outside_bit});
}

triangle_mesh mesh_builder::finish() {
  const auto& sp = vol_.spacing();
  const auto& org = vol_.origin();
  // In place: the grid positions are not needed after this (no second array to fault in).
  mesh_.vertices = std::move(grid_);
  for (vec3& v : mesh_.vertices) {
    for (std::size_t q = 0; q < 3; ++q) v[q] = org[q] + v[q] * sp[q];
  }
  // Drop vertices that only clipped-away triangles used. Without clipping every vertex is
  // used and ids are already in order of first use.
  if (clipped_.empty() && !clipped_any_) return std::move(mesh_);
  const std::size_t count = mesh_.vertices.size();
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
  PROGISO_ASSERT(grid_.size() < outside_bit);
  const auto id = static_cast<std::uint32_t>(grid_.size());
  const auto ends = hier_.edge_ends(key);
  const double fa = vol_.value(ends[0][0], ends[0][1], ends[0][2]);
  const double fb = vol_.value(ends[1][0], ends[1][1], ends[1][2]);
  const vec3 p = interpolate(ends[0], fa, ends[1], fb, w_);
  grid_.push_back(p);
  const bool inside = p[0] <= box_[0] && p[1] <= box_[1] && p[2] <= box_[2];
  return inside ? id : id | outside_bit;
}

std::uint32_t mesh_builder::clip_vertex(const vec3& p) {
  const auto [it, inserted] = clipped_.try_emplace(p, static_cast<std::uint32_t>(grid_.size()));
  if (inserted) grid_.push_back(p);
  return it->second;
}

// Sutherland–Hodgman against x_q ≤ box_q. Each crossing point is computed from the segment's
// ends in lexicographic order, so the two triangles sharing a segment get the same point.
void mesh_builder::clip(const std::array<std::uint32_t, 3>& ids) {
  // Clipping a convex polygon by a plane adds at most one vertex: at most 6 after 3 planes.
  std::array<std::uint32_t, 8> poly{ids[0], ids[1], ids[2]};
  std::array<std::uint32_t, 8> next{};
  std::size_t size = 3;
  for (std::size_t q = 0; q < 3 && size >= 3; ++q) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < size; ++i) {
      const std::uint32_t a = poly[i];
      const std::uint32_t b = poly[i + 1 == size ? 0 : i + 1];
      const bool ain = grid_[a][q] <= box_[q];
      const bool bin = grid_[b][q] <= box_[q];
      if (ain) next[kept++] = a;
      // A crossing whose inside end lies on the plane is that end itself, already emitted.
      const bool on_plane = ain ? grid_[a][q] == box_[q] : grid_[b][q] == box_[q];
      if (ain != bin && !on_plane) {
        vec3 p = grid_[a];
        vec3 r = grid_[b];
        if (r < p) std::swap(p, r);
        const double s = (box_[q] - p[q]) / (r[q] - p[q]);
        vec3 x{};
        for (std::size_t k = 0; k < 3; ++k) x[k] = p[k] + s * (r[k] - p[k]);
        x[q] = box_[q];
        next[kept++] = clip_vertex(x);
      }
    }
    PROGISO_ASSERT(kept <= 6);
    poly = next;
    size = kept;
  }
  if (size < 3) return;
  for (std::size_t i = 1; i + 1 < size; ++i) {
    const std::array<std::uint32_t, 3> t{poly[0], poly[i], poly[i + 1]};
    if (grid_[t[0]] == grid_[t[1]] || grid_[t[1]] == grid_[t[2]] || grid_[t[0]] == grid_[t[2]]) {
      continue;
    }
    mesh_.triangles.push_back(t);
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
