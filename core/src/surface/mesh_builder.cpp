#include <progiso/core/surface/detail/mesh_builder.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/surface/marching.hpp>

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
  // In place: the grid positions are not needed after this (no second array to fault in).
  mesh_.vertices = std::move(grid_);
  for (vec3& v : mesh_.vertices) v = physical_position(vol_, v);
  drop_unused(mesh_, suspects_);
  return std::move(mesh_);
}

// Every vertex is used (in order of first use) unless clipping left one of its triangles' inside
// corners out (a corner on the box's face with the rest of the piece beyond it) and no other
// triangle uses it: then the unused ones are dropped.
void drop_unused(triangle_mesh& m, const std::vector<std::uint32_t>& suspects,
                 const parallel_loop& run, std::size_t parts) {
  if (suspects.empty()) return;
  const std::size_t count = m.vertices.size();
  {
    // The suspects marked, then each mark a triangle meets cleared: a byte read per corner,
    // written only at suspects (a bit vector of all vertices set for every corner cost a
    // read-modify-write per corner, and ran on one thread).
    std::vector<std::uint8_t> unused(count, 0);
    for (const std::uint32_t v : suspects) unused[v] = 1;
    const std::size_t n = m.triangles.size();
    parts = std::clamp<std::size_t>(parts, 1, std::max<std::size_t>(n, 1));
    run_loop(run, parts, [&](std::size_t k) {
      for (std::uint64_t i = piece_begin(n, parts, k); i < piece_begin(n, parts, k + 1); ++i) {
        for (const std::uint32_t v : m.triangles[i]) {
          const std::atomic_ref<std::uint8_t> mark(unused[v]);
          // relaxed: the parallel loop's join orders these stores before the check below.
          if (mark.load(std::memory_order_relaxed) != 0) mark.store(0, std::memory_order_relaxed);
        }
      }
    });
    if (std::none_of(suspects.begin(), suspects.end(),
                     [&unused](std::uint32_t v) { return unused[v] != 0; })) {
      return;
    }
  }
  std::vector<std::uint32_t> remap(count, ~std::uint32_t{0});
  std::uint32_t n = 0;
  for (auto& t : m.triangles) {
    for (auto& v : t) {
      if (remap[v] == ~std::uint32_t{0}) remap[v] = n++;
      v = remap[v];
    }
  }
  if (n != count) {
    std::vector<vec3> kept(n);
    for (std::size_t i = 0; i < count; ++i) {
      if (remap[i] != ~std::uint32_t{0}) kept[remap[i]] = m.vertices[i];
    }
    m.vertices = std::move(kept);
  } else {
    std::vector<vec3> ordered(n);
    for (std::size_t i = 0; i < count; ++i) ordered[remap[i]] = m.vertices[i];
    m.vertices = std::move(ordered);
  }
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

void mesh_builder::clip(const std::array<std::uint32_t, 3>& ids) {
  const std::array<vec3, 3> p{position(ids[0]), position(ids[1]), position(ids[2])};
  const std::array<bool, 3> used = clip_to_box(
      p, ids, box_, [this](const vec3& x) { return clip_vertex(x); },
      [this](const std::array<std::uint32_t, 3>& t) { mesh_.triangles.push_back(t); });
  for (std::size_t j = 0; j < 3; ++j) {
    if ((ids[j] & outside_bit) == 0 && !used[j]) suspects_.push_back(ids[j]);
  }
}

std::size_t position_hash::operator()(const vec3& p) const noexcept {
  std::uint64_t h = 0;
  for (const double v : p) {
    // + 0.0 makes -0.0 hash as 0.0 (they compare equal).
    h = (h ^ std::bit_cast<std::uint64_t>(v + 0.0)) * 0x9E3779B97F4A7C15ULL;
  }
  return static_cast<std::size_t>(h ^ (h >> 29));
}

}  // namespace progiso::detail
