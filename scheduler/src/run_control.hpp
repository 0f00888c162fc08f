// scheduler/src/run_control.hpp — what the 3D engine (engine_impl.hpp) and the contour engine
// (contour_engine.cpp) share to run in the background and be read while they do: the control
// of runs (a driver thread per run, stop requests, cancel and wait, the progress callback and
// its errors), statistics counters, and the epoch participants of reading threads.
//
// Not installed. The rules it keeps, for both engines: control calls serialise on `control`;
// a run is one driver thread, joined before the next starts; a stop request is a relaxed flag
// that every worker reads between splits; cancel() from the progress callback only requests the
// stop (joining there would wait for the caller itself); an exception of the callback stops the
// run and is rethrown by the control thread's wait() or refine(), never across a worker.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <progiso/concurrent/epoch.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso::detail {

using clock = std::chrono::steady_clock;

// Counters written by one writer at a time (the commit step, or whoever publishes) and read by
// anyone: relaxed atomics, each exact at some moment; no other data is published through them.
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

// The epoch participants of the threads that read one engine. A thread's participant is
// registered on its first read of that engine (takes a mutex once), then found in a small
// thread-local cache, most recent first, by the registry's serial number (never reused).
class reader_registry {
 public:
  explicit reader_registry(epoch_domain& domain) : domain_(&domain), serial_(next_serial()) {}
  reader_registry(const reader_registry&) = delete;
  reader_registry& operator=(const reader_registry&) = delete;

  [[nodiscard]] epoch_participant& reader() const;
  // Bounded re-reads of protect() by every reader so far (statistics).
  [[nodiscard]] std::uint64_t snapshot_retries() const;
  // Unregisters every participant (the engine's destruction, before its domain goes).
  void clear();

 private:
  static std::uint64_t next_serial() {
    static std::atomic<std::uint64_t> n{1};
    // relaxed: a unique number; nothing is published with it.
    return n.fetch_add(1, std::memory_order_relaxed);
  }
  epoch_domain* domain_;
  std::uint64_t serial_;
  mutable std::mutex mutex_;
  mutable std::vector<std::unique_ptr<epoch_participant>> readers_;
};

// Background runs of one engine. `who` names the engine in error messages.
struct run_control {
  explicit run_control(const char* who) noexcept : who_(who) {}

  [[nodiscard]] bool stopping() const noexcept {
    // relaxed: a request flag; the data a run publishes is ordered by its own publication.
    return stop.load(std::memory_order_relaxed);
  }
  void request_stop() noexcept {
    // relaxed: see stopping().
    stop.store(true, std::memory_order_relaxed);
  }

  // Marks the progress callback's thread, so that control calls made from inside it can tell.
  struct callback_scope {
    explicit callback_scope(const run_control* e) noexcept : saved(in_callback_of) {
      in_callback_of = e;
    }
    callback_scope(const callback_scope&) = delete;
    callback_scope& operator=(const callback_scope&) = delete;
    ~callback_scope() { in_callback_of = saved; }
    const run_control* saved;
  };
  static thread_local const run_control* in_callback_of;
  [[nodiscard]] bool in_own_callback() const noexcept { return in_callback_of == this; }
  // Throws progiso::error when called from this engine's progress callback.
  void refuse_in_callback(const char* call) const;
  // Calls the progress callback `f` (by whoever publishes, one at a time): marks the thread,
  // and turns an exception into a stop request and a pending error for the control thread.
  template <class F>
  void call_progress(F&& f) noexcept {
    if (callback_error) return;
    const callback_scope in_callback(this);
    try {
      f();
    } catch (...) {
      callback_error = std::current_exception();
      request_stop();
    }
  }

  // Control calls; the caller holds `control` where a lock is passed.
  // Requests the stop of the active run and joins its driver (unlocks while joining).
  void stop_and_join(std::unique_lock<std::mutex>& lock);
  // Starts `body` on a new driver thread: after stop_and_join(), with `stop` cleared and the
  // run's state set by the caller (the thread's start orders them for the driver).
  void begin_run(std::function<void()> body);
  // The driver's last step: the run reached its goal when `goal_reached` and neither the user
  // nor the progress callback stopped it; wakes wait().
  void end_run(bool goal_reached);
  // engine::cancel(): from the progress callback only a stop request, else stop and join.
  void cancel();
  // engine::wait(): blocks until idle and rethrows a callback's exception.
  void wait();
  // engine::refine()'s second half, after the launch: waits until idle; returns whether the
  // goal was reached; rethrows a callback's exception.
  bool wait_reached(std::unique_lock<std::mutex>& lock);
  // After a run: moves a callback's exception to the control thread.
  void rethrow_callback_error(std::unique_lock<std::mutex>& lock);
  [[nodiscard]] bool running() const noexcept {
    // relaxed: a status reading; waiters synchronise through `control`.
    return active_flag.load(std::memory_order_relaxed);
  }

