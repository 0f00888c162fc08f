// The contour engine (contour_engine.hpp): roots, the driver's split loop, publication,
// snapshots and the public calls. Run control, counters and the readers' participants are the
// 3D engine's (run_control.hpp); the split records and the readiness rule are contour_refiner's
// (contour/detail/contour_frontier.hpp).

#include <progiso/scheduler/contour_engine.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <progiso/concurrent/append_log.hpp>
#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/detail/chunked_store.hpp>
#include <progiso/core/base/detail/cut_index.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_split.hpp>
#include <progiso/core/contour/detail/contour_frontier.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>

#include "run_control.hpp"

namespace progiso::detail {

namespace {

constexpr std::uint64_t contour_root_alive = 0x70726f67636f6e31;  // "progcon1"
// Splits between publications: readers see progress at least this often (a 2D split is cheap,
// so this many is still a short lag), and the release store and counter updates stay off the
// per-split path.
constexpr std::uint64_t publish_every = 64;
// The most segments one split's record holds: two triangles become four, one segment each.
constexpr std::uint32_t max_record_segments = 8;

}  // namespace

// One published split: its new segments (placed, in the root's store; a record's segments are
// one piece), its nested error (for cuts by error) and the cut's segment count once it is
// published. Record 0 is the root contour (its segments are contour_root::root_segments).
struct contour_record {
  std::uint64_t diamond;  // grid index; no_owner2 for the root record
  const placed_segment* segments;
  std::uint32_t count;
  double error;
  std::uint64_t cut_segments;
};

// One isovalue's progressive contour. Readers reach it through contour_engine_impl::root (under
// an epoch guard) and read the published prefix of `records`; the rest belongs to the run's
// driver (or the control thread while no run is active). No per-vertex array serves readers: a
// snapshot marks its cut's splits when it needs them (contour_snapshot::build, split_bits).
struct contour_root : epoch_object {
  contour_root(contour_engine_impl& owner, double w, std::uint64_t gen, const hierarchy2d& hier)
      : impl(&owner),
        isovalue(w),
        generation(gen),
        frontier(hier),
        segments(chunked_store<placed_segment>::bits_for(hier.vertex_count())) {}

  std::uint64_t magic = contour_root_alive;
  contour_engine_impl* impl;
  double isovalue;
  std::uint64_t generation;
  // A run on this root threw (drive()): it refines no further. Written by the driver, read by the
  // control thread after joining it.
  bool failed = false;
  // When the root surface was published (make_root(), just before the store that publishes it).
  clock::time_point published_at{};
  append_log<contour_record> records;
  // Set before the root is published, immutable afterwards.
  std::vector<placed_segment> root_segments;
  std::vector<ipoint2> root_centres;

  // Driver only.
  bool seeded = false;
  contour_frontier frontier;
  chunked_store<placed_segment> segments;
  ready_queue<contour_ready> queue{queue_discipline::largest_error};
  std::uint64_t cut_segments = 0;

  // Statistics (the driver writes, anyone reads).
  counter splits, visited, culled, segment_count, record_segments, remaining;
  std::array<counter, contour_case_count> cases;
  std::array<counter, contour_primitive_count> primitives;
};

// What the driver's splits add to the root's counters, added at each publication.
struct contour_tally {
  std::array<std::uint64_t, contour_case_count> cases{};
  std::array<std::uint64_t, contour_primitive_count> primitives{};
  std::uint64_t splits = 0, visited = 0, culled = 0, added = 0;

