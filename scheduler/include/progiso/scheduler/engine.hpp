// progiso/scheduler/engine.hpp — the concurrent progressive isosurface engine.
//
// What it is. An engine owns one volume's hierarchy and range data (built once, in parallel, by
// the first run, independent of the isovalue; the root surface published at construction needs
// none) and the progressive surface of the current isovalue. Split records of ready diamonds
// (all parents split; compute_split() is pure) are published in dependency order, every record
// after its parents'. On one thread a run is a loop in its driver. On more, a full run (and an
// error target in any order) is oneTBB tasks over slabs of the volume's grid planes, each
// taking its ready diamonds plane by plane, publishing in batches and making children ready by
// atomic parent counts after publication; error, budget and deadline runs are tasks over
// subtrees, each depth first from its own stack, band by band of the priority queue (a quarter
// octave of nested errors each, largest first; a child below the band waits for its own).
// engine_options::schedule selects a oneTBB flow graph for those instead: splits computed in
// parallel in batches, a serial commit step that publishes them and keeps the priority queue, at
// most `tasks_per_thread × threads` batches in flight (slower: its commit step is serial).
//
// The four scenarios of the paper (§1):
//  - quality-driven:  refine_until(ε) splits until every remaining error is ≤ ε;
//  - time-critical:   refine_for(τ1), take a snapshot, refine_for(τ2) to improve it;
//  - asynchronous:    start(goal) returns at once; cancel() from any thread stops every worker
//                     within one split, and what was published stays;
//  - dynamic:         set_isovalue(w) from any thread cancels in-flight work, publishes the new
//                     isovalue's root surface at once and resumes the interrupted goal.
//
// Snapshots. A root object holds one isovalue, its split records (an append_log) and a record
// index per grid vertex. The commit step writes a record, then the diamond's record index, then
// release-publishes the record count W. snapshot() pins an epoch guard, protects the root
// pointer and acquire-loads W: O(1), no lock, no retry loop beyond epoch_guard::protect's
// bounded one, and it never waits for a writer nor delays one. The snapshot's cut is exactly the
// first W records: a triangle of record r < W is in it iff its owner has no record below W.
// It holds one isovalue by construction (the isovalue is a field of the root) and one
// parent-closed cut (records are published parent before child). An isovalue change swaps the
// root pointer and retires the old root through the epoch domain (interval-based: a stalled
// snapshot pins only the root it reads, see concurrent/epoch.hpp).
//
// Determinism: records are pure, so the snapshot's surface depends only on its set of split
// diamonds. mesh() orders records by diamond (canonical order), so the same split set gives the
// same mesh bytes whatever the thread count or completion order.
//
// Thread safety: every member function of engine may be called from any thread. Control calls
// (set_isovalue, start, cancel, wait, refine_*) serialise among themselves on a mutex; readers
// (snapshot, statistics, isovalue, running) never take it. A surface_snapshot belongs to the
// thread that took it (it holds that thread's epoch guard) and must be destroyed on that thread
// before the engine. TBB types stay out of this header.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <progiso/concurrent/epoch.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/refine/detail/path_choice.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/normals.hpp>
#include <progiso/core/surface/split_record.hpp>
#include <progiso/core/surface/surface_change.hpp>

