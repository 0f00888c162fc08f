#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <tbb/flow_graph.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <progiso/concurrent/append_log.hpp>
#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/base/zeroed_array.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>
#include <progiso/core/surface/detail/mesh_builder.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

namespace progiso {
namespace detail {
namespace {

using clock = std::chrono::steady_clock;

// Core's pieces of work (range slabs, mesh parts) as oneTBB tasks in the calling arena.
void tbb_loop(std::size_t n, const std::function<void(std::size_t)>& body) {
  tbb::parallel_for(std::size_t{0}, n, [&body](std::size_t i) { body(i); });
}

// One published split: the new triangles of the split as packed groups (in a buffer the root
// owns; unpacked with the diamond's centre and scale), the diamond, its nested error and the
// cut's triangle count once it is published. Record 0 is the root surface: its triangles are
// engine_root::root_triangles, in plain form, and `count` is their number.
struct engine_record {
  std::uint64_t diamond;  // grid index; no_owner for the root record
  const packed_group* groups;
  std::uint32_t count;
  std::int32_t depth;
  std::int32_t scale;
  double error;
  std::uint64_t cut_triangles;
};

struct ready_item {
  double error;
  int depth;
  std::uint64_t index;
};

// Counters written by the commit step (one writer at a time) and read by anyone: relaxed
// atomics, each exact at some moment; no other data is published through them.
class counter {
 public:
  void add(std::uint64_t n) noexcept {
    // relaxed: single writer; readers want a recent value only (statistics).
    v_.store(v_.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
  }
  void set(std::uint64_t n) noexcept {
    // relaxed: as add().
    v_.store(n, std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t get() const noexcept {
    // relaxed: as add().
    return v_.load(std::memory_order_relaxed);
  }

 private:
  std::atomic<std::uint64_t> v_{0};
};

constexpr std::uint64_t root_alive = 0x70726f6769736f31;  // "progiso1"
constexpr std::uint64_t root_dead = 0xdbdbdbdbdbdbdbdb;
constexpr unsigned char poison_byte = 0xdb;

}  // namespace

// A root's per-grid-vertex arrays (engine_root::record_of and parents), all zero when handed to
// a root. A reclaimed root gives them back to its engine, cleared, for the next root: a fresh
// mapping would pay a page fault for every page the next refinement touches, and a TLB flush
// interrupt on every core for each page first read (by a compute task's hint load or a reader)
// and then written.
struct vertex_state {
  zeroed_array<std::uint32_t> record_of;
  zeroed_array<std::uint8_t> parents;
};

// One isovalue's progressive surface. Readers reach it through engine_impl::root (protected by
// an epoch guard) and read the published prefix of `records` and `record_of`; everything under
// "commit step only" belongs to whichever thread runs the serial commit (or the control thread
// while no run is active).
struct engine_root : epoch_object {
  engine_root(engine_impl& owner, double w, std::uint64_t gen, vertex_state&& state)
      : impl(&owner),
        isovalue(w),
        generation(gen),
        record_of(std::move(state.record_of)),
        parents(std::move(state.parents)) {}

  std::uint64_t magic = root_alive;
  engine_impl* impl;
  double isovalue;
  std::uint64_t generation;
  append_log<engine_record> records;
  // Per grid vertex: index of the diamond's record, 0 while unsplit. Written once (0 → r) by the
  // commit step before the release of records.publish(); read by readers through atomic_ref
  // (relaxed: a value below the reader's watermark was written before that watermark's release,
  // and any other value means "not in this cut").
  zeroed_array<std::uint32_t> record_of;

  // Parents split so far, per grid vertex: written by the commit step only (relaxed
  // atomic_ref stores); compute tasks load it, relaxed, as a hint of which parent is last.
  zeroed_array<std::uint8_t> parents;
  // Root surface: set before the root is published, immutable afterwards.
  std::vector<owned_triangle> root_triangles;
  // The root diamonds, queued (or culled) by the first run, once the range data exists: the root
  // surface needs none, so it is published before any pass over the volume. Commit step only.
  std::vector<ipoint> root_centres;
  bool seeded = false;
  // Some queued diamond was made ready without the range data (a deadline run before it was
  // built): queued by placeholder, never culled. The driver re-queues them by their ranges once
  // the data is built (requeue_by_ranges), between graph runs. Commit step and driver.
  bool unranged = false;
  // Some queued diamond was keyed by an error bound (hi − lo: the range data's error pass was
  // not done); re-keyed by the exact errors once they exist. Commit step and driver.
  bool bounded = false;

  // Commit step only.
  std::vector<std::vector<packed_group>> buffers;
  detail::ready_queue<ready_item> queue{queue_discipline::largest_error};
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
    for (const auto& b : buffers) n += b.capacity() * sizeof(packed_group);
    return n;
  }
  std::uint64_t retired_bytes = 0;  // bytes() when retired

  [[nodiscard]] std::uint32_t record_index(std::uint64_t vertex) const noexcept {
    // relaxed: see record_of.
    return std::atomic_ref<std::uint32_t>(record_of[vertex]).load(std::memory_order_relaxed);
  }
};

namespace {

struct child_info {
  std::uint64_t index;
  double error;
  std::uint8_t parents_needed;
  bool known;  // error and straddles were looked up (else the commit step looks them up)
  bool straddles;
};

struct batch_item {
  ready_item item;
  std::uint32_t first = 0;  // groups in the batch's buffer
  std::uint32_t count = 0;
  std::int32_t scale = 0;
  int added = 0;  // triangles
  int removed = 0;
  split_configuration configuration{};
  std::array<std::uint8_t, tet_case_count> cases{};
  std::array<std::uint16_t, primitive_count> primitives{};
  std::uint8_t children = 0;
  std::array<child_info, 8> child{};
};

// A compute task: diamonds taken from the ready queue together, computed by one worker.
struct batch {
  engine_root* root = nullptr;
  bool seed = false;  // no work: asks the commit step to fill the window (a run's start)
  std::vector<batch_item> items;
  std::size_t computed = 0;
  std::vector<packed_group> groups;
};

}  // namespace

struct engine_impl {
  engine_impl(std::shared_ptr<const volume> owned, const volume& v, engine_options o)
      : owned_volume(std::move(owned)),
        vol(v),
        opt(std::move(o)),
        hier(v.dims()),
        threads(effective_threads(opt.threads)),
        domain(opt.reclamation),
        control_participant(domain),
        serial(next_serial()),
        arena(static_cast<int>(threads)) {
    arena.execute([this] {
      graph = std::make_unique<tbb::flow::graph>();
      compute = std::make_unique<tbb::flow::function_node<batch*, batch*>>(
          *graph, tbb::flow::unlimited, [this](batch* b) { return compute_batch(b); });
      commit = std::make_unique<tbb::flow::function_node<batch*>>(
          *graph, tbb::flow::serial, [this](batch* b) { commit_batch(b); });
      tbb::flow::make_edge(*compute, *commit);
    });
  }

