// progiso/core/surface/finest_surface.hpp — the finest cut's surface in two streaming passes,
// without the hierarchy: what a full refinement ends at, for a caller who wants only that.
//
// The finest bisection mesh has six tetrahedra in each unit cube of the data box, around the
// diagonal from the cube's corner with even coordinates (the corner whose every coordinate is
// even) to the opposite one, and one diagonal on each unit square, from its even corner. Its
// marching-tetrahedra surface is the finest cut's: every triangle, every vertex (interpolate()
// on the same edge ends) and every orientation (march_tet()) are the ones full refinement and
// extraction give, only numbered in another order.
//
// How, as Flying Edges does for marching cubes: no vertex is looked up. Each grid point owns
// up to seven edges (+x, +y, +z, the diagonals of the three unit squares and the unit cube of
// which it is the lowest corner); a first pass over the rows of grid points records each point's
// cube corner colours (one byte per point, from which a table gives the owned edges it crosses)
// and counts each row's vertices and its cubes' triangles (a table per cube, of the colours of
// its eight corners and the parity of its lowest corner, made once from march_tet()); prefix
// sums give every row its first vertex and first
// triangle; a second pass writes each row's vertex positions and its cubes' triangles, the id
// of an owned edge being its row's first id, plus the crossed edges of the points before it in
// the row, plus those before it at its point. Both passes run over pieces of rows through a
// parallel_loop, and the output is the same for every piece count.
//
// Progress: each pass reports the rows it has finished, in steps of 64 rows, through an
// optional callback (a command's progress bar over a 1024³ volume's seconds).
//
// Cost: the samples are read twice, each pass in row order; one byte per grid point and two
// counts per row beside the output, for a grid of up to detail::finest_whole_grid_bytes points,
// and a larger grid in slabs of z planes that hold a bounded number of those bytes (the plane
// after each slab counted twice). No allocation per vertex or triangle.
// Thread safety: reads `field` only.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso {

/// Work done by finest_surface(): rows of grid points finished by its two passes (each row
/// counted once per pass), out of `rows_total` (twice the rows of the volume). Called from
/// whichever thread finished them, one call at a time (calls never overlap; one that would is
/// dropped), with `rows_done` never decreasing from one call to the next; the last call, on the
/// calling thread after both passes, has rows_done == rows_total. Keep it short.
using finest_progress = std::function<void(std::uint64_t rows_done, std::uint64_t rows_total)>;

/// The surface of the finest cut at `isovalue` (see the file comment), positions in the physical
/// frame (origin + index × spacing), in `parts` pieces of rows through `run` (on this thread
/// when `run` is empty). Vertices are numbered by grid point (z, then y, then x) and owned
/// edge; triangles follow their cubes in the same order. `progress`, when not empty, is told the
/// rows done (finest_progress). Throws progiso::error for a non-finite isovalue and for a
/// surface of 2^32 vertices or more; what `progress` throws ends the call.
[[nodiscard]] triangle_mesh finest_surface(const volume& field, double isovalue,
                                           const parallel_loop& run = {}, std::size_t parts = 1,
                                           const finest_progress& progress = {});

/// The surface of a uniform cut one or more levels above the finest: marching tetrahedra on
/// the grid of every `stride`-th sample along each axis, the box's last sample plane included
/// (stride a power of two; 1 gives finest_surface()). Where `stride` divides each dims − 1,
/// this is exactly the cut of the hierarchy in which every diamond of scale ≥ `stride` is split
/// (cubes of side `stride`, six tetrahedra each around the diagonal from the corner whose
/// coordinates are even multiples of `stride`): the surface refinement reaches there, vertex
/// for vertex. Otherwise the last layer of cells along an axis is thinner than `stride` (it
/// ends on the box's last plane) and its tetrahedra are those cells', stretched: a valid
/// surface (no crack, no self-intersection, open only on the box) that covers the whole box.
/// Cost: the subsampled grid's samples copied (pieces of planes through `run`), then
/// finest_surface() on them: between 1 / stride³ (the samples) and 1 / stride² (the output,
/// which follows the surface's area) of the finest surface's (bench/README.md). `progress`
/// hears the rows of the subsampled grid. Throws progiso::error for a stride that is not a power
/// of two in [1, 2^14], a 2D field (dims[2] == 1) with a stride above 1, and as finest_surface().
[[nodiscard]] triangle_mesh uniform_surface(const volume& field, double isovalue,
                                            std::int32_t stride, const parallel_loop& run = {},
                                            std::size_t parts = 1,
                                            const finest_progress& progress = {});

/// The grid uniform_surface() reads at `stride`: dims[q] → (dims[q] − 2) / stride + 2 for
/// dims[q] ≥ 2 (every stride-th index and the last), 1 stays 1.
[[nodiscard]] index3 uniform_grid_dims(const index3& dims, std::int32_t stride) noexcept;

