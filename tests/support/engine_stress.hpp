// tests/support/engine_stress.hpp — what the stress tests of the 3D and the contour engine share:
// the control thread's random operations, and the reclamation check at the end.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <random>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/scheduler/engine.hpp>

namespace progiso::test {

/// One random control operation on an engine (3D or contour): an isovalue change (2 in 7),
/// a full run, an error run to `error_goal` (by priority or in any order), a cancel, a deadline
/// run of 0–3 ms, or a run to a budget of 50–20 000 triangles (segments); then a pause of
/// 0–1.2 ms. Returns whether the isovalue changed.
template <class Engine, class Rng>
bool random_control_step(Engine& e, Rng& rng, const std::vector<double>& isovalues,
                         double error_goal) {
  std::uniform_int_distribution<int> action(0, 6);
  std::uniform_int_distribution<std::uint64_t> budget(50, 20000);
  std::uniform_int_distribution<std::size_t> pick(0, isovalues.size() - 1);
  std::uniform_int_distribution<int> ms(0, 3);
  bool changed = false;
  switch (action(rng)) {
    case 0:
    case 1:
      e.set_isovalue(isovalues[pick(rng)]);
      changed = true;
      break;
    case 2:
      e.start(refine_goal::full());
      break;
    case 3:  // by priority, or in any order (the contour engine takes both by priority)
      e.start(ms(rng) % 2 == 0 ? refine_goal::error(error_goal)
                               : refine_goal::error_in_any_order(error_goal));
      break;
    case 4:
      e.cancel();
      break;
    case 5:
      e.refine_for(std::chrono::milliseconds(ms(rng)));
      break;
    case 6:
      e.start(refine_goal::triangles(budget(rng)));
      break;
  }
  std::this_thread::sleep_for(std::chrono::microseconds(ms(rng) * 400));
  return changed;
}

/// The control thread of a stress test: random_control_step() until `end`, then cancel(), then
/// `finished` set (release: pairs with the readers' acquire loads of it) and the readers joined;
/// checks that the engine retired a root per isovalue change. Returns the isovalue changes;
/// `ops` counts the steps.
template <class Engine, class Rng, class TimePoint>
std::uint64_t control_until(Engine& e, Rng& rng, const std::vector<double>& isovalues,
                            double error_goal, TimePoint end, std::atomic<bool>& finished,
                            std::vector<std::thread>& readers, std::uint64_t& ops) {
  std::uint64_t changes = 0;
  while (std::chrono::steady_clock::now() < end) {
    if (random_control_step(e, rng, isovalues, error_goal)) ++changes;
    ++ops;
  }
  e.cancel();
  finished.store(true, std::memory_order_release);  // release: see above
  for (auto& r : readers) r.join();
  const auto stats = e.statistics();
  if constexpr (requires { stats.roots; }) {
    // The 3D engine publishes roots beside isovalue changes (uniform cuts): all but the last
    // are retired.
    EXPECT_EQ(stats.reclamation.retired, stats.roots - 1);
    EXPECT_GE(stats.roots, changes + 1);
  } else {
    EXPECT_EQ(stats.reclamation.retired, changes);
  }
  return changes;
}

/// Every root of generations 0 … `generations` reclaimed exactly once (engine_options::on_reclaim
/// recorded them in `reclaimed`).
inline void expect_each_root_reclaimed_once(const std::multiset<std::uint64_t>& reclaimed,
                                            std::uint64_t generations) {
  std::multiset<std::uint64_t> expected;
  for (std::uint64_t g = 0; g <= generations; ++g) expected.insert(g);
  EXPECT_EQ(reclaimed, expected) << "every root reclaimed exactly once";
}

/// The same where a generation may have several roots (the 3D engine's uniform cuts): `roots`
/// published roots (engine_statistics::roots) reclaimed, each once, every generation among them.
inline void expect_each_root_reclaimed_once(const std::multiset<std::uint64_t>& reclaimed,
                                            std::uint64_t generations, std::uint64_t roots) {
  EXPECT_EQ(reclaimed.size(), roots) << "every published root reclaimed exactly once";
  for (std::uint64_t g = 0; g <= generations; ++g) {
    EXPECT_GE(reclaimed.count(g), 1u) << "generation " << g << " reclaimed";
  }
  EXPECT_TRUE(reclaimed.empty() || *reclaimed.rbegin() <= generations);
}

}  // namespace progiso::test
