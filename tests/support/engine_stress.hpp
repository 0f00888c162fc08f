// tests/support/engine_stress.hpp — what the stress tests of the 3D and the contour engine share:
// the control thread's random operations.
#pragma once

#include <chrono>
#include <cstddef>
#include <random>
#include <thread>
#include <vector>

#include <progiso/scheduler/engine.hpp>

namespace progiso::test {

/// One random control operation on an engine (3D or contour): an isovalue change (2 in 6),
/// a full run, an error run to `error_goal`, a cancel, or a deadline run of 0–3 ms; then a
/// pause of 0–1.2 ms. Returns whether the isovalue changed.
template <class Engine, class Rng>
bool random_control_step(Engine& e, Rng& rng, const std::vector<double>& isovalues,
                         double error_goal) {
  std::uniform_int_distribution<int> action(0, 5);
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
    case 3:
      e.start(refine_goal::error(error_goal));
      break;
    case 4:
      e.cancel();
      break;
    case 5:
      e.refine_for(std::chrono::milliseconds(ms(rng)));
      break;
  }
  std::this_thread::sleep_for(std::chrono::microseconds(ms(rng) * 400));
  return changed;
}

}  // namespace progiso::test
