// scheduler/src/engine_impl.hpp — the engine's inside, shared by the files that implement it.
//
// Not installed. One role per file: root.cpp (a root: its surface, its seeding, its per-vertex
// arrays), range_build.cpp (the pruning data, built in slices), refinement_graph.cpp
// (run_graph(), which picks each run's schedule, and the flow graph's compute and commit
// nodes), serial_refinement.cpp (any goal on one thread), full_refinement.cpp (tasks over the
// volume's planes or subtrees on more threads), run_control.cpp (the driver thread of a run,
// stop requests, the progress callback), snapshot.cpp (readers: snapshots and their meshes)
// and engine.cpp (the public engine: construction, control calls, statistics).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include <tbb/flow_graph.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <progiso/concurrent/append_log.hpp>
#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/detail/chunked_store.hpp>
#include <progiso/core/base/zeroed_array.hpp>
#include <progiso/core/field/detail/sample_threshold.hpp>
#include <progiso/core/refine/detail/plane_lists.hpp>
#include <progiso/core/refine/detail/prefetch.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>
#include <progiso/core/refine/detail/vertex_pages.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include "run_control.hpp"

namespace progiso::detail {

// Parts for a reader's pass over `records` records on `threads` threads: one per 2 K records, up
// to 8 per thread, because records gather where the surface is and parts of equal record ranges
// differ in work, so many small parts balance the threads (bench/README.md); one on one thread.
[[nodiscard]] inline std::size_t reader_parts(std::uint64_t records, std::size_t threads) noexcept {
  return threads <= 1
             ? 1
             : std::clamp<std::size_t>(static_cast<std::size_t>(records / 2048), 1, 8 * threads);
}

// Core's pieces of work (range slabs, mesh parts) as oneTBB tasks in the calling arena.
inline void tbb_loop(std::size_t n, const std::function<void(std::size_t)>& body) {
  tbb::parallel_for(std::size_t{0}, n, [&body](std::size_t i) { body(i); });
}

// One published split: the new triangles of the split as packed groups (in a buffer the root
// owns; unpacked with the diamond's centre and scale), the diamond and the cut's triangle count
// once it is published (no error: a cut by error reads them from the range data, see
// surface_snapshot::mesh_cut). Record 0 is the root surface: its triangles are
// engine_root::root_triangles, in plain form, and `count` is their number. The diamond's scale and
// depth are not kept: its centre gives them (hierarchy::scale_of, depth_of), and a record is paid
// for every split a root keeps, 32 bytes rather than 40.
struct engine_record {
  std::uint64_t diamond;  // grid index; no_owner for the root record
  const packed_group* groups;
  std::uint32_t count;
  std::uint32_t crossed;  // split_summary::crossed: the new edges the surface crosses
  std::uint64_t cut_triangles;
};
static_assert(sizeof(engine_record) == 32);
// A split record's diamond scale and depth, from its centre.
[[nodiscard]] inline std::int32_t record_scale(const hierarchy& hier, const engine_record& rec) {
  return hier.scale_of(hier.point(rec.diamond));
}
[[nodiscard]] inline int record_depth(const hierarchy& hier, const engine_record& rec) {
  return hier.depth_of(hier.point(rec.diamond));
}

struct ready_item {
  double error;
  int depth;
  std::uint64_t index;
};

inline constexpr std::uint64_t root_alive = 0x70726f6769736f31;  // "progiso1"

// A root's memory that does not depend on its isovalue, handed from a reclaimed root to the next
// one: the per-grid-vertex words' brick table (engine_root::record_of), every brick freed, and
// the records' chunk directory, all null. Mapping the directory fresh would make the next root
// wait for the address space's lock, which a running refinement's page faults hold
// (set_isovalue() publishes the new root before it stops the run: swap_root).
struct vertex_state {
  detail::vertex_pages<std::uint32_t> record_of;
  zeroed_array<struct engine_record*> record_chunks;
  std::uint64_t vertices = 0;  // the grid's (sizes the groups' chunks)
};

// A grid vertex's word in engine_root::record_of. 0 while none of the diamond's parents is
// split; then, while the diamond is unsplit, 2^32 − (its parents split so far), counted down by
// one per parent; once it is split, the index of its record, stored over the (then complete)
// count. Readers take a diamond as split in a cut when its word is non-zero and below the cut's
// watermark, so a count (≥ 2^32 − 4: a diamond has at most 4 parents) reads as "not in this cut",
// as 0 does. One word where there were two arrays (a 4-byte record index and a 1-byte count):
// the count and the record of a diamond share a cache line, and a brick holds 4 bytes per vertex
// instead of 5. Words live in bricks made when first written (vertex_pages.hpp), so a root's
// memory follows its surface, not the grid.
inline constexpr std::size_t max_records = (std::size_t{1} << 32) - 8;
// Parents counted so far in an unsplit diamond's word.
[[nodiscard]] constexpr std::uint32_t parents_counted(std::uint32_t word) noexcept {
  return 0u - word;
}

// One isovalue's progressive surface. Readers reach it through engine_impl::root (protected by
// an epoch guard) and read the published prefix of `records` and `record_of`; everything under
// "commit step only" belongs to whichever thread runs the serial commit (or the control thread
// while no run is active).
struct engine_root : epoch_object {
  engine_root(engine_impl& owner, double w, std::uint64_t gen, vertex_state&& state)
      : impl(&owner),
        isovalue(w),
        threshold(w),
        generation(gen),
        records(std::move(state.record_chunks)),
        record_of(std::move(state.record_of)),
        groups(detail::chunked_store<packed_group>::bits_for(state.vertices)) {}

