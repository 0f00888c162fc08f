// Refinement on more than one thread: tasks over parts of the volume or of a band, no serial
// step per split.
//
// Each task refines from its own ready diamonds and publishes its computed splits every 64:
// under `publish_mutex` it reserves their places in the log (and their groups' in the root's
// store); without the mutex it counts its splits as parents of their children (an atomic
// decrement per child: the task whose decrement completes a child's parent count makes the child
// ready in its own lists) and then fills the places (records, groups, record_of: the copies and
// the page faults of fresh chunks run on every task at once); under the mutex again it marks
// them filled and moves the watermark over the filled ranges at the front (tasks reserve in log
// order but may finish out of order). A child is therefore computed, hence reserved, after
// every parent's place was reserved, so it lies above them in the log; the watermark passes no
// range before it is filled, so every published prefix of the records is a valid cut. A task with
// work to spare gives half of it to a new task whenever fewer tasks than threads are running;
// oneTBB's work stealing places it on an idle thread.
//
// In full refinement a task takes its diamonds by grid plane, as the one-thread sweep does
// (plane_lists.hpp): the run starts with the volume cut into one slab of planes per thread, and
// a task gives away the planes above the middle of those it holds, so that each task's front
// stays in its own part of the volume and in its own cache. In a band of a priority run a task
// refines depth first from a stack and gives away the older half (the coarser diamonds, the
// larger subtrees).
//
// Full refinement splits every straddling diamond whatever the order: one run over everything
// queued, so the split set and the mesh are those of one thread. Refinement by priority (a
// deadline, an error target, a budget) runs band by band: the driver takes the queue's top band
// (a quarter octave of errors, see ready_queue.hpp), the tasks refine it depth first, and a child
// ranked below the band waits for a later one. A child's error is at most its parent's, so each
// band is taken once, and the order is the one-thread loop's up to the order inside a band. The
// flow graph (refinement_schedule::flow_graph: compute tasks feeding a serial commit node that
// makes every child ready) runs priority refinement at about the same splits per second on two
// threads, but from a fresh engine it publishes far fewer splits by a deadline, and a deadline
// buys correspondingly less surface (docs/ARCHITECTURE.md, bench/README.md).

#include "engine_impl.hpp"

#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <deque>
#include <memory>

#include <progiso/core/refine/detail/prefetch.hpp>

