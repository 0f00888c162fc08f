#include "support/hashed_mesh.hpp"

#include <algorithm>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/surface/marching.hpp>
#include <progiso/core/surface/split_record.hpp>

namespace progiso::test {

using detail::clip_to_box;
using detail::drop_unused;
using detail::physical_position;

hashed_mesh_builder::hashed_mesh_builder(const hierarchy& hier, const volume& vol, double w,
                                         std::size_t expected)
    : hier_(hier), vol_(vol), w_(w), keys_(expected) {
  for (std::size_t q = 0; q < 3; ++q) box_[q] = static_cast<double>(hier.data_max()[q]);
  // A closed surface has about half as many vertices as triangles; clipping at the data box
  // (padded hierarchies only) adds some of both. Reserving for them saves a copy of each array.
  const bool padded = hier.grid_max() != hier.data_max();
  const std::size_t slack = padded ? expected / 8 + 64 : 0;
  grid_.reserve(expected + slack);
  mesh_.triangles.reserve(2 * (expected + slack));
}

triangle_mesh hashed_mesh_builder::finish() {
  // In place: the grid positions are not needed after this (no second array to fault in).
  mesh_.vertices = std::move(grid_);
  for (vec3& v : mesh_.vertices) v = physical_position(vol_, v);
  drop_unused(mesh_, suspects_);
  return std::move(mesh_);
}

std::uint32_t hashed_mesh_builder::new_vertex(std::uint64_t key) {
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

std::uint32_t hashed_mesh_builder::clip_vertex(const vec3& p) {
  const auto [it, inserted] = clipped_.try_emplace(p, static_cast<std::uint32_t>(grid_.size()));
  if (inserted) grid_.push_back(p);
  return it->second;
}

void hashed_mesh_builder::clip(const std::array<std::uint32_t, 3>& ids) {
  const std::array<vec3, 3> p{position(ids[0]), position(ids[1]), position(ids[2])};
  const std::array<bool, 3> used = clip_to_box(
      p, ids, box_, [this](const vec3& x) { return clip_vertex(x); },
      [this](const std::array<std::uint32_t, 3>& t) { mesh_.triangles.push_back(t); });
  for (std::size_t j = 0; j < 3; ++j) {
    if ((ids[j] & outside_bit) == 0 && !used[j]) suspects_.push_back(ids[j]);
  }
}

triangle_mesh hashed_mesh_of(const hierarchy& hier, const volume& vol, double isovalue,
                             const std::vector<std::uint64_t>& split) {
  std::vector<std::uint64_t> sorted = split;
  std::sort(sorted.begin(), sorted.end());
  const auto live = [&sorted](std::uint64_t owner) {
    return owner == no_owner || !std::binary_search(sorted.begin(), sorted.end(), owner);
  };
  hashed_mesh_builder b(hier, vol, isovalue, 64);
  std::vector<owned_triangle> roots;
  for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
    (void)compute_root(hier, vol, isovalue, r, roots);
  }
  for (const owned_triangle& t : roots) {
    if (live(t.owner)) b.add(t.keys);
  }
  std::vector<packed_group> groups;
  for (const std::uint64_t d : split) {
    groups.clear();
    const ipoint c = hier.point(d);
    const std::int32_t scale = hier.scale_of(c);
    (void)compute_split(hier, vol, isovalue, c, scale, groups);
    for_each_unpacked(
        hier, d, scale, groups.data(), 0, static_cast<std::uint32_t>(groups.size()), live,
        [&b](std::uint64_t, const std::array<std::uint64_t, 3>& keys) { b.add(keys); });
  }
  return b.finish();
}

}  // namespace progiso::test