namespace progiso {

class engine;
class hierarchy_exporter;

namespace detail {
struct engine_root;
struct engine_impl;
}  // namespace detail

/// Progress of a running engine, passed to engine_options::progress from the commit step.
struct engine_progress {
  std::uint64_t splits = 0;
  std::uint64_t triangles = 0;
  /// Error of the next ready diamond (0 when none). In a run by grid plane (full refinement,
  /// an error target in any order) the largest error queued for a later goal: 0 in a full run,
  /// at most the target in an error run.
  double next_error = 0.0;
  int depth = 0;  ///< depth of the last diamond published
};

/// How runs by priority (error, budget, deadline) share more than one thread. Full runs always
/// use tasks; one thread always runs a loop in the driver.
enum class refinement_schedule {
  /// Tasks over subtrees, band by band of the priority queue (the default: a deadline buys
  /// markedly more of the surface within a voxel this way than on the flow graph;
  /// bench/README.md).
  tasks,
  /// A oneTBB flow graph: compute tasks in batches feeding a serial commit node.
  flow_graph,
};

struct engine_options {
  /// Worker threads; 0: all cores. Capped at default_concurrency(), the size of oneTBB's pool.
  unsigned threads = 0;
  /// See refinement_schedule.
  refinement_schedule schedule = refinement_schedule::tasks;
  /// Diamonds per compute task of the flow graph (refinement_schedule::flow_graph; a TBB task
  /// costs about as much as a split, so a task of one diamond would spend most of its time on
  /// scheduling; bench/README.md).
  std::size_t batch = 32;
  /// In-flight batches per thread of the flow graph: bounds what a cancel must drain.
  std::size_t tasks_per_thread = 4;
  /// Reclamation of retired roots. Roots are few and large (one per isovalue change), so each
  /// retirement advances the era clock and is followed by a flush: a reader stalled in a
  /// snapshot then pins only its own root (plus, at most, the one retired in its era).
  epoch_options reclamation{1, 1, 3, true};
  /// Fill retired roots with a poison pattern before freeing them (stress tests: a use after
  /// free reads poison that snapshot::check_integrity() reports).
  bool poison_retired = false;
  /// Called with the generation of every published root as it is destroyed (stress tests count
  /// them; engine_statistics::roots), on the engine's reclaimer thread or in ~engine.
  std::function<void(std::uint64_t generation)> on_reclaim;
  /// Called from the commit step about every `progress_interval` splits (keep it short). It may
  /// call engine::cancel() (a stop request) and any reader; an exception it throws stops the
  /// run and is rethrown by wait() / refine().
  std::function<void(const engine_progress&)> progress;
  std::uint64_t progress_interval = 4096;
  /// Refine the smoothed field of the volume (smoothing.hpp) instead of the data itself, when
  /// active(). field() is then the smoothed volume; the constructor throws progiso::error on
  /// bad parameters (as smooth() does).
  smoothing smooth;
  /// Uniform cuts by streaming passes (finest_surface.hpp) where they buy more than splits: a
  /// full run publishes the finest cut made by finest_surface(); a deadline run (without a
  /// focus) on a root that holds no split yet — a fresh engine, a new isovalue — publishes the
  /// ladder's uniform cuts of the hierarchy coarse to fine (uniform_cut(): every diamond of
  /// scale ≥ the stride split, clipped to the box), each as soon as it is made, until the
  /// deadline; a later deadline run goes on down the ladder. Such a cut is a cut of the
  /// hierarchy without records (surface_snapshot::uniform_stride()): an error, budget or focused
  /// run from it refines a root of records out of sight and publishes it once its goal is
  /// reached, so readers never see a coarser surface than the uniform cut. Off (or for a 2D or
  /// smoothed field): every run refines the hierarchy split by split, with a record per split
  /// (what hierarchy streams and split sets need).
  bool uniform_cuts = true;
};

// What a run refines towards: refine_goal (core/refine/goal.hpp).

/// Counters of the current isovalue's refinement (and of the engine's life). Readable while
/// running: each counter is exact at some moment of the run, not all at the same moment.
struct engine_statistics {
  refine_statistics refine;      ///< of the current root (isovalue)
  std::uint64_t published = 0;   ///< records published (including the root record)
  std::uint64_t discarded = 0;   ///< splits computed but not published (cancel, deadline)
  std::uint64_t batches = 0;     ///< compute tasks run for this root
  std::uint64_t generation = 0;  ///< isovalue changes so far
  /// When the current isovalue's first surface (its root surface) became visible to snapshots:
  /// set_isovalue() may publish it before the run on the old isovalue has stopped.
  std::chrono::steady_clock::time_point surface_published_at{};
  std::uint64_t runs = 0;                ///< runs started (engine life)
  std::uint64_t cancelled_runs = 0;      ///< runs stopped before reaching their goal
  epoch_statistics reclamation;          ///< retired/reclaimed roots
  std::uint64_t snapshot_retries = 0;    ///< bounded re-reads in snapshot() (era clock moved)
  std::uint64_t root_bytes = 0;          ///< records and triangles of the current root
  std::uint64_t retired_bytes = 0;       ///< of retired roots not yet reclaimed
  std::uint64_t peak_retired_bytes = 0;  ///< the largest retired_bytes so far
  /// Roots (isovalues) that took the cleared per-vertex arrays of a reclaimed root instead of
  /// mapping fresh ones (engine life).
  std::uint64_t recycled_roots = 0;
  /// Roots published (engine life): one per isovalue, one per uniform cut, and one per root of
  /// records refined out of sight and then shown (engine_options::uniform_cuts). Every one but
  /// the current is retired (reclamation.retired), and engine_options::on_reclaim hears each
  /// as it is destroyed.
  std::uint64_t roots = 0;
};

/// Where a snapshot's cut stood (surface_snapshot::mark()): plain data, kept by a renderer
/// between frames (on any thread) to ask a later snapshot what changed since.
struct cut_mark {
  const engine* owner = nullptr;
  std::uint64_t generation = 0;
  std::uint64_t records = 0;  ///< 0: no cut
  /// Which of the engine's roots (a new one per isovalue and per uniform cut published).
  std::uint64_t root = 0;
};

/// An immutable view of one published cut of one isovalue. Cheap to take, O(cut records) to
/// walk. Holds an epoch guard of the thread that took it: destroy it on that thread, before
/// the engine. Move-only.
class surface_snapshot {
 public:
  surface_snapshot() = default;
  surface_snapshot(surface_snapshot&&) noexcept = default;
  surface_snapshot& operator=(surface_snapshot&&) noexcept = default;
  surface_snapshot(const surface_snapshot&) = delete;
  surface_snapshot& operator=(const surface_snapshot&) = delete;
  ~surface_snapshot() = default;