  void add_to(contour_root& r) noexcept {
    r.splits.add(splits);
    r.visited.add(visited);
    r.culled.add(culled);
    r.record_segments.add(added);
    for (std::size_t k = 0; k < contour_case_count; ++k) r.cases[k].add(cases[k]);
    for (std::size_t k = 0; k < contour_primitive_count; ++k) r.primitives[k].add(primitives[k]);
    *this = contour_tally{};
  }
};

struct contour_engine_impl : run_control {
  contour_engine_impl(std::shared_ptr<const volume> owned, const volume& img,
                      contour_engine_options o)
      : run_control("contour engine"),
        owned_image(std::move(owned)),
        image(img),
        opt(std::move(o)),
        hier(img.dims()[0], img.dims()[1]),
        origin{img.origin()[0], img.origin()[1]},
        spacing{img.spacing()[0], img.spacing()[1]},
        domain(opt.reclamation),
        control_participant(domain),
        readers(domain) {}

  // The range data, built whole by the first caller (the first run's driver, or ranges()).
  const range_data2d& ranges() const {
    // acquire: pairs with the release below (the data is then complete and never replaced).
    if (ranges_ready.load(std::memory_order_acquire)) return *ranges_;
    const std::lock_guard lock(build_mutex);
    if (!ranges_) {
      const auto t0 = clock::now();
      ranges_.emplace(image, hier);
      // relaxed: a statistic.
      range_seconds.store(std::chrono::duration<double>(clock::now() - t0).count(),
                          std::memory_order_relaxed);
      // release: pairs with the acquire above.
      ranges_ready.store(true, std::memory_order_release);
    }
    return *ranges_;
  }

  contour_root* make_root(double w, std::uint64_t gen) {
    auto* r = make_managed<contour_root>(domain, *this, w, gen, hier);
    root_contour(hier, image, w, r->root_segments, r->root_centres);
    const std::uint64_t n = r->root_segments.size();
    r->records.push_back(
        {no_owner2, r->root_segments.data(), static_cast<std::uint32_t>(n), 0.0, n});
    r->records.publish();
    r->cut_segments = n;
    r->segment_count.set(n);
    r->record_segments.set(n);
    r->remaining.set(r->root_centres.size());  // every root may still split
    r->published_at = clock::now();
    return r;
  }

  // A contour root maps its records' chunk directory fresh, so set_isovalue() stops the run
  // before making it (swap_root). 2D roots are small and their runs short.
  [[nodiscard]] static bool can_publish_early() noexcept { return false; }

  static void destroy_root(void* p) noexcept {
    auto* r = static_cast<contour_root*>(p);
    PROGISO_ASSERT(r->magic == contour_root_alive);
    contour_engine_impl& impl = *r->impl;
    if (impl.opt.poison_retired) {
      r->segments.overwrite(poison_byte);
      poison_vector(r->root_segments);
      poison_log(r->records);
      r->isovalue = std::nan("");
    }
    r->magic = root_dead;
    if (impl.opt.on_reclaim) impl.opt.on_reclaim(r->generation);
    delete r;
  }

  [[nodiscard]] contour_root* current() const noexcept {
    // relaxed: the control thread is the only writer of `root`.
    return root.load(std::memory_order_relaxed);
  }

  // Driver: queues the root diamonds that straddle (once per root).
  void seed(contour_root& r, const range_data2d& rd, contour_tally& t) {
    if (r.seeded) return;
    r.seeded = true;
    for (const ipoint2& c : r.root_centres) {
      ++t.visited;
      if (const auto item = ready_contour_diamond(rd, r.isovalue, c, hier.scale_of(c))) {
        r.queue.push(*item);
      } else {
        ++t.culled;
      }
    }
  }

  // Driver: makes the records appended since the last publication visible, then their counts.
  void publish(contour_root& r, contour_tally& t, std::uint64_t published) {
    r.records.publish();
    t.add_to(r);
    r.segment_count.set(r.cut_segments);
    r.remaining.set(r.queue.size());
    if (!opt.progress) return;
    since_progress += published;
    if (since_progress < opt.progress_interval) return;
    since_progress = 0;
    call_progress([&] {
      opt.progress({r.splits.get(), r.cut_segments, r.queue.empty() ? 0.0 : r.queue.top().error,
                    last_depth});
    });
  }

