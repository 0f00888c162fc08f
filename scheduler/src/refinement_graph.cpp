// The refinement graph (refinement_schedule::flow_graph, runs by priority on more than one
// thread): compute tasks make split records in parallel; the serial commit node publishes them,
// makes children ready and keeps the window of tasks in flight full. run_graph() also picks the
// one-thread loop and the tasks (full_refinement.cpp) for the other runs.

#include "engine_impl.hpp"

namespace progiso::detail {

// The engine. Nothing here touches the arena: oneTBB's first use in a process (its scheduler,
// allocator library and worker threads) costs more than the root surface, so it
// waits for the first run, after the first surface (see make_graph()).
engine_impl::engine_impl(std::shared_ptr<const volume> owned, const volume& v, engine_options o)
    : run_control("engine"),
      owned_volume(std::move(owned)),
      vol(v),
      opt(std::move(o)),
      hier(v.dims()),
      threads(effective_threads(opt.threads)),
      domain(opt.reclamation),
      control_participant(domain),
      readers(domain),
      arena(static_cast<int>(threads)) {}

// The graph: compute (any number in parallel) feeding commit (serial), made in the arena (a
// graph runs its tasks in the arena it was made in) by the first run that uses it.
void engine_impl::make_graph() {
  if (graph) return;
  arena.execute([this] {
    graph = std::make_unique<tbb::flow::graph>();
    compute = std::make_unique<tbb::flow::function_node<batch*, batch*>>(
        *graph, tbb::flow::unlimited, [this](batch* b) { return compute_batch(b); });
    commit = std::make_unique<tbb::flow::function_node<batch*>>(
        *graph, tbb::flow::serial, [this](batch* b) { commit_batch(b); });
    tbb::flow::make_edge(*compute, *commit);
  });
}

void engine_impl::dispatch(engine_root& r) {
  const std::size_t window = std::max<std::size_t>(1, opt.tasks_per_thread * threads);
  const std::size_t max_batch = std::max<std::size_t>(1, opt.batch);
  while (inflight < window && !stopping() && eligible(r) && !past_deadline()) {
    const std::size_t n = std::clamp<std::size_t>(r.queue.size() / (2 * threads), 1, max_batch);
    batch* b = nullptr;
    if (spare_batches.empty()) {
      b = new batch;
    } else {
      b = spare_batches.back().release();
      spare_batches.pop_back();
    }
    b->root = &r;
    b->items.reserve(n);
    while (b->items.size() < n && eligible(r)) {
      b->items.emplace_back(r.queue.top());
      r.queue.pop();
    }
    inflight_items += b->items.size();
    ++inflight;
    compute->try_put(b);
  }
}

batch* engine_impl::compute_batch(batch* b) {
  const double w = b->root->isovalue;
  const range_data* rd = built_ranges();
  for (std::size_t j = 0; j < b->items.size(); ++j) {
    // The clock every fourth split: a clock read costs a noticeable part of a split.
    if (stopping() || (j % 4 == 0 && past_deadline())) break;
    batch_item& it = b->items[j];
    const ipoint centre = hier.point(it.item.index);
    const std::int32_t scale = hier.scale_of(centre);
    it.word = &b->root->word(centre);
    const std::size_t first = b->groups.size();
    const split_summary s = compute_split(hier, vol, w, centre, scale, b->groups);
    it.first = static_cast<std::uint32_t>(first);
    it.count = static_cast<std::uint32_t>(b->groups.size() - first);
    it.scale = scale;
    it.crossed = s.crossed;
    it.added = s.added_triangles;
    it.removed = s.removed_triangles;
    it.configuration = s.configuration;
    it.cases = s.cases;
    it.primitives = s.primitives;
    const child_list children = hier.children_of(centre, scale, hierarchy::type_of(centre, scale));
    it.children = static_cast<std::uint8_t>(children.count);
    for (int i = 0; i < children.count; ++i) {
      const ipoint& c = children.centre[static_cast<std::size_t>(i)];
      child_info& ci = it.child[static_cast<std::size_t>(i)];
      ci.index = hier.index(c);
      ci.word = &b->root->word(c);
      ci.parents_needed = children.parents[static_cast<std::size_t>(i)];
      // The child's range is needed once, when its last parent commits. The parent that
      // finds all the others already committed looks it up here, in parallel; for the other
      // parents it would be wasted work (a child has up to four). When two last parents are
      // in flight together, neither may look: the commit step then does.
      const std::uint32_t split_parents = parents_counted(
          std::atomic_ref<std::uint32_t>(*ci.word)
              // relaxed: a hint only; the commit step, the sole writer, decides readiness,
              // and a stale count just moves the lookup to the commit step or repeats it.
              .load(std::memory_order_relaxed));
      ci.known = rd != nullptr && split_parents + 1 >= ci.parents_needed;
      if (ci.known) {
        const std::optional<ready_item> child =
            ready_child(*b->root, c, children.scale, it.item.depth + 1, ci.index, rd,
                        owns_piece(b->groups.data() + first, b->groups.size() - first,
                                   it.item.index, scale, ci.index));
        ci.straddles = child.has_value();
        ci.error = child ? child->error : 0.0;
      }
    }
    ++b->computed;
  }
  return b;
}

void engine_impl::commit_batch(batch* b) {
  engine_root& r = *b->root;
  if (b->seed) {
    delete b;
    seed_roots(r);
    dispatch(r);
    r.remaining.set(r.queue.size() + inflight_items);
    return;
  }
  const range_data* rd = built_ranges();
  mark_if_keys_are_bounds(r, rd);
  --inflight;
  inflight_items -= b->items.size();
  std::size_t published = 0;
  split_tally tally;
  if (!stopping() && b->computed > 0) {
    // The per-vertex state the loop below writes, requested ahead: in priority order the
    // diamonds lie all over the grid, and these lines are the serial step's cache misses.
    for (std::size_t i = 0; i < b->computed; ++i) {
      const batch_item& it = b->items[i];
      __builtin_prefetch(it.word, 1);
      for (std::size_t c = 0; c < it.children; ++c) __builtin_prefetch(it.child[c].word, 1);
    }
    for (std::size_t i = 0; i < b->computed; ++i) {
      const batch_item& it = b->items[i];
      if (i % 8 == 0 && past_deadline()) {  // every eighth record, as in compute
        request_stop();
        break;
      }
      const std::uint64_t after =
          r.cut_triangles + static_cast<unsigned>(it.added) - static_cast<unsigned>(it.removed);
      if (!goal_admits(after)) {
        budget_hit = true;
        request_stop();
        break;
      }
      const std::size_t index = r.records.size();
      PROGISO_ASSERT(index < max_records);
      r.cut_triangles = after;
      r.records.push_back({it.item.index,
                           r.groups.append_contiguous(b->groups.data() + it.first, it.count),
                           it.count, it.crossed, after});
      std::atomic_ref<std::uint32_t>(*it.word).store(
          static_cast<std::uint32_t>(index),
          // relaxed: published by the release in records.publish() below.
          std::memory_order_relaxed);
      ++tally.splits;
      tally.added += static_cast<unsigned>(it.added);
      for (std::size_t k = 0; k < tet_case_count; ++k) tally.cases[k] += it.cases[k];
      for (std::size_t k = 0; k < primitive_count; ++k) tally.primitives[k] += it.primitives[k];
      ++tally.configurations[static_cast<std::size_t>(it.configuration)];
      for (std::size_t c = 0; c < it.children; ++c) {
        const child_info& ci = it.child[c];
        // The commit step is the only writer; compute tasks read a hint (relaxed atomic loads).
        const std::uint32_t word = add_in_place(*ci.word, ~std::uint32_t{0});
        if (parents_counted(word) != ci.parents_needed) continue;
        ++tally.visited;
        if (ci.known) {
          if (ci.straddles) {
            r.queue.push({ci.error, it.item.depth + 1, ci.index});
          } else {
            ++tally.culled;
          }
        } else {
          const ipoint centre = hier.point(ci.index);
          if (!queue_if_straddles(r, centre, hier.scale_of(centre), it.item.depth + 1, ci.index,
                                  rd)) {
            ++tally.culled;
          }
        }
      }
      last_depth = it.item.depth;
      ++published;
    }
    r.records.publish();
    if (!errors_needed()) r.placeholder_keys = true;  // children queued by placeholder
    r.triangles.set(r.cut_triangles);
  }
  // What was not published goes back to the queue: still ready, never lost.
  for (std::size_t i = published; i < b->items.size(); ++i) r.queue.push(b->items[i].item);
  tally.discarded = b->computed - std::min(b->computed, published);
  tally.add_to(r);
  r.batches.add(1);
  b->items.clear();
  b->groups.clear();
  b->computed = 0;
  spare_batches.emplace_back(b);
  dispatch(r);
  r.remaining.set(r.queue.size() + inflight_items);
  report_progress(r, rd, published);
}

void engine_impl::report_progress(engine_root& r, const range_data* rd, std::uint64_t published) {
  if (!opt.progress || callback_error) return;
  since_progress += published;
  if (since_progress < opt.progress_interval) return;
  since_progress = 0;
  call_progress([&] {
    opt.progress({r.splits.get(), r.cut_triangles, next_error(r, rd), last_depth});
  });
}

void engine_impl::run_graph(engine_root* r) {
  queue_deadline_leftovers(*r);
  if (threads == 1) {
    refine_serially(*r);
    return;
  }
  if (goal.what == refine_goal::kind::full || opt.schedule == refinement_schedule::tasks) {
    refine_in_tasks(*r);
    return;
  }
  make_graph();
  arena.execute([&] {
    auto* seed = new batch;
    seed->root = r;
    seed->seed = true;
    commit->try_put(seed);
    graph->wait_for_all();
  });
}

double engine_impl::next_error(const engine_root& r, const range_data* rd) const {
  if (r.queue.empty()) return 0.0;
  const ready_item& top = r.queue.top();
  if (top.error < placeholder_key(60) || rd == nullptr) return top.error;
  const ipoint c = hier.point(top.index);
  return rd->get(c, hier.scale_of(c)).error;
}

}  // namespace progiso::detail