/// The cut of the hierarchy (hierarchy.hpp) in which every diamond of scale ≥ `stride` is split,
/// clipped to the data box as a cut is meshed (stride a power of two; 1 gives finest_surface()):
/// uniform_surface()'s cells, all `stride` wide, the last layer reaching past the box where
/// `stride` does not divide dims − 1 (its samples those of the box's last plane, as the
/// hierarchy's padding repeats the nearest sample) and clipped there (mesh_clip.hpp). So it is
/// the surface the engine's refinement reaches for that split set, on every grid, as a set of
/// triangles vertex for vertex (numbered otherwise). Cost: uniform_surface()'s, plus one scan of
/// its triangles where the box is not divided. Throws as uniform_surface().
[[nodiscard]] triangle_mesh uniform_cut(const volume& field, double isovalue, std::int32_t stride,
                                        const parallel_loop& run = {}, std::size_t parts = 1,
                                        const finest_progress& progress = {});

/// Work done by ladder_surface(): the rows of the cut at `stride` done so far, as
/// finest_progress says them for each cut in turn (rows_total is that cut's own).
using ladder_progress =
    std::function<void(std::int32_t stride, std::uint64_t rows_done, std::uint64_t rows_total)>;

/// What ladder_surface() made by its deadline.
struct ladder_result {
  triangle_mesh mesh;       ///< the finest uniform cut done
  std::int32_t stride = 0;  ///< its stride (1: the finest cut)
  int levels_done = 0;      ///< uniform cuts finished, the returned one included
  bool abandoned = false;   ///< a finer cut was begun and given up at the deadline
  /// A finer cut was begun and given up because its memory could not be had (std::bad_alloc:
  /// a data limit, or a cut larger than the machine): the finest cut that fit is returned.
  bool out_of_memory = false;
  double first_seconds = 0.0;  ///< from the call to the first (coarsest) cut done
  std::size_t triangles = 0;   ///< the triangles of the finest cut done (also with on_cut)
};

/// The time-critical scenario on uniform cuts: uniform_surface() at strides 2^k, 2^(k−1), …, 1,
/// coarse to fine, until `deadline`; returns the finest one done. The first stride is the
/// largest power of two that leaves at least 8 cells along the longest axis (at most 17 points
/// along each axis, so it is cheap), and it is always made, whatever the deadline. Each later one
/// is begun only if its predicted time (the last one's rates per grid point and per output
/// element, its points and four times the last one's output) ends before the deadline, and is
/// given up (its work dropped) when, after its first pass, its exact output no longer fits, or
/// when the deadline passes: between planes of its copy, between steps of sizing its output,
/// every 64 rows of its passes. A later cut whose memory cannot be had (std::bad_alloc) is given
/// up the same way (out_of_memory); the first cut's throws. A 2D field (dims[2] == 1) has one
/// stride: 1. `progress` hears the rows of each cut in turn, with its stride; what it throws ends
/// the call.
[[nodiscard]] ladder_result ladder_surface(const volume& field, double isovalue,
                                           std::chrono::steady_clock::time_point deadline,
                                           const parallel_loop& run = {}, std::size_t parts = 1,
                                           const ladder_progress& progress = {});