  std::uint64_t magic = root_alive;
  engine_impl* impl;
  double isovalue;
  detail::sample_threshold threshold;  // isovalue, as straddle tests compare samples with it
  std::uint64_t generation;
  // Which of the engine's published roots this is (cut_mark::root): set just before it is
  // published; 0 for a root never published (engine_options::on_reclaim hears only the others).
  std::uint64_t serial = 0;
  // A uniform cut made by streaming passes (engine_options::uniform_cuts), shown instead of
  // records: every diamond of scale ≥ base_stride split (0: a root of records). Its mesh is
  // final (clipped, physical); record 0 holds no triangle and counts the mesh's. Set before
  // the root is published, immutable afterwards.
  std::int32_t base_stride = 0;
  triangle_mesh base;
  // When the root surface was published (make_root(), just before the store that publishes it).
  clock::time_point published_at{};
  append_log<engine_record> records;
  // Per grid vertex: the count of split parents while unsplit, then the index of the diamond's
  // record (see parents_counted). The count is written by whoever counts the children (the
  // commit step, the one-thread loop, or full-refinement tasks by fetch_sub); compute tasks load
  // it, relaxed, as a hint of which parent is last. The record index is written once, by the
  // thread that fills the record, before the release of records.publish() that first covers
  // it (full-refinement tasks: ordered before it by publish_mutex); readers load it through
  // atomic_ref (relaxed: a value below the reader's watermark was written before that watermark's
  // release, which orders it after every count before it; any other value means "not in this cut").
  detail::vertex_pages<std::uint32_t> record_of;
  // Root surface: set before the root is published, immutable afterwards.
  std::vector<owned_triangle> root_triangles;
  // The root diamonds, queued (or culled) by the first run, once the range data exists: the root
  // surface needs none, so it is published before any pass over the volume. Commit step only.
  std::vector<ipoint> root_centres;
  bool seeded = false;
  // A run on this root threw (drive()): it refines no further. Written by the driver, read by the
  // control thread after joining it.
  bool failed = false;
  // Some queued diamond is keyed by placeholder (placeholder_key): made ready without the range
  // data (a deadline run before it was built: never culled), or by full refinement, which
  // needs no errors (culled by a straddle test that stops at the first samples on both sides).
  // The driver re-queues them by their ranges before the next run (requeue_by_ranges).
  // Commit step and driver.
  bool placeholder_keys = false;
  // Some queued diamond was keyed by an error bound (hi − lo: the range data's error pass was
  // not done); re-keyed by the exact errors once they exist. Commit step and driver.
  bool bound_keys = false;
  // The focus (refine_goal::focus) the queue's exact keys are weighted by: a run with another
  // one keys them again (requeue_by_ranges). Commit step and driver.
  std::optional<refine_focus> keyed_focus;

  // Commit step only. The packed groups of the published records (each record's in one piece;
  // records point into the chunks, which never move).
  detail::chunked_store<packed_group> groups;
  detail::ready_queue<ready_item> queue{queue_discipline::largest_error};
  // Ready diamonds a deadline left on the tasks' stacks, not yet in `queue`: queued by the next
  // run on this root (queue_deadline_leftovers), so that the run returns at its deadline instead of
  // queueing them one by one (a deadline can leave so many that queueing them would push the
  // return past it; bench/README.md); a root retired by an isovalue change never queues them.
  // Commit step and driver.
  std::vector<std::vector<ready_item>> leftover;
  std::size_t leftover_items = 0;
  // Records a deadline's last publications made without counting their children as split
  // parents (each child's count and readiness test adds up over many records), counted by the next
  // run on this root (queue_deadline_leftovers) for the same reason. Commit step and driver (tasks
  // append under publish_mutex).
  std::vector<std::uint32_t> uncounted;
  std::uint64_t cut_triangles = 0;

  // Statistics (commit step writes, anyone reads).
  counter splits, visited, culled, triangles, record_triangles, discarded, batches, remaining;
  std::array<counter, tet_case_count> cases;
  std::array<counter, primitive_count> primitives;
  std::array<counter, split_configuration_count> configurations;

  // Bytes of records and triangle buffers (commit step, or the control thread while idle).
  [[nodiscard]] std::uint64_t bytes() const noexcept {
    std::uint64_t n = records.byte_size();
    n += root_triangles.capacity() * sizeof(owned_triangle);
    n += groups.byte_size();
    n += base.vertices.capacity() * sizeof(vec3) + base.triangles.capacity() * 12;
    return n;
  }
  std::uint64_t retired_bytes = 0;  // bytes() when retired

