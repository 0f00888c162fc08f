// progiso/core/refine/deadline.hpp — deadlines from time budgets, without overflow.
//
// A time budget given as a double (seconds, or milliseconds from a command line) can be far
// larger than steady_clock can represent from now: 9.3e12 ms is about 295 years, past the
// 292 years of a signed 64-bit nanosecond count. Converting it with duration_cast overflows
// (undefined behaviour; in practice a deadline in the past, so a "budget" of centuries gives
// the coarsest surface). deadline_after() saturates instead: a budget that cannot be reached
// before the clock's end is no deadline at all, which is the honest meaning of such a budget.
#pragma once

#include <algorithm>
#include <chrono>
#include <optional>
#include <type_traits>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

/// start + budget, or time_point::max() when that is not representable (or budget is +inf).
/// A negative or NaN budget gives `start`. Cost: a few floating-point operations.
[[nodiscard]] inline std::chrono::steady_clock::time_point deadline_after(
    std::chrono::steady_clock::time_point start, std::chrono::duration<double> budget) noexcept {
  using clock = std::chrono::steady_clock;
  if (!(budget.count() > 0.0)) return start;
  const double room = std::chrono::duration<double>(clock::time_point::max() - start).count();
  // Compare in doubles, with a margin for rounding at the clock's end.
  if (!(budget.count() < room * 0.999)) return clock::time_point::max();
  return start + std::chrono::duration_cast<clock::duration>(budget);
}

/// start + budget for an integral duration (std::chrono::milliseconds …), saturating at
/// time_point::max().
template <class Rep, class Period>
requires std::is_integral_v<Rep>
[[nodiscard]] std::chrono::steady_clock::time_point deadline_after(
    std::chrono::steady_clock::time_point start,
    std::chrono::duration<Rep, Period> budget) noexcept {
  using clock = std::chrono::steady_clock;
  if (budget <= budget.zero()) return start;
  const double room = std::chrono::duration<double>(clock::time_point::max() - start).count();
  if (!(std::chrono::duration<double>(budget).count() < room * 0.999)) {
    return clock::time_point::max();
  }
  return start + std::chrono::duration_cast<clock::duration>(budget);
}

namespace detail {

/// The build's share of a deadline run's next step while the range data is incomplete (the
/// engine alternates slices of the build with slices of refinement without culling).
struct deadline_build_step {
  bool to_the_end;  ///< build what is left now, then refine culled
  double seconds;   ///< the most this step may build
};

/// `estimate`: seconds the pieces left are expected to take, from the pieces built so far
/// (nothing when none is built yet); `left`: seconds to the deadline; `slice`: the alternation's
/// current slice. The build goes to the end when its estimate, with a quarter more for error,
/// fits in the time left, and then stops at nine tenths of it whatever it has done, so that
/// refinement always keeps time; otherwise the step builds for one slice, at most half the time
/// left. Committing pays whenever the build ends with time to spare, since culled refinement
/// buys several times the surface per millisecond of unculled refinement; but a build that runs
/// into the deadline leaves the root surface alone: with the estimate alone (no margin, no cap)
/// a short deadline on one thread bought a small fraction of the surface that two threads,
/// which never committed, bought (bench/README.md).
[[nodiscard]] inline deadline_build_step plan_deadline_build(std::optional<double> estimate,
                                                             double left, double slice) noexcept {
  left = std::max(left, 0.0);
  if (estimate && 1.25 * *estimate <= left) return {true, 0.9 * left};
  return {false, std::min(slice, 0.5 * left)};
}

}  // namespace detail

}  // namespace progiso