namespace detail {

/// Storage for a surface's output, asked for once its vertex and triangle counts are known: a
/// mesh whose vectors' capacity the output reuses (its contents are dropped), or an empty one.
/// An engine hands back a retired cut's storage this way, so that a new cut neither maps fresh
/// pages nor waits while the old ones are unmapped.
using mesh_storage = std::function<triangle_mesh(std::uint64_t vertices, std::uint64_t triangles)>;

/// A mesh whose positions are floats (what a renderer or numpy takes), for callers that would
/// otherwise round a triangle_mesh's doubles into a second array.
struct float_mesh {
  std::vector<std::array<float, 3>> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};
/// finest_surface() with each position rounded to the nearest float as it is written: the
/// same triangles, and positions equal to finest_surface()'s rounded, in half its vertex memory.
/// `slab_bytes` as finest_slab_planes()'s.
[[nodiscard]] float_mesh finest_surface_floats(const volume& field, double isovalue,
                                               const parallel_loop& run = {}, std::size_t parts = 1,
                                               const finest_progress& progress = {},
                                               std::size_t slab_bytes = 0);

/// A grid whose corner bytes (one per grid point) are at most this is meshed in one slab.
inline constexpr std::uint64_t finest_whole_grid_bytes = std::uint64_t{256} << 20;
/// A larger grid's slabs hold at most this many corner bytes (at least one plane).
inline constexpr std::uint64_t finest_slab_bytes = std::uint64_t{64} << 20;
/// The z planes of each slab the finest surface is made in: all of them when the grid's corner
/// bytes are at most finest_whole_grid_bytes, else as many as finest_slab_bytes hold, or, when
/// `slab_bytes` is not 0, as many as it holds (at least one, at most dims[2]). A slab's first
/// pass also covers the plane after it, whose vertices its cubes' triangles name; so what the
/// passes hold beside the output is one slab's corner bytes and row counts, and the surface,
/// its ids and its order are the same for every slab size.
[[nodiscard]] std::int64_t finest_slab_planes(const index3& dims,
                                              std::size_t slab_bytes = 0) noexcept;

/// A piece of the finest surface: a slab's vertices, whose ids begin at `first_vertex` (each
/// piece's follow the last one's), and the triangles of its cubes, naming vertices by their ids
/// in the whole surface (those of the slab's last plane of cubes name vertices of the next
/// piece). The callee may change or take the piece's arrays (they are cleared after it returns).
using finest_piece = std::function<void(triangle_mesh& piece, std::uint64_t first_vertex)>;
/// finest_surface() handed over slab by slab (finest_slab_planes()), so that the output held is
/// one slab's: a surface larger than memory goes to a file as it is made. The pieces, joined in
/// order, are finest_surface()'s mesh. One slab gives one piece, the whole surface. Called on the
/// calling thread, between the slabs' passes; throws as finest_surface(), and what `piece` throws.
/// A share of the finest surface for one of several processes (MPI ranks, each meshing planes of
/// one grid): the planes [z_begin, z_end) whose grid points' owned edges give its vertices and
/// whose cubes give its triangles (z_end −1: to the last plane), their ids starting at
/// first_vertex and first_triangle (the counts of the shares before it). The shares of a
/// partition of the planes, joined in order, are finest_surface()'s mesh, ids and all. A share
/// reads the samples of planes [z_begin, z_end + 2) alone.
struct finest_share {
  std::int64_t z_begin = 0;
  std::int64_t z_end = -1;
  std::uint64_t first_vertex = 0;
  std::uint64_t first_triangle = 0;
};
/// The vertices and triangles of `share`'s planes (its ids ignored): one pass over its samples,
/// slab by slab, nothing written. Throws as finest_surface().
[[nodiscard]] std::array<std::uint64_t, 2> finest_share_counts(const volume& field, double isovalue,
                                                               const parallel_loop& run,
                                                               std::size_t parts,
                                                               const finest_share& share,
                                                               std::size_t slab_bytes = 0);
void finest_surface_pieces(const volume& field, double isovalue, const parallel_loop& run,
                           std::size_t parts, const finest_progress& progress,
                           const finest_piece& piece, std::size_t slab_bytes = 0,
                           const finest_share& share = {});
/// finest_surface() writing into storage from `storage` (when it is not empty) where the grid is
/// one slab (finest_slab_planes()); a larger grid grows its output slab by slab, as without it.
[[nodiscard]] triangle_mesh finest_surface(const volume& field, double isovalue,
                                           const parallel_loop& run, std::size_t parts,
                                           const finest_progress& progress,
                                           const mesh_storage& storage);

/// What an engine asks of the ladder beyond ladder_surface()'s.
struct ladder_hooks {
  /// uniform_cut() (hierarchy cuts, clipped) instead of uniform_surface() (stretched).
  bool hierarchy_cuts = false;
  /// A cut of this stride is shown already (0: none): the ladder begins one stride below it,
  /// and no cut is forced, so that nothing is made past the deadline.
  std::int32_t shown_stride = 0;
  /// Asked wherever the deadline is: true gives up the cut in progress and ends the call.
  std::function<bool()> stopping;
  /// Each cut done, coarse to fine, handed over as it is made (the result then holds no mesh).
  std::function<void(triangle_mesh&&, std::int32_t stride)> on_cut;
  /// Storage for each cut's output (mesh_storage), when not empty.
  mesh_storage storage;
  /// Begin every finer cut while time is left and give it up only at the deadline (or a stop),
  /// not when the model says it will not end in time. For a caller that has shown each cut as
  /// it was made (an engine), a cut given up costs nothing shown, and the model, fitted on the
  /// cuts of one call, is pessimistic in a call's first cuts (cold pages and workers).
  bool begin_when_time_is_left = false;
  /// Corner bytes a cut's slab of z planes may hold (0: finest_slab_planes()'s default). A cut
  /// of more than one slab is asked to stop between slabs and as its passes report progress.
  std::size_t slab_bytes = 0;
};

/// ladder_surface() with hooks (the engine's deadline runs on an unrefined root).
[[nodiscard]] ladder_result ladder_surface(const volume& field, double isovalue,
                                           std::chrono::steady_clock::time_point deadline,
                                           const parallel_loop& run, std::size_t parts,
                                           const ladder_progress& progress,
                                           const ladder_hooks& hooks);

}  // namespace detail

}  // namespace progiso