  [[nodiscard]] std::uint32_t record_index(std::uint64_t vertex) const noexcept {
    std::uint32_t* word = record_of.find(vertex);
    // relaxed: see record_of (a word never written reads 0: not split in any cut).
    return word == nullptr ? 0
                           : std::atomic_ref<std::uint32_t>(*word).load(std::memory_order_relaxed);
  }
  // The word of a grid point, made when missing (writers).
  [[nodiscard]] std::uint32_t& word(const ipoint& p) { return record_of.at(p); }
  [[nodiscard]] std::uint32_t& word(std::uint64_t vertex) { return record_of.at(vertex); }
};

// What a run's splits add to a root's statistics, counted by one thread and added to the root's
// counters when its records are published (by whoever publishes: the commit step, the one-thread
// loop, or a full-refinement task under the publication mutex).
struct split_tally {
  std::array<std::uint64_t, tet_case_count> cases{};
  std::array<std::uint64_t, primitive_count> primitives{};
  std::array<std::uint64_t, split_configuration_count> configurations{};
  std::uint64_t splits = 0;
  std::uint64_t added = 0;  // triangles of the records
  std::uint64_t visited = 0;
  std::uint64_t culled = 0;
  std::uint64_t discarded = 0;

  void count(const split_summary& s) noexcept {
    ++splits;
    added += static_cast<unsigned>(s.added_triangles);
    for (std::size_t k = 0; k < tet_case_count; ++k) cases[k] += s.cases[k];
    for (std::size_t k = 0; k < primitive_count; ++k) primitives[k] += s.primitives[k];
    ++configurations[static_cast<std::size_t>(s.configuration)];
  }
  // Adds everything to r's counters (their one writer at a time) and starts again from zero.
  void add_to(engine_root& r) noexcept {
    add_counts_to(r);
    for (std::size_t k = 0; k < tet_case_count; ++k) r.cases[k].add(cases[k]);
    for (std::size_t k = 0; k < primitive_count; ++k) r.primitives[k].add(primitives[k]);
    for (std::size_t k = 0; k < split_configuration_count; ++k) {
      r.configurations[k].add(configurations[k]);
    }
    *this = split_tally{};
  }
  // Adds the counts (splits, triangles, visited, culled, discarded) to r's counters and zeroes
  // them; the histograms (cases, primitives, configurations) stay for a later add_to().
  void add_counts_to(engine_root& r) noexcept {
    r.splits.add(splits);
    r.record_triangles.add(added);
    r.visited.add(visited);
    r.culled.add(culled);
    r.discarded.add(discarded);
    splits = added = visited = culled = discarded = 0;
  }
  // Adds o's tallies to these (o is then zero).
  void take(split_tally& o) noexcept {
    splits += o.splits;
    added += o.added;
    visited += o.visited;
    culled += o.culled;
    discarded += o.discarded;
    for (std::size_t k = 0; k < tet_case_count; ++k) cases[k] += o.cases[k];
    for (std::size_t k = 0; k < primitive_count; ++k) primitives[k] += o.primitives[k];
    for (std::size_t k = 0; k < split_configuration_count; ++k) {
      configurations[k] += o.configurations[k];
    }
    o = split_tally{};
  }
};

struct child_info {
  std::uint64_t index;
  // The child's word in the root's record_of, found (its brick made) by the compute task, so
  // the serial commit step neither looks it up nor allocates.
  std::uint32_t* word;
  double error;
  std::uint8_t parents_needed;
  bool known;  // error and straddles were looked up (else the commit step looks them up)
  bool straddles;
};

struct batch_item {
  explicit batch_item(const ready_item& i) noexcept : item(i) {}
  ready_item item;
  // Written by the compute task for the items it computes; left unset for the rest, which the
  // commit step only queues again (item): an item is ~300 bytes, zeroing it cost more than the
  // dispatch loop's other work.
  std::uint32_t* word;  // the diamond's own, as child_info::word
  std::uint32_t first;  // groups in the batch's buffer
  std::uint32_t count;
  std::int32_t scale;
  std::uint32_t crossed;
  int added;  // triangles
  int removed;
  split_configuration configuration;
  std::array<std::uint8_t, tet_case_count> cases;
  std::array<std::uint16_t, primitive_count> primitives;
  std::uint8_t children;
  std::array<child_info, 8> child;
};

// A compute task: diamonds taken from the ready queue together, computed by one worker.
struct batch {
  engine_root* root = nullptr;
  bool seed = false;  // no work: asks the commit step to fill the window (a run's start)
  std::vector<batch_item> items;
  std::size_t computed = 0;
  std::vector<packed_group> groups;
};

// The engine behind the public handle: its volume, hierarchy, range data, roots, graph and run
// state. Member functions are defined in the file of their role (see the top of this file).
struct engine_impl : run_control {
  engine_impl(std::shared_ptr<const volume> owned, const volume& v, engine_options o);

