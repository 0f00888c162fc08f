// Refinement on one thread: the engine's records, publication rule, queue, goals and statistics,
// without the flow graph. With one thread the graph has nothing to run in parallel, and its round
// trip (a compute task writes each diamond's split and children into its batch, the commit step
// reads them back) cost about as much as the splits themselves, so a full refinement on the graph
// is much slower than the sequential refiner (bench/README.md).
//
// A full goal, which splits every straddling diamond in any order, and an error target taken
// in any order take the ready diamonds by grid plane instead of from the queue
// (sweep_on_one_thread): see there.

#include "engine_impl.hpp"

#include <algorithm>

#include <progiso/core/refine/detail/prefetch.hpp>

namespace progiso::detail {

namespace {

// Records published at a time: a reader's snapshot lags the run by at most this many splits
// (a lag too short for a viewer to notice), and the watermark's release store and the counters
// are paid once per step.
constexpr std::size_t serial_publish_step = 64;
// A deadline is checked every this many splits (a clock read costs a noticeable part of a
// split), as the commit step does; a sweep checks for a stop request as often.
constexpr std::size_t serial_clock_step = 8;
// Volumes larger than the cache only: when the loop takes a cold item of the queue (one that
// was in its bucket when the bucket became the top, ready_queue::top_is_cold), the data of the
// cold item this many cold items later is asked for (request_diamond). The items pushed since,
// the last splits' children, are taken first and are near data already in the cache; the cold
// ones lie anywhere in the grid, and their order is known however many are pushed meanwhile.
// (The sequential refiner's request of the item eight places ahead mostly named an item that
// the depth-first order takes much later.) Asking this way raises the splits a second of an
// error target on one thread (bench/README.md).
constexpr std::size_t serial_cold_prefetch_distance = 2;

}  // namespace

template <class Take, class Sink>
bool engine_impl::split_on_one_thread(engine_root& r, const ready_item& item, const ipoint& centre,
                                      const range_data* rd, split_tally& tally, Take&& take,
                                      Sink&& ready) {
  const std::int32_t scale = hier.scale_of(centre);
  // The children's words are counted after the split: asked for now, their cache misses
  // overlap the split's work.
  const child_list children = children_requested(r, centre, scale);
  std::vector<packed_group>& groups = serial_groups;
  groups.clear();
  const split_summary s = compute_split(hier, vol, r.isovalue, centre, scale, groups);
  const std::uint64_t after = r.cut_triangles + static_cast<unsigned>(s.added_triangles) -
                              static_cast<unsigned>(s.removed_triangles);
  if (!goal_admits(after)) {
    budget_hit = true;
    ++tally.discarded;  // computed, not published; it stays queued
    return false;
  }
  take();
  const std::size_t index = r.records.size();
  PROGISO_ASSERT(index < max_records);
  r.cut_triangles = after;
  r.records.push_back({item.index, r.groups.append_contiguous(groups.data(), groups.size()),
                       static_cast<std::uint32_t>(groups.size()), s.crossed, after});
  std::atomic_ref<std::uint32_t>(r.word(item.index))
      .store(static_cast<std::uint32_t>(index),
             // relaxed: published by the release in records.publish() (the caller's publish).
             std::memory_order_relaxed);
  tally.count(s);
  count_children(r, children, item.index, scale, item.depth, groups.data(), groups.size(), rd,
                 tally, ready);
  last_depth = item.depth;
  return true;
}

void engine_impl::refine_serially(engine_root& r) {
  seed_roots(r);  // a no-op once seeded
  const range_data* rd = built_ranges();
  mark_if_keys_are_bounds(r, rd);
  const bool prefetch = vol.byte_size() > prefetch_min_bytes;
  split_tally tally;

  const auto publish = [&] {
    r.records.publish();
    if (!errors_needed()) r.placeholder_keys = true;  // children queued by placeholder
    r.triangles.set(r.cut_triangles);
    const std::uint64_t published = tally.splits;
    tally.add_to(r);
    r.batches.add(1);
    r.remaining.set(r.queue.size() + sweep_planes.size());  // sweep_on_one_thread's ready diamonds
    report_progress(r, rd, published);
  };

  if (goal_runs_by_plane() && rd != nullptr) {
    sweep_on_one_thread(r, rd, tally, publish);
    publish();
    return;
  }

  const auto push = queue_sink(r, rd);
  for (std::size_t n = 0; !stopping() && eligible(r); ++n) {
    if (n % serial_clock_step == 0 && past_deadline()) {
      request_stop();
      break;
    }
    const ready_item item = r.queue.top();
    if (prefetch && r.queue.top_is_cold()) {
      if (const ready_item* ahead = r.queue.cold_ahead(serial_cold_prefetch_distance)) {
        request_diamond(r, ahead->index);
      }
    }
    if (!split_on_one_thread(
            r, item, hier.point(item.index), rd, tally, [&r] { r.queue.pop(); }, push)) {
      request_stop();
      break;
    }
    if (tally.splits == serial_publish_step) publish();
  }
  publish();
}

// Full refinement splits every straddling diamond, in any order that splits parents first, so
// the one-thread loop need not follow the queue: it takes the ready diamonds by grid plane
// (plane_lists.hpp: the lowest plane first, last in first out within a plane), so that the fine
// levels advance as one front and what they touch stays in the cache. The records come out in
// that order too, and so do the later passes over them (extraction). Readiness, culling and the
// statistics are the queue loop's (count_children); only the order differs.
//
// An error target fixes its split set the same way: every straddling diamond of error > ε whose
// parents are split (a child's nested error is at most its parent's, so the set is closed under
// parents), whatever the order. Taken in any order (refine_goal::any_order), the diamonds of
// error > ε go to the planes and the others to the queue, keyed by their errors as the queue
// loop keys them, for a later goal. Only the order differs from the queue loop's: the errors
// are computed all the same, but in plane order their samples are near the last splits' in the
// cache, so a target taken by plane splits markedly faster than one taken by priority
// (bench/README.md).
//
// A stopped sweep hands what is left back to the queue, keyed by placeholder as a full run keys
// it (`placeholder_keys`: the next run keys them again by their ranges, requeue_by_ranges()).
template <class Publish>
void engine_impl::sweep_on_one_thread(engine_root& r, const range_data* rd, split_tally& tally,
                                      Publish&& publish) {
  plane_lists& planes = sweep_planes;
  reset_planes(planes);
  const bool full = goal.what == refine_goal::kind::full;
  const auto mark = [&](const ready_item& child) {
    // Queued children of an error target are in the queue's bands below it (launch() aimed the
    // queue at it: an error > ε ranks above, NaN too).
    if (full || r.queue.rank(child.error) >= r.queue.above_target_rank()) {
      planes.push(child.index);
    } else {
      r.queue.push(child);
    }
  };
  while (eligible(r)) {
    planes.push(r.queue.top().index);
    r.queue.pop();
  }
  for (std::size_t n = 0; !planes.empty(); ++n) {
    if (n % serial_clock_step == 0 && stopping()) break;
    const std::uint64_t index = planes.pop();
    const ipoint centre = hier.point(index);
    (void)split_on_one_thread(
        r, full_item(index, centre), centre, rd, tally, [] {}, mark);
    if (tally.splits == serial_publish_step) publish();
  }
  // Stopped: what is ready goes back to the queue, keyed by placeholder as a full run queues.
  if (!planes.empty() && !full) r.placeholder_keys = true;
  planes.drain([&](std::uint64_t index) { r.queue.push(full_item(index)); });
}

}  // namespace progiso::detail