namespace progiso::detail {

namespace {

// Splits a task computes between two publications: a reader's snapshot lags a task by at most
// this many splits, and the mutex is taken once per step.
constexpr std::size_t task_publish_step = 64;
constexpr std::size_t task_publish_most = 256;
constexpr std::size_t task_prefetch_distance = 8;
// A deadline is checked every this many splits, as the one-thread loop does.
constexpr std::size_t task_clock_step = 8;

// A computed split waiting for its task's next publication.
struct pending_split {
  // Leaves the fields to the task, which sets every one (value-initialising 184 bytes cost a
  // `rep stos` per split).
  pending_split() noexcept {}
  ready_item item;
  std::int32_t scale;
  std::uint32_t crossed;
  std::uint32_t first;  // groups in the task's buffer
  std::uint32_t count;
  int added;
  int removed;
  // Set when publication reserves the split's places: the cut's triangles with it, and where
  // its groups go in the root's store.
  std::uint64_t cut_triangles;
  packed_group* dest;
  // The split's children, found when it is computed: their words in record_of are requested
  // then, so that publication's counting, up to 256 splits later, finds them in cache (the
  // locked decrement waits for its line; without the request it was a large part of
  // publication's time on two threads).
  child_list children;
};

// Children of one rank (ready_queue::rank) held for a later band.
struct ranked_items {
  std::uint64_t rank;
  std::vector<ready_item> items;
};

}  // namespace

// State shared by the tasks of one run (one band of a priority run).
struct engine_impl::full_run {
  engine_root* root = nullptr;
  const range_data* ranges = nullptr;
  tbb::task_group* group = nullptr;
  // A band of a priority run: children ranked below `floor` (ready_queue::rank) are left for a
  // later band. Off in full refinement. An error target in any order is one band, every rank
  // above the target, taken by plane.
  bool banded = false;
  std::uint64_t floor = 0;
  // Where full_task::hold_below() counts ranks down from: the floor of a band; for an error
  // target, the rank just above the target's own (the errors held are at most the target, most
  // of them just below it).
  std::uint64_t hold_base = 0;
  // Ready diamonds taken by grid plane (plane_lists), volume cut into slabs: full refinement
  // and an error target in any order (engine_impl::goal_runs_by_plane()). Otherwise a stack.
  bool by_plane = false;
  // Tasks running or spawned: a hint for sharing work (relaxed; a stale value only shares a
  // little early or late).
  std::atomic<unsigned> active{0};
  // Ready diamonds on the tasks' stacks plus computed, unpublished splits: the root's
  // `remaining` while the run lasts (relaxed; statistics only).
  std::atomic<std::int64_t> outstanding{0};
  // Ready diamonds the run leaves to the queue, in the tasks' own vectors (moved, not copied):
  // what stopped tasks did not publish, and children ranked below the band, one vector per
  // rank. Queued by the driver after the run (a rank's vector in one piece), or, after a
  // deadline, by the next run (engine_root::leftover).
  std::mutex left_mutex;
  std::vector<std::vector<ready_item>> left;
  std::vector<ranked_items> left_ranked;
  // Records reserved by tasks and not yet published, in log order (under publish_mutex): each
  // range's end and whether its task has filled it. The watermark moves over the filled ranges
  // at the front; at most one range per task.
  struct reserved_range {
    std::size_t end;
    bool filled;
  };
  std::deque<reserved_range> unfilled;
};

struct engine_impl::full_task {
  full_run* run = nullptr;
  // Ready diamonds: by grid plane in a run by plane (full refinement, an error target in any
  // order: the one-thread sweep's order), on a stack (next at the back: depth first) in a band
  // of a priority run. A stopped task's planes go to the stack keyed by placeholder.
  plane_lists planes;
  std::vector<ready_item> stack;
  // A band's first task takes its share of the band from here on its own thread: [lo, hi) of
  // the driver's vector, which outlives the run.
  const std::vector<ready_item>* band = nullptr;
  std::size_t band_lo = 0;
  std::size_t band_hi = 0;
  // Children ranked below the band (or the error target), by rank, and where each rank's vector
  // is: by the rank's distance below full_run::hold_base (at most below_near − 1), else
  // searched.
  std::vector<ranked_items> below;
  static constexpr std::uint64_t below_near = 64;
  std::array<std::int32_t, below_near> below_at{};  // 1 + index in `below`, 0: none yet