  // The range data: a staged build (range_data::staged), its pieces built with the engine's
  // threads, one slab of bricks per task. Until it is complete the engine publishes its root
  // surfaces (they need none), and a deadline run refines without culling while it builds pieces
  // in between (drive()); every other run, and engine::ranges(), build what is left first.
  // Building happens only on threads outside the arena, under `build_mutex` (the driver between
  // its graph runs, users): a thread that held an arena slot while it waited for another
  // thread's build would keep that build from the slot it needs (a deadlock with one slot, seen
  // in the stress test). Tasks read the data through built_ranges().
  const range_data& ranges() const;
  // Builds pieces until done or `until` (or a stop request, when `stop_requests`: a cancelled
  // deadline run returns within one step): the min/max pass, then (when `errors`) the error
  // pass, fused with the first where neither has started (each slab read once); finishes each
  // pass after its last piece. Caller holds build_mutex and is outside the arena. Returns
  // whether what was asked for is complete.
  bool build_ranges(clock::time_point until, bool stop_requests, bool errors) const;
  // Wall seconds per piece of the min/max pass so far, steps of `threads` pieces in parallel,
  // not counting the data's allocation (0 before the first). Caller holds build_mutex.
  // Seconds per unit of range_data::piece_work() in the min/max pieces built alone so far.
  [[nodiscard]] double seconds_per_work() const {
    return min_max_work == 0 ? 0.0 : piece_seconds / static_cast<double>(min_max_work);
  }
  // The range data inside a run's tasks when it is complete, else null (a deadline run that
  // refines before it is built): then only ranges_for_empty() may be asked.
  const range_data* built_ranges() const noexcept {
    // acquire: pairs with the release in build_ranges().
    return ranges_ready.load(std::memory_order_acquire) ? &*ranges_ : nullptr;
  }
  // The staged data's empty() needs no piece: the driver made it before the run's first task,
  // and the task graph's start orders that.
  const range_data& ranges_for_empty() const noexcept {
    PROGISO_ASSERT(ranges_.has_value());
    return *ranges_;
  }
  // The queue key of a diamond made ready without its error: above every error the data can
  // have, halving with depth, so that coarse diamonds go first.
  static double placeholder_key(int depth) noexcept {
    // A table: full refinement keys every child this way (ldexp was a library call each).
    static constexpr std::array<double, 61> keys = [] {
      std::array<double, 61> k{};
      double v = std::numeric_limits<double>::max();
      for (double& e : k) {
        e = v;
        v /= 2;  // exact: every value stays a normal double
      }
      return k;
    }();
    return keys[static_cast<std::size_t>(std::clamp(depth, 0, 60))];
  }
  // A ready diamond of a full run given by its grid index (plane_lists keep only that), keyed
  // by placeholder as full refinement queues its children.
  [[nodiscard]] ready_item full_item(std::uint64_t index) const noexcept {
    return full_item(index, hier.point(index));
  }
  // The same when the diamond's centre (hier.point(index)) is at hand.
  [[nodiscard]] ready_item full_item(std::uint64_t index, const ipoint& centre) const noexcept {
    const int depth = hier.depth_of(centre);
    return {placeholder_key(depth), depth, index};
  }
  // Empties `planes` and shapes them for this grid (one list per z plane).
  void reset_planes(plane_lists& planes) const {
    const auto count = static_cast<std::size_t>(hier.grid_max()[2]) + 1;
    planes.reset(count, hier.vertex_count() / count);
  }
  // oneTBB's pool has default_concurrency() threads; asking an arena for more only warns.
  static unsigned effective_threads(unsigned requested) {
    const auto available = static_cast<unsigned>(scheduler::default_concurrency());
    return requested == 0 ? available : std::min(requested, available);
  }
  // ---- roots ---------------------------------------------------------------------------------

  // A root of records showing the root surface of w. `published`: it is about to be published
  // (named now, name_published()); else it is refined out of sight first (launch()).
  engine_root* make_root(double w, std::uint64_t gen, bool published = true);
  // Gives r the next serial (cut_mark::root), just before it is published. Control thread.
  void name_published(engine_root& r) noexcept {
    // relaxed: a name, not an order (the store that publishes the root carries it).
    r.serial = next_serial.fetch_add(1, std::memory_order_relaxed) + 1;
  }
  // A root for a uniform cut at w (engine_root::base): no per-vertex words, its records'
  // directory and first chunk allocated. Made before a run's passes begin, one per cut it may
  // publish: mapping memory while the passes fault pages in waits for the address space's lock
  // (bench/README.md). Any thread.
  engine_root* make_base_root(double w, std::uint64_t gen);
  // Makes r show `mesh`, the uniform cut of `stride`: record 0, holding no triangle, counts the
  // mesh's. Before r is published.
  static void set_base(engine_root& r, std::int32_t stride, triangle_mesh&& mesh);
  // Whether a run towards `g` from root r takes the passes (engine_options::uniform_cuts): a
  // full goal unless r shows the finest cut; an unfocused deadline on a root that holds no
  // split record (its root surface, or a uniform cut). Control thread.
  [[nodiscard]] bool by_uniform_cuts(const engine_root& r, const refine_goal& g) const noexcept;
  // The driver of a run by uniform cuts: the finest cut (a full goal) or the ladder's cuts
  // until the deadline (deadline_ladder's model), each published, in one of the roots `made`,
  // in place of the one this run shows; the roots it did not use are destroyed after it. Publishes
  // under `control` only while the root it replaces is still the published one (an isovalue change
  // wins), and never touches a root after retiring it.
  void drive_uniform(engine_root* r, std::vector<engine_root*> made);
  // The roots a run by uniform cuts towards `g` from r may publish (make_base_root()), made by
  // launch() before the driver starts. Control thread.
  std::vector<engine_root*> make_base_roots(const engine_root& r, const refine_goal& g);
  // Under `control`: publishes `fresh` in place of `shown` and retires `shown`, when `shown` is
  // still the published root; else destroys `fresh` (never published). Returns whether it
  // published. Without `retire_now` the caller retires `shown` later (retire_root(), under
  // `control`; drive_uniform() does after its run).
  bool replace_root(engine_root* shown, engine_root* fresh, bool retire_now = true);
  // Counts a root being retired in the retired-bytes statistics. Under `control`.
  void count_retired(engine_root& old);
  // Retires a root no longer published (count_retired()) and flushes. Under `control`.
  void retire_root(engine_root* old);

