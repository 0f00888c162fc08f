// progiso/core/refine/refiner.hpp — sequential progressive isosurface refinement and cut
// extraction.
//
// A refiner holds one isovalue's progressive surface over a volume: the set of split diamonds
// (always parent-closed: a diamond is split only after all its parents) and the split records
// produced so far. The surface of the current cut is the marching-tetrahedra surface of the
// conforming bisection mesh it defines, so every surface a refiner returns is crack-free and free
// of self-intersections, and the fully refined one equals marching tetrahedra on the finest mesh.
//
// Work is output sensitive: only diamonds whose nested range straddles the isovalue are ever
// split (range_data.hpp). The first surface, from the root tetrahedra, needs no split at all.
// Ready diamonds (all parents split) wait in a queue ordered breadth first (full refinement) or
// by largest nested error (quality-, budget- and time-driven refinement).
//
// Records: the root record holds the surface pieces of the root tetrahedra; each split appends
// the pieces of its children tetrahedra, each tagged with the diamond that owns it. A piece is
// in a cut exactly when its record is in the cut and its owner is not, so extract() and
// extract_cut() walk records without touching the field except to place vertices.
//
// extract_isosurface() is the one-shot entry point on this thread; the command-line tool runs
// extract_isosurface_parallel() (scheduler/engine.hpp), the same through the engine.
//
// Thread safety: a refiner is a single-threaded object; distinct refiners over the same
// volume, hierarchy and range data may run concurrently.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/borrow.hpp>
#include <progiso/core/base/detail/chunked_store.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/detail/vertex_pages.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/split_record.hpp>

namespace progiso {

/// Counters of a refinement.
struct refine_statistics {
  std::uint64_t splits = 0;            ///< diamonds split
  std::uint64_t visited = 0;           ///< diamonds examined (became ready), split or not
  std::uint64_t culled = 0;            ///< examined and rejected by their range
  std::uint64_t triangles = 0;         ///< triangles in the current cut (before box clipping)
  std::uint64_t record_triangles = 0;  ///< triangles held by all records
  std::array<std::uint64_t, tet_case_count> cases{};
  std::array<std::uint64_t, primitive_count> primitives{};
  std::array<std::uint64_t, split_configuration_count> configurations{};
};

/// Order in which ready diamonds are split. The split set reached by refining fully is the
/// same in every order; depth first keeps the working set local (fastest full refinement),
/// breadth first refines coarse to fine, largest error first serves quality and budgets.
enum class refine_order { breadth_first, depth_first, largest_error_first };

/// Sequential progressive refinement at one isovalue.
class refiner {
 public:
  /// Starts at the root cut. The volume, hierarchy and range data must outlive the refiner.
  /// Throws progiso::error when the isovalue is not finite.
  refiner(const volume& vol, const hierarchy& hier, const range_data& ranges, double isovalue,
          refine_order order = refine_order::largest_error_first);
  /// Refused at compile time: the refiner keeps references to all three (detail/borrow.hpp).
  template <class V, class H, class R>
  requires detail::any_rvalue<V, H, R> refiner(V&&, H&&, R&&, double,
                                               refine_order = refine_order::largest_error_first)
  = delete;
  ~refiner();
  refiner(const refiner&) = delete;
  refiner& operator=(const refiner&) = delete;

  [[nodiscard]] double isovalue() const noexcept { return isovalue_; }
  /// True when no split can change the surface any more (the cut is full resolution).
  [[nodiscard]] bool done() const noexcept;
  /// Nested error of the next diamond to split (0 when done). In largest-error-first order the
  /// queue takes errors by bands at most a factor 1.25 wide, so within a band the next error need
  /// not be the largest; aim_at_error() makes the order exact at one error.
  [[nodiscard]] double next_error() const noexcept;
  /// Orders every ready diamond of error > max_error before every other, so that
  /// `while (!done() && next_error() > max_error) split_next();` splits exactly the diamonds of
  /// error > max_error (refine_to_error() calls it). O(ready diamonds) when the target moves.
  void aim_at_error(double max_error);
  /// Depth of the next diamond to split (-1 when done).
  [[nodiscard]] int next_depth() const noexcept;

  /// Splits the next ready diamond. Returns false when none is left.
  bool split_next();
  /// Splits the next ready diamond only if the cut then has at most max_triangles triangles.
  bool split_next_within(std::uint64_t max_triangles);

