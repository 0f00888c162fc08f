// progiso/core/refine/goal.hpp — what a run refines towards: the one vocabulary of goals.
//
// Every entry that refines takes a refine_goal: the one-shot calls (extract_isosurface(),
// extract_contours() through their options' `goal`), both engines (scheduler::engine and
// scheduler::contour_engine: start(goal), refine(goal)) and the command (--full, --error,
// --max-triangles / --max-segments, --time-ms). The paper's scenarios map onto it: quality
// driven is kind::error, time critical kind::deadline; asynchronous interruption and dynamic
// isovalues are the engines' cancel() and set_isovalue() during a run towards any goal.
//
// Adding a goal: an enumerator here, its factory, a check in check_goal(), and one case in each
// strategy that switches on `kind` (docs/ARCHITECTURE.md, "Where to change what").
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>

namespace progiso {

struct refine_goal {
  enum class kind {
    full,      ///< split every diamond whose range holds the isovalue: the finest cut
    error,     ///< split until every split left would change the surface by at most max_error
    budget,    ///< as many splits, largest error first, as keep max_elements (triangles in 3D,
               ///< segments in 2D)
    deadline,  ///< split largest error first until the clock reaches `deadline`
  };
  kind what = kind::full;
  double max_error = 0.0;                            ///< kind::error: non-negative
  std::uint64_t max_elements = 0;                    ///< kind::budget
  std::chrono::steady_clock::time_point deadline{};  ///< kind::deadline
  /// kind::error only: split the diamonds of error > max_error by grid plane, as a full run
  /// splits every straddling one, instead of largest error first. An error target fixes its
  /// split set, so the cut it ends on is the same either way; in any order it comes sooner
  /// because no priority queue orders the work, but the cuts published on the way are refined
  /// plane by plane, not the best of their size: for a caller that waits for the goal (a
  /// one-shot extraction), not for one that shows or interrupts the run. The 2D entries take
  /// their targets by priority either way.
  bool any_order = false;

  static refine_goal full() { return {}; }
  static refine_goal error(double e) { return {kind::error, e, 0, {}, false}; }
  static refine_goal error_in_any_order(double e) { return {kind::error, e, 0, {}, true}; }
  /// A budget of k triangles (3D) …
  static refine_goal triangles(std::uint64_t k) { return {kind::budget, 0.0, k, {}, false}; }
  /// … or of k segments (2D): the same goal, named for the element counted.
  static refine_goal segments(std::uint64_t k) { return triangles(k); }
  static refine_goal until(std::chrono::steady_clock::time_point t) {
    return {kind::deadline, 0.0, 0, t, false};
  }
  /// A deadline `budget` from now; a budget past the clock's range is no deadline at all
  /// (deadline_after() saturates).
  static refine_goal within(std::chrono::duration<double> budget) {
    return until(deadline_after(std::chrono::steady_clock::now(), budget));
  }
};

/// Throws progiso::error for a goal no run can take: an error target that is negative or NaN.
inline void check_goal(const refine_goal& goal) {
  if (goal.what == refine_goal::kind::error && !(goal.max_error >= 0.0)) {
    throw error("error threshold: expected a non-negative number, found " +
                std::to_string(goal.max_error));
  }
}

}  // namespace progiso