  // Commit step (the first run on this root): queues the root diamonds whose range straddles
  // (every one not wholly in the padding, by placeholder, before the range data is built).
  void seed_roots(engine_root& r);

  // Marks the root when keys made with `rd` are error bounds (the error pass not done): once per
  // batch, not per queued diamond (an acquire load and a pointer chase on the commit path).
  static void mark_if_keys_are_bounds(engine_root& r, const range_data* rd) noexcept {
    if (rd != nullptr && !rd->errors_exact()) r.bound_keys = true;
  }

  // Queues the diamond centred at c (scale h) if it straddles: by its error, or by placeholder
  // in full refinement (no error needed), or by placeholder when `rd` is null and its subtree is
  // not wholly in the padding; returns whether it was queued. Commit step, or the driver
  // between graph runs.
  bool queue_if_straddles(engine_root& r, const ipoint& c, std::int32_t h, int depth,
                          std::uint64_t index, const range_data* rd);

  // The queue item of a diamond whose parents are all split (centre c, scale h), or nothing
  // when it is culled. An owner of a piece of its last parent's surface is kept unless empty()
  // (it straddles unless wholly in the padding) and keyed by range_data::error() (its splits'
  // samples only); another by get() (range and error in one pass), or, in full refinement, by
  // straddles(). Full refinement keys by placeholder, as does a run while `rd` is null (culled
  // only when wholly in the padding). Reads only immutable data: any thread.
  [[nodiscard]] std::optional<ready_item> ready_child(const engine_root& r, const ipoint& c,
                                                      std::int32_t h, int depth,
                                                      std::uint64_t index, const range_data* rd,
                                                      bool owns_surface) const;

  // The children of the diamond (centre, scale), their words in r.record_of asked for (for
  // writing) so that counting them after the split finds them in cache: the split's work, or a
  // task's later splits, overlaps the misses. Any thread (a hint: reads nothing of r's state).
  [[nodiscard]] child_list children_requested(const engine_root& r, const ipoint& centre,
                                              std::int32_t scale) const noexcept {
    const child_list children = hier.children_of(centre, scale, hierarchy::type_of(centre, scale));
    for (int i = 0; i < children.count; ++i) {
      r.record_of.prefetch(children.centre[static_cast<std::size_t>(i)]);
    }
    return children;
  }

  // Asks for the data a split of the diamond `index` reads first: its samples and the rows of
  // per-vertex words around its centre (its children's, at ± its scale). For a cold queue item a
  // few cold items ahead (ready_queue::cold_ahead): in priority order such an item lies anywhere
  // in the grid, and its first reads miss. Any thread (a hint: reads nothing of r's state).
  void request_diamond(const engine_root& r, std::uint64_t index) const noexcept {
    const ipoint c = hier.point(index);
    const std::int32_t h = hier.scale_of(c);
    prefetch_diamond_samples(vol, c, h);
    const ipoint& g = hier.grid_max();
    const std::int32_t x0 = std::max(c[0] - h, 0);
    const std::int32_t x1 = std::min(c[0] + h, g[0]);
    for (std::int32_t dz = -h; dz <= h; dz += h) {
      const std::int32_t z = std::clamp(c[2] + dz, 0, g[2]);
      for (std::int32_t dy = -h; dy <= h; dy += h) {
        const std::int32_t y = std::clamp(c[1] + dy, 0, g[1]);
        r.record_of.prefetch({x0, y, z});
        r.record_of.prefetch({x1, y, z});
      }
    }
  }

  // A published split (centre, scale, depth; its surface `groups`) counted as a parent of each of
  // its children; the children it completes are queued (or culled). The one thread of the root's
  // run: the one-thread loop, or the driver between task runs (queue_deadline_leftovers).
  void count_children_on_one_thread(engine_root& r, const ipoint& centre, std::int32_t scale,
                                    int depth, const packed_group* groups, std::size_t count,
                                    const range_data* rd, split_tally& tally) const;
  // count_children()'s sink that queues a ready child in the root's queue (keyed by placeholder
  // while `rd` is null). The one thread of the root's run.
  [[nodiscard]] static auto queue_sink(engine_root& r, const range_data* rd) noexcept {
    return [&r, rd](const ready_item& child) {
      r.queue.push(child);
      if (rd == nullptr) r.placeholder_keys = true;
    };
  }
  // The same with the children listed, handing each child made ready (and not culled) to
  // `ready` (queue_sink(), or the sweeps' plane lists).
  // `parent` and `scale`: the split diamond's grid index and scale (the groups' frame).
  template <class Sink>
  void count_children(engine_root& r, const child_list& children, std::uint64_t parent,
                      std::int32_t scale, int depth, const packed_group* groups, std::size_t count,
                      const range_data* rd, split_tally& tally, Sink&& ready) const {
    for (int i = 0; i < children.count; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const ipoint& c = children.centre[ui];
      const std::uint64_t ci = hier.index(c);
      // This thread is the only writer while it counts (no other task runs on the root); the
      // tasks' fetch_sub, the graph's hint loads and readers' loads are atomic accesses of the
      // same word (a count reads as "not in this cut" to readers). One read-modify-write
      // instruction, not a load and a store: a fresh page of the words is first touched by a
      // write (add_in_place() says why that matters).
      const std::uint32_t word = add_in_place(r.word(c), ~std::uint32_t{0});
      if (parents_counted(word) != children.parents[ui]) continue;
      ++tally.visited;
      const std::optional<ready_item> child = ready_child(
          r, c, children.scale, depth + 1, ci, rd, owns_piece(groups, count, parent, scale, ci));
      if (child) {
        ready(*child);
      } else {
        ++tally.culled;
      }
    }
  }