  [[nodiscard]] bool valid() const noexcept { return root_ != nullptr; }
  [[nodiscard]] double isovalue() const noexcept;
  /// Number of isovalue changes before this snapshot's root (0 for the first isovalue).
  [[nodiscard]] std::uint64_t generation() const noexcept;
  /// Split diamonds in the cut with a record (records − 1): 0 for a uniform cut.
  [[nodiscard]] std::uint64_t split_count() const noexcept { return published_ - 1; }
  /// 0 for a cut of split records; s for a uniform cut made by streaming passes
  /// (engine_options::uniform_cuts): every diamond of scale ≥ s split, 1 being the finest cut.
  [[nodiscard]] std::int32_t uniform_stride() const noexcept;
  /// Triangles in the cut before box clipping: O(1).
  [[nodiscard]] std::uint64_t triangle_count() const noexcept;
  /// Whether the diamond with this grid index is split in the cut (in a uniform cut of stride
  /// s: whether its scale is s or more).
  [[nodiscard]] bool is_split(std::uint64_t index) const noexcept;
  /// Calls f(grid index) for every split diamond of the cut, in publication order (a uniform
  /// cut's: every diamond of scale ≥ its stride whose range holds the isovalue, by grid index;
  /// the others hold no surface at any cut).
  void for_each_split(const std::function<void(std::uint64_t)>& f) const;
  /// Calls f(owned_triangle) for every triangle of the cut (edge keys, unclipped). A uniform
  /// cut holds positions, not keys: throws progiso::error there.
  void for_each_triangle(const std::function<void(const owned_triangle&)>& f) const;
  /// The cut's surface: indexed, clipped to the data box, physical coordinates, records in
  /// canonical order (by diamond), so it depends only on the split set.
  [[nodiscard]] triangle_mesh mesh() const;
  /// The coarser cut of the split diamonds whose nested error exceeds max_error, by the range
  /// data's exact errors: makes them first if no run has (engine::ranges(); so, like it, not
  /// from the progress callback). A uniform cut has no records to choose from: throws
  /// progiso::error there (refine_until() gives the cut by error).
  [[nodiscard]] triangle_mesh mesh_cut(double max_error) const;
  /// mesh() as float positions and indices in buffers the caller owns (a renderer's, reused
  /// frame after frame: their storage is kept, see render_buffers); with
  /// vertex_normals::gradient also a unit normal per vertex in out.normals (engine::add_normals),
  /// else out.normals is emptied.
  void mesh_into(render_buffers& out, vertex_normals normals = vertex_normals::none) const;
  /// mesh_cut(max_error) into the caller's buffers, normals as mesh_into().
  void mesh_cut_into(double max_error, render_buffers& out,
                     vertex_normals normals = vertex_normals::none) const;
  /// The cut of the records r (1 … split_count()) with split[r] != 0 (entry 0 is unused; the
  /// set must be closed under parents): a cut between the root surface and this one, made as
  /// mesh() makes it. Hierarchy streams number records as the engine does, so a stream's split
  /// sets (hierarchy_stream.hpp) apply here. Throws progiso::error for a set of another size.
  [[nodiscard]] triangle_mesh mesh_of_records(const std::vector<std::uint8_t>& split) const;
  /// Where this cut stands, for change_since() on a later snapshot. O(1).
  [[nodiscard]] cut_mark mark() const noexcept;
  /// Makes this snapshot the cut of its first `records` records (at least 1, the root surface;
  /// no more than it holds): a cut the engine published on its way here, since a record is
  /// published after its parents', so every prefix of the publication order is closed under
  /// parents. A renderer that cannot take a large change at once catches up by prefixes, each
  /// a valid surface. A uniform cut (no records) is left as it is. O(1).
  void truncate(std::uint64_t records) noexcept;
  /// What changed from the cut `earlier` marked to this one (surface_change.hpp): the ids of the
  /// triangles gone and the pieces added, float positions clipped to the data box in physical
  /// coordinates as mesh_into() gives them, and with vertex_normals::gradient their normals.
  /// When `earlier` is of another engine or isovalue, of no cut, or later than this cut, the
  /// change is the whole cut (`rebuilt`). Applied in order to a render_slots pool, the changes
  /// leave in it the triangles of mesh_into(), as a set, bit for bit. Costs what changed: the
  /// records published since `earlier` and their parents' (plus one pass over the root
  /// surface's triangles when a root diamond split). In parallel on the engine's thread count
  /// for large changes, the same output for every thread count. `out`'s storage is reused.
  void change_since(const cut_mark& earlier, surface_change& out,
                    vertex_normals normals = vertex_normals::none) const;
  /// Checks that the root is alive and every record in the cut is well-formed (owners in the
  /// grid, triangle counts plausible); returns false on poison or garbage (stress tests).
  [[nodiscard]] bool check_integrity() const noexcept;

