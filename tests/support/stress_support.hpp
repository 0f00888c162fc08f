// Helpers shared by the tests of progiso::concurrent: the stress duration and a start signal.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

namespace progiso::test {

/// Seconds each stress test runs: PROGISO_STRESS_SECONDS, default 1 (short in CI, long on demand).
inline std::chrono::duration<double> stress_duration() {
  if (const char* env = std::getenv("PROGISO_STRESS_SECONDS"); env != nullptr && *env != '\0') {
    const double seconds = std::stod(env);
    if (seconds > 0) return std::chrono::duration<double>(seconds);
  }
  return std::chrono::duration<double>(1.0);
}

/// Turns a hang into a failure: aborts the process with `what` if it is still alive `limit` after
/// construction (a deadlocked stress test would otherwise hold CI until ctest's timeout).
class stall_watchdog {
 public:
  stall_watchdog(std::string what, std::chrono::duration<double> limit)
      : what_(std::move(what)), thread_([this, limit] {
          std::unique_lock lock(mutex_);
          if (!done_cv_.wait_for(lock, limit, [this] { return done_; })) {
            std::fprintf(stderr, "stall: %s did not finish within %.0f s; aborting\n",
                         what_.c_str(), limit.count());
            std::abort();
          }
        }) {}
  stall_watchdog(const stall_watchdog&) = delete;
  stall_watchdog& operator=(const stall_watchdog&) = delete;
  ~stall_watchdog() {
    {
      const std::lock_guard lock(mutex_);
      done_ = true;
    }
    done_cv_.notify_one();
    thread_.join();
  }

 private:
  std::string what_;
  std::mutex mutex_;
  std::condition_variable done_cv_;
  bool done_ = false;
  std::thread thread_;
};

/// The watchdog limit of a stress test that runs stress_duration(): generous (sanitizers, a
/// loaded machine), yet far below ctest's timeout.
inline std::chrono::duration<double> stall_limit() {
  return 4 * stress_duration() + std::chrono::seconds(240);
}

/// A value one thread sets and others wait for (C++20 atomic wait; TSan sees the release/acquire).
class phase_signal {
 public:
  void advance_to(int phase) noexcept {
    phase_.store(phase, std::memory_order_release);  // pairs with the acquire-load in wait_for()
    phase_.notify_all();
  }
  void wait_for(int phase) const noexcept {
    for (int seen = phase_.load(std::memory_order_acquire); seen < phase;
         seen = phase_.load(std::memory_order_acquire)) {
      phase_.wait(seen, std::memory_order_acquire);
    }
  }

 private:
  std::atomic<int> phase_{0};
};

}  // namespace progiso::test
