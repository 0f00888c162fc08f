// Refinement on one thread: the engine's records, publication rule, queue, goals and statistics,
// without the flow graph. With one thread the graph has nothing to run in parallel, and its round
// trip (a compute task writes each diamond's split and children into its batch, the commit step
// reads them back) cost as much as the splits themselves (Marschner–Lobb 257³, full refinement:
// 515 ms on the graph against the sequential refiner's 287 ms).

#include "engine_impl.hpp"

#include <progiso/core/refine/detail/prefetch.hpp>

namespace progiso::detail {

namespace {

// Records published at a time: a reader's snapshot lags the run by at most this many splits
// (about 15 µs), and the watermark's release store and the counters are paid once per step.
constexpr std::size_t serial_publish_step = 64;
// A deadline is checked every this many splits (a clock read costs ~4% of a split), as the
// commit step does.
constexpr std::size_t serial_clock_step = 8;
// Samples of the diamond this many places ahead in the queue are asked for (volumes larger than
// the cache only), as the sequential refiner does.
constexpr std::size_t serial_prefetch_distance = 8;

}  // namespace

void engine_impl::refine_serially(engine_root& r) {
  seed_roots(r);  // a no-op once seeded
  const range_data* rd = built_ranges();
  note_keys(r, rd);
  const double w = r.isovalue;
  const bool prefetch = vol.byte_size() > prefetch_min_bytes;
  std::vector<packed_group>& groups = serial_groups;
  split_tally tally;

  const auto publish = [&] {
    r.records.publish();
    if (!errors_needed()) r.unranged = true;  // children queued by placeholder
    r.triangles.set(r.cut_triangles);
    const std::uint64_t published = tally.splits;
    tally.add_to(r);
    r.batches.add(1);
    r.remaining.set(r.queue.size());
    report_progress(r, rd, published);
  };

  for (std::size_t n = 0; !stopping() && eligible(r); ++n) {
    if (n % serial_clock_step == 0 && past_deadline()) {
      request_stop();
      break;
    }
    const ready_item item = r.queue.top();
    if (prefetch) {
      if (const ready_item* ahead = r.queue.peek(serial_prefetch_distance)) {
        const ipoint a = hier.point(ahead->index);
        prefetch_diamond_samples(vol, a, hier.scale_of(a));
      }
    }
    const ipoint centre = hier.point(item.index);
    const std::int32_t scale = hier.scale_of(centre);
    // The children's words are counted after the split: asked for now, their cache misses
    // overlap the split's work.
    const child_list children = children_requested(r, centre, scale);
    groups.clear();
    const split_summary s = compute_split(hier, vol, w, centre, scale, groups);
    const std::uint64_t after = r.cut_triangles + static_cast<unsigned>(s.added_triangles) -
                                static_cast<unsigned>(s.removed_triangles);
    if (goal.what == refine_goal::kind::triangles && after > goal.max_triangles) {
      budget_hit = true;
      ++tally.discarded;  // computed, not published; it stays queued
      request_stop();
      break;
    }
    r.queue.pop();
    const std::size_t index = r.records.size();
    PROGISO_ASSERT(index < max_records);
    r.cut_triangles = after;
    r.records.push_back({item.index, r.groups.append_contiguous(groups.data(), groups.size()),
                         static_cast<std::uint32_t>(groups.size()), item.depth, scale, s.crossed,
                         after});
    std::atomic_ref<std::uint32_t>(r.record_of[item.index])
        .store(static_cast<std::uint32_t>(index),
               // relaxed: published by the release in records.publish() (publish above).
               std::memory_order_relaxed);
    tally.count(s);

    count_children_alone(r, children, item.depth, groups.data(), groups.size(), rd, tally);
    last_depth = item.depth;
    if (tally.splits == serial_publish_step) publish();
  }
  publish();
}

}  // namespace progiso::detail