  /// Splits until done.
  void refine_full();
  /// Splits, largest error first, until every remaining error is ≤ max_error.
  void refine_to_error(double max_error);
  /// Splits while the cut stays within max_triangles.
  void refine_to_triangles(std::uint64_t max_triangles);
  /// Splits until the deadline; checked between splits.
  void refine_until(std::chrono::steady_clock::time_point deadline);
  /// Splits every ready diamond whose grid index satisfies `in_set`, until none is left; the
  /// others are dropped from the queue. Given a parent-closed set of diamonds, this splits
  /// exactly that set (sequential replay of a concurrent engine's cut).
  void refine_set(const std::function<bool(std::uint64_t)>& in_set);

  [[nodiscard]] std::uint64_t triangle_count() const noexcept { return stats_.triangles; }
  [[nodiscard]] const refine_statistics& statistics() const noexcept;
  [[nodiscard]] bool is_split(const ipoint& centre) const noexcept;

  /// The surface of the current cut: indexed, clipped to the data box, physical coordinates.
  [[nodiscard]] triangle_mesh extract() const;
  /// The coarser cut made of the split diamonds whose nested error exceeds max_error.
  [[nodiscard]] triangle_mesh extract_cut(double max_error) const;

 private:
  // One split: what the extraction (detail::cut_mesher, as the engine's) reads of it, and its
  // error. Record 0 is the root surface, kept in root_triangles_.
  struct record {
    std::uint64_t diamond;       // the centre's grid index (no_owner for the root record)
    const packed_group* groups;  // `count` groups, contiguous in groups_
    double error;                // NaN: not computed (see errors_needed_)
    std::uint32_t count;
    std::uint32_t crossed;  // split_summary::crossed: the crossed edges at the centre
    std::int32_t scale;     // the diamond's h (packed_group's unit)
  };
  struct ready {
    double error;
    std::uint64_t index;
    ipoint centre;
    std::int32_t scale;  // h and type of the diamond, known from its parent
    std::int16_t type;
    std::int16_t depth;
  };
  struct queue;

  bool split(std::uint64_t max_triangles);
  static constexpr std::size_t prefetch_distance = 8;
  // The mesh of the cut made of the records r with in_cut(r) (closed under parents).
  template <class InCut>
  triangle_mesh build_mesh(const InCut& in_cut) const;

  const volume& vol_;
  const hierarchy& hier_;
  const range_data& ranges_;
  double isovalue_;
  detail::vertex_pages<std::uint8_t> state_;  // per grid vertex: split flag, split parents

