// progiso/core/surface/normals.hpp — unit vertex normals from the field's gradient, for shading.
//
// add_vertex_normals(mesh, field) fills mesh.normals: at each vertex, −∇f / |∇f|, where ∇f is
// the gradient of central differences at the grid points (one-sided on the faces of the data
// box, 0 along an axis one sample thick) interpolated trilinearly at the vertex, each index
// difference divided by its axis's spacing. So the normals live in the physical frame of the
// positions (origin + index × spacing) and point out of the region f > isovalue, the side every
// triangle's right-hand normal faces. On a vertex of an axis-aligned grid edge the trilinear
// weights reduce to the edge's two ends, so the normal is the linear interpolation of their
// gradients, the rule marching cubes implementations shade with (VTK's vtkFlyingEdges3D with
// ComputeNormals on; the VTK tests compare the two); a vertex on a face or body diagonal of a
// cell, or on a coarse cut's longer edge, blends the cell's corners around it. Where the
// interpolated gradient vanishes (samples whose central differences cancel, such as a pattern
// alternating along an axis), the vertex takes the normalised sum of its triangles'
// area-weighted normals instead, which faces the same side.
//
// Cost: one pass over the vertices, each reading the gradients of the cell corners with a
// non-zero weight (2 on an axis-aligned edge, up to 8; 6 samples each), in pieces that `run`
// may spread over threads; a pass over the triangles only when some gradient vanished.
// Thread safety: reads `field` only; `mesh` is the caller's.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso {

/// Whether a mesh handed to a renderer carries vertex normals, and from what.
enum class vertex_normals : std::uint8_t {
  none,      ///< positions only
  gradient,  ///< add_vertex_normals(): −∇f / |∇f| at each vertex
};

/// Sets mesh.normals to one unit normal per vertex (see the file comment). Precondition: the
/// positions are physical coordinates of `field`, as extraction from `field` writes them (a
/// position outside the data box is taken at the nearest point of the box). `field` may be a
/// smoothed volume (smooth()): its gradient is that of its computed samples.
void add_vertex_normals(triangle_mesh& mesh, const volume& field, const parallel_loop& run = {});
/// The same normals as floats, 3 per vertex into `normals`, without a mesh (a caller handing
/// float arrays on, such as the Python binding, whose vertices are not yet floats); and, when
/// `gradient_l1` is not null, one float per vertex there: |∂f/∂i| + |∂f/∂j| + |∂f/∂k| of the
/// same interpolated gradient in index units (the `values` scikit-image's marching_cubes gives
/// each vertex; 0 where the gradient vanishes). `triangles` serve the vertices whose gradient
/// vanishes, as in add_vertex_normals().
void vertex_normals_into(std::span<const vec3> vertices,
                         std::span<const std::array<std::uint32_t, 3>> triangles,
                         const volume& field, float* normals, float* gradient_l1,
                         const parallel_loop& run = {});
/// The same from float positions (detail::finest_surface_floats(); each taken as the double it
/// is).
void vertex_normals_into(std::span<const std::array<float, 3>> vertices,
                         std::span<const std::array<std::uint32_t, 3>> triangles,
                         const volume& field, float* normals, float* gradient_l1,
                         const parallel_loop& run = {});

}  // namespace progiso