  // Driver: counts the children of what a deadline published last (engine_root::uncounted)
  // and queues what it left (engine_root::leftover). Before anything reads the queue in a run.
  void queue_deadline_leftovers(engine_root& r);
  // Ready diamonds queued or left, and records whose children are not counted yet: the root's
  // `remaining` (0 only when nothing is left to split).
  [[nodiscard]] static std::size_t ready_count(const engine_root& r) noexcept {
    return r.queue.size() + r.leftover_items + r.uncounted.size();
  }

  // Driver, between graph runs, once the range data is built: the diamonds queued by
  // placeholder are queued again by their ranges, or culled; those queued by error bounds (a
  // deadline run before the error pass) by their exact errors once they exist.
  void requeue_by_ranges(engine_root& r);

  // The cleared arrays of a reclaimed root if there are any, else fresh ones. Control thread.
  vertex_state take_vertex_state();
  [[nodiscard]] vertex_state fresh_vertex_state() const;
  // Whether make_root() will take a reclaimed root's arrays (maps no memory). Only the control
  // thread takes them, so a true answer holds until its next make_root().
  [[nodiscard]] bool can_publish_early() {
    const std::lock_guard lock(reclaim_mutex);
    return spare.has_value();
  }

  // Retired roots are destroyed on a thread of the engine's own (`reclaimer`), so that
  // set_isovalue() returns without freeing the old root's records and groups or clearing its
  // per-vertex arrays (which would take far longer than making the new root's surface;
  // bench/README.md). hand_over() queues a root for it (control thread, from
  // the domain's flush); it refuses while two are queued, and the caller then destroys the root
  // itself, so retired memory stays bounded however fast the isovalue moves.
  [[nodiscard]] bool hand_over(engine_root* r) noexcept;
  void reclaim_loop() noexcept;
  // Finishes what is queued and joins the reclaimer (~engine, before the domain drains).
  void stop_reclaimer() noexcept;
  // Destroys a root. With `keep`, and no spare arrays waiting, its per-vertex arrays are first
  // cleared and kept for the next root: a run wrote record_of at each published diamond and at
  // each of its children, nothing else, so a small cut is cleared entry by entry and a large
  // one by zeroing the array whole (cheaper beyond about one record per 64 vertices).
  void reclaim(engine_root& r, bool keep) noexcept;

  static void destroy_root(void* p) noexcept;

  // ---- readers -------------------------------------------------------------------------------

  // ---- the run -------------------------------------------------------------------------------

  // Full refinement splits every straddling diamond whatever its error: children are tested
  // by straddles() (stops at the first samples on both sides), and queued by placeholder.
  [[nodiscard]] bool errors_needed() const noexcept { return goal.what != refine_goal::kind::full; }
  // Goals whose split set does not depend on the order (full refinement, an error target taken
  // in any order) run by grid plane (sweep_on_one_thread(), the tasks' plane lists), not by the
  // queue.
  [[nodiscard]] bool goal_runs_by_plane() const noexcept {
    return goal.what == refine_goal::kind::full ||
           (goal.what == refine_goal::kind::error && goal.any_order);
  }
  // What a ready diamond's error is needed up to (ready_rule(), range_data::test_upto()): an
  // error target in any order only tells errors above it from the rest, and a diamond's error
  // mostly exceeds it after a few of its splits or bricks; every other goal keys its queue by
  // exact errors.
  [[nodiscard]] double error_bound() const noexcept {
    return goal.what == refine_goal::kind::error && goal.any_order
               ? goal.max_error
               : std::numeric_limits<double>::infinity();
  }
  [[nodiscard]] bool eligible(const engine_root& r) const noexcept {
    if (r.queue.empty()) return false;
    if (goal.what == refine_goal::kind::error) return r.queue.top().error > goal.max_error;
    return true;
  }
  // Whether the goal lets a split leave the cut with `triangles_after` triangles: the one
  // admission test of every schedule (serial, tasks, flow graph), at the commit step.
  [[nodiscard]] bool goal_admits(std::uint64_t triangles_after) const noexcept {
    return goal.what != refine_goal::kind::budget || triangles_after <= goal.max_elements;
  }
  [[nodiscard]] bool past_deadline() const noexcept {
    return goal.what == refine_goal::kind::deadline && clock::now() >= slice_end;
  }
  // Commit step only: fills the in-flight window.
  void dispatch(engine_root& r);

  // Any worker, in parallel: split records of the batch's diamonds (pure), and what the
  // commit step needs to know about their children.
  batch* compute_batch(batch* b);

  // The serial commit step: publishes the batch's records in order (their parents are all
  // published: they were ready when taken), makes children ready, refills the window.
  void commit_batch(batch* b);

  // The error of the queue's next diamond for the progress callback (0 when none): its key, or
  // the range data's error when it is queued by placeholder. Commit step.
  [[nodiscard]] double next_error(const engine_root& r, const range_data* rd) const;

