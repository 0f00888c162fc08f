// Helpers shared by the tests of progiso::concurrent: the stress duration and a start signal.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <string>

namespace progiso::test {

/// Seconds each stress test runs: PROGISO_STRESS_SECONDS, default 1 (short in CI, long on demand).
inline std::chrono::duration<double> stress_duration() {
  if (const char* env = std::getenv("PROGISO_STRESS_SECONDS"); env != nullptr && *env != '\0') {
    const double seconds = std::stod(env);
    if (seconds > 0) return std::chrono::duration<double>(seconds);
  }
  return std::chrono::duration<double>(1.0);
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
