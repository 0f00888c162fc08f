// tests/support/reference_mt.hpp — the independent reference extractor (oracle of
// invariant 1, docs/ARCHITECTURE.md).
//
// Plain marching tetrahedra over the finest mesh of the longest-edge bisection hierarchy: every
// unit cell inside the data box is cut into 6 tetrahedra around the diagonal that joins its
// all-even corner to its all-odd corner (docs/ARCHITECTURE.md, "The hierarchy"), and each
// tetrahedron is marched on its own. The rules for colours, vertex positions, quad diagonals and
// orientation are those stated in progiso/core/surface/marching.hpp, re-implemented here from that
// text alone: nothing of progiso's extraction code is called, so a bug there cannot hide in the
// oracle. The fully refined progressive surface must equal this one vertex for vertex (same
// positions, bit for bit) and triangle for triangle (same oriented triangles, in any order).
//
// Use it in tests and benchmarks (as the non-progressive baseline). It visits every cell, so it
// costs O(voxels) time and O(surface) memory; volumes with NaN samples are not supported.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso::test {

/// The reference surface and the grid edge of each of its vertices.
struct reference_surface {
  /// One vertex per crossed edge of the finest mesh, in physical coordinates; triangles
  /// oriented with the right-hand normal pointing from black (f > w) to white (f <= w).
  triangle_mesh mesh;
  /// edge key (doubled midpoint packed x | y << 21 | z << 42) of each vertex, parallel to
  /// mesh.vertices.
  std::vector<std::uint64_t> vertex_keys;
};

/// Marching tetrahedra at isovalue w on the finest bisection mesh of `v`, by the rules of
/// marching.hpp. Vertices appear in order of first use (cells in z, y, x order).
/// Throws progiso::error when w is NaN.
[[nodiscard]] reference_surface reference_marching_tetrahedra(const volume& v, double isovalue);

/// The number of triangles reference_marching_tetrahedra() produces, from colours alone
/// (1 per tetrahedron with one or three black corners, 2 per tetrahedron with two).
[[nodiscard]] std::size_t reference_triangle_count(const volume& v, double isovalue);

}  // namespace progiso::test