  // One graph run: the first dispatch goes through the serial commit node too (the queue
  // belongs to it: tasks started by the dispatch loop commit while it still runs).
  void run_graph(engine_root* r);
  void make_graph();

  // Whether a piece of the surface `groups` of the split of diamond `parent` (grid index, scale
  // h) lies in its child `index` (the piece's owner).
  [[nodiscard]] bool owns_piece(const packed_group* groups, std::size_t count, std::uint64_t parent,
                                std::int32_t h, std::uint64_t index) const noexcept {
    return std::any_of(groups, groups + count, [&](const packed_group& g) {
      return group_owner(hier, parent, h, g) == index;
    });
  }
  // After a publication of `published` records: calls the progress callback once
  // opt.progress_interval records were published since its last call. The callback may
  // cancel() (a stop request); an exception it throws stops the run and is rethrown by the
  // control thread's wait() or refine(), never across TBB. Whoever publishes (one at a time).
  void report_progress(engine_root& r, const range_data* rd, std::uint64_t published);

  // One run on one thread (serial_refinement.cpp): the same records, publication rule, queue,
  // goals and statistics as the graph, split by split in the driver thread, published every
  // 64 splits. run_graph() takes it when the engine has one thread.
  void refine_serially(engine_root& r);
  // refine_serially()'s split of `item`: computes it, appends its record (published by the
  // caller's next publication) and counts its children, handing those it makes ready to
  // `ready`; `take()` is called once the split is kept. False, with nothing changed, when a
  // triangle budget refuses the split.
  template <class Take, class Sink>
  bool split_on_one_thread(engine_root& r, const ready_item& item, const ipoint& centre,
                           const range_data* rd, split_tally& tally, Take&& take, Sink&& ready);
  // refine_serially()'s goals that run by grid plane (goal_runs_by_plane()): the ready diamonds
  // taken by grid plane, lowest first (serial_refinement.cpp), from sweep_planes.
  template <class Publish>
  void sweep_on_one_thread(engine_root& r, const range_data* rd, split_tally& tally,
                           Publish&& publish);

  // A run on more than one thread (full_refinement.cpp): tasks over subtrees, each a
  // depth-first loop like refine_serially()'s, publishing its splits every 64 (up to 256 while
  // another task holds the mutex): their places in the log reserved under `publish_mutex`,
  // filled without it, the watermark moved under it again; a child becomes ready when the atomic
  // decrement of its last parent, made after that parent's place was reserved, completes its
  // count.
  // Full refinement is one such run over everything queued; refinement by priority one per band
  // of the queue (a quarter octave of errors), largest first, a child below the band left for a
  // later one. run_graph() takes it on more than one thread (for runs by priority unless
  // engine_options::schedule asks for the flow graph).
  struct full_run;
  struct full_task;
  void refine_in_tasks(engine_root& r);
  void run_full_task(full_task& t);
  // Publishes the task's computed splits (the prefix a triangle budget allows) and makes their
  // children ready; without `wait`, only if publish_mutex is free; once the run is stopping, only
  // when `stopped` (a deadline's last publication). Returns whether it published.
  bool publish_full_task(full_task& t, bool wait, bool stopped = false);
  // The children of the task's pending splits, whose places start at `first_record`: counted,
  // and those whose count completes made ready on the task's lists. Returns how many it queued.
  std::int64_t count_full_task_children(full_task& t, std::size_t first_record);
  // Runs run_full_task(*part) as a task of the run's group.
  void spawn_full_task(full_run& run, std::shared_ptr<full_task> part);

  // After a graph run that stopped at the end of its slice (not at the goal's deadline): clears
  // the stop request and returns true, unless the user or the progress callback stopped the run
  // (then the run ends). Under `control`, so that a cancel() is either seen here or made after.
  bool continue_after_slice();

  // A deadline run before the range data is complete (DESIGN §7, "the first surface needs no
  // preprocessing"): slices of the build alternate with slices of refinement without culling
  // (placeholder order: coarse first), each twice as long as the one before, from 1 ms, a build
  // slice never more than half the time left and never a step expected to end past its slice;
  // once the estimate for the pieces left (weighed by range_data::piece_work) and a quarter more
  // fits in the time left, the build runs to the end, but for nine tenths of that time at most
  // (plan_deadline_build(), core/refine/deadline.hpp): refinement always keeps time. When the
  // data is complete the queue is culled and ordered by it, and the run goes on as usual. What the
  // build did is kept for the next run; what refinement did is a valid cut. Only the first step of
  // all, which has no estimate, can overrun a deadline (by one slab per thread). Deadlines shorter
  // than a step refine without building: the data is then built by the first run with time for it,
  // or by any other kind of run. Why the build goes first whenever it fits: refinement culled by
  // the data buys far more surface per unit of time than refinement without it, enough to make
  // up for the time the build takes (bench/README.md).
  void drive_unranged(engine_root* r);

  // The driver thread of one run. With `replaces`, r is a root of records made for this run,
  // unpublished, in place of the uniform cut `replaces` shows: published by the driver once
  // the goal is reached (replace_root()), else destroyed. What refinement throws (memory for
  // its words, records or queue, beyond what the process may have) ends the run there, for
  // wait() or refine() to rethrow: what was published stays readable, and the root, which may
  // hold a split begun and not ended, is marked failed (launch() refuses to refine it further;
  // a new isovalue makes a fresh root), or destroyed when it was never published.
  void drive(engine_root* r, engine_root* replaces = nullptr);
  // drive() without the failure handling.
  void drive_records(engine_root* r, engine_root* replaces);