  void hold_below(std::uint64_t base, std::uint64_t rank, const ready_item& item) {
    const std::uint64_t d = base - rank;
    if (d < below_near && below_at[d] != 0) {
      below[static_cast<std::size_t>(below_at[d] - 1)].items.push_back(item);
      return;
    }
    if (d >= below_near) {
      for (ranked_items& part : below) {
        if (part.rank == rank) {
          part.items.push_back(item);
          return;
        }
      }
    } else {
      below_at[d] = static_cast<std::int32_t>(below.size() + 1);
    }
    below.push_back({rank, {item}});
  }
  std::vector<pending_split> pending;
  std::vector<packed_group> groups;  // of the pending splits
  // Of the pending splits, under a triangle budget only (publication may keep a prefix).
  std::vector<split_summary> summaries;
  split_tally pending_tally;  // of the pending splits
  split_tally tally;          // published splits, visited and culled children
  // Of the pending splits: their triangles added less removed (the cut's change).
  std::int64_t pending_delta = 0;
  std::uint32_t publications = 0;
};

void engine_impl::refine_in_tasks(engine_root& r) {
  seed_roots(r);  // a no-op once seeded
  const range_data* rd = built_ranges();
  const bool banded = goal.what != refine_goal::kind::full;
  // By grid plane: one run over every eligible diamond; an error target's queue keeps the rest.
  const bool by_plane = goal_runs_by_plane() && rd != nullptr;
  PROGISO_ASSERT(banded || rd != nullptr);  // drive() builds the ranges before a full run
  mark_if_keys_are_bounds(r, rd);
  while (!stopping() && eligible(r)) {
    if (past_deadline()) {
      request_stop();
      break;
    }
    // A band: the queue's top rank whole, the next diamond at the back (every item of a rank is
    // eligible or none: an error goal aims the queue at its target). Full refinement: all.
    std::vector<ready_item> items;
    std::uint64_t floor = 0;
    full_run run;
    if (!by_plane) {
      floor = r.queue.top_rank();
      items = r.queue.take_top_band();
    } else {
      // An error target in any order: every rank above it (launch() aimed the queue at it).
      if (banded) {
        floor = r.queue.above_target_rank();
        run.hold_base = r.queue.rank(goal.max_error) + 1;
      }
      items.reserve(r.queue.size());
      while (eligible(r)) {
        items.push_back(r.queue.top());
        r.queue.pop();
      }
      std::reverse(items.begin(), items.end());
    }

    run.root = &r;
    run.ranges = rd;
    run.banded = banded;
    run.floor = floor;
    if (!by_plane) run.hold_base = floor;
    run.by_plane = by_plane;
    run.outstanding.store(static_cast<std::int64_t>(items.size()), std::memory_order_relaxed);
    arena.execute([&] {
      tbb::task_group group;
      run.group = &group;
      if (!by_plane) {
        // A band: its diamonds in queue order, cut into one run of consecutive ones per thread.
        const std::size_t tasks = std::min<std::size_t>(threads, items.size());
        for (std::size_t k = 0; k < tasks; ++k) {
          auto part = std::make_shared<full_task>();
          part->band = &items;
          part->band_lo = items.size() * k / tasks;
          part->band_hi = items.size() * (k + 1) / tasks;
          spawn_full_task(run, std::move(part));
        }
      } else {
        // By plane: the volume cut into slabs of planes, one per thread, each swept from its
        // lowest plane up; the slab with the most diamonds is halved until there are as many as
        // threads.
        std::vector<std::shared_ptr<full_task>> parts;
        parts.push_back(std::make_shared<full_task>());
        reset_planes(parts[0]->planes);
        for (const ready_item& it : items) parts[0]->planes.push(it.index);
        while (parts.size() < threads) {
          full_task& most = **std::max_element(
              parts.begin(), parts.end(),
              [](const auto& a, const auto& b) { return a->planes.size() < b->planes.size(); });
          if (most.planes.size() < 2) break;
          parts.push_back(std::make_shared<full_task>());
          most.planes.give_upper_half(parts.back()->planes);
        }
        for (std::shared_ptr<full_task>& part : parts) spawn_full_task(run, std::move(part));
      }
      group.wait();
    });
    // Stopped: what was not published is still ready, never lost; and the lower bands. After a
    // deadline the next run queues it (the run returns now).
    if (stopping() && goal.what == refine_goal::kind::deadline) {
      for (ranked_items& part : run.left_ranked) run.left.push_back(std::move(part.items));
      for (std::vector<ready_item>& part : run.left) {
        r.leftover_items += part.size();
        r.leftover.push_back(std::move(part));
      }
    } else {
      for (const std::vector<ready_item>& part : run.left) {
        for (const ready_item& it : part) r.queue.push(it);
      }
      for (ranked_items& part : run.left_ranked)
        r.queue.push_band(part.rank, std::move(part.items));
    }
    // Left by a stopped run by plane: keyed by placeholder (full_item()).
    if (by_plane && !run.left.empty()) r.placeholder_keys = true;
    if (by_plane) break;  // one run over everything eligible
  }
  // Queued by placeholder: full refinement's children, or any before the range data exists.
  if (ready_count(r) != 0 && (!banded || rd == nullptr)) r.placeholder_keys = true;
  r.remaining.set(ready_count(r));
}

void engine_impl::run_full_task(full_task& t) {
  full_run& run = *t.run;
  const engine_root& r = *run.root;
  const double w = r.isovalue;
  const bool prefetch = vol.byte_size() > prefetch_min_bytes;
  const bool deadline = goal.what == refine_goal::kind::deadline;
  const bool budget = goal.what == refine_goal::kind::budget;
  const bool by_plane = run.by_plane;  // by grid plane (plane_lists)
  if (t.band != nullptr) {
    t.stack.assign(t.band->begin() + static_cast<std::ptrdiff_t>(t.band_lo),
                   t.band->begin() + static_cast<std::ptrdiff_t>(t.band_hi));
    t.band = nullptr;
  }
  std::size_t n = 0;
  for (;;) {
    while (!(by_plane ? t.planes.empty() : t.stack.empty()) && !stopping()) {
      if (deadline && n++ % task_clock_step == 0 && past_deadline()) {
        request_stop();
        break;
      }
      ready_item item;
      ipoint centre;
      if (by_plane) {
        const std::uint64_t index = t.planes.pop();
        centre = hier.point(index);
        item = full_item(index, centre);
      } else {
        item = t.stack.back();
        t.stack.pop_back();
        if (prefetch && t.stack.size() > task_prefetch_distance) {
          const ipoint a = hier.point(t.stack[t.stack.size() - 1 - task_prefetch_distance].index);
          prefetch_diamond_samples(vol, a, hier.scale_of(a));
        }
        centre = hier.point(item.index);
      }
      const std::int32_t scale = hier.scale_of(centre);
      const child_list children = children_requested(r, centre, scale);
      const std::size_t first = t.groups.size();
      const split_summary s = compute_split(hier, vol, w, centre, scale, t.groups);
      // Filled field by field in the vector: a pending split assembled on the stack and then
      // copied over waited on its own narrow stores at every wide load of the copy (a failed
      // store-to-load forwarding per field, a large share of this loop's profile on one thread).
      pending_split& p = t.pending.emplace_back();
      p.item = item;
      p.scale = scale;
      p.crossed = s.crossed;
      p.first = static_cast<std::uint32_t>(first);
      p.count = static_cast<std::uint32_t>(t.groups.size() - first);
      p.added = s.added_triangles;
      p.removed = s.removed_triangles;
      p.cut_triangles = 0;
      p.dest = nullptr;
      p.children = children;
      t.pending_tally.count(s);
      t.pending_delta += s.added_triangles - s.removed_triangles;
      if (budget) t.summaries.push_back(s);
      // Every 64 splits when the mutex is free; a task that finds it taken goes on computing
      // (waiting for it was a sizeable part of the time on two threads), up to 256.
      if (t.pending.size() >= task_publish_step && (t.pending.size() % task_publish_step) == 0) {
        (void)publish_full_task(t, t.pending.size() >= task_publish_most);
      }
    }
    if (stopping() || t.pending.empty()) break;
    (void)publish_full_task(t, true);  // the children it makes ready refill the stack
  }
  // At a deadline what is computed is published (a stop by the user or the callback discards
  // it): the deadline is the run's goal, and a cut with these splits is as valid.
  if (!t.pending.empty() && deadline && past_deadline()) (void)publish_full_task(t, true, true);
  t.planes.drain([&](std::uint64_t index) { t.stack.push_back(full_item(index)); });
  if (!t.pending.empty() || !t.stack.empty() || !t.below.empty()) {
    t.tally.discarded += t.pending.size();
    for (const pending_split& p : t.pending) t.stack.push_back(p.item);
    const std::lock_guard lock(run.left_mutex);
    if (!t.stack.empty()) run.left.push_back(std::move(t.stack));
    for (ranked_items& part : t.below) run.left_ranked.push_back(std::move(part));
  }
  {
    const std::lock_guard lock(publish_mutex);
    t.tally.add_to(*run.root);
  }
  run.active.fetch_sub(1, std::memory_order_relaxed);  // relaxed: a hint (see full_run)
}

bool engine_impl::publish_full_task(full_task& t, bool wait, bool stopped) {
  full_run& run = *t.run;
  engine_root& r = *run.root;
  std::size_t kept = t.pending.size();
  std::size_t first_record = 0;  // of the records published below
  // Outside a triangle budget every pending split is published: the mutex guards the cut's
  // triangle count and the groups' store for one addition each (the splits' own counts and
  // places follow from them below, without it). Pending groups are at most 256 × 16, within
  // a chunk of the store.
  const bool whole =
      goal.what != refine_goal::kind::budget && t.groups.size() <= r.groups.chunk_size();
  std::uint64_t triangles_before = 0;
  packed_group* groups_at = nullptr;
  // 1. Under the mutex: the records' places in the log and the groups' in the root's store
  //    (the budget's triangle count is sequential), nothing copied.
  {
    std::unique_lock lock(publish_mutex, std::defer_lock);
    if (wait) {
      lock.lock();
    } else if (!lock.try_lock()) {
      return false;
    }
    if (stopping() && !stopped) return false;  // the caller returns the pending splits
    if (whole) {
      triangles_before = r.cut_triangles;
      r.cut_triangles =
          static_cast<std::uint64_t>(static_cast<std::int64_t>(r.cut_triangles) + t.pending_delta);
      if (!t.groups.empty()) groups_at = r.groups.reserve_contiguous(t.groups.size());
    }
    for (std::size_t i = 0; !whole && i < t.pending.size(); ++i) {
      pending_split& p = t.pending[i];
      const std::uint64_t after =
          r.cut_triangles + static_cast<unsigned>(p.added) - static_cast<unsigned>(p.removed);
      if (!goal_admits(after)) {
        // The budget: this split and the task's later ones stay ready (computed, discarded).
        budget_hit = true;
        request_stop();
        kept = i;
        break;
      }
      r.cut_triangles = after;
      p.cut_triangles = after;
      p.dest = r.groups.reserve_contiguous(p.count);
    }
    PROGISO_ASSERT(r.records.size() + kept <= max_records);
    first_record = r.records.reserve(kept);
    if (kept < t.pending.size()) {
      // Counted by pending_tally but not published: counted again from the records kept.
      t.pending_tally = split_tally{};
      for (std::size_t i = 0; i < kept; ++i) t.pending_tally.count(t.summaries[i]);
      t.tally.discarded += t.pending.size() - kept;
      for (std::size_t i = kept; i < t.pending.size(); ++i) t.stack.push_back(t.pending[i].item);
      t.pending.resize(kept);
    }
    if (kept == 0) {  // a budget that allows none of them: nothing to publish or count
      t.summaries.clear();
      t.groups.clear();
      return true;
    }
    run.unfilled.push_back({first_record + kept, false});
    if (stopped) {
      // A deadline's last publication: the next run counts the children (the run returns).
      for (std::size_t i = 0; i < kept; ++i) {
        r.uncounted.push_back(static_cast<std::uint32_t>(first_record + i));
      }
    }
  }
  t.pending_delta = 0;
  if (whole) {
    std::uint64_t after = triangles_before;
    for (pending_split& p : t.pending) {
      after = after + static_cast<unsigned>(p.added) - static_cast<unsigned>(p.removed);
      p.cut_triangles = after;
      p.dest = groups_at + p.first;
    }
  }
  // 2. Still without it, and before the records are filled: the children of these splits.
  //    The decrement that completes a child's parent count makes it ready, on this task's own
  //    lists. A child needs its parents' places reserved (step 1), not filled: it is computed,
  //    hence reserved, after them, so it lies above them in the log, and the watermark (step 4)
  //    passes no range that is not filled yet. Counting before filling keeps the locked
  //    decrements clear of the fill's stores to fresh pages, which each of them would otherwise
  //    wait for (x86 drains its store buffer at a locked instruction). A deadline that passes
  //    meanwhile leaves the rest to the next run (engine_root::uncounted): counting up to 256
  //    records here would take long enough to push the return past it.
  const std::int64_t pushed = stopped ? 0 : count_full_task_children(t, first_record);
  // 3. Without it: the records, their groups and the diamonds' record indices, into the places
  //    reserved (the pages these first touch fault in here, on every task at once).
  for (std::size_t i = 0; i < kept; ++i) {
    const pending_split& p = t.pending[i];
    std::copy_n(t.groups.data() + p.first, p.count, p.dest);
    r.records.at_unpublished(first_record + i) = {p.item.index, p.dest, p.count, p.crossed,
                                                  p.cut_triangles};
    std::atomic_ref<std::uint32_t>(r.word(p.item.index))
        .store(static_cast<std::uint32_t>(first_record + i),
               // relaxed: published by the release in records.publish() below, which the
               // mutex orders after this (this task's unlock, the publisher's lock).
               std::memory_order_relaxed);
  }
  t.tally.take(t.pending_tally);
  // 4. Under the mutex again: this task's places are filled; the watermark moves over every
  //    filled range that follows it (tasks reserve in order but may finish out of order).
  {
    const std::lock_guard lock(publish_mutex);
    for (full_run::reserved_range& u : run.unfilled) {
      if (u.end == first_record + kept) u.filled = true;
    }
    std::size_t mark = 0;
    while (!run.unfilled.empty() && run.unfilled.front().filled) {
      mark = run.unfilled.front().end;
      run.unfilled.pop_front();
    }
    if (mark != 0) {
      r.records.publish(mark);
      r.triangles.set(r.records[mark - 1].cut_triangles);
    }
    // The counts every publication; the histograms every eighth and at the task's end (a
    // cache line or two under the mutex instead of five).
    if (++t.publications % 8 == 0) {
      t.tally.add_to(r);
    } else {
      t.tally.add_counts_to(r);
    }
    r.batches.add(1);
    last_depth = t.pending.back().item.depth;
    // relaxed: statistics (see full_run::outstanding).
    r.remaining.set(static_cast<std::uint64_t>(
        std::max<std::int64_t>(1, run.outstanding.load(std::memory_order_relaxed))));
    report_progress(r, run.ranges, static_cast<std::uint64_t>(kept));
  }
  const auto published = static_cast<std::int64_t>(kept);
  // relaxed: statistics (see full_run::outstanding).
  run.outstanding.fetch_add(pushed - published, std::memory_order_relaxed);
  t.pending.clear();
  t.summaries.clear();
  t.groups.clear();
  if (stopped) return true;

  // Work to spare for an idle thread: the planes ahead of the front in full refinement (about
  // half the volume left), the older half of the stack (coarser diamonds) in a band.
  // relaxed: a hint (see full_run::active).
  if ((t.planes.size() >= 2 || t.stack.size() >= 2) &&
      run.active.load(std::memory_order_relaxed) < threads) {
    auto part = std::make_shared<full_task>();
    if (run.by_plane) {
      t.planes.give_upper_half(part->planes);
    } else {
      const auto half = static_cast<std::ptrdiff_t>(t.stack.size() / 2);
      part->stack.assign(t.stack.begin(), t.stack.begin() + half);
      t.stack.erase(t.stack.begin(), t.stack.begin() + half);
    }
    spawn_full_task(run, std::move(part));
  }
  return true;
}

std::int64_t engine_impl::count_full_task_children(full_task& t, std::size_t first_record) {
  full_run& run = *t.run;
  engine_root& r = *run.root;
  std::int64_t pushed = 0;
  const bool deadline = goal.what == refine_goal::kind::deadline;
  for (std::size_t j = 0; j < t.pending.size(); ++j) {
    if (deadline && j % 8 == 0 && stopping()) {
      const std::lock_guard lock(publish_mutex);
      for (std::size_t k = j; k < t.pending.size(); ++k) {
        r.uncounted.push_back(static_cast<std::uint32_t>(first_record + k));
      }
      break;
    }
    const pending_split& p = t.pending[j];
    const child_list& children = p.children;
    const int depth = p.item.depth + 1;
    for (int i = 0; i < children.count; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const ipoint& c = children.centre[ui];
      const std::uint64_t ci = hier.index(c);
      // acq_rel: the counts of a child's parents form one release sequence; the last one
      // acquires the others, each made after its parent's place in the log was reserved (under
      // publish_mutex above), so the child, computed and reserved after it, lies above all its
      // parents in the records, and the watermark moves over the log in order. Partner: this
      // same fetch_sub by the tasks of the child's other parents.
      const std::uint32_t before =
          std::atomic_ref<std::uint32_t>(r.word(c)).fetch_sub(1, std::memory_order_acq_rel);
      if (parents_counted(before - 1) != children.parents[ui]) continue;
      ++t.tally.visited;
      const std::optional<ready_item> child =
          ready_child(r, c, children.scale, depth, ci, run.ranges,
                      owns_piece(t.groups.data() + p.first, p.count, p.item.index, p.scale, ci));
      if (!child) {
        ++t.tally.culled;
      } else if (const std::uint64_t rank = run.banded ? r.queue.rank(child->error) : run.floor;
                 rank < run.floor) {
        t.hold_below(run.hold_base, rank, *child);  // a later band's, or below the target
      } else if (run.by_plane) {
        t.planes.push(ci);  // by grid plane
        ++pushed;
      } else {
        t.stack.push_back(*child);
        ++pushed;
      }
    }
  }
  return pushed;
}

void engine_impl::spawn_full_task(full_run& run, std::shared_ptr<full_task> part) {
  part->run = &run;
  run.active.fetch_add(1, std::memory_order_relaxed);  // relaxed: a hint (see full_run)
  // oneTBB calls the body as const: the task's state is held by pointer, not copied.
  run.group->run([this, part = std::move(part)] { run_full_task(*part); });
}

}  // namespace progiso::detail