  std::vector<owned_triangle> root_triangles_;
  detail::chunked_store<packed_group> groups_;  // packed_group: one word for one or two triangles
  std::vector<packed_group> scratch_;
  detail::chunked_store<record> records_;
  std::unique_ptr<queue> queue_;
  bool prefetch_;  // prefetching samples pays off (the volume is larger than the cache)
  // The queue orders by error (largest_error_first). In the other orders a ready diamond's
  // error is left unknown when the range lookup is skipped (one of its tetrahedra holds
  // surface: see surface_bit in refiner.cpp).
  bool errors_needed_;
  detail::sample_threshold threshold_;  // the isovalue, for range_data::straddles()
  // Case, primitive and configuration counts of interior splits are kept per classification
  // (split_summary::classification) and added into stats_ when statistics() is read: one
  // increment per split instead of twenty.
  mutable refine_statistics stats_;
  mutable std::array<std::uint64_t, interior_classification_count> pending_{};
  mutable bool any_pending_ = false;
  void add_classification(const split_summary& s, std::uint64_t times) const noexcept;
};

// -------------------------------------------------------------------------------------------
// One-shot extraction (what the command-line tool runs).

/// Progress of a running extraction. On the hierarchy's path: splits, triangles and depths;
/// on the direct path (the finest cut by finest_surface()): the rows of grid points its two passes
/// have done (finest_progress, surface/finest_surface.hpp) and depth == max_depth.
struct extract_progress {
  std::uint64_t splits = 0;
  std::uint64_t triangles = 0;
  int depth = 0;      ///< depth being refined
  int max_depth = 0;  ///< deepest level of the hierarchy
  /// The direct path: rows done by its two passes, of rows_total (twice the volume's rows);
  /// both 0 on the hierarchy's path.
  std::uint64_t rows_done = 0;
  std::uint64_t rows_total = 0;
  /// The direct paths: the stride of the cut whose rows these are (1: the finest; above 1, a
  /// deadline's uniform cut, extract_options::deadline_ladder, whose rows are of its grid);
  /// 0 on the hierarchy's path.
  std::int32_t stride = 0;
};

struct extract_options {
  /// What to refine towards (core/refine/goal.hpp). kind::full gives the finest cut by
  /// finest_surface() (surface/finest_surface.hpp), two streaming passes over the samples,
  /// rather than by refining the hierarchy to the end: the same surface, its vertices and
  /// triangles numbered in grid order. kind::deadline counts to goal.deadline, so the caller
  /// says when the clock starts (refine_goal::within() from the moment the volume is in memory).
  refine_goal goal;
  /// Called about every 4096 splits; on the direct path every 64 rows of a pass (one call at a
  /// time, from any of the run's threads).
  std::function<void(const extract_progress&)> progress;
  /// Give the mesh vertex normals from the field's gradient (add_vertex_normals(),
  /// surface/normals.hpp), after the pipeline: timed as normals_seconds.
  bool normals = false;
  /// kind::deadline: spend the time on uniform cuts, coarse to fine (ladder_surface(),
  /// surface/finest_surface.hpp): each a few streaming passes over every stride-th sample, the
  /// finest one done by the deadline returned. False: refine the hierarchy by priority (largest
  /// error first) until the deadline, which adapts to the field but splits diamonds at a
  /// fraction of the passes' speed (bench/README.md, "What a deadline buys"). A 2D field
  /// (dims[2] == 1) has no coarser uniform cut: it refines by priority either way. Public
  /// because the command's --by-priority chooses it.
  bool deadline_ladder = true;
};

struct extract_result {
  triangle_mesh mesh;
  refine_statistics stats;
  double range_build_seconds = 0.0;
  /// Root surface extracted: from the volume in memory (the engine's path), from the start of
  /// refinement (extract_isosurface()). The direct path of extract_isosurface() makes no root
  /// surface: its first surface is the finest one, from the volume in memory.
  double first_surface_seconds = 0.0;
  double refine_seconds = 0.0;
  double extract_seconds = 0.0;
  double total_seconds = 0.0;
  /// Volume in memory → indexed mesh of the cut in memory (range data, refinement, extraction;
  /// no file I/O).
  double pipeline_seconds = 0.0;
  /// The vertex normals, when asked for (extract_options::normals); not in pipeline_seconds.
  double normals_seconds = 0.0;
  std::size_t range_bytes = 0;
  bool isovalue_outside_data = false;  ///< empty because the isovalue misses the data range
  /// The mesh came from finest_surface(): no range data, no splits; extract_seconds is its two
  /// passes.
  bool finest_direct = false;
  /// The mesh is a uniform cut of the ladder (extract_options::deadline_ladder): its stride (1:
  /// the finest cut); 0 otherwise. No range data, no splits; extract_seconds is its cuts' time.
  std::int32_t ladder_stride = 0;
  /// The ladder gave up a finer cut because its memory could not be had (ladder_result).
  bool ladder_out_of_memory = false;
};

/// Throws progiso::error for a non-finite isovalue or an invalid goal (check_goal(); shared by
/// every entry).
void check_extract_inputs(double isovalue, const extract_options& options);

/// What the direct path passes to finest_surface() to tell
/// `options.progress` of its rows (an empty callback when `options.progress` is; shared by
/// every entry): depth and max_depth both `max_depth`.
[[nodiscard]] finest_progress direct_progress(const extract_options& options, int max_depth);
/// The same for ladder_surface() (the deadline's uniform cuts), each report with its cut's
/// stride.
[[nodiscard]] ladder_progress ladder_direct_progress(const extract_options& options, int max_depth);

/// Builds the hierarchy and range data, refines towards the goal and extracts the cut; for
/// refine_goal::kind::full, finest_surface() instead (and for a deadline, unless
/// deadline_ladder is false, ladder_surface()), on this thread. Throws progiso::error for a
/// non-finite isovalue or an invalid goal.
[[nodiscard]] extract_result extract_isosurface(const volume& vol, double isovalue,
                                                const extract_options& options);

}  // namespace progiso