  // The driver thread of one run. What the run throws (memory, beyond what the process may have)
  // ends it for wait() or refine() to rethrow, as in the 3D engine: the published cut stays
  // readable, and the root, perhaps mid-split, is marked failed (launch() refuses it).
  void drive(contour_root* r) {
    try {
      drive_splits(r);
    } catch (...) {
      // This thread is the run's only publisher, the one writer of callback_error.
      callback_error = std::current_exception();
      r->failed = true;
      end_run(false);
    }
  }

  // drive() without the failure handling: the split loop of contour_refiner::split_next(),
  // records published every publish_every splits and at the end.
  void drive_splits(contour_root* r) {
    const range_data2d& rd = ranges();
    contour_tally t;
    seed(*r, rd, t);
    std::uint64_t unpublished = 0;
    while (!stopping() && !r->queue.empty()) {
      const contour_ready next = r->queue.top();
      if (goal.what == refine_goal::kind::error && !(next.error > goal.max_error)) break;
      if (goal.what == refine_goal::kind::deadline && clock::now() >= goal.deadline) break;
      const diamond2 d = hier.make_diamond(next.centre);
      const std::uint64_t index = hier.index(next.centre);
      scratch.clear();
      const contour_split_summary s =
          compute_placed_contour_split(hier, image, r->isovalue, d, scratch);
      const std::uint64_t after = r->cut_segments + static_cast<std::uint64_t>(s.added_segments) -
                                  static_cast<std::uint64_t>(s.removed_segments);
      if (goal.what == refine_goal::kind::budget && after > goal.max_elements) {
        budget_hit = true;
        break;
      }
      r->queue.pop();
      PROGISO_ASSERT(scratch.size() <= max_record_segments);
      const auto count = static_cast<std::uint32_t>(scratch.size());
      const placed_segment* at =
          count == 0 ? nullptr : r->segments.append_contiguous(scratch.data(), count);
      r->records.push_back({index, at, count, next.error, after});
      r->cut_segments = after;
      ++t.splits;
      t.added += count;
      ++t.cases[static_cast<std::size_t>(s.kind)];
      for (int i = 0; i < s.op_count; ++i) {
        ++t.primitives[static_cast<std::size_t>(s.ops[static_cast<std::size_t>(i)].kind)];
      }
      r->frontier.split(d, index, [&](const ipoint2& c, std::int32_t h) {
        ++t.visited;
        if (const auto item = ready_contour_diamond(rd, r->isovalue, c, h)) {
          r->queue.push(*item);
        } else {
          ++t.culled;
        }
      });
      last_depth = d.depth;
      if (++unpublished == publish_every) {
        publish(*r, t, unpublished);
        unpublished = 0;
      }
    }
    publish(*r, t, unpublished);
    bool reached = false;
    switch (goal.what) {
      case refine_goal::kind::full:
      case refine_goal::kind::deadline:
        reached = r->queue.empty();
        break;
      case refine_goal::kind::error:
        reached = r->queue.empty() || !(r->queue.top().error > goal.max_error);
        break;
      case refine_goal::kind::budget:
        reached = budget_hit || r->queue.empty();
        break;
    }
    end_run(reached);
  }

  // Control (caller holds `control`).
  void launch(std::unique_lock<std::mutex>& lock, const refine_goal& g) {
    stop_and_join(lock);
    contour_root* r = current();
    if (r->failed) {
      throw error(
          "contour engine: an earlier run on this isovalue failed (its contours stay readable); "
          "set the isovalue to refine afresh");
    }
    goal = g;
    r->queue.set_discipline(g.what == refine_goal::kind::full ? queue_discipline::lifo
                                                              : queue_discipline::largest_error);
    if (g.what == refine_goal::kind::error) r->queue.aim_at(g.max_error);
    stop.store(false, std::memory_order_relaxed);  // relaxed: the thread start orders it
    budget_hit = false;
    begin_run([this, r] { drive(r); });
  }

