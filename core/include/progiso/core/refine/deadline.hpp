// progiso/core/refine/deadline.hpp — deadlines from time budgets, without overflow.
//
// A time budget given as a double (seconds, or milliseconds from a command line) can be far
// larger than steady_clock can represent from now: 9.3e12 ms is about 295 years, past the
// 292 years of a signed 64-bit nanosecond count. Converting it with duration_cast overflows
// (undefined behaviour; in practice a deadline in the past, so a "budget" of centuries gives
// the coarsest surface). deadline_after() saturates instead: a budget that cannot be reached
// before the clock's end is no deadline at all, which is the honest meaning of such a budget.
#pragma once

#include <chrono>
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

}  // namespace progiso
