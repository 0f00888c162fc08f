// progiso/core/refine/detail/readiness.hpp — the readiness rule of a diamond whose parents are
// all split, shared by the sequential refiner and the engine, so that both keep and cull the
// same diamonds with the same errors.
#pragma once

#include <cstdint>
#include <limits>

#include <progiso/core/field/detail/sample_threshold.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>

namespace progiso::detail {

/// Whether a ready diamond is kept (its range straddles the isovalue) and, when the order needs
/// it, its nested error (NaN otherwise).
struct readiness {
  bool keep;
  double error;
};

/// The diamond centred at c with scale h, whose parents are all split. An owner of a piece of its
/// parents' surface straddles w unless its range is empty (wholly in the padding): no sample is
/// read to keep it, and for the error only the samples of its splits (range_data::error()).
/// Others take the straddle test, which stops at the first samples on both sides, or, when the
/// error is needed, the range and error in one pass.
///
/// With a finite `error_bound` (a run to an error target in any order, which only asks whether
/// the error exceeds it) the error is exact when at most the bound and otherwise some value above
/// it (range_data::test_upto(), error_upto(): fewer samples and bricks read).
[[nodiscard]] inline readiness ready_rule(
    const range_data& rd, const ipoint& c, std::int32_t h, bool owns_surface, bool errors_needed,
    double isovalue, const sample_threshold& threshold,
    double error_bound = std::numeric_limits<double>::infinity()) noexcept {
  constexpr double unknown = std::numeric_limits<double>::quiet_NaN();
  const bool bounded = error_bound < std::numeric_limits<double>::infinity();
  if (owns_surface) {
    if (rd.empty(c, h)) return {false, unknown};
    if (!errors_needed) return {true, unknown};
    return {true, bounded ? rd.error_upto(c, h, error_bound) : rd.error(c, h)};
  }
  if (!errors_needed) return {rd.straddles(c, h, threshold), unknown};
  if (bounded) {
    const straddle_and_error t = rd.test_upto(c, h, error_bound, threshold);
    return {t.straddles, t.error};
  }
  const diamond_range r = rd.get(c, h);
  return {r.straddles(isovalue), r.error};
}

}  // namespace progiso::detail