 private:
  friend class engine;
  friend class hierarchy_exporter;
  template <class Keep>
  triangle_mesh build(Keep&& keep) const;

  epoch_guard guard_;
  const engine* owner_ = nullptr;
  const detail::engine_root* root_ = nullptr;
  std::uint64_t published_ = 0;
};

/// The engine. See the file comment.
class engine {
 public:
  /// Builds the hierarchy of `vol` (which must outlive the engine) and publishes the root surface
  /// of `isovalue`: no pass over the volume. The range data is built, in parallel, by the first
  /// run (a deadline run builds it between slices of refinement; see ranges_built()) or the first
  /// call of ranges(). Throws progiso::error for a non-finite isovalue.
  engine(const volume& vol, double isovalue, engine_options options = {});
  /// The same for a volume the engine takes over (a temporary such as read_nrrd(…) or
  /// make_demo_volume(…) binds here, so it cannot dangle).
  engine(volume&& vol, double isovalue, engine_options options = {});
  /// The same for a volume shared with the caller; the engine keeps it alive. Throws
  /// progiso::error for a null pointer.
  engine(std::shared_ptr<const volume> vol, double isovalue, engine_options options = {});
  /// Cancels any run and waits for it; every root is reclaimed. Precondition: no snapshot of
  /// this engine is alive.
  ~engine();
  engine(const engine&) = delete;
  engine& operator=(const engine&) = delete;