  std::shared_ptr<const volume> owned_image;
  const volume& image;
  contour_engine_options opt;
  hierarchy2d hier;
  std::array<double, 2> origin;  // copied so that extraction never reads the image
  std::array<double, 2> spacing;
  mutable std::mutex build_mutex;
  mutable std::optional<range_data2d> ranges_;
  mutable std::atomic<bool> ranges_ready{false};
  mutable std::atomic<double> range_seconds{0.0};
  // Declared after `opt` (destroy_root reads it) and before the readers' participants.
  mutable epoch_domain domain;
  epoch_participant control_participant;  // retires roots; used under `control`
  reader_registry readers;
  // The published root: release-stored by set_isovalue() (pairs with the acquire in
  // epoch_guard::protect() of snapshot()).
  std::atomic<contour_root*> root{nullptr};

  // Run state: set before the driver starts (its thread start orders them), then the driver's.
  refine_goal goal;
  bool budget_hit = false;
  int last_depth = 0;
  std::uint64_t since_progress = 0;
  std::vector<placed_segment> scratch;
  std::uint64_t generation = 0;  // guarded by control
};

}  // namespace progiso::detail

namespace progiso {

// ---------------------------------------------------------------------------------------------
// contour_snapshot

double contour_snapshot::isovalue() const noexcept { return root_->isovalue; }
std::uint64_t contour_snapshot::generation() const noexcept { return root_->generation; }
std::uint64_t contour_snapshot::segment_count() const noexcept {
  return root_->records[published_ - 1].cut_segments;
}

contour_snapshot::contour_snapshot(contour_snapshot&& other) noexcept
    : guard_(std::move(other.guard_)),
      owner_(std::exchange(other.owner_, nullptr)),
      root_(std::exchange(other.root_, nullptr)),
      published_(std::exchange(other.published_, 0)),
      // relaxed: a snapshot is moved by the one thread that holds it (no call is in flight).
      split_bits_(other.split_bits_.exchange(nullptr, std::memory_order_relaxed)) {}

contour_snapshot& contour_snapshot::operator=(contour_snapshot&& other) noexcept {
  if (this != &other) {
    // relaxed: as in the move constructor.
    delete split_bits_.exchange(other.split_bits_.exchange(nullptr, std::memory_order_relaxed),
                                std::memory_order_relaxed);
    guard_ = std::move(other.guard_);
    owner_ = std::exchange(other.owner_, nullptr);
    root_ = std::exchange(other.root_, nullptr);
    published_ = std::exchange(other.published_, 0);
  }
  return *this;
}

contour_snapshot::~contour_snapshot() {
  // relaxed: destroyed by the thread that holds it, after every call on it returned.
  delete split_bits_.load(std::memory_order_relaxed);
}

const detail::cut_index& contour_snapshot::split_bits() const {
  // acquire: pairs with the release of the compare-and-swap below (the index's contents).
  if (const auto* b = split_bits_.load(std::memory_order_acquire)) return *b;
  auto made = std::make_unique<detail::cut_index>(
      detail::cut_index::dense(owner_->hierarchy_of().vertex_count()));
  for (std::uint64_t r = 1; r < published_; ++r) made->add_on_one_thread(root_->records[r].diamond);
  const detail::cut_index* expected = nullptr;
  // acq_rel: releases this thread's index to later loads (the acquire above) and, when another
  // call won, acquires that one's. Partner: this same exchange in a concurrent first call.
  if (split_bits_.compare_exchange_strong(expected, made.get(), std::memory_order_acq_rel)) {
    return *made.release();
  }
  return *expected;
}

bool contour_snapshot::is_split(const ipoint2& c) const {
  const hierarchy2d& h = owner_->hierarchy_of();
  return h.in_grid(c) && split_bits().contains(h.index(c));
}

template <class InCut>
contour_set contour_snapshot::build(InCut&& in_cut) const {
  const detail::contour_engine_impl& e = *owner_->impl_;
  detail::contour_assembler out(e.hier, root_->isovalue, static_cast<std::size_t>(segment_count()));
  // Records in canonical order (the root's, then by diamond), so that the polylines depend
  // only on the split set, not on the order of the splits (goal, interruptions, resumptions):
  // each record goes to its diamond's rank in the cut's index, which also answers "is this
  // segment's owner split in the cut". The index is a bitmap with counts per word when the cut
  // has a split per 4096 grid vertices (at most 512 bytes a split, less than sorting them), the
  // sorted grid indices otherwise.
  std::vector<std::uint64_t> selected;  // records of the cut, in publication order
  for (std::uint64_t r = 1; r < published_; ++r) {
    if (in_cut(root_->records[r])) selected.push_back(r);
  }
  const std::uint64_t vertices = e.hier.vertex_count();
  detail::cut_index cut;
  if (selected.size() > vertices / 4096) {
    cut = detail::cut_index::dense(vertices);
    for (const std::uint64_t r : selected) cut.add_on_one_thread(root_->records[r].diamond);
    cut.finish({}, 1);
  } else {
    std::vector<std::uint64_t> diamonds;
    diamonds.reserve(selected.size());
    for (const std::uint64_t r : selected) diamonds.push_back(root_->records[r].diamond);
    cut = detail::cut_index::sparse(std::move(diamonds));
  }
  std::vector<std::uint64_t> order(selected.size());
  for (const std::uint64_t r : selected) order[cut.rank(root_->records[r].diamond)] = r;
  const auto add_live = [&](const detail::contour_record& rec) {
    out.begin_record(rec.diamond);
    for (std::uint32_t i = 0; i < rec.count; ++i) {
      const detail::placed_segment& s = rec.segments[i];
      if (s.seg.owner == detail::no_owner2 || !cut.contains(s.seg.owner)) out.add(s);
    }
  };
  add_live(root_->records[0]);
  for (const std::uint64_t r : order) add_live(root_->records[r]);
  return out.finish(e.origin, e.spacing);
}

contour_set contour_snapshot::extract() const {
  return build([](const detail::contour_record&) { return true; });
}

contour_set contour_snapshot::extract_cut(double max_error) const {
  // Nested errors: the records of error > max_error are parent-closed.
  return build([max_error](const detail::contour_record& rec) { return rec.error > max_error; });
}

bool contour_snapshot::check_integrity() const {
  if (root_ == nullptr || root_->magic != detail::contour_root_alive) return false;
  const std::uint64_t vertices = owner_->hierarchy_of().vertex_count();
  std::vector<std::uint64_t> seen((vertices + 63) / 64, 0);
  for (std::uint64_t r = 0; r < published_; ++r) {
    const detail::contour_record& rec = root_->records[r];
    if (r == 0 ? rec.diamond != detail::no_owner2 : rec.diamond >= vertices) return false;
    if (r != 0) {
      // Each diamond split once.
      const std::uint64_t bit = std::uint64_t{1} << (rec.diamond % 64);
      if (rec.count > detail::max_record_segments || (seen[rec.diamond / 64] & bit) != 0) {
        return false;
      }
      seen[rec.diamond / 64] |= bit;
    }
    for (std::uint32_t i = 0; i < rec.count; ++i) {
      const std::uint64_t o = rec.segments[i].seg.owner;
      if (o != detail::no_owner2 && o >= vertices) return false;
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// contour_engine

contour_engine::contour_engine(const volume& image, double isovalue,
                               contour_engine_options options) {
  init(nullptr, image, isovalue, std::move(options));
}

contour_engine::contour_engine(volume&& image, double isovalue, contour_engine_options options) {
  auto owned = std::make_shared<const volume>(std::move(image));
  const volume& v = *owned;
  init(std::move(owned), v, isovalue, std::move(options));
}

contour_engine::contour_engine(std::shared_ptr<const volume> image, double isovalue,
                               contour_engine_options options) {
  if (!image) throw error("contour engine: expected an image, found a null pointer");
  const volume& v = *image;
  init(std::move(image), v, isovalue, std::move(options));
}

void contour_engine::init(std::shared_ptr<const volume> owned, const volume& image, double isovalue,
                          contour_engine_options options) {
  if (image.dims()[2] != 1) {
    throw error("contour engine: expected a 2D image (depth 1), found depth " +
                std::to_string(image.dims()[2]));
  }
  if (!std::isfinite(isovalue)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(isovalue));
  }
  impl_ =
      std::make_unique<detail::contour_engine_impl>(std::move(owned), image, std::move(options));
  // release: pairs with the acquire in epoch_guard::protect() (snapshot()).
  impl_->root.store(impl_->make_root(isovalue, 0), std::memory_order_release);
}

contour_engine::~contour_engine() {
  {
    std::unique_lock lock(impl_->control);
    impl_->stop_and_join(lock);
  }
  detail::contour_root* r = impl_->current();
  impl_->root.store(nullptr, std::memory_order_relaxed);  // relaxed: no reader is left
  detail::contour_engine_impl::destroy_root(r);
  // Participants, then the domain (which drains the retired roots), go with impl_.
  impl_->readers.clear();
}

void contour_engine::set_isovalue(double w) {
  detail::swap_root(*impl_, w, [](const detail::contour_root&) {});
}

void contour_engine::start(const refine_goal& goal) { detail::start_run(*impl_, goal); }
void contour_engine::cancel() { impl_->cancel(); }
void contour_engine::wait() { impl_->wait(); }
bool contour_engine::refine(const refine_goal& goal) {
  return detail::refine_blocking(*impl_, goal);
}

contour_snapshot contour_engine::snapshot() const {
  contour_snapshot s;
  s.guard_ = impl_->readers.reader().pin();
  s.owner_ = this;
  s.root_ = s.guard_.protect(impl_->root);
  s.published_ = s.root_->records.published();
  return s;
}

double contour_engine::isovalue() const {
  epoch_guard g = impl_->readers.reader().pin();
  return g.protect(impl_->root)->isovalue;
}

bool contour_engine::running() const noexcept { return impl_->running(); }

bool contour_engine::done() const {
  epoch_guard g = impl_->readers.reader().pin();
  return g.protect(impl_->root)->remaining.get() == 0;
}

contour_engine_statistics contour_engine::statistics() const {
  contour_engine_statistics s;
  {
    epoch_guard g = impl_->readers.reader().pin();
    const detail::contour_root* r = g.protect(impl_->root);
    s.refine.splits = r->splits.get();
    s.refine.visited = r->visited.get();
    s.refine.culled = r->culled.get();
    s.refine.segments = r->segment_count.get();
    s.refine.record_segments = r->record_segments.get();
    for (std::size_t k = 0; k < contour_case_count; ++k) s.refine.cases[k] = r->cases[k].get();
    for (std::size_t k = 0; k < contour_primitive_count; ++k) {
      s.refine.primitives[k] = r->primitives[k].get();
    }
    s.published = r->records.published();
    s.generation = r->generation;
    s.surface_published_at = r->published_at;
  }
  s.runs = impl_->runs.get();
  s.cancelled_runs = impl_->cancelled_runs.get();
  s.reclamation = impl_->domain.statistics();
  s.snapshot_retries = impl_->readers.snapshot_retries();
  return s;
}

const volume& contour_engine::image() const noexcept { return impl_->image; }
const hierarchy2d& contour_engine::hierarchy_of() const noexcept { return impl_->hier; }
const range_data2d& contour_engine::ranges() const { return impl_->ranges(); }
double contour_engine::range_build_seconds() const noexcept {
  // relaxed: a statistic.
  return impl_->range_seconds.load(std::memory_order_relaxed);
}

}  // namespace progiso
