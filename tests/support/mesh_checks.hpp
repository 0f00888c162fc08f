// tests/support/mesh_checks.hpp — validity checks of extracted surfaces (invariant 2,
// docs/ARCHITECTURE.md).
//
// Each check takes a triangle_mesh and returns a check_result: whether the property holds and,
// when it does not, a one-line description of the first violation (triangle and vertex indices
// and positions), so that a failing gtest assertion says what is wrong and where. The checks
// are exact: topology is compared by vertex index, boundary planes by exact coordinate
// equality (extraction computes every vertex bit-identically, so no tolerance is needed), and
// geometry uses CGAL's exact predicates (Exact_predicates_inexact_constructions_kernel).
//
// check_valid_cut() bundles what every surface a reader can obtain must satisfy: edge-manifold,
// consistently oriented, open only along the data box, no degenerate triangles, no
// self-intersections. same_surface() compares two meshes as sets of oriented triangles by
// exact positions, independent of vertex numbering and triangle order (invariant 1).
//
// Cost: O(T log T) for the topological checks; the self-intersection test uses CGAL's box
// intersection, about O(T log T) for well-spread surfaces (seconds for 10^6 triangles).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso::test {

/// The outcome of one check: ok, or the first violation found.
struct check_result {
  bool ok = true;
  /// Empty when ok; otherwise a description of the first violation.
  std::string message;

  explicit operator bool() const noexcept { return ok; }
};

/// Every vertex index is in range, no triangle repeats a vertex index, no two triangles use the
/// same three vertices (in any order), and every undirected edge belongs to at most 2 triangles.
[[nodiscard]] check_result edge_manifold(const triangle_mesh& mesh);

/// Every boundary edge (an edge of exactly one triangle) lies in a face plane of the box: for
/// one axis q, both endpoints have coordinate q exactly equal to box_min[q], or both exactly
/// equal to box_max[q].
[[nodiscard]] check_result boundary_on_box(const triangle_mesh& mesh, const vec3& box_min,
                                           const vec3& box_max);

/// No boundary edge at all: every edge belongs to 2 or more triangles.
[[nodiscard]] check_result watertight(const triangle_mesh& mesh);

/// Every edge of exactly two triangles is traversed once in each direction.
[[nodiscard]] check_result consistently_oriented(const triangle_mesh& mesh);

/// No triangle has two equal positions or three collinear positions (exact predicate).
[[nodiscard]] check_result no_degenerate_triangles(const triangle_mesh& mesh);

/// No two triangles intersect except in a shared edge or vertex (CGAL's
/// Polygon_mesh_processing::does_self_intersect, exact predicates). A mesh that is not a valid
/// polygon mesh (non-manifold edge or vertex, inconsistent orientation, repeated vertex) fails
/// with that reason, since CGAL's test needs one. The message counts intersecting pairs (at most
/// 1000) and describes the first.
[[nodiscard]] check_result no_self_intersections(const triangle_mesh& mesh);

/// Pairs of intersecting triangles, counted up to `limit` (a degenerate triangle counts as one
/// pair); nullopt when the mesh is not a valid polygon mesh, so CGAL cannot test it.
[[nodiscard]] std::optional<std::size_t> self_intersection_count(const triangle_mesh& mesh,
                                                                 unsigned limit = 1000);

/// V − E + F, where V counts only vertices used by some triangle and E undirected edges
/// (0 when a vertex index is out of range).
[[nodiscard]] std::int64_t euler_characteristic(const triangle_mesh& mesh);

/// Number of connected components (triangles connected through shared vertex indices;
/// triangles with an out-of-range index are ignored).
[[nodiscard]] std::size_t connected_components(const triangle_mesh& mesh);

/// Number of boundary edges (edges of exactly one triangle; 0 when an index is out of range).
[[nodiscard]] std::size_t boundary_edge_count(const triangle_mesh& mesh);

/// Signed volume enclosed by the triangles, Σ det(v0, v1, v2) / 6: positive when a closed
/// surface's right-hand normals point outward.
[[nodiscard]] double signed_volume(const triangle_mesh& mesh);

/// The data box of a volume: origin and origin + (dims − 1) · spacing, computed the way
/// extraction computes positions, so boundary vertices lie exactly on its faces.
[[nodiscard]] std::array<vec3, 2> data_box(const volume& v);

/// Every check, for one mesh.
struct mesh_report {
  check_result manifold;
  check_result boundary;
  check_result oriented;
  check_result nondegenerate;
  check_result self_intersection_free;
  std::int64_t euler = 0;
  std::size_t components = 0;
  std::size_t boundary_edges = 0;

  /// All five checks hold.
  [[nodiscard]] bool valid() const noexcept {
    return manifold.ok && boundary.ok && oriented.ok && nondegenerate.ok &&
           self_intersection_free.ok;
  }
  /// Counts and the message of every failed check, one per line.
  [[nodiscard]] std::string summary() const;
};

/// Runs every check; boundary edges are allowed on the faces of [box_min, box_max].
[[nodiscard]] mesh_report make_report(const triangle_mesh& mesh, const vec3& box_min,
                                      const vec3& box_max);

/// Success when make_report(mesh, box_min, box_max).valid() and every vertex is used by some
/// triangle; otherwise a failure carrying the summary. Use as
/// EXPECT_TRUE(check_valid_cut(mesh, lo, hi)).
[[nodiscard]] ::testing::AssertionResult check_valid_cut(const triangle_mesh& mesh,
                                                         const vec3& box_min, const vec3& box_max);

/// An oriented triangle by its positions.
using position_triangle = std::array<vec3, 3>;

/// The mesh's triangles as position triples, each rotated (orientation kept) so that its
/// lexicographically smallest position comes first, sorted. Two meshes describe the same
/// oriented surface exactly when these vectors are equal.
[[nodiscard]] std::vector<position_triangle> canonical_triangles(const triangle_mesh& mesh);

/// Success when canonical_triangles(a) == canonical_triangles(b); otherwise a failure with both
/// triangle counts, how many triangles of each are missing from the other, and the first of them.
[[nodiscard]] ::testing::AssertionResult same_surface(const triangle_mesh& a,
                                                      const triangle_mesh& b);

}  // namespace progiso::test
