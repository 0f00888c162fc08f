// progiso/core/field/detail/sample_threshold.hpp — the colour test "sample > w" for typed samples.
//
// Integer samples are compared with floor(w) as integers: s > w exactly when s > floor(w), with
// no conversion per sample. Floating-point samples are compared as doubles (NaN is never above).
// Shared by the table splits (split_record.cpp) and the range data's straddle test, which must
// agree with each other and with the colours of marching (value > w).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>

namespace progiso::detail {

struct sample_threshold {
  double w;
  std::int64_t floor_w;

  explicit sample_threshold(double isovalue) noexcept
      // floor(w) within ±2^62: beyond that no integer sample type reaches, and the order of
      // every sample against it is the same as against w. A NaN (which callers refuse, some
      // after making a threshold) takes 0 rather than an undefined conversion.
      : w(isovalue),
        floor_w(std::isnan(isovalue)
                    ? 0
                    : static_cast<std::int64_t>(std::floor(std::clamp(
                          isovalue, -4.611686018427387904e18, 4.611686018427387904e18)))) {}

  template <class T>
  [[nodiscard]] bool above(T v) const noexcept {
    if constexpr (std::is_integral_v<T>) {
      return static_cast<std::int64_t>(v) > floor_w;
    } else {
      return static_cast<double>(v) > w;
    }
  }
};

}  // namespace progiso::detail