  // Control (caller holds `control`).
  void launch(std::unique_lock<std::mutex>& lock, const refine_goal& g);
  [[nodiscard]] engine_root* current() const noexcept {
    // relaxed: the control thread is the only writer of `root`.
    return root.load(std::memory_order_relaxed);
  }

  std::shared_ptr<const volume> owned_volume;  // set when the engine owns its volume
  const volume& vol;
  engine_options opt;
  hierarchy hier;
  // The range data (see ranges()): made, built piece by piece and finished under build_mutex;
  // complete once ranges_ready is set.
  mutable std::mutex build_mutex;
  mutable std::optional<range_data> ranges_;
  // Guarded by build_mutex: pieces of the min/max pass built (min_max_work of them, by
  // range_data::piece_work, alone, in piece_seconds), pieces of the error pass built.
  mutable std::size_t pieces_built = 0;
  mutable std::uint64_t min_max_work = 0;
  mutable double piece_seconds = 0.0;
  mutable std::size_t error_pieces_built = 0;
  mutable std::atomic<bool> ranges_ready{false};
  mutable std::atomic<double> range_seconds{0.0};
  unsigned threads;
  // The reclaimer (hand_over()): its queue, its stop flag and the per-vertex arrays of the
  // last root it cleared, until the next root takes them, all guarded by reclaim_mutex.
  // Declared before the domain, which destroys the retired roots when it goes. `recycle` is
  // cleared by ~engine after stop_reclaimer(): roots destroyed then are destroyed in place and
  // keep nothing.
  std::mutex reclaim_mutex;
  std::condition_variable reclaim_wake;
  std::vector<engine_root*> reclaim_queue;
  bool reclaim_quit = false;
  std::optional<vertex_state> spare;
  bool spare_fresh = false;  // `spare` was mapped fresh (by the reclaimer), not cleared
  // The storage of a reclaimed uniform cut's mesh (the largest one), for a later cut of about
  // its size (take_mesh_storage()): the new cut's pages are then mapped already, and the old
  // ones are not unmapped while a run makes the new one (unmapping a large mesh on the
  // reclaimer slowed a deadline run after an isovalue change; bench/README.md).
  triangle_mesh spare_mesh;
  // Recycled storage for a cut of `vertices` and `triangles` (detail::mesh_storage): the spare
  // mesh when it holds them and is at most four times larger, else nothing. Any thread.
  triangle_mesh take_mesh_storage(std::uint64_t vertices, std::uint64_t triangles);
  std::thread reclaimer;
  bool recycle = true;
  mutable epoch_domain domain;
  epoch_participant control_participant;  // retires roots; used under `control`
  reader_registry readers;                // participants of reading threads (snapshots)
  // The published root: release-stored by set_isovalue() (pairs with the acquire in
  // epoch_guard::protect() of snapshot()).
  std::atomic<engine_root*> root{nullptr};

  mutable tbb::task_arena arena;
  // The flow graph, made by the first run that uses it (make_graph(), driver thread; the
  // destructor reads it after joining the driver).
  std::unique_ptr<tbb::flow::graph> graph;
  std::unique_ptr<tbb::flow::function_node<batch*, batch*>> compute;
  std::unique_ptr<tbb::flow::function_node<batch*>> commit;

  // Run state. `goal` is set before the driver starts (thread start orders it) and read by
  // tasks; inflight, inflight_items, budget_hit, last_depth, since_progress belong to the
  // commit step.
  refine_goal goal;
  // Deadline runs stop here: the goal's deadline, or the end of a slice of refinement while the
  // range data is built (drive_unranged). Written by the driver between graph runs.
  clock::time_point slice_end{};
  std::size_t inflight = 0;
  std::size_t inflight_items = 0;
  // Batches done with, kept with their buffers' capacity for the next ones (commit step: both
  // dispatch() and commit_batch() run there).
  std::vector<std::unique_ptr<batch>> spare_batches;
  bool budget_hit = false;
  int last_depth = 0;
  // The split groups of refine_serially()'s current diamond (the driver's; kept for capacity).
  std::vector<packed_group> serial_groups;
  // sweep_on_one_thread()'s ready diamonds (the driver's; empty between runs, kept for their
  // capacity).
  plane_lists sweep_planes;
  // Full runs in tasks: the reservation of records' and groups' places, the watermark, the
  // root's counters, last_depth, since_progress and the progress callback are one task at a
  // time under this mutex (filling the places is not: full_refinement.cpp).
  std::mutex publish_mutex;
  std::uint64_t since_progress = 0;

  // Written by the control thread (a root retired) and the reclaimer (a root destroyed).
  std::atomic<std::uint64_t> retired_bytes{0};
  mutable counter peak_retired_bytes, root_bytes;
  counter recycled_roots;
  std::uint64_t generation = 0;  // guarded by control
  // The last serial given to a published root (engine_root::serial): written under `control`
  // (or by the constructor), read by statistics().
  std::atomic<std::uint64_t> next_serial{0};
};

}  // namespace progiso::detail