  // The range data: a staged build (range_data::staged), its pieces built with the engine's
  // threads, one slab of bricks per task. Until it is complete the engine publishes its root
  // surfaces (they need none), and a deadline run refines without culling while it builds pieces
  // in between (drive()); every other run, and engine::ranges(), build what is left first.
  // Building happens only on threads outside the arena, under `build_mutex` (the driver between
  // its graph runs, users): a thread that held an arena slot while it waited for another
  // thread's build would keep that build from the slot it needs (a deadlock with one slot, seen
  // in the stress test). Tasks read the data through built_ranges().
  const range_data& ranges() const {
    // acquire: pairs with the release in build_ranges(); the data is then complete.
    if (ranges_ready.load(std::memory_order_acquire) && ranges_->errors_exact()) return *ranges_;
    if (in_own_callback()) {
      throw error(
          "engine: ranges() cannot build the range data from the engine's progress callback "
          "(it would wait for the run that calls it); call it outside the callback");
    }
    const std::lock_guard lock(build_mutex);
    build_ranges(clock::time_point::max(), false, true);
    return *ranges_;
  }
  // Builds pieces until done or `until` (or a stop request, when `stop_requests`: a cancelled
  // deadline run returns within one step): the min/max pass, then (when `errors`) the error
  // pass, fused with the first where neither has started (each slab read once); finishes each
  // pass after its last piece. Caller holds build_mutex and is outside the arena. Returns
  // whether what was asked for is complete.
  bool build_ranges(clock::time_point until, bool stop_requests, bool errors) const {
    const auto t0 = clock::now();
    if (!ranges_) ranges_.emplace(vol, hier, range_data::staged);
    range_data& rd = *ranges_;
    const std::size_t n = rd.piece_count();
    const std::size_t m = rd.error_piece_count();
    const bool fuse = errors && m == n;
    // No step that is expected to end past `until` (the first has no estimate yet).
    const auto fits = [&](std::size_t step) {
      const auto expected =
          std::chrono::duration<double>(seconds_per_piece() * static_cast<double>(step));
      return clock::now() + std::chrono::duration_cast<clock::duration>(expected) < until &&
             !(stop_requests && stopping());
    };
    // isolate: while it waits for its slabs, the building thread runs only slab tasks, never
    // another caller's delegated work. Steps of one slab per thread, the clock between them.
    arena.execute([&] {
      tbb::this_task_arena::isolate([&] {
        // Without a time limit, one parallel loop over everything left (no step barriers).
        const bool unlimited = until == clock::time_point::max() && !stop_requests;
        while (pieces_built < n) {
          const std::size_t step =
              unlimited ? n - pieces_built : std::min<std::size_t>(n - pieces_built, threads);
          if (!fits(step)) break;
          const auto p0 = clock::now();
          if (fuse && error_pieces_built == pieces_built) {
            rd.build_pieces_with_errors(pieces_built, pieces_built + step, tbb_loop);
            error_pieces_built += step;
          } else {
            rd.build_pieces(pieces_built, pieces_built + step, tbb_loop);
            piece_seconds += std::chrono::duration<double>(clock::now() - p0).count();
            min_max_pieces += step;
          }
          pieces_built += step;
        }
        if (pieces_built == n && !rd.complete()) rd.finish();
        if (!errors || !rd.complete()) return;
        while (error_pieces_built < m) {
          const std::size_t step = unlimited
                                       ? m - error_pieces_built
                                       : std::min<std::size_t>(m - error_pieces_built, threads);
          if (!fits(0)) break;
          rd.build_error_pieces(error_pieces_built, error_pieces_built + step, tbb_loop);
          error_pieces_built += step;
        }
        if (error_pieces_built == m && !rd.errors_exact()) rd.finish_errors();
      });
    });
    const double spent = std::chrono::duration<double>(clock::now() - t0).count();
    // relaxed: a statistic; writers hold build_mutex, readers take any value.
    range_seconds.store(range_seconds.load(std::memory_order_relaxed) + spent,
                        std::memory_order_relaxed);
    // relaxed: this thread holds build_mutex, and only holders of it store the flag.
    if (rd.complete() && !ranges_ready.load(std::memory_order_relaxed)) {
      // release: pairs with the acquire loads in ranges(), built_ranges(), the driver and
      // engine::ranges_built() / errors_built().
      ranges_ready.store(true, std::memory_order_release);
    }
    return rd.complete() && (!errors || rd.errors_exact());
  }
  // Wall seconds per piece of the min/max pass so far, steps of `threads` pieces in parallel,
  // not counting the data's allocation (0 before the first). Caller holds build_mutex.
  [[nodiscard]] double seconds_per_piece() const {
    return min_max_pieces == 0 ? 0.0 : piece_seconds / static_cast<double>(min_max_pieces);
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
  // The queue key and record error of a diamond made ready without its range: above every
  // error the data can have, halving with depth, so coarse diamonds go first and every cut by
  // error stays parent-closed (a placeholder parent is never below its children).
  static double unranged_error(int depth) noexcept {
    return std::ldexp(std::numeric_limits<double>::max(), -std::min(depth, 60));
  }
  // oneTBB's pool has default_concurrency() threads; asking an arena for more only warns.
  static unsigned effective_threads(unsigned requested) {
    const auto available = static_cast<unsigned>(scheduler::default_concurrency());
    return requested == 0 ? available : std::min(requested, available);
  }
  static std::uint64_t next_serial() {
    static std::atomic<std::uint64_t> n{1};
    // relaxed: a unique number; nothing is published with it.
    return n.fetch_add(1, std::memory_order_relaxed);
  }

  // ---- roots ---------------------------------------------------------------------------------

  engine_root* make_root(double w, std::uint64_t gen) {
    auto* r = make_managed<engine_root>(domain, *this, w, gen, take_vertex_state());
    std::vector<owned_triangle> tris;
    for (std::uint64_t q = 0; q < hier.root_count(); ++q) {
      const std::optional<ipoint> centre = compute_root(hier, vol, w, q, tris);
      if (centre) r->root_centres.push_back(*centre);
    }
    r->cut_triangles = tris.size();
    r->records.push_back(
        {no_owner, nullptr, static_cast<std::uint32_t>(tris.size()), -1, 0, 0.0, tris.size()});
    r->root_triangles = std::move(tris);
    r->records.publish();
    r->triangles.set(r->cut_triangles);
    r->record_triangles.set(r->cut_triangles);
    // Not known before the seeding: every root may still split.
    r->remaining.set(r->root_centres.size());
    return r;
  }

  // Commit step (the first run on this root): queues the root diamonds whose range straddles
  // (every one not wholly in the padding, by placeholder, before the range data is built).
  void seed_roots(engine_root& r) {
    if (r.seeded) return;
    r.seeded = true;
    std::uint64_t culled = 0;
    const range_data* rd = built_ranges();
    note_keys(r, rd);
    for (const ipoint& c : r.root_centres) {
      if (!queue_if_straddles(r, c, hier.scale_of(c), hier.depth_of(c), hier.index(c), rd)) {
        ++culled;
      }
    }
    r.visited.add(r.root_centres.size());
    r.culled.add(culled);
  }

  // Marks the root when keys made with `rd` are error bounds (the error pass not done): once per
  // batch, not per queued diamond (an acquire load and a pointer chase on the commit path).
  static void note_keys(engine_root& r, const range_data* rd) noexcept {
    if (rd != nullptr && !rd->errors_exact()) r.bounded = true;
  }

  // Queues the diamond centred at c (scale h) by its range, or by placeholder when `rd` is null
  // and its subtree is not wholly in the padding; returns whether it was queued. Commit step,
  // or the driver between graph runs.
  bool queue_if_straddles(engine_root& r, const ipoint& c, std::int32_t h, int depth,
                          std::uint64_t index, const range_data* rd) {
    if (rd == nullptr) {
      if (ranges_for_empty().empty(c, h)) return false;
      r.queue.push({unranged_error(depth), depth, index});
      r.unranged = true;
      return true;
    }
    const diamond_range cr = rd->get(c, h);
    if (!cr.straddles(r.isovalue)) return false;
    r.queue.push({cr.error, depth, index});
    return true;
  }

  // Driver, between graph runs, once the range data is built: the diamonds queued by
  // placeholder are queued again by their ranges, or culled; those queued by error bounds (a
  // deadline run before the error pass) by their exact errors once they exist.
  void requeue_by_ranges(engine_root& r) {
    const range_data* rd = built_ranges();
    PROGISO_ASSERT(rd != nullptr);
    if (!r.unranged && !(r.bounded && rd->errors_exact())) return;
    std::vector<ready_item> items;
    items.reserve(r.queue.size());
    while (!r.queue.empty()) {
      items.push_back(r.queue.top());
      r.queue.pop();
    }
    std::uint64_t culled = 0;
    const bool all = r.bounded && rd->errors_exact();
    r.bounded = false;
    note_keys(r, rd);
    for (const ready_item& it : items) {
      if (!all && it.error < unranged_error(60)) {  // already by its range
        r.queue.push(it);
        continue;
      }
      const ipoint c = hier.point(it.index);
      if (!queue_if_straddles(r, c, hier.scale_of(c), it.depth, it.index, rd)) ++culled;
    }
    r.culled.add(culled);
    r.unranged = false;
  }

  // The cleared arrays of a reclaimed root if there are any, else fresh ones. Control thread.
  vertex_state take_vertex_state() {
    if (cleaner.joinable() && cleaner_done.load(std::memory_order_acquire)) cleaner.join();
    if (!cleaner.joinable() && spare) {
      vertex_state s = std::move(*spare);
      spare.reset();
      recycled_roots.add(1);
      return s;
    }
    const std::size_t n = hier.vertex_count();
    return {zeroed_array<std::uint32_t>(n), zeroed_array<std::uint8_t>(n)};
  }

  // A dying root's arrays become the next root's, cleared on a thread of their own so that
  // neither set_isovalue() nor the next run waits for it (one spare set at most; arrays that
  // find the spare taken or the cleaner busy are unmapped). The commit step wrote record_of at
  // each published diamond and parents at each of its children, nothing else: a small cut is
  // cleared entry by entry, a large one by zeroing the arrays whole (cheaper beyond about one
  // record per 64 vertices). Control thread, or the engine's destruction (then `recycle` is
  // false and nothing is kept).
  void keep_vertex_state(engine_root& r) noexcept {
    if (!recycle) return;
    if (cleaner.joinable()) {
      if (!cleaner_done.load(std::memory_order_acquire)) return;  // `spare` is the cleaner's
      cleaner.join();
    }
    if (spare) return;
    const std::size_t n = r.records.size();
    std::vector<std::pair<std::uint64_t, std::int32_t>> written;  // (diamond, scale)
    if (n * 64 < r.record_of.size()) {
      written.reserve(n);
      for (std::size_t i = 1; i < n; ++i) {
        const engine_record& rec = r.records.at_unpublished(i);
        written.emplace_back(rec.diamond, rec.scale);
      }
    }
    vertex_state s{std::move(r.record_of), std::move(r.parents)};
    const bool whole = written.empty() && n > 1;
    cleaner_done.store(false, std::memory_order_relaxed);  // relaxed: the thread start orders it
    try {
      cleaner =
          std::thread([this, s = std::move(s), written = std::move(written), whole]() mutable {
            if (whole) {
              s.record_of.zero();
              s.parents.zero();
            }
            for (const auto& [d, h] : written) {
              s.record_of[d] = 0;
              const ipoint c = hier.point(d);
              const child_list children = hier.children_of(c, h, hierarchy::type_of(c, h));
              for (int k = 0; k < children.count; ++k) {
                s.parents[hier.index(children.centre[static_cast<std::size_t>(k)])] = 0;
              }
            }
            spare = std::move(s);
            // release: pairs with the acquire loads in take/keep_vertex_state (they then join).
            cleaner_done.store(true, std::memory_order_release);
          });
    } catch (...) {
      // No thread: the arrays are freed with the lambda, and the next root maps fresh ones.
    }
  }

  static void destroy_root(void* p) noexcept {
    auto* r = static_cast<engine_root*>(p);
    PROGISO_ASSERT(r->magic == root_alive);
    engine_impl& impl = *r->impl;
    impl.keep_vertex_state(*r);  // reads the records: before they are poisoned
    if (impl.opt.poison_retired) {
      for (auto& b : r->buffers) {
        if (b.empty()) continue;  // no data pointer to poison
        std::memset(static_cast<void*>(b.data()), poison_byte, b.size() * sizeof(packed_group));
      }
      if (!r->root_triangles.empty()) {
        std::memset(static_cast<void*>(r->root_triangles.data()), poison_byte,
                    r->root_triangles.size() * sizeof(owned_triangle));
      }
      for (std::size_t i = 0; i < r->records.size(); ++i) {
        std::memset(static_cast<void*>(&r->records.at_unpublished(i)), poison_byte,
                    sizeof(engine_record));
      }
      r->isovalue = std::nan("");
    }
    impl.retired_bytes.add(0 - r->retired_bytes);  // single writer: control or drain
    r->magic = root_dead;
    if (impl.opt.on_reclaim) impl.opt.on_reclaim(r->generation);
    delete r;
  }

  // ---- readers -------------------------------------------------------------------------------

  // This thread's participant in the domain, registered on the thread's first snapshot of this
  // engine (takes a mutex once); then found in a small thread-local cache, most recent first.
  epoch_participant& reader() const {
    struct entry {
      std::uint64_t serial;
      epoch_participant* participant;
    };
    thread_local std::vector<entry> cache;
    for (std::size_t i = 0; i < cache.size(); ++i) {
      if (cache[i].serial == serial) {
        if (i != 0) std::swap(cache[i], cache[0]);
        return *cache[0].participant;
      }
    }
    epoch_participant* p = nullptr;
    {
      const std::lock_guard lock(readers_mutex);
      readers.push_back(std::make_unique<epoch_participant>(domain));
      p = readers.back().get();
    }
    // Forgotten entries keep their participant registered (owned by its engine) but unused.
    if (cache.size() >= 8) cache.pop_back();
    cache.push_back({serial, p});
    std::rotate(cache.begin(), cache.end() - 1, cache.end());
    return *p;
  }

  // ---- the run -------------------------------------------------------------------------------

  [[nodiscard]] bool eligible(const engine_root& r) const noexcept {
    if (r.queue.empty()) return false;
    if (goal.what == refine_goal::kind::error) return r.queue.top().error > goal.max_error;
    return true;
  }
  [[nodiscard]] bool past_deadline() const noexcept {
    return goal.what == refine_goal::kind::deadline && clock::now() >= slice_end;
  }
  [[nodiscard]] bool stopping() const noexcept {
    // relaxed: a request flag; the data the run publishes is ordered by records.publish().
    return stop.load(std::memory_order_relaxed);
  }
  void request_stop() noexcept {
    // relaxed: see stopping().
    stop.store(true, std::memory_order_relaxed);
  }

  // Commit step only: fills the in-flight window.
  void dispatch(engine_root& r) {
    const std::size_t window = std::max<std::size_t>(1, opt.tasks_per_thread * threads);
    const std::size_t max_batch = std::max<std::size_t>(1, opt.batch);
    while (inflight < window && !stopping() && eligible(r) && !past_deadline()) {
      const std::size_t n = std::clamp<std::size_t>(r.queue.size() / (2 * threads), 1, max_batch);
      auto* b = new batch;
      b->root = &r;
      b->items.reserve(n);
      while (b->items.size() < n && eligible(r)) {
        b->items.push_back({r.queue.top()});
        r.queue.pop();
      }
      inflight_items += b->items.size();
      ++inflight;
      compute->try_put(b);
    }
  }

  // Any worker, in parallel: split records of the batch's diamonds (pure), and what the
  // commit step needs to know about their children.
  batch* compute_batch(batch* b) {
    const double w = b->root->isovalue;
    const range_data* rd = built_ranges();
    for (std::size_t j = 0; j < b->items.size(); ++j) {
      // The clock every fourth split (~2 µs): a clock read costs ~4% of a split.
      if (stopping() || (j % 4 == 0 && past_deadline())) break;
      batch_item& it = b->items[j];
      const ipoint centre = hier.point(it.item.index);
      const std::int32_t scale = hier.scale_of(centre);
      const std::size_t first = b->groups.size();
      const split_summary s = compute_split(hier, vol, w, centre, scale, b->groups);
      it.first = static_cast<std::uint32_t>(first);
      it.count = static_cast<std::uint32_t>(b->groups.size() - first);
      it.scale = scale;
      it.added = s.added_triangles;
      it.removed = s.removed_triangles;
      it.configuration = s.configuration;
      it.cases = s.cases;
      it.primitives = s.primitives;
      const child_list children =
          hier.children_of(centre, scale, hierarchy::type_of(centre, scale));
      it.children = static_cast<std::uint8_t>(children.count);
      for (int i = 0; i < children.count; ++i) {
        const ipoint& c = children.centre[static_cast<std::size_t>(i)];
        child_info& ci = it.child[static_cast<std::size_t>(i)];
        ci.index = hier.index(c);
        ci.parents_needed = children.parents[static_cast<std::size_t>(i)];
        // The child's range is needed once, when its last parent commits. The parent that
        // finds all the others already committed looks it up here, in parallel; for the other
        // parents it would be wasted work (a child has up to four). When two last parents are
        // in flight together, neither may look: the commit step then does.
        const std::uint8_t split_parents =
            std::atomic_ref<std::uint8_t>(b->root->parents[ci.index])
                // relaxed: a hint only; the commit step, the sole writer, decides readiness,
                // and a stale count just moves the lookup to the commit step or repeats it.
                .load(std::memory_order_relaxed);
        ci.known = rd != nullptr && split_parents + 1 >= ci.parents_needed;
        if (ci.known) {
          const diamond_range cr = rd->get(c, children.scale);
          ci.straddles = cr.straddles(w);
          ci.error = cr.error;
        }
      }
      ++b->computed;
    }
    return b;
  }

  // The serial commit step: publishes the batch's records in order (their parents are all
  // published: they were ready when taken), makes children ready, refills the window.
  void commit_batch(batch* b) {
    engine_root& r = *b->root;
    if (b->seed) {
      delete b;
      seed_roots(r);
      dispatch(r);
      r.remaining.set(r.queue.size() + inflight_items);
      return;
    }
    const range_data* rd = built_ranges();
    note_keys(r, rd);
    --inflight;
    inflight_items -= b->items.size();
    std::size_t published = 0;
    if (!stopping() && b->computed > 0) {
      r.buffers.push_back(std::move(b->groups));
      const packed_group* base = r.buffers.back().data();
      std::array<std::uint64_t, tet_case_count> cases{};
      std::array<std::uint64_t, primitive_count> prims{};
      std::array<std::uint64_t, split_configuration_count> configs{};
      std::uint64_t added = 0;
      std::uint64_t visited = 0;
      std::uint64_t culled = 0;
      // The per-vertex state the loop below writes, requested ahead: in priority order the
      // diamonds lie all over the grid, and these lines are the serial step's cache misses.
      for (std::size_t i = 0; i < b->computed; ++i) {
        const batch_item& it = b->items[i];
        __builtin_prefetch(&r.record_of[it.item.index], 1);
        for (std::size_t c = 0; c < it.children; ++c) {
          __builtin_prefetch(&r.parents[it.child[c].index], 1);
        }
      }
      for (std::size_t i = 0; i < b->computed; ++i) {
        const batch_item& it = b->items[i];
        if (i % 8 == 0 && past_deadline()) {  // every eighth record (~1 µs), as in compute
          request_stop();
          break;
        }
        const std::uint64_t after =
            r.cut_triangles + static_cast<unsigned>(it.added) - static_cast<unsigned>(it.removed);
        if (goal.what == refine_goal::kind::triangles && after > goal.max_triangles) {
          budget_hit = true;
          request_stop();
          break;
        }
        const std::size_t index = r.records.size();
        PROGISO_ASSERT(index < (std::size_t{1} << 32));
        r.cut_triangles = after;
        r.records.push_back({it.item.index, base + it.first, it.count, it.item.depth, it.scale,
                             it.item.error, after});
        std::atomic_ref<std::uint32_t>(r.record_of[it.item.index])
            .store(static_cast<std::uint32_t>(index),
                   // relaxed: published by the release in records.publish() below.
                   std::memory_order_relaxed);
        added += static_cast<unsigned>(it.added);
        for (std::size_t k = 0; k < tet_case_count; ++k) cases[k] += it.cases[k];
        for (std::size_t k = 0; k < primitive_count; ++k) prims[k] += it.primitives[k];
        ++configs[static_cast<std::size_t>(it.configuration)];
        for (std::size_t c = 0; c < it.children; ++c) {
          const child_info& ci = it.child[c];
          const std::atomic_ref<std::uint8_t> slot(r.parents[ci.index]);
          // relaxed: the commit step is the only writer; compute tasks read a hint.
          const auto count = static_cast<std::uint8_t>(slot.load(std::memory_order_relaxed) + 1);
          slot.store(count, std::memory_order_relaxed);  // relaxed: as the load above
          if (count != ci.parents_needed) continue;
          ++visited;
          if (ci.known) {
            if (ci.straddles) {
              r.queue.push({ci.error, it.item.depth + 1, ci.index});
            } else {
              ++culled;
            }
          } else {
            const ipoint centre = hier.point(ci.index);
            if (!queue_if_straddles(r, centre, hier.scale_of(centre), it.item.depth + 1, ci.index,
                                    rd)) {
              ++culled;
            }
          }
        }
        last_depth = it.item.depth;
        ++published;
      }
      r.records.publish();
      r.splits.add(published);
      r.triangles.set(r.cut_triangles);
      r.record_triangles.add(added);
      r.visited.add(visited);
      r.culled.add(culled);
      for (std::size_t k = 0; k < tet_case_count; ++k) r.cases[k].add(cases[k]);
      for (std::size_t k = 0; k < primitive_count; ++k) r.primitives[k].add(prims[k]);
      for (std::size_t k = 0; k < split_configuration_count; ++k) {
        r.configurations[k].add(configs[k]);
      }
    }
    // What was not published goes back to the queue: still ready, never lost.
    for (std::size_t i = published; i < b->items.size(); ++i) r.queue.push(b->items[i].item);
    r.discarded.add(b->computed - std::min(b->computed, published));
    r.batches.add(1);
    delete b;
    dispatch(r);
    r.remaining.set(r.queue.size() + inflight_items);
    if (opt.progress && !callback_error) {
      since_progress += published;
      if (since_progress >= opt.progress_interval) {
        since_progress = 0;
        // The callback may call cancel() (a stop request from here) but no control call that
        // waits for this run; an exception it throws stops the run and is rethrown by the
        // control thread's wait() or refine(), never across TBB.
        const callback_scope in_callback(this);
        try {
          opt.progress({r.splits.get(), r.cut_triangles,
                        r.queue.empty() ? 0.0 : r.queue.top().error, last_depth});
        } catch (...) {
          callback_error = std::current_exception();
          request_stop();
        }
      }
    }
  }

  // Marks the progress callback's thread, so that control calls made from inside it can tell.
  struct callback_scope {
    explicit callback_scope(const engine_impl* e) noexcept : saved(in_callback_of) {
      in_callback_of = e;
    }
    callback_scope(const callback_scope&) = delete;
    callback_scope& operator=(const callback_scope&) = delete;
    ~callback_scope() { in_callback_of = saved; }
    const engine_impl* saved;
  };
  static thread_local const engine_impl* in_callback_of;
  [[nodiscard]] bool in_own_callback() const noexcept { return in_callback_of == this; }
  void refuse_in_callback(const char* call) const {
    if (in_own_callback()) {
      throw error(std::string("engine: ") + call +
                  " cannot be called from the engine's progress callback (it would wait for the "
                  "run that calls it); call cancel() there, which requests a stop");
    }
  }
  // After a run: moves a callback's exception to the control thread (caller holds `control`).
  void rethrow_callback_error(std::unique_lock<std::mutex>& lock) {
    if (!pending_error) return;
    std::exception_ptr e = std::move(pending_error);
    pending_error = nullptr;
    lock.unlock();
    std::rethrow_exception(e);
  }

  // One graph run: the first dispatch goes through the serial commit node too (the queue
  // belongs to it: tasks started by the dispatch loop commit while it still runs).
  void run_graph(engine_root* r) {
    arena.execute([&] {
      auto* seed = new batch;
      seed->root = r;
      seed->seed = true;
      commit->try_put(seed);
      graph->wait_for_all();
    });
  }

  // After a graph run that stopped at the end of its slice (not at the goal's deadline): clears
  // the stop request and returns true, unless the user or the progress callback stopped the run
  // (then the run ends). Under `control`, so that a cancel() is either seen here or made after.
  bool continue_after_slice() {
    const std::lock_guard lock(control);
    if (user_cancelled || callback_cancel || callback_error != nullptr) return false;
    if (clock::now() >= goal.deadline) return false;
    stop.store(false, std::memory_order_relaxed);  // relaxed: the next graph run orders it
    return true;
  }

  // A deadline run before the range data is complete (DESIGN §7, "the first surface needs no
  // preprocessing"): slices of the build alternate with slices of refinement without culling
  // (placeholder order: coarse first), each twice as long as the one before, from 1 ms, a build
  // slice never more than half the time left and never a step expected to end past its slice;
  // once the pieces left are estimated to fit in the time left, the build runs to the end. When the
  // data is complete the queue is culled and ordered by it, and the run goes on as usual. What the
  // build did is kept for the next run; what refinement did is a valid cut. Only the first step of
  // all, which has no estimate, can overrun a deadline (by one slab per thread). Deadlines shorter
  // than a step refine without building: the data is then built by the first run with time for it,
  // or by any other kind of run. Why the build wins whenever it fits: refinement culled by the data
  // buys far more surface per millisecond than refinement without it (brainsmall, 1 thread: 40 ms
  // gave 118 K triangles with the data built after 10.5 ms; 20 ms spent half on each gave 5 K).
  void drive_unranged(engine_root* r) {
    auto slice = std::chrono::duration_cast<clock::duration>(std::chrono::milliseconds(1));
    for (;;) {
      {
        const std::lock_guard lock(build_mutex);
        const auto now = clock::now();
        const double left = std::chrono::duration<double>(goal.deadline - now).count();
        const std::size_t pieces_left = ranges_->piece_count() - pieces_built;
        const double estimate = seconds_per_piece() * static_cast<double>(pieces_left);
        const bool to_the_end = pieces_built > 0 && estimate <= left;
        // A slice of the build takes at most half the time left, so that a short deadline
        // still refines.
        const auto half_left = std::chrono::duration_cast<clock::duration>(
            std::chrono::duration<double>(0.5 * std::max(left, 0.0)));
        const clock::time_point until =
            to_the_end ? goal.deadline : now + std::min(slice, half_left);
        if (build_ranges(until, true, false) || clock::now() >= goal.deadline || stopping()) {
          return;
        }
      }
      slice_end = std::min(goal.deadline, clock::now() + slice);
      run_graph(r);
      if (!continue_after_slice()) return;
      slice *= 2;
    }
  }

  // The driver thread of one run.
  void drive(engine_root* r) {
    slice_end = goal.deadline;
    if (goal.what == refine_goal::kind::full) {
      // Full refinement splits every straddling diamond whatever the errors: ranges only.
      const std::lock_guard lock(build_mutex);
      (void)build_ranges(clock::time_point::max(), false, false);
    } else if (goal.what != refine_goal::kind::deadline) {
      (void)ranges();  // ranges and exact errors: what is not built yet, in parallel
    } else if (!ranges_ready.load(std::memory_order_acquire)) {  // acquire: see build_ranges()
      // A deadline run needs only the ranges (errors of scale ≥ 2 are then bounds).
      {
        const std::lock_guard lock(build_mutex);
        if (!ranges_) ranges_.emplace(vol, hier, range_data::staged);
      }
      drive_unranged(r);
    }
    // A stopped run still seeds a fresh root (the seed batch queues its roots, dispatches
    // nothing), so that done() tells an unrefined root from a finished one.
    // acquire: see build_ranges().
    if (ranges_ready.load(std::memory_order_acquire)) {
      slice_end = goal.deadline;
      requeue_by_ranges(*r);
      run_graph(r);
    }
    // Unseeded (a deadline passed inside the first build step): every root may still split.
    if (r->seeded) r->remaining.set(r->queue.size());
    root_bytes.set(r->bytes());
    {
      const std::lock_guard lock(control);
      bool reached = false;
      // callback_error and callback_cancel were written by commit tasks, which happen before
      // wait_for_all() returns above.
      const bool stopped_by_callback = callback_cancel || callback_error != nullptr;
      callback_cancel = false;
      if (callback_error) pending_error = std::move(callback_error);
      callback_error = nullptr;
      if (!user_cancelled && !stopped_by_callback) {
        switch (goal.what) {
          case refine_goal::kind::full:
          case refine_goal::kind::error:
            reached = !eligible(*r);
            break;
          case refine_goal::kind::triangles:
            reached = budget_hit || r->queue.empty();
            break;
          case refine_goal::kind::deadline:
            reached = r->seeded && r->queue.empty();
            break;
        }
      }
      last_reached = reached;
      active = false;
      // relaxed: a status reading for running(); waiters synchronise through `control`.
      active_flag.store(false, std::memory_order_relaxed);
      if (!reached) cancelled_runs.add(1);
    }
    idle.notify_all();
  }

  // Control (caller holds `control`).
  void launch(std::unique_lock<std::mutex>& lock, const refine_goal& g) {
    stop_and_join(lock);
    engine_root* r = current();
    goal = g;
    r->queue.set_discipline(g.what == refine_goal::kind::full ? queue_discipline::lifo
                                                              : queue_discipline::largest_error);
    stop.store(false, std::memory_order_relaxed);  // relaxed: the thread start orders it
    user_cancelled = false;
    pending_error = nullptr;  // a callback error belongs to the run it stopped
    budget_hit = false;
    active = true;
    active_flag.store(true, std::memory_order_relaxed);  // relaxed: status only
    runs.add(1);
    driver = std::thread([this, r] { drive(r); });
  }
  void stop_and_join(std::unique_lock<std::mutex>& lock) {
    if (!driver.joinable()) return;
    if (active) {
      user_cancelled = true;
      request_stop();
    }
    std::thread t = std::move(driver);
    lock.unlock();
    t.join();
    lock.lock();
  }
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
  // Guarded by build_mutex: pieces of the min/max pass built (min_max_pieces of them alone,
  // in piece_seconds), pieces of the error pass built.
  mutable std::size_t pieces_built = 0;
  mutable std::size_t min_max_pieces = 0;
  mutable double piece_seconds = 0.0;
  mutable std::size_t error_pieces_built = 0;
  mutable std::atomic<bool> ranges_ready{false};
  mutable std::atomic<double> range_seconds{0.0};
  unsigned threads;
  // The per-vertex arrays of the last reclaimed root, cleared by `cleaner` (keep_vertex_state),
  // until the next root takes them; the control thread reads `spare` only after joining the
  // cleaner. Declared before the domain, which destroys the retired roots when it goes.
  // `recycle` is cleared by ~engine, after joining the cleaner: roots destroyed then keep nothing.
  std::optional<vertex_state> spare;
  std::thread cleaner;
  std::atomic<bool> cleaner_done{false};
  bool recycle = true;
  mutable epoch_domain domain;
  epoch_participant control_participant;  // retires roots; used under `control`
  mutable std::mutex readers_mutex;
  mutable std::vector<std::unique_ptr<epoch_participant>> readers;
  std::uint64_t serial;
  // The published root: release-stored by set_isovalue() (pairs with the acquire in
  // epoch_guard::protect() of snapshot()).
  std::atomic<engine_root*> root{nullptr};

  mutable tbb::task_arena arena;
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
  std::atomic<bool> stop{false};
  std::size_t inflight = 0;
  std::size_t inflight_items = 0;
  bool budget_hit = false;
  int last_depth = 0;
  std::uint64_t since_progress = 0;

  std::mutex control;
  std::condition_variable idle;
  std::thread driver;
  bool active = false;          // guarded by control
  bool user_cancelled = false;  // guarded by control (read by the driver after its run)
  bool last_reached = false;    // guarded by control
  // Set by the progress callback (commit step) during a run, read by the driver after it.
  bool callback_cancel = false;
  std::exception_ptr callback_error;
  std::exception_ptr pending_error;  // guarded by control: rethrown by wait() / refine()
  std::atomic<bool> active_flag{false};
  counter runs, cancelled_runs;
  mutable counter retired_bytes, peak_retired_bytes, root_bytes;
  counter recycled_roots;
  std::uint64_t generation = 0;  // guarded by control
};

thread_local const engine_impl* engine_impl::in_callback_of = nullptr;

}  // namespace detail

// ---------------------------------------------------------------------------------------------
// engine

engine::engine(const volume& vol, double isovalue, engine_options options) {
  init(nullptr, vol, isovalue, std::move(options));
}

engine::engine(volume&& vol, double isovalue, engine_options options) {
  auto owned = std::make_shared<const volume>(std::move(vol));
  const volume& v = *owned;
  init(std::move(owned), v, isovalue, std::move(options));
}

engine::engine(std::shared_ptr<const volume> vol, double isovalue, engine_options options) {
  if (!vol) throw error("engine: expected a volume, found a null pointer");
  const volume& v = *vol;
  init(std::move(vol), v, isovalue, std::move(options));
}

void engine::init(std::shared_ptr<const volume> owned, const volume& vol, double isovalue,
                  engine_options options) {
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  if (options.smooth.active()) {
    // The engine refines the smoothed field; it keeps the data alive through it when it owns
    // the data, and borrows it (as for any volume given by reference) otherwise.
    std::shared_ptr<const volume> data =
        owned ? std::move(owned) : std::shared_ptr<const volume>(std::shared_ptr<void>(), &vol);
    auto field = std::make_shared<const volume>(smooth(std::move(data), options.smooth));
    const volume& f = *field;
    impl_ = std::make_unique<detail::engine_impl>(std::move(field), f, std::move(options));
  } else {
    impl_ = std::make_unique<detail::engine_impl>(std::move(owned), vol, std::move(options));
  }
  // release: pairs with the acquire in epoch_guard::protect() (snapshot()).
  impl_->root.store(impl_->make_root(isovalue, 0), std::memory_order_release);
}

engine::~engine() {
  {
    std::unique_lock lock(impl_->control);
    impl_->stop_and_join(lock);
  }
  impl_->arena.execute([this] { impl_->graph->wait_for_all(); });
  detail::engine_root* r = impl_->current();
  impl_->root.store(nullptr, std::memory_order_relaxed);  // relaxed: no reader is left
  impl_->recycle = false;
  if (impl_->cleaner.joinable()) impl_->cleaner.join();
  impl_->spare.reset();
  detail::engine_impl::destroy_root(r);
  // Participants, then the domain (which drains the retired roots), go with impl_.
  impl_->readers.clear();
}

void engine::set_isovalue(double w) {
  if (!std::isfinite(w)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(w));
  }
  impl_->refuse_in_callback("set_isovalue()");
  std::unique_lock lock(impl_->control);
  const bool resume = impl_->active;
  const refine_goal goal = impl_->goal;
  impl_->stop_and_join(lock);
  detail::engine_root* old = impl_->current();
  detail::engine_root* fresh = impl_->make_root(w, ++impl_->generation);
  // seq_cst (the default): release for readers' protect(), and the unlink must be seq_cst for
  // the TSan variant of the reclamation argument (concurrent/epoch.hpp).
  impl_->root.store(fresh);
  old->retired_bytes = old->bytes();
  impl_->retired_bytes.add(old->retired_bytes);
  impl_->peak_retired_bytes.set(
      std::max(impl_->peak_retired_bytes.get(), impl_->retired_bytes.get()));
  impl_->control_participant.retire(old, &detail::engine_impl::destroy_root, old->birth_era());
  // Roots are large and few: reclaim now what no snapshot holds, rather than every
  // reclaim_threshold retirements. A reader stalled in a snapshot pins only its own root.
  impl_->control_participant.flush();
  if (resume) impl_->launch(lock, goal);
}

void engine::start(const refine_goal& goal) {
  if (goal.what == refine_goal::kind::error && !(goal.max_error >= -1e300)) {
    throw error("refine goal: expected a number as error threshold");
  }
  impl_->refuse_in_callback("start()");
  std::unique_lock lock(impl_->control);
  impl_->launch(lock, goal);
}

void engine::cancel() {
  if (impl_->in_own_callback()) {
    // From the progress callback, on a thread of the run itself: joining the run here would
    // wait for this very call, so only request the stop; the run ends within one split.
    impl_->callback_cancel = true;
    impl_->request_stop();
    return;
  }
  std::unique_lock lock(impl_->control);
  impl_->stop_and_join(lock);
}

void engine::wait() {
  impl_->refuse_in_callback("wait()");
  std::unique_lock lock(impl_->control);
  impl_->idle.wait(lock, [this] { return !impl_->active; });
  impl_->rethrow_callback_error(lock);
}

bool engine::refine(const refine_goal& goal) {
  impl_->refuse_in_callback("refine()");
  std::unique_lock lock(impl_->control);
  impl_->launch(lock, goal);
  impl_->idle.wait(lock, [this] { return !impl_->active; });
  const bool reached = impl_->last_reached;
  impl_->rethrow_callback_error(lock);
  return reached;
}

surface_snapshot engine::snapshot() const {
  surface_snapshot s;
  s.guard_ = impl_->reader().pin();
  s.owner_ = this;
  s.root_ = s.guard_.protect(impl_->root);
  s.published_ = s.root_->records.published();
  return s;
}

double engine::isovalue() const {
  epoch_guard g = impl_->reader().pin();
  return g.protect(impl_->root)->isovalue;
}

bool engine::running() const noexcept {
  // relaxed: a status reading.
  return impl_->active_flag.load(std::memory_order_relaxed);
}

bool engine::done() const {
  epoch_guard g = impl_->reader().pin();
  return g.protect(impl_->root)->remaining.get() == 0;
}

engine_statistics engine::statistics() const {
  engine_statistics s;
  {
    epoch_guard g = impl_->reader().pin();
    const detail::engine_root* r = g.protect(impl_->root);
    s.refine.splits = r->splits.get();
    s.refine.visited = r->visited.get();
    s.refine.culled = r->culled.get();
    s.refine.triangles = r->triangles.get();
    s.refine.record_triangles = r->record_triangles.get();
    for (std::size_t k = 0; k < tet_case_count; ++k) s.refine.cases[k] = r->cases[k].get();
    for (std::size_t k = 0; k < primitive_count; ++k) {
      s.refine.primitives[k] = r->primitives[k].get();
    }
    for (std::size_t k = 0; k < split_configuration_count; ++k) {
      s.refine.configurations[k] = r->configurations[k].get();
    }
    s.published = r->records.published();
    s.discarded = r->discarded.get();
    s.batches = r->batches.get();
    s.generation = r->generation;
  }
  s.retired_bytes = impl_->retired_bytes.get();
  s.peak_retired_bytes = impl_->peak_retired_bytes.get();
  s.recycled_roots = impl_->recycled_roots.get();
  s.root_bytes = impl_->root_bytes.get();
  s.runs = impl_->runs.get();
  s.cancelled_runs = impl_->cancelled_runs.get();
  s.reclamation = impl_->domain.statistics();
  {
    const std::lock_guard lock(impl_->readers_mutex);
    for (const auto& p : impl_->readers) s.snapshot_retries += p->protect_retries();
  }
  return s;
}

const volume& engine::field() const noexcept { return impl_->vol; }
const hierarchy& engine::hierarchy_of() const noexcept { return impl_->hier; }
const range_data& engine::ranges() const { return impl_->ranges(); }
unsigned engine::threads() const noexcept { return impl_->threads; }
double engine::range_build_seconds() const noexcept {
  // relaxed: a statistic, added to by each step of the build.
  return impl_->range_seconds.load(std::memory_order_relaxed);
}

bool engine::errors_built() const noexcept {
  // acquire: see ranges_built(); ranges_ is then made and never replaced.
  return impl_->ranges_ready.load(std::memory_order_acquire) && impl_->ranges_->errors_exact();
}

std::size_t engine::range_bytes() const {
  const std::lock_guard lock(impl_->build_mutex);
  return impl_->ranges_ ? impl_->ranges_->byte_size() : 0;
}

bool engine::ranges_built() const noexcept {
  // acquire: pairs with the release in build_ranges() (a caller may then read ranges()).
  return impl_->ranges_ready.load(std::memory_order_acquire);
}

// ---------------------------------------------------------------------------------------------
// surface_snapshot

double surface_snapshot::isovalue() const noexcept { return root_->isovalue; }
std::uint64_t surface_snapshot::generation() const noexcept { return root_->generation; }
std::uint64_t surface_snapshot::triangle_count() const noexcept {
  return root_->records[published_ - 1].cut_triangles;
}

bool surface_snapshot::is_split(std::uint64_t index) const noexcept {
  const std::uint32_t r = root_->record_index(index);
  return r != 0 && r < published_;
}

void surface_snapshot::for_each_split(const std::function<void(std::uint64_t)>& f) const {
  for (std::uint64_t r = 1; r < published_; ++r) f(root_->records[r].diamond);
}

namespace {

// Calls f(owner, edge keys) for the triangles of record r whose owner passes take(owner).
template <class Take, class F>
void walk_record(const detail::engine_root& root, const hierarchy& hier, std::uint64_t r,
                 Take&& take, F&& f) {
  const detail::engine_record& rec = root.records[r];
  if (r == 0) {
    for (std::uint32_t k = 0; k < rec.count; ++k) {
      const owned_triangle& t = root.root_triangles[k];
      if (take(t.owner)) f(t.owner, t.keys);
    }
    return;
  }
  for_each_unpacked(hier, rec.diamond, rec.scale, rec.groups, 0, rec.count, take, f);
}

}  // namespace

void surface_snapshot::for_each_triangle(
    const std::function<void(const owned_triangle&)>& f) const {
  const auto live = [this](std::uint64_t owner) { return owner == no_owner || !is_split(owner); };
  for (std::uint64_t r = 0; r < published_; ++r) {
    walk_record(*root_, owner_->hierarchy_of(), r, live,
                [&f](std::uint64_t owner, const std::array<std::uint64_t, 3>& keys) {
                  f(owned_triangle{owner, keys});
                });
  }
}

// The records in canonical order (diamond order), cut into consecutive parts, each fed to its
// own builder on the engine's thread count, then joined into the mesh one builder fed them all
// would make (mesh_builder::join): the same mesh, vertex for vertex, for every thread count. One
// part per 16 K records, up to 8 per thread (the records gather where the surface is, so parts of
// equal vertex ranges differ in size). A fresh arena per call: the caller (any thread) takes its
// reserved slot at once, whatever the engine's own arena is doing.
template <class Take>
triangle_mesh surface_snapshot::build(Take&& take, bool canonical, double max_error) const {
  const engine& e = *owner_;
  const hierarchy& hier = e.hierarchy_of();
  const std::uint64_t vertices = hier.vertex_count();
  const std::size_t threads = e.threads();
  const std::size_t parts =
      threads <= 1
          ? 1
          : std::clamp<std::size_t>(static_cast<std::size_t>(published_ / 16384), 1, 8 * threads);
  // Canonical order is diamond order: with this many records, one sequential pass over the
  // per-vertex record index costs less than sorting them.
  const bool scan = canonical && vertices <= 64 * published_;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  if (!scan) {
    order.reserve(published_);
    for (std::uint64_t r = 1; r < published_; ++r) {
      const detail::engine_record& rec = root_->records[r];
      if (rec.error > max_error) order.emplace_back(rec.diamond, static_cast<std::uint32_t>(r));
    }
    if (canonical) std::sort(order.begin(), order.end());
  }
  // Part k of n items: [first(k), first(k + 1)).
  const auto first = [parts](std::uint64_t items, std::size_t k) {
    return k * (items / parts) + std::min<std::uint64_t>(k, items % parts);
  };
  const auto expected = static_cast<std::size_t>(triangle_count() / 2 + 16);
  std::vector<detail::mesh_builder> builders;
  builders.reserve(parts);
  for (std::size_t k = 0; k < parts; ++k) {
    builders.emplace_back(hier, e.field(), root_->isovalue, expected / parts + 16);
  }
  const auto feed = [&](std::size_t k) {
    detail::mesh_builder& b = builders[k];
    const auto add = [&b](std::uint64_t, const std::array<std::uint64_t, 3>& keys) { b.add(keys); };
    if (k == 0) walk_record(*root_, hier, 0, take, add);
    if (scan) {
      for (std::uint64_t v = first(vertices, k), end = first(vertices, k + 1); v < end; ++v) {
        const std::uint32_t r = root_->record_index(v);
        if (r == 0 || r >= published_ || !(root_->records[r].error > max_error)) continue;
        walk_record(*root_, hier, r, take, add);
      }
    } else {
      for (std::uint64_t i = first(order.size(), k), end = first(order.size(), k + 1); i < end;
           ++i) {
        walk_record(*root_, hier, order[i].second, take, add);
      }
    }
  };
  if (parts == 1) {
    feed(0);
    return builders[0].finish();
  }
  triangle_mesh m;
  tbb::task_arena arena(static_cast<int>(std::min(threads, parts)));
  arena.execute([&] {
    detail::tbb_loop(parts, feed);
    m = detail::mesh_builder::join(builders, detail::tbb_loop);
  });
  return m;
}

triangle_mesh surface_snapshot::mesh() const {
  PROGISO_ASSERT(valid());
  return build([this](std::uint64_t owner) { return owner == no_owner || !is_split(owner); }, true,
               -std::numeric_limits<double>::infinity());
}

triangle_mesh surface_snapshot::mesh_cut(double max_error) const {
  PROGISO_ASSERT(valid());
  return build(
      [this, max_error](std::uint64_t owner) {
        if (owner == no_owner || !is_split(owner)) return true;
        return !(root_->records[root_->record_index(owner)].error > max_error);
      },
      true, max_error);
}

bool surface_snapshot::check_integrity() const noexcept {
  if (root_ == nullptr) return false;
  if (root_->magic != detail::root_alive || !std::isfinite(root_->isovalue)) return false;
  const std::uint64_t vertices = owner_->hierarchy_of().vertex_count();
  for (std::uint64_t r = 0; r < published_; ++r) {
    const detail::engine_record& rec = root_->records[r];
    if (r == 0) {
      if (rec.diamond != no_owner || rec.count != root_->root_triangles.size()) return false;
      for (const owned_triangle& t : root_->root_triangles) {
        if (t.owner != no_owner && t.owner >= vertices) return false;
      }
      continue;
    }
    if (rec.diamond >= vertices || root_->record_index(rec.diamond) != r) return false;
    // At most one group per child tetrahedron: 2 per ring tetrahedron, 8 of those.
    if (rec.count > 16 || !(rec.error >= 0.0) || rec.scale <= 0) return false;
    for (std::uint32_t k = 0; k < rec.count; ++k) {
      const packed_group& g = rec.groups[k];
      if (g.owner != no_owner && g.owner >= vertices) return false;
      if (g.count() != 1 && g.count() != 2) return false;
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

extract_result extract_isosurface_parallel(const volume& vol, double isovalue,
                                           const extract_options& options, unsigned threads) {
  using clock = std::chrono::steady_clock;
  const auto seconds = [](clock::duration d) { return std::chrono::duration<double>(d).count(); };
  check_extract_inputs(isovalue, options);
  extract_result res;
  engine_options eo;
  eo.threads = threads;
  int max_depth = 0;
  if (options.progress) {
    eo.progress = [&options, &max_depth](const engine_progress& p) {
      options.progress({p.splits, p.triangles, p.depth, max_depth});
    };
  }
  const auto t0 = clock::now();  // the volume is in memory
  engine eng(vol, isovalue, std::move(eo));
  max_depth = eng.hierarchy_of().max_depth();
  {
    // The root surface: no range data, no pass over the volume.
    const surface_snapshot first = eng.snapshot();
    const triangle_mesh m = first.mesh();
    res.first_surface_seconds = seconds(clock::now() - t0);
  }
  const auto t1 = clock::now();
  switch (options.mode) {
    case extract_mode::full:
      eng.refine_full();
      break;
    case extract_mode::error:
      eng.refine_until(options.max_error);
      break;
    case extract_mode::triangles:
      eng.refine(refine_goal::triangles(options.max_triangles));
      break;
    case extract_mode::time:
      // The budget counts from the volume in memory: the range data is built inside it.
      eng.refine(refine_goal::until(deadline_after(t0, options.time_budget)));
      break;
  }
  const auto t2 = clock::now();
  // The first run built the range data (in parallel); refinement is the rest of the run.
  res.range_build_seconds = eng.range_build_seconds();
  // What is built so far (completing the data here would put a build after the deadline into
  // the pipeline).
  res.range_bytes = eng.range_bytes();
  res.refine_seconds = std::max(0.0, seconds(t2 - t1) - res.range_build_seconds);
  {
    const surface_snapshot s = eng.snapshot();
    res.mesh = s.mesh();
  }
  const auto t3 = clock::now();
  res.extract_seconds = seconds(t3 - t2);
  res.total_seconds = seconds(t3 - t0);
  res.pipeline_seconds = res.total_seconds;
  res.stats = eng.statistics().refine;
  // A scan of every sample: after the timings, not inside "first surface".
  const auto [lo, hi] = vol.value_range();
  res.isovalue_outside_data = !(lo <= isovalue && isovalue < hi);
  return res;
}

}  // namespace progiso
