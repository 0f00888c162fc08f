// progiso/core/surface/mesh.hpp — the indexed triangle mesh that extraction produces.
//
// Vertices are stored once and shared by index; a vertex shared by several triangles is
// bit-identical for all of them by construction (extraction computes each surface vertex once,
// from a canonical ordering of its grid edge). Triangles are oriented counter-clockwise seen
// from the side of decreasing field values: the right-hand normal points out of the region
// f > isovalue. Coordinates are physical: origin + grid index * spacing.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

using vec3 = std::array<double, 3>;

/// An indexed triangle mesh.
struct triangle_mesh {
  std::vector<vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  /// Empty, or one unit normal per vertex, in the frame of the positions
  /// (add_vertex_normals(), surface/normals.hpp).
  std::vector<vec3> normals;

  [[nodiscard]] bool empty() const noexcept { return triangles.empty(); }
};

/// The right-hand normal of triangle (a, b, c) scaled by twice its area: (b − a) × (c − a). It
/// points out of the region f > isovalue for the triangles extraction writes; zero for a
/// degenerate triangle.
[[nodiscard]] inline vec3 area_normal(const vec3& a, const vec3& b, const vec3& c) noexcept {
  const vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const vec3 v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

/// A mesh as a renderer uploads it: x, y, z floats per vertex, optionally a unit normal's x, y,
/// z per vertex, and three indices per triangle, in buffers the renderer owns. Filling them again
/// (frame after frame) reuses their storage: nothing is allocated while a surface fits the capacity
/// an earlier one left.
struct render_buffers {
  std::vector<float> positions;        ///< 3 per vertex
  std::vector<float> normals;          ///< 3 per vertex when the mesh has normals, else empty
  std::vector<std::uint32_t> indices;  ///< 3 per triangle, same orientation as triangle_mesh

  [[nodiscard]] std::size_t vertex_count() const noexcept { return positions.size() / 3; }
  [[nodiscard]] std::size_t triangle_count() const noexcept { return indices.size() / 3; }
};

/// Writes m into out (resized, storage reused): each coordinate rounded to the nearest float, so
/// a vertex shared by triangles stays one vertex and bit-identical; the normals likewise when m
/// has them (out.normals is emptied, its storage kept, when it has none).
void fill_render_buffers(const triangle_mesh& m, render_buffers& out);

}  // namespace progiso
