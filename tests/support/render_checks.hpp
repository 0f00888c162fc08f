// tests/support/render_checks.hpp — what a renderer holds, compared as triangles: a slot pool
// (render_slots) and indexed buffers (render_buffers) as multisets of their triangles' nine
// floats (positions, or normals), so that a pool that followed changes can be compared with
// mesh_into() of the same cut whatever the slot order; and meshes compared byte for byte.
#pragma once

#include <array>
#include <map>

#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/surface_change.hpp>

namespace progiso::test {

/// Nine floats: a triangle's three corners, x y z each.
using float_corners = std::array<float, 9>;

/// The live slots' triangles (positions, or normals), each with its count.
[[nodiscard]] std::map<float_corners, int> slot_triangles(const render_slots& s,
                                                          bool normals = false);

/// The buffers' triangles (positions, or normals), each with its count.
[[nodiscard]] std::map<float_corners, int> buffer_triangles(const render_buffers& b,
                                                            bool normals = false);

/// Whether two meshes hold the same bytes: vertices and triangles in the same order.
[[nodiscard]] bool same_bytes(const triangle_mesh& a, const triangle_mesh& b);

}  // namespace progiso::test
