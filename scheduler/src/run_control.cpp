// Run control: what both engines share (run_control.hpp: the driver thread, stop requests,
// cancel and wait, the progress callback and its errors, readers' participants), and the 3D
// engine's driver (range build slices, deadline slices, the goal reached).

#include "engine_impl.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/surface/finest_surface.hpp>

namespace progiso::detail {

// ---- shared with the contour engine (run_control.hpp) ---------------------------------------

epoch_participant& reader_registry::reader() const {
  struct entry {
    std::uint64_t serial;
    epoch_participant* participant;
  };
  thread_local std::vector<entry> cache;
  for (std::size_t i = 0; i < cache.size(); ++i) {
    if (cache[i].serial == serial_) {
      if (i != 0) std::swap(cache[i], cache[0]);
      return *cache[0].participant;
    }
  }
  epoch_participant* p = nullptr;
  {
    const std::lock_guard lock(mutex_);
    readers_.push_back(std::make_unique<epoch_participant>(*domain_));
    p = readers_.back().get();
  }
  // Forgotten entries keep their participant registered (owned by its engine) but unused.
  if (cache.size() >= 8) cache.pop_back();
  cache.push_back({serial_, p});
  std::rotate(cache.begin(), cache.end() - 1, cache.end());
  return *p;
}

std::uint64_t reader_registry::snapshot_retries() const {
  const std::lock_guard lock(mutex_);
  std::uint64_t n = 0;
  for (const auto& p : readers_) n += p->protect_retries();
  return n;
}

void reader_registry::clear() {
  const std::lock_guard lock(mutex_);
  readers_.clear();
}

void require_finite_isovalue(double w) {
  if (!std::isfinite(w)) {
    throw error("isovalue: expected a finite number, found " + std::to_string(w));
  }
}

void require_valid_goal(const refine_goal& goal) {
  if (goal.what == refine_goal::kind::error && !(goal.max_error >= -1e300)) {
    throw error("refine goal: expected a number as error threshold");
  }
  if (goal.focus) {
    refine_goal focus_only;
    focus_only.focus = goal.focus;
    check_goal(focus_only);
  }
}

thread_local const run_control* run_control::in_callback_of = nullptr;

void run_control::refuse_in_callback(const char* call) const {
  if (in_own_callback()) {
    throw error(std::string(who_) + ": " + call + " cannot be called from the " + who_ +
                "'s progress callback (it would wait for the run that calls it); call cancel() "
                "there, which requests a stop");
  }
}

void run_control::rethrow_callback_error(std::unique_lock<std::mutex>& lock) {
  if (!pending_error) return;
  std::exception_ptr e = std::move(pending_error);
  pending_error = nullptr;
  lock.unlock();
  std::rethrow_exception(e);
}

void run_control::stop_and_join(std::unique_lock<std::mutex>& lock) {
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

void run_control::begin_run(std::function<void()> body) {
  user_cancelled = false;
  pending_error = nullptr;  // a callback error belongs to the run it stopped
  active = true;
  active_flag.store(true, std::memory_order_relaxed);  // relaxed: status only
  runs.add(1);
  driver = std::thread(std::move(body));
}

void run_control::end_run(bool goal_reached) {
  {
    const std::lock_guard lock(control);
    // callback_error and callback_cancel were written by the run's publishers, which happen
    // before the driver's end (the graph's wait_for_all(), a task group's wait, or the driver
    // itself).
    const bool stopped_by_callback = callback_cancel || callback_error != nullptr;
    callback_cancel = false;
    if (callback_error) pending_error = std::move(callback_error);
    callback_error = nullptr;
    const bool reached = goal_reached && !user_cancelled && !stopped_by_callback;
    last_reached = reached;
    active = false;
    // relaxed: a status reading for running(); waiters synchronise through `control`.
    active_flag.store(false, std::memory_order_relaxed);
    if (!reached) cancelled_runs.add(1);
  }
  idle.notify_all();
}

void run_control::cancel() {
  if (in_own_callback()) {
    // From the progress callback, on a thread of the run itself: joining the run here would
    // wait for this very call, so only request the stop; the run ends within one split.
    callback_cancel = true;
    request_stop();
    return;
  }
  std::unique_lock lock(control);
  stop_and_join(lock);
}

void run_control::wait() {
  refuse_in_callback("wait()");
  std::unique_lock lock(control);
  idle.wait(lock, [this] { return !active; });
  rethrow_callback_error(lock);
}

bool run_control::wait_reached(std::unique_lock<std::mutex>& lock) {
  idle.wait(lock, [this] { return !active; });
  const bool reached = last_reached;
  rethrow_callback_error(lock);
  return reached;
}

// ---- the engine's driver ------------------------------------------------------------------

bool engine_impl::continue_after_slice() {
  const std::lock_guard lock(control);
  if (user_cancelled || callback_cancel || callback_error != nullptr) return false;
  if (clock::now() >= goal.deadline) return false;
  stop.store(false, std::memory_order_relaxed);  // relaxed: the next graph run orders it
  return true;
}

void engine_impl::drive_unranged(engine_root* r) {
  auto slice = std::chrono::duration_cast<clock::duration>(std::chrono::milliseconds(1));
  for (;;) {
    {
      const std::lock_guard lock(build_mutex);
      const auto now = clock::now();
      const double left = std::chrono::duration<double>(goal.deadline - now).count();
      // The pieces left weighed by the planes they read (the first pieces built, padding
      // mostly, read a quarter of the others), and finish() after them, allowed a tenth of the
      // pieces' time since it is small beside them (bench/README.md).
      std::optional<double> estimate;
      if (min_max_work > 0) {
        estimate = 1.1 * seconds_per_work() *
                   static_cast<double>(ranges_->piece_work(pieces_built, ranges_->piece_count()));
      }
      // Refinement keeps time whatever the build takes: see plan_deadline_build().
      const detail::deadline_build_step step =
          detail::plan_deadline_build(estimate, left, std::chrono::duration<double>(slice).count());
      const clock::time_point until = now + std::chrono::duration_cast<clock::duration>(
                                                std::chrono::duration<double>(step.seconds));
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

bool engine_impl::by_uniform_cuts(const engine_root& r, const refine_goal& g) const noexcept {
  if (!opt.uniform_cuts || vol.dims()[2] < 2 || opt.smooth.active()) return false;
  switch (g.what) {
    case refine_goal::kind::full:
      return true;
    case refine_goal::kind::deadline:
      return !g.focus && (r.base_stride > 0 || r.records.published() <= 1);
    default:
      return false;
  }
}

bool engine_impl::replace_root(engine_root* shown, engine_root* fresh, bool retire_now) {
  const std::lock_guard lock(control);
  if (current() != shown) {
    // An isovalue change published its root first: `fresh` was never seen.
    reclaim(*fresh, false);
    return false;
  }
  name_published(*fresh);
  // seq_cst (the default), as swap_root(): release for readers' protect(), and the unlink seq_cst
  // for the TSan variant of the reclamation argument (concurrent/epoch.hpp).
  root.store(fresh);
  root_bytes.set(fresh->bytes());
  if (retire_now) retire_root(shown);
  return true;
}

void engine_impl::count_retired(engine_root& old) {
  old.retired_bytes = old.bytes();
  // relaxed: a statistic; the reclaimer's fetch_sub is the other writer.
  const std::uint64_t now =
      retired_bytes.fetch_add(old.retired_bytes, std::memory_order_relaxed) + old.retired_bytes;
  peak_retired_bytes.set(std::max(peak_retired_bytes.get(), now));
}

void engine_impl::retire_root(engine_root* old) {
  count_retired(*old);
  control_participant.retire(old, &engine_impl::destroy_root, old->birth_era());
  control_participant.flush();
}

namespace {
// Thrown through the ladder when a uniform cut could not be published (an isovalue change).
struct root_replaced {};
}  // namespace

std::vector<engine_root*> engine_impl::make_base_roots(const engine_root& r, const refine_goal& g) {
  // The ladder tries at most one cut per stride below what is shown; a full goal makes one.
  const std::int32_t top = r.base_stride > 0 ? r.base_stride : hier.root_size();
  const std::size_t cuts =
      g.what == refine_goal::kind::full
          ? 1
          : static_cast<std::size_t>(std::bit_width(static_cast<std::uint32_t>(top)) - 1);
  std::vector<engine_root*> made;
  made.reserve(cuts);
  try {
    for (std::size_t k = 0; k < cuts; ++k) made.push_back(make_base_root(r.isovalue, r.generation));
  } catch (...) {
    for (engine_root* m : made) reclaim(*m, false);
    throw;
  }
  return made;
}

void engine_impl::drive_uniform(engine_root* r, std::vector<engine_root*> made) {
  const double w = r->isovalue;
  engine_root* shown = r;  // never read after it is retired: only compared
  const std::int32_t shown_stride = r->base_stride;
  std::vector<engine_root*> superseded;  // published before, replaced by this run: to retire
  superseded.reserve(64);                // more than the ladder's strides: no growth mid-run
  bool reached = false;
  const auto publish = [&](triangle_mesh&& m, std::int32_t stride) {
    PROGISO_ASSERT(!made.empty());
    engine_root* b = made.back();
    made.pop_back();
    set_base(*b, stride, std::move(m));
    const std::uint64_t triangles = b->cut_triangles;
    // The roots this run replaces are retired after it, not while its next cut is made
    // (freeing them on the reclaimer competed with the passes; bench/README.md).
    if (!replace_root(shown, b, false)) throw root_replaced{};
    superseded.push_back(shown);
    shown = b;
    if (opt.progress) {
      call_progress([&] { opt.progress({0, triangles, 0.0, hier.max_depth()}); });
    }
  };
  const detail::mesh_storage storage = [this](std::uint64_t v, std::uint64_t t) {
    return take_mesh_storage(v, t);
  };
  // The passes run pieces of rows on the engine's threads, in its arena.
  const auto passes = [&](auto&& f) {
    if (threads <= 1) {
      f(parallel_loop{}, std::size_t{1});
    } else {
      arena.execute([&] { f(parallel_loop{tbb_loop}, std::size_t{16} * threads); });
    }
  };
  try {
    if (goal.what == refine_goal::kind::full) {
      if (shown_stride != 1) {
        passes([&](const parallel_loop& loop, std::size_t parts) {
          finest_progress watch;
          watch = [this](std::uint64_t, std::uint64_t) {
            if (stopping()) throw root_replaced{};
          };
          publish(detail::finest_surface(vol, w, loop, parts, watch, storage), 1);
        });
      }
      reached = true;
    } else if (shown_stride != 1) {
      detail::ladder_hooks hooks;
      hooks.hierarchy_cuts = true;
      // The root surface is the uniform cut of the root cubes' side: the ladder begins below.
      hooks.shown_stride = shown_stride > 0 ? shown_stride : hier.root_size();
      hooks.stopping = [this] { return stopping(); };
      hooks.on_cut = publish;
      hooks.storage = storage;
      hooks.begin_when_time_is_left = true;  // each cut is shown as it is made
      std::int32_t finest = shown_stride;
      passes([&](const parallel_loop& loop, std::size_t parts) {
        const ladder_result l =
            detail::ladder_surface(vol, w, goal.deadline, loop, parts, {}, hooks);
        if (l.levels_done > 0) finest = l.stride;
      });
      reached = finest == 1;
    } else {
      reached = true;
    }
  } catch (const root_replaced&) {
    // Stopped, or an isovalue change published its root: what was published stays.
  } catch (...) {
    // The passes' own failure (memory, a surface beyond 32-bit ids): the run stops, what was
    // published stays, and wait() or refine() rethrows it, as a progress callback's error. This
    // thread is the run's only publisher, the one writer of callback_error.
    callback_error = std::current_exception();
  }
  end_run(reached);
  // The roots this run replaced, retired now that its caller has its result (a control call
  // that would start another run, or the destructor, joins this thread first); those it did not
  // use, never published, destroyed.
  for (engine_root* unused : made) reclaim(*unused, false);
  const std::lock_guard lock(control);
  for (engine_root* old : superseded) retire_root(old);
}

void engine_impl::drive(engine_root* r, engine_root* replaces) {
  try {
    drive_records(r, replaces);
  } catch (...) {
    // The graph's tasks have ended (its wait rethrew): this thread is the run's only publisher
    // now, the one writer of callback_error. Nothing after replace_root() throws, so a root
    // made for this run (`replaces`) was never published: no reader holds it.
    callback_error = std::current_exception();
    if (replaces != nullptr) {
      destroy_root(r);
    } else {
      r->failed = true;
    }
    end_run(false);
  }
}

void engine_impl::drive_records(engine_root* r, engine_root* replaces) {
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
  if (r->seeded) r->remaining.set(ready_count(*r));
  root_bytes.set(r->bytes());
  bool reached = false;
  switch (goal.what) {
    case refine_goal::kind::full:
    case refine_goal::kind::error:
      reached = !eligible(*r);
      break;
    case refine_goal::kind::budget:
      reached = budget_hit || r->queue.empty();
      break;
    case refine_goal::kind::deadline:
      reached = r->seeded && ready_count(*r) == 0;
      break;
  }
  if (replaces != nullptr) {
    // Records made out of sight in place of a uniform cut: shown once the goal is reached, or,
    // for a deadline or a budget, once they hold at least the uniform cut's triangles.
    const bool as_many =
        (goal.what == refine_goal::kind::deadline || goal.what == refine_goal::kind::budget) &&
        r->cut_triangles >= replaces->cut_triangles;
    if ((reached || as_many) && !stopping()) {
      if (!replace_root(replaces, r)) reached = false;  // an isovalue change came first
    } else {
      reached = false;
      destroy_root(r);  // never published: no reader holds it
    }
  }
  end_run(reached);
}

void engine_impl::launch(std::unique_lock<std::mutex>& lock, const refine_goal& g) {
  stop_and_join(lock);
  engine_root* r = current();
  if (r->failed) {
    throw error(
        "engine: an earlier run on this isovalue failed (its surface stays readable); set the "
        "isovalue to refine afresh");
  }
  goal = g;
  // A focus weights the keys: an error target is then taken by priority (its split set depends on
  // the weights, which the plane sweep does not know).
  if (goal.focus) goal.any_order = false;
  stop.store(false, std::memory_order_relaxed);  // relaxed: the thread start orders it
  budget_hit = false;
  if (by_uniform_cuts(*r, goal)) {
    // The roots it may publish first, then the workers woken (see below), then the driver: the
    // passes begin as soon as it starts.
    std::vector<engine_root*> made = make_base_roots(*r, goal);
    if (threads > 1) arena.enqueue([] {});
    begin_run([this, r, made] { drive_uniform(r, made); });
    return;
  }
  engine_root* replaces = nullptr;
  if (r->base_stride == 1 && goal.what != refine_goal::kind::deadline) {
    // The finest cut holds every split: an error or budget goal asks for nothing more.
    begin_run([this] { end_run(true); });
    return;
  }
  if (r->base_stride > 0) {
    // A uniform cut has no records to go on from: a root of records is refined out of sight.
    replaces = r;
    r = make_root(r->isovalue, r->generation, false);
  }
  r->queue.set_discipline(g.what == refine_goal::kind::full ? queue_discipline::lifo
                                                            : queue_discipline::largest_error);
  if (g.what == refine_goal::kind::error) r->queue.aim_at(g.max_error);  // eligible() is exact
  // An empty task asks oneTBB for the arena's workers now, before the driver thread starts:
  // workers that have idled long enough to sleep join new work late, by as long as a whole
  // range build of a mid-sized grid can take (bench/README.md).
  if (threads > 1) arena.enqueue([] {});
  begin_run([this, r, replaces] { drive(r, replaces); });
}

}  // namespace progiso::detail
