#include <progiso/core/field/volume.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <string>
#include <type_traits>
#include <vector>

#include <progiso/core/base/error.hpp>

namespace progiso {

std::size_t sample_size(sample_type type) noexcept {
  switch (type) {
    case sample_type::u8:
    case sample_type::i8:
      return 1;
    case sample_type::u16:
    case sample_type::i16:
      return 2;
    case sample_type::u32:
    case sample_type::i32:
    case sample_type::f32:
      return 4;
    case sample_type::f64:
      return 8;
  }
  return 1;
}

std::string_view to_string(sample_type type) noexcept {
  switch (type) {
    case sample_type::u8:
      return "u8";
    case sample_type::i8:
      return "i8";
    case sample_type::u16:
      return "u16";
    case sample_type::i16:
      return "i16";
    case sample_type::u32:
      return "u32";
    case sample_type::i32:
      return "i32";
    case sample_type::f32:
      return "f32";
    case sample_type::f64:
      return "f64";
  }
  return "?";
}

std::optional<sample_type> parse_sample_type(std::string_view name) noexcept {
  for (auto t : {sample_type::u8, sample_type::i8, sample_type::u16, sample_type::i16,
                 sample_type::u32, sample_type::i32, sample_type::f32, sample_type::f64}) {
    if (name == to_string(t)) return t;
  }
  return std::nullopt;
}

volume::volume(index3 dims, sample_type type, std::vector<std::byte> samples,
               std::array<double, 3> spacing, std::array<double, 3> origin)
    : dims_(dims), type_(type), spacing_(spacing), origin_(origin) {
  auto owned = std::make_shared<const std::vector<std::byte>>(std::move(samples));
  data_ = owned->data();
  size_ = owned->size();
  keeper_ = std::move(owned);
  check_layout();
  scan_samples();
}

volume::volume(index3 dims, sample_type type, std::shared_ptr<const void> keeper,
               const std::byte* data, std::size_t size, bool borrowed,
               std::array<double, 3> spacing, std::array<double, 3> origin)
    : dims_(dims),
      type_(type),
      keeper_(std::move(keeper)),
      data_(data),
      size_(size),
      borrowed_(borrowed),
      spacing_(spacing),
      origin_(origin) {}

volume volume::borrow(index3 dims, sample_type type, std::span<const std::byte> samples,
                      std::shared_ptr<const void> keeper, std::array<double, 3> spacing,
                      std::array<double, 3> origin, const parallel_loop& run) {
  volume v(dims, type, std::move(keeper), samples.data(), samples.size(), true, spacing, origin);
  v.check_layout();
  if (type == sample_type::f32 || type == sample_type::f64) {
    v.scan_samples(run);
  } else {
    v.deferred_ = std::make_shared<deferred_range>();
  }
  return v;
}

volume volume::borrow_unscanned(index3 dims, sample_type type, std::span<const std::byte> samples,
                                std::shared_ptr<const void> keeper, std::array<double, 3> spacing,
                                std::array<double, 3> origin, std::array<double, 2> range) {
  volume v(dims, type, std::move(keeper), samples.data(), samples.size(), true, spacing, origin);
  v.check_layout();
  v.range_ = range;
  return v;
}

void volume::check_layout() const {
  for (std::size_t a = 0; a < 3; ++a) {
    // x and y need two samples; z may be 1 (a 2D image is a volume one sample thick).
    if (dims_[a] < (a == 2 ? 1 : 2)) {
      throw error("volume: dims must be at least 2,2,1, found " + std::to_string(dims_[0]) + "," +
                  std::to_string(dims_[1]) + "," + std::to_string(dims_[2]));
    }
    if (dims_[a] > (std::int64_t{1} << 15) + 1) {
      throw error("volume: dims above 32769 per axis are not supported, found " +
                  std::to_string(dims_[a]));
    }
    if (!(std::isfinite(spacing_[a]) && spacing_[a] > 0.0)) {
      throw error("volume: spacing must be finite and positive, found " +
                  std::to_string(spacing_[a]));
    }
    if (!std::isfinite(origin_[a])) throw error("volume: origin must be finite");
    // Every written coordinate (origin + index × spacing) must be a finite double.
    const double far = std::fabs(origin_[a]) + static_cast<double>(dims_[a] - 1) * spacing_[a];
    if (!std::isfinite(far)) {
      throw error("volume: origin + (dims - 1) × spacing overflows on axis " + std::to_string(a) +
                  " (spacing " + std::to_string(spacing_[a]) + ", " + std::to_string(dims_[a]) +
                  " samples)");
    }
  }
  const std::size_t expected = voxel_count() * sample_size(type_);
  if (size_ != expected) {
    throw error("volume: expected " + std::to_string(expected) + " bytes of samples, found " +
                std::to_string(size_));
  }
  if (data_ == nullptr) throw error("volume: expected samples, found a null pointer");
}

namespace {

#if defined(__SSE2__)
// SSE2 operations on four floats or two doubles, for simd_range().
struct sse_floats {
  using T = float;
  using V = __m128;
  static constexpr std::size_t lanes = 4;
  static V load(const T* p) { return _mm_loadu_ps(p); }
  static V min(V a, V b) { return _mm_min_ps(a, b); }
  static V max(V a, V b) { return _mm_max_ps(a, b); }
  static V unordered_diff(V a) {  // all ones where a − a is NaN: a is NaN or infinite
    const V d = _mm_sub_ps(a, a);
    return _mm_cmpunord_ps(d, d);
  }
  static V bit_or(V a, V b) { return _mm_or_ps(a, b); }
  static bool any(V a) { return _mm_movemask_ps(a) != 0; }
  static void store(T* p, V a) { _mm_storeu_ps(p, a); }
};
struct sse_doubles {
  using T = double;
  using V = __m128d;
  static constexpr std::size_t lanes = 2;
  static V load(const T* p) { return _mm_loadu_pd(p); }
  static V min(V a, V b) { return _mm_min_pd(a, b); }
  static V max(V a, V b) { return _mm_max_pd(a, b); }
  static V unordered_diff(V a) {
    const V d = _mm_sub_pd(a, a);
    return _mm_cmpunord_pd(d, d);
  }
  static V bit_or(V a, V b) { return _mm_or_pd(a, b); }
  static bool any(V a) { return _mm_movemask_pd(a) != 0; }
  static void store(T* p, V a) { _mm_storeu_pd(p, a); }
};

// The floating-point part of block_range(): whole steps of four vectors from s + i on, four
// accumulators deep (a min or max waits for the one before it in its chain); advances i.
template <class Ops>
bool simd_range(const typename Ops::T* s, std::size_t& i, std::size_t e, typename Ops::T& lo,
                typename Ops::T& hi) {
  using V = typename Ops::V;
  constexpr std::size_t step = 4 * Ops::lanes;
  if (e - i < step) return false;
  V l[4];
  V h[4];
  V nan[4];
  for (std::size_t k = 0; k < 4; ++k) {
    l[k] = h[k] = Ops::load(s + i);
    nan[k] = Ops::unordered_diff(l[k]);
  }
  for (; i + step <= e; i += step) {
    for (std::size_t k = 0; k < 4; ++k) {
      const V v = Ops::load(s + i + k * Ops::lanes);
      l[k] = Ops::min(l[k], v);
      h[k] = Ops::max(h[k], v);
      nan[k] = Ops::bit_or(nan[k], Ops::unordered_diff(v));
    }
  }
  typename Ops::T out[Ops::lanes];
  for (std::size_t k = 0; k < 4; ++k) {
    Ops::store(out, l[k]);
    for (const auto x : out) lo = x < lo ? x : lo;
    Ops::store(out, h[k]);
    for (const auto x : out) hi = x > hi ? x : hi;
  }
  return Ops::any(Ops::bit_or(Ops::bit_or(nan[0], nan[1]), Ops::bit_or(nan[2], nan[3])));
}
#endif

// The smallest and largest of s[b, e) into lo, hi, and whether one of them is not finite
// (NaN or infinite: v − v is NaN exactly then). Integer loops vectorise as written; floating
// ones would not (a compare-and-select is not a min without -ffinite-math-only), so on x86-64
// they take SSE2's min and max (simd_range()), and read at about memory speed.
template <class T>
bool block_range(const T* s, std::size_t b, std::size_t e, T& lo, T& hi) {
  std::size_t i = b;
  bool bad = false;
#if defined(__SSE2__)
  if constexpr (std::is_same_v<T, float>) {
    bad = simd_range<sse_floats>(s, i, e, lo, hi);
  } else if constexpr (std::is_same_v<T, double>) {
    bad = simd_range<sse_doubles>(s, i, e, lo, hi);
  }
#endif
  unsigned flag = 0;
  for (; i < e; ++i) {
    const T v = s[i];
    lo = v < lo ? v : lo;
    hi = v > hi ? v : hi;
    if constexpr (std::is_floating_point_v<T>) flag |= static_cast<unsigned>(!(v - v == T{0}));
  }
  return bad || flag != 0;
}

// The first of `items` items in piece k of `parts` near-equal pieces.
std::size_t piece_of(std::size_t items, std::size_t parts, std::size_t k) noexcept {
  return k * (items / parts) + std::min(k, items % parts);
}

// The smallest and largest sample, and the first non-finite one (n when none), block by block;
// only a block holding a non-finite sample is searched again for its first one.
template <class T>
std::array<double, 2> sample_range(const T* s, std::size_t n, std::size_t& non_finite) {
  constexpr std::size_t block = 16384;
  non_finite = n;
  T lo = s[0];
  T hi = s[0];
  for (std::size_t b = 0; b < n; b += block) {
    const std::size_t e = std::min(n, b + block);
    if (block_range(s, b, e, lo, hi)) {
      for (std::size_t i = b; i < e; ++i) {
        if (!(s[i] - s[i] == T{0})) {
          non_finite = i;
          return {0.0, 0.0};
        }
      }
    }
  }
  return {static_cast<double>(lo), static_cast<double>(hi)};
}

}  // namespace

void volume::scan_samples(const parallel_loop& run) {
  const std::size_t n = voxel_count();
  std::size_t non_finite = n;
  if (!run) {
    range_ = visit_samples([&](const auto* s) { return sample_range(s, n, non_finite); });
  } else {
    // Pieces of about 4 M samples; the range the extremes of theirs, the first non-finite
    // sample the first of theirs.
    const std::size_t parts = std::max<std::size_t>(1, n >> 22);
    std::vector<std::array<double, 2>> ranges(parts);
    std::vector<std::size_t> firsts(parts, n);
    visit_samples([&](const auto* s) {
      run(parts, [&](std::size_t k) {
        const std::size_t b = piece_of(n, parts, k), e = piece_of(n, parts, k + 1);
        std::size_t first = e - b;
        ranges[k] = sample_range(s + b, e - b, first);
        if (first != e - b) firsts[k] = b + first;
      });
    });
    range_ = ranges[0];
    for (std::size_t k = 0; k < parts; ++k) {
      range_[0] = std::min(range_[0], ranges[k][0]);
      range_[1] = std::max(range_[1], ranges[k][1]);
      non_finite = std::min(non_finite, firsts[k]);
    }
  }
  if (non_finite != voxel_count()) {
    const auto i = static_cast<std::int64_t>(non_finite);
    const std::int64_t x = i % dims_[0];
    const std::int64_t y = (i / dims_[0]) % dims_[1];
    const std::int64_t z = i / (dims_[0] * dims_[1]);
    throw error("volume: expected finite samples, found " + std::to_string(at(non_finite)) +
                " at sample " + std::to_string(non_finite) + " (x " + std::to_string(x) + ", y " +
                std::to_string(y) + ", z " + std::to_string(z) + ")");
  }
}

std::array<double, 2> volume::value_range() const noexcept {
  if (deferred_ == nullptr) return range_;
  std::call_once(deferred_->once, [this] {
    std::size_t unused = 0;
    deferred_->range =
        visit_samples([&](const auto* s) { return sample_range(s, voxel_count(), unused); });
  });
  return deferred_->range;
}

}  // namespace progiso
