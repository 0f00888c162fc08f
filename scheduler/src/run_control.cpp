// Run control: what both engines share (run_control.hpp: the driver thread, stop requests,
// cancel and wait, the progress callback and its errors, readers' participants), and the 3D
// engine's driver (range build slices, deadline slices, the goal reached).

#include "engine_impl.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>

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

void engine_impl::drive(engine_root* r) {
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
  end_run(reached);
}

void engine_impl::launch(std::unique_lock<std::mutex>& lock, const refine_goal& g) {
  stop_and_join(lock);
  engine_root* r = current();
  goal = g;
  // A focus weights the keys: an error target is then taken by priority (its split set depends on
  // the weights, which the plane sweep does not know).
  if (goal.focus) goal.any_order = false;
  r->queue.set_discipline(g.what == refine_goal::kind::full ? queue_discipline::lifo
                                                            : queue_discipline::largest_error);
  if (g.what == refine_goal::kind::error) r->queue.aim_at(g.max_error);  // eligible() is exact
  stop.store(false, std::memory_order_relaxed);  // relaxed: the thread start orders it
  budget_hit = false;
  // An empty task asks oneTBB for the arena's workers now, before the driver thread starts:
  // workers that have idled long enough to sleep join new work late, by as long as a whole
  // range build of a mid-sized grid can take (bench/README.md).
  if (threads > 1) arena.enqueue([] {});
  begin_run([this, r] { drive(r); });
}

}  // namespace progiso::detail