  std::atomic<bool> stop{false};
  std::mutex control;
  std::condition_variable idle;
  std::thread driver;
  bool active = false;          // guarded by control
  bool user_cancelled = false;  // guarded by control (read by the driver after its run)
  bool last_reached = false;    // guarded by control
  // Set by the progress callback (whoever publishes) during a run, read by the driver after it.
  bool callback_cancel = false;
  std::exception_ptr callback_error;
  std::exception_ptr pending_error;  // guarded by control: rethrown by wait() / refine()
  std::atomic<bool> active_flag{false};
  counter runs, cancelled_runs;

 private:
  const char* who_;
};

// Retired roots: a dead root's magic, and the poison that fills its storage before it is freed
// when the options ask for it (stress tests: a reader of a reclaimed root then reads poison,
// which snapshot::check_integrity() reports).
inline constexpr std::uint64_t root_dead = 0xdbdbdbdbdbdbdbdb;
inline constexpr unsigned char poison_byte = 0xdb;
// Poisons every element of an append_log (published or not) and of a vector.
template <class Log>
void poison_log(Log& log) noexcept {
  for (std::size_t i = 0; i < log.size(); ++i) {
    std::memset(static_cast<void*>(&log.at_unpublished(i)), poison_byte, sizeof(log[i]));
  }
}
template <class T>
void poison_vector(std::vector<T>& v) noexcept {
  if (!v.empty()) std::memset(static_cast<void*>(v.data()), poison_byte, v.size() * sizeof(T));
}

// Throws progiso::error for a non-finite isovalue (both engines' constructors and
// set_isovalue()).
void require_finite_isovalue(double w);
// Throws progiso::error for an error goal whose threshold is not a number.
void require_valid_goal(const refine_goal& goal);

// The control calls both engines make the same way. `Impl` derives from run_control and has
// `goal`, `generation`, `root` (an atomic root pointer), `control_participant`, current(),
// make_root(w, generation), can_publish_early(), launch(lock, goal) and a static
// destroy_root(void*).

// start(): a run towards `goal` in the background (cancelling a run in progress).
template <class Impl>
void start_run(Impl& impl, const refine_goal& goal) {
  require_valid_goal(goal);
  impl.refuse_in_callback("start()");
  std::unique_lock lock(impl.control);
  impl.launch(lock, goal);
}

// refine(): start_run() and wait; whether the goal was reached.
template <class Impl>
bool refine_blocking(Impl& impl, const refine_goal& goal) {
  require_valid_goal(goal);
  impl.refuse_in_callback("refine()");
  std::unique_lock lock(impl.control);
  impl.launch(lock, goal);
  return impl.wait_reached(lock);
}

// set_isovalue(): publishes w's root, stops the run, retires the old root (after
// `on_retire(old)`, the caller's accounting) and resumes the interrupted goal. The new root's
// surface reads only the root cubes' (squares') corners and shares nothing with the run on the
// old root, so where make_root() maps no memory (`can_publish_early()`: the engine holds a
// reclaimed root's arrays) it is published first, and readers see it within make_root()'s time,
// not after the run's workers have stopped, which on a loaded machine can wait for a scheduler
// tick. Otherwise the run is stopped first: mapping memory while its workers fault pages in
// waits for the address space's lock, which they take again and again (bench/README.md). The
// old root is destroyed by the engine's reclaimer where it has one, not by this call.
template <class Impl, class OnRetire>
void swap_root(Impl& impl, double w, OnRetire&& on_retire) {
  require_finite_isovalue(w);
  impl.refuse_in_callback("set_isovalue()");
  std::unique_lock lock(impl.control);
  const bool resume = impl.active;
  const refine_goal goal = impl.goal;
  const bool early = impl.can_publish_early();
  if (!early) impl.stop_and_join(lock);
  auto* old = impl.current();
  auto* fresh = impl.make_root(w, ++impl.generation);
  // seq_cst (the default): release for readers' protect(), and the unlink must be seq_cst for
  // the TSan variant of the reclamation argument (concurrent/epoch.hpp).
  impl.root.store(fresh);
  if (early) impl.stop_and_join(lock);  // the run on `old` ends before `old` is retired
  on_retire(*old);
  impl.control_participant.retire(old, &Impl::destroy_root, old->birth_era());
  if (resume) impl.launch(lock, goal);
  // Roots are large and few: reclaim now what no snapshot holds, rather than every
  // reclaim_threshold retirements. A reader stalled in a snapshot pins only its own root.
  impl.control_participant.flush();
}

}  // namespace progiso::detail
