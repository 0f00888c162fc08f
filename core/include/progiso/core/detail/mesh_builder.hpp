// progiso/core/detail/mesh_builder.hpp — turns the triangles of a cut (edge keys) into an indexed
// mesh: deduplicates surface vertices by edge key, places each on its edge (canonical
// interpolation, bit-identical for every triangle that shares it), clips the pieces that reach
// past the data box (only coarse tetrahedra of padded hierarchies do; crossing points are
// computed from the segment's ends in lexicographic order so neighbours agree exactly), drops
// vertices only clipped-away triangles used, and maps to physical coordinates.
//
// Shared by the sequential refiner and the engine's snapshots. Not thread-safe: one builder per
// extraction. Cost: O(triangles added) expected.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include <progiso/core/detail/flat_map.hpp>
#include <progiso/core/hierarchy.hpp>
#include <progiso/core/mesh.hpp>
#include <progiso/core/volume.hpp>

namespace progiso::detail {

class mesh_builder {
 public:
  /// `expected`: about how many vertices the mesh will have (a sizing hint).
  mesh_builder(const hierarchy& hier, const volume& vol, double isovalue, std::size_t expected);
  /// Adds one oriented triangle given by the edge keys of its vertices.
  void add(const std::array<std::uint64_t, 3>& keys);
  /// The mesh; the builder is spent.
  triangle_mesh finish();

 private:
  std::uint32_t vertex(std::uint64_t key);
  std::uint32_t clip_vertex(const vec3& p);
  void clip(const std::array<std::uint32_t, 3>& ids);

  const hierarchy& hier_;
  const volume& vol_;
  double w_;
  vec3 box_{};
  flat_map keys_;
  std::map<vec3, std::uint32_t> clipped_;
  bool clipped_any_ = false;
  std::vector<vec3> grid_;
  triangle_mesh mesh_;
};

}  // namespace progiso::detail
