// progiso/core/ranges/detail/range_entry.hpp — the stored form of a diamond's range, shared by the
// 3D and 2D range data.
//
// An entry keeps min and max in the sample type and the nested error as an unsigned integer of
// the same width (rounded up) or as float (rounded up) for floating-point samples, so a stored
// error is never below the true one and culling and nesting stay sound. An empty range is
// encoded as lo > hi.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <progiso/core/ranges/range_data.hpp>

namespace progiso::detail {

template <class T>
struct error_type_of {
  using type = std::make_unsigned_t<T>;
};
template <>
struct error_type_of<float> {
  using type = float;
};
template <>
struct error_type_of<double> {
  using type = float;
};
template <class T>
using error_type = typename error_type_of<T>::type;

template <class T>
struct range_entry {
  T lo;
  T hi;
  error_type<T> error;
};

/// Rounds e up into E (saturating).
template <class E>
E quantize_error(double e) noexcept {
  if constexpr (std::is_floating_point_v<E>) {
    if (e >= static_cast<double>(std::numeric_limits<float>::max())) {
      return std::numeric_limits<float>::infinity();
    }
    auto f = static_cast<float>(e);
    if (static_cast<double>(f) < e) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
  } else {
    // ceil(e), saturated. Not std::ceil: without SSE4.1 that is a library call, and this runs
    // once per stored diamond. e ≥ 0 (an absolute difference); NaN saturates.
    if (!(e < static_cast<double>(std::numeric_limits<E>::max()))) {
      return std::numeric_limits<E>::max();
    }
    auto c = static_cast<std::uint64_t>(e);
    if (static_cast<double>(c) < e) ++c;
    return static_cast<E>(c);
  }
}

template <class T>
range_entry<T> empty_entry() noexcept {
  return {std::numeric_limits<T>::max(), std::numeric_limits<T>::lowest(), error_type<T>{}};
}

template <class T>
diamond_range decode(const range_entry<T>& e) noexcept {
  diamond_range r;
  r.lo = static_cast<double>(e.lo);
  r.hi = static_cast<double>(e.hi);
  r.error = static_cast<double>(e.error);
  return r;
}

template <class T>
range_entry<T> encode(const diamond_range& r) noexcept {
  range_entry<T> e = empty_entry<T>();
  if (!r.empty()) {
    e.lo = static_cast<T>(r.lo);
    e.hi = static_cast<T>(r.hi);
  }
  e.error = quantize_error<error_type<T>>(r.error);
  return e;
}

/// into ← into ∪ r (ranges), max of errors.
inline void merge(diamond_range& into, const diamond_range& r) noexcept {
  into.error = std::max(into.error, r.error);
  if (r.empty()) return;
  if (into.empty()) {
    into.lo = r.lo;
    into.hi = r.hi;
    return;
  }
  into.lo = std::min(into.lo, r.lo);
  into.hi = std::max(into.hi, r.hi);
}

}  // namespace progiso::detail
