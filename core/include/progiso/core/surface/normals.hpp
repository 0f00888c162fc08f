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
#include <functional>
#include <span>
#include <vector>

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

namespace detail {

/// A vertex's partial sums for the fallback where its gradient vanishes, over some of the
/// triangles around it: the sum of their area-weighted normals and the last unit normal among
/// them (zero for none), as add_vertex_normals() accumulates them in triangle order.
struct normal_partial {
  std::uint64_t vertex = 0;  ///< an id of the whole mesh
  vec3 sum{};
  vec3 any{};
};

/// add_vertex_normals() for one share of a mesh made in shares (MPI ranks), whose triangles follow
/// the triangles of the shares before it in the whole mesh's order. `mesh` holds the share's
/// triangles and every vertex they name, at ids local to the share; `global` gives each local
/// vertex's id in the whole mesh. `carried` holds the partial sums, over the earlier shares'
/// triangles, of vertices whose gradient vanishes (by global id, ascending; any vertices). Sets
/// mesh.normals for every vertex the share's triangles complete: those with a gradient, and
/// those whose gradient vanishes and `last(global id)` says no later share's triangle names.
/// Returns the partial sums for the others (after this share's triangles) and for the carried
/// vertices this share does not name and `last` says are not done, by global id ascending: what
/// the next share is carried. The whole mesh's normals are then add_vertex_normals()' exactly.
[[nodiscard]] std::vector<normal_partial> add_share_normals(
    triangle_mesh& mesh, std::span<const std::uint64_t> global, const volume& field,
    std::span<const normal_partial> carried, const std::function<bool(std::uint64_t)>& last,
    const parallel_loop& run = {});

}  // namespace detail

}  // namespace progiso
