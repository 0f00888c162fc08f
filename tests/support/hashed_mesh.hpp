// tests/support/hashed_mesh.hpp — an extraction that names surface vertices by a hash of their
// edge keys: the tests' reference for the library's extraction (core/surface/detail/cut_mesher.hpp,
// which names them by rank without any lookup). It takes a cut's triangles as edge keys,
// deduplicates vertices by key, places each on its edge (canonical interpolation), clips at the
// data box with the library's clip_to_box and maps to physical coordinates; the mesh is the same
// surface as the library's, numbered in order of first use.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/detail/mesh_clip.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso::test {

using detail::flat_map;
using detail::position_hash;

class hashed_mesh_builder {
 public:
  /// `expected`: about how many vertices the mesh will have (a sizing hint).
  hashed_mesh_builder(const hierarchy& hier, const volume& vol, double isovalue,
                      std::size_t expected);
  /// Adds one oriented triangle given by the edge keys of its vertices.
  void add(const std::array<std::uint64_t, 3>& keys) {
    // Consecutive triangles often share vertices (the two of a quad, neighbours in one split),
    // so the previous triangle's keys are tried before the hash.
    const auto id = [&](std::uint64_t key) {
      for (std::size_t i = 0; i < 3; ++i) {
        if (last_keys_[i] == key) return last_ids_[i];
      }
      return vertex(key);
    };
    const std::uint32_t a = id(keys[0]);
    const std::uint32_t b = id(keys[1]);
    const std::uint32_t c = id(keys[2]);
    last_keys_ = keys;
    last_ids_ = {a, b, c};
    // Vertex ids carry the outside flag (outside_bit), so a triangle is tested against the
    // data box without reading its vertices' positions.
    if (((a | b | c) & outside_bit) == 0) {
      mesh_.triangles.push_back({a, b, c});
    } else {
      clip({a, b, c});
    }
  }
  /// The mesh; the builder is spent.
  triangle_mesh finish();

 private:
  // Vertex ids are below 2^31 (a mesh has fewer than 2^31 vertices: positions alone would take
  // 48 GiB). A vertex outside the data box is never in the output (clipping removes it); it is
  // kept apart, in outside_, and its id is its index there with this bit set.
  static constexpr std::uint32_t outside_bit = std::uint32_t{1} << 31;
  [[nodiscard]] const vec3& position(std::uint32_t id) const noexcept {
    return (id & outside_bit) != 0 ? outside_[id & ~outside_bit] : grid_[id];
  }
  // The id of the vertex on the edge with this key; a hash hit is all most calls do (each vertex
  // is reached from about six triangles), so that part is inline.
  std::uint32_t vertex(std::uint64_t key) {
    const auto [stored, inserted] = keys_.try_emplace_ref(key, 0);
    if (inserted) *stored = new_vertex(key);  // new_vertex() does not touch keys_
    return *stored;
  }
  std::uint32_t new_vertex(std::uint64_t key);
  std::uint32_t clip_vertex(const vec3& p);
  void clip(const std::array<std::uint32_t, 3>& ids);

  const hierarchy& hier_;
  const volume& vol_;
  double w_;
  vec3 box_{};
  flat_map keys_;
  std::array<std::uint64_t, 3> last_keys_{flat_map::empty_key, flat_map::empty_key,
                                          flat_map::empty_key};
  std::array<std::uint32_t, 3> last_ids_{};
  // Clip vertices by position.
  std::unordered_map<vec3, std::uint32_t, position_hash> clipped_;
  std::vector<std::uint32_t> suspects_;  // inside vertices clipping left out of a triangle
  std::vector<vec3> grid_;               // vertices inside the data box, then clip vertices
  std::vector<vec3> outside_;
  triangle_mesh mesh_;
};

/// The mesh of the cut made of a parent-closed set of split diamonds (grid indices), through
/// hashed_mesh_builder: the root triangles and each split's groups (compute_root, compute_split)
/// whose owner is not in the set.
[[nodiscard]] triangle_mesh hashed_mesh_of(const hierarchy& hier, const volume& vol,
                                           double isovalue,
                                           const std::vector<std::uint64_t>& split);

}  // namespace progiso::test