  /// Swaps to isovalue w: publishes w's root surface, cancels in-flight work, retires the old
  /// root, and resumes the interrupted run's goal (if a run was active). Once a retired root's
  /// memory is waiting for reuse (after the first change), the new surface is published before
  /// the old run has stopped; the old root is destroyed on the engine's reclaimer thread, not in
  /// this call. Throws progiso::error for a non-finite w, and when called from the progress
  /// callback.
  void set_isovalue(double w);
  /// Starts refining towards `goal` in the background (cancelling a run in progress). Throws
  /// progiso::error when called from the progress callback.
  void start(const refine_goal& goal);
  /// Stops the run: every worker stops within one split; returns once all are quiet. What was
  /// published stays; unpublished ready diamonds go back to the queue. No-op when idle.
  /// From engine_options::progress (a thread of the run itself) it only requests the stop and
  /// returns at once; the run then ends within one split per worker.
  void cancel();
  /// Blocks until no run is active (finished or cancelled). Rethrows an exception that the
  /// progress callback threw during the run (which stopped it). Throws progiso::error when
  /// called from the progress callback.
  void wait();
  /// Blocking runs: start(goal) then wait(). Return true when the goal was reached (false when
  /// cancelled, or for refine_for, when the deadline stopped the run). Rethrows as wait().
  bool refine(const refine_goal& goal);
  bool refine_full() { return refine(refine_goal::full()); }
  bool refine_until(double max_error) { return refine(refine_goal::error(max_error)); }
  bool refine_for(std::chrono::steady_clock::duration budget) {
    return refine(refine_goal::until(deadline_after(std::chrono::steady_clock::now(), budget)));
  }

  /// A consistent view of the last published cut. O(1); never waits. Any thread.
  [[nodiscard]] surface_snapshot snapshot() const;
  /// The current isovalue. Any thread.
  [[nodiscard]] double isovalue() const;
  [[nodiscard]] bool running() const noexcept;
  /// True when no ready diamond is left (the cut is full resolution). Any thread.
  [[nodiscard]] bool done() const;
  [[nodiscard]] engine_statistics statistics() const;

  [[nodiscard]] const volume& field() const noexcept;
  [[nodiscard]] const hierarchy& hierarchy_of() const noexcept;
  /// Sets mesh.normals for a mesh of field() (a snapshot's mesh(), mesh_cut()): −∇f / |∇f| at
  /// each vertex (add_vertex_normals(), surface/normals.hpp), on the engine's thread count. Any
  /// thread.
  void add_normals(triangle_mesh& mesh) const;
  /// The range data; builds what no run has built yet (on the engine's threads). Any thread but
  /// the progress callback's (throws there when the data is not complete).
  [[nodiscard]] const range_data& ranges() const;
  [[nodiscard]] unsigned threads() const noexcept;
  /// Seconds the range data took to build; 0 until it is built.
  [[nodiscard]] double range_build_seconds() const noexcept;
  /// Whether the ranges are complete. A deadline run that starts before they are refines
  /// without culling while it builds pieces of them in between (coarse levels first), so that a
  /// deadline shorter than the build still buys surface. Deadline and full runs need no exact
  /// errors: they order by error bounds (hi − lo; full refinement splits the same set either
  /// way) until an error or budget run, ranges() or mesh_cut() makes the exact errors (a second
  /// pass, several times costlier than the first); full refinement tests children by their
  /// ranges alone.
  /// Any thread.
  [[nodiscard]] bool ranges_built() const noexcept;
  /// Whether the range data's exact errors exist (ranges(), error and budget runs make them).
  /// Any thread.
  [[nodiscard]] bool errors_built() const noexcept;
  /// Bytes of the range data as far as it is built (no build). Any thread.
  [[nodiscard]] std::size_t range_bytes() const;

 private:
  friend class surface_snapshot;
  void init(std::shared_ptr<const volume> owned, const volume& vol, double isovalue,
            engine_options options);
  std::unique_ptr<detail::engine_impl> impl_;
};

/// extract_isosurface() through the engine with `threads` workers (0: all cores): the
/// command-line tool's path. A full goal gives the same mesh for every thread count; a
/// deadline returns the surface made by it.
[[nodiscard]] extract_result extract_isosurface_parallel(const volume& vol, double isovalue,
                                                         const extract_options& options,
                                                         unsigned threads);

namespace detail {
/// extract_isosurface_parallel() on the chosen path (benchmarks and tests that compare the
/// two: core/refine/detail/path_choice.hpp).
[[nodiscard]] extract_result extract_isosurface_parallel(const volume& vol, double isovalue,
                                                         const extract_options& options,
                                                         unsigned threads, path_choice path);
}  // namespace detail

}  // namespace progiso
