// A root: one isovalue's progressive surface. Its root surface (published before any pass over
// the volume), the seeding of its root diamonds, the queue re-keyed once the range data exists,
// and its per-vertex arrays, recycled from one root to the next.

#include "engine_impl.hpp"

#include <cstring>

#include <progiso/core/refine/detail/readiness.hpp>

namespace progiso::detail {

engine_root* engine_impl::make_base_root(double w, std::uint64_t gen) {
  vertex_state none{detail::vertex_pages<std::uint32_t>(),
                    zeroed_array<engine_record*>(append_log<engine_record>::max_chunks), 0};
  auto* r = make_managed<engine_root>(domain, *this, w, gen, std::move(none));
  r->seeded = true;
  // Its first chunk of records, allocated now (set_base() only writes record 0 into it).
  r->records.push_back({no_owner, nullptr, 0, 0, 0});
  return r;
}

void engine_impl::set_base(engine_root& r, std::int32_t stride, triangle_mesh&& mesh) {
  r.base_stride = stride;  // its serial comes with its publication (replace_root())
  r.base = std::move(mesh);
  const std::uint64_t n = r.base.triangles.size();
  r.cut_triangles = n;
  r.records.at_unpublished(0).cut_triangles = n;
  r.records.publish();
  r.triangles.set(n);
  r.record_triangles.set(n);
  // The finest cut leaves nothing to split; a coarser one leaves its frontier (not listed).
  r.remaining.set(stride == 1 ? 0 : 1);
  r.published_at = clock::now();
}

engine_root* engine_impl::make_root(double w, std::uint64_t gen, bool published) {
  auto* r = make_managed<engine_root>(domain, *this, w, gen, take_vertex_state());
  if (published) name_published(*r);
  std::vector<owned_triangle> tris;
  for (std::uint64_t q = 0; q < hier.root_count(); ++q) {
    const std::optional<ipoint> centre = compute_root(hier, vol, w, q, tris);
    if (centre) r->root_centres.push_back(*centre);
  }
  r->cut_triangles = tris.size();
  r->records.push_back(
      {no_owner, nullptr, static_cast<std::uint32_t>(tris.size()), 0, tris.size()});
  r->root_triangles = std::move(tris);
  r->records.publish();
  r->triangles.set(r->cut_triangles);
  r->record_triangles.set(r->cut_triangles);
  // Not known before the seeding: every root may still split.
  r->remaining.set(r->root_centres.size());
  r->published_at = clock::now();
  return r;
}

void engine_impl::seed_roots(engine_root& r) {
  if (r.seeded) return;
  r.seeded = true;
  std::uint64_t culled = 0;
  const range_data* rd = built_ranges();
  mark_if_keys_are_bounds(r, rd);
  for (const ipoint& c : r.root_centres) {
    if (!queue_if_straddles(r, c, hier.scale_of(c), hier.depth_of(c), hier.index(c), rd)) {
      ++culled;
    }
  }
  r.visited.add(r.root_centres.size());
  r.culled.add(culled);
}

std::optional<ready_item> engine_impl::ready_child(const engine_root& r, const ipoint& c,
                                                   std::int32_t h, int depth, std::uint64_t index,
                                                   const range_data* rd, bool owns_surface) const {
  if (rd == nullptr) {
    if (ranges_for_empty().empty(c, h)) return std::nullopt;
    return ready_item{placeholder_key(depth), depth, index};
  }
  // An error target in any order asks only whether an error exceeds it (error_bound()).
  const detail::readiness ready =
      ready_rule(*rd, c, h, owns_surface, errors_needed(), r.isovalue, r.threshold, error_bound());
  if (!ready.keep) return std::nullopt;
  if (!errors_needed()) return ready_item{placeholder_key(depth), depth, index};
  if (goal.focus) {
    return ready_item{ready.error * focus_weight(*goal.focus, c, h, hierarchy::type_of(c, h)),
                      depth, index};
  }
  return ready_item{ready.error, depth, index};
}

bool engine_impl::queue_if_straddles(engine_root& r, const ipoint& c, std::int32_t h, int depth,
                                     std::uint64_t index, const range_data* rd) {
  const std::optional<ready_item> item = ready_child(r, c, h, depth, index, rd, false);
  if (!item) return false;
  r.queue.push(*item);
  if (rd == nullptr || !errors_needed()) r.placeholder_keys = true;
  return true;
}

void engine_impl::count_children_on_one_thread(engine_root& r, const ipoint& centre,
                                               std::int32_t scale, int depth,
                                               const packed_group* groups, std::size_t count,
                                               const range_data* rd, split_tally& tally) const {
  count_children(r, hier.children_of(centre, scale, hierarchy::type_of(centre, scale)),
                 hier.index(centre), scale, depth, groups, count, rd, tally, queue_sink(r, rd));
}

void engine_impl::queue_deadline_leftovers(engine_root& r) {
  if (!r.uncounted.empty()) {
    const range_data* rd = built_ranges();
    split_tally tally;
    for (const std::uint32_t i : r.uncounted) {
      const engine_record& rec = r.records[i];
      const ipoint c = hier.point(rec.diamond);
      count_children_on_one_thread(r, c, hier.scale_of(c), hier.depth_of(c), rec.groups, rec.count,
                                   rd, tally);
    }
    if (!errors_needed() && !r.queue.empty()) r.placeholder_keys = true;  // queued by placeholder
    r.uncounted.clear();
    tally.add_to(r);
  }
  for (const std::vector<ready_item>& part : r.leftover) {
    for (const ready_item& it : part) r.queue.push(it);
  }
  r.leftover.clear();
  r.leftover_items = 0;
}

void engine_impl::requeue_by_ranges(engine_root& r) {
  queue_deadline_leftovers(r);
  const range_data* rd = built_ranges();
  PROGISO_ASSERT(rd != nullptr);
  const std::optional<refine_focus> focus = errors_needed() ? goal.focus : std::nullopt;
  const bool refocus = r.keyed_focus != focus;
  r.keyed_focus = focus;
  if (!r.placeholder_keys && !(r.bound_keys && rd->errors_exact()) && !refocus) return;
  std::vector<ready_item> items;
  items.reserve(r.queue.size());
  while (!r.queue.empty()) {
    items.push_back(r.queue.top());
    r.queue.pop();
  }
  std::uint64_t culled = 0;
  const bool all = (r.bound_keys && rd->errors_exact()) || refocus;
  r.bound_keys = false;
  r.placeholder_keys = false;  // set again by what is queued by placeholder below (full refinement)
  mark_if_keys_are_bounds(r, rd);
  for (const ready_item& it : items) {
    if (!all && it.error < placeholder_key(60)) {  // already by its range
      r.queue.push(it);
      continue;
    }
    const ipoint c = hier.point(it.index);
    if (!queue_if_straddles(r, c, hier.scale_of(c), it.depth, it.index, rd)) ++culled;
  }
  r.culled.add(culled);
}

vertex_state engine_impl::take_vertex_state() {
  {
    const std::lock_guard lock(reclaim_mutex);
    if (spare) {
      vertex_state s = std::move(*spare);
      spare.reset();
      if (!spare_fresh) recycled_roots.add(1);
      return s;
    }
  }
  return fresh_vertex_state();
}

vertex_state engine_impl::fresh_vertex_state() const {
  return {detail::vertex_pages<std::uint32_t>(hier),
          zeroed_array<engine_record*>(append_log<engine_record>::max_chunks), hier.vertex_count()};
}

bool engine_impl::hand_over(engine_root* r) noexcept {
  const std::lock_guard lock(reclaim_mutex);
  if (reclaim_quit || reclaim_queue.size() >= 2) return false;
  try {
    if (!reclaimer.joinable()) {
      reclaim_queue.reserve(2);
      reclaimer = std::thread([this] { reclaim_loop(); });
    }
  } catch (...) {
    return false;  // no thread or no memory: the caller destroys the root
  }
  reclaim_queue.push_back(r);  // within the reserved capacity
  reclaim_wake.notify_one();
  return true;
}

void engine_impl::reclaim_loop() noexcept {
  for (;;) {
    engine_root* r = nullptr;
    bool need_fresh = false;
    {
      std::unique_lock lock(reclaim_mutex);
      reclaim_wake.wait(lock, [this] { return reclaim_quit || !reclaim_queue.empty(); });
      if (reclaim_queue.empty()) return;  // quit, and nothing left
      r = reclaim_queue.front();
      reclaim_queue.erase(reclaim_queue.begin());
      need_fresh = !spare;
    }
    // First a fresh set for the next root, if there is none (mapped here, where waiting for the
    // address space's lock delays no caller; nothing is touched, so it costs no memory yet):
    // clearing the old root's arrays takes a while, and the next isovalue change may come
    // sooner.
    if (need_fresh) {
      try {
        vertex_state f = fresh_vertex_state();
        const std::lock_guard lock(reclaim_mutex);
        if (!spare) {
          spare = std::move(f);
          spare_fresh = true;
        }
      } catch (...) {
        // No memory: the next root maps its own.
      }
    }
    reclaim(*r, true);
  }
}

void engine_impl::stop_reclaimer() noexcept {
  {
    const std::lock_guard lock(reclaim_mutex);
    reclaim_quit = true;
  }
  reclaim_wake.notify_one();
  if (reclaimer.joinable()) reclaimer.join();
}

void engine_impl::reclaim(engine_root& r, bool keep) noexcept {
  PROGISO_ASSERT(r.magic == root_alive);
  keep = keep && r.base_stride == 0;  // a uniform cut's root has no per-vertex words
  if (keep) {
    const std::lock_guard lock(reclaim_mutex);
    keep = !spare || spare_fresh;  // one spare set at most, a cleared one rather than a fresh one
  }
  if (keep) {
    // Every brick freed: the next root's words follow its own surface.
    r.record_of.clear();
  }
  if (r.base_stride > 0 && recycle && !opt.poison_retired) {
    // The mesh's storage kept for a later cut (take_mesh_storage()): the larger of it and the
    // spare; the smaller one is freed after the lock.
    triangle_mesh smaller;
    {
      const std::lock_guard lock(reclaim_mutex);
      if (r.base.triangles.capacity() > spare_mesh.triangles.capacity()) {
        std::swap(r.base, spare_mesh);
      }
      smaller = std::move(r.base);
    }
  }
  if (opt.poison_retired) {
    r.groups.overwrite(poison_byte);
    poison_vector(r.root_triangles);
    poison_log(r.records);
    r.isovalue = std::nan("");
  }
  if (keep) {
    std::optional<vertex_state> replaced;  // unmapped after the lock is released
    vertex_state s{std::move(r.record_of), r.records.release_directory(), hier.vertex_count()};
    const std::lock_guard lock(reclaim_mutex);
    if (!spare || spare_fresh) {
      replaced = std::move(spare);
      spare = std::move(s);
      spare_fresh = false;
    }
  }
  // relaxed: a statistic; the control thread's fetch_add is the other writer.
  retired_bytes.fetch_sub(r.retired_bytes, std::memory_order_relaxed);
  r.magic = root_dead;
  if (opt.on_reclaim && r.serial != 0) opt.on_reclaim(r.generation);  // published roots only
  delete &r;
}

triangle_mesh engine_impl::take_mesh_storage(std::uint64_t vertices, std::uint64_t triangles) {
  const std::lock_guard lock(reclaim_mutex);
  const std::size_t v = spare_mesh.vertices.capacity();
  const std::size_t t = spare_mesh.triangles.capacity();
  if (v < vertices || t < triangles || 4 * triangles < t) return {};
  return std::exchange(spare_mesh, triangle_mesh{});
}

void engine_impl::destroy_root(void* p) noexcept {
  auto* r = static_cast<engine_root*>(p);
  engine_impl& impl = *r->impl;
  if (impl.recycle && impl.hand_over(r)) return;
  impl.reclaim(*r, false);
}

}  // namespace progiso::detail
