// progiso/core/field/detail/subdivision.hpp — the machinery behind a smoothed volume
// (smoothing.hpp): per-axis rows of the composed 4-point rule, lazy evaluation of fine samples, and
// the bound on their values over a box that the range data of a smoothed volume uses.
//
// Thread safety: immutable after construction except the evaluation counter (sharded relaxed
// counters, exact once readers have joined the threads that evaluated).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>

namespace progiso::detail {

/// One axis of the composed rule: fine sample x is Σ_k weights(x)[k] · data[first(x) + k ·
/// stride()], k < taps(x). Every data sample a row uses is a control sample (a multiple of 2^K),
/// so a row is a run of consecutive control samples (zero weights fill its gaps): with K = 0 a
/// fine sample reads short contiguous runs of the data.
class subdivision_axis {
 public:
  static constexpr std::size_t max_taps = 8;
  /// Rows for `n` data samples, `levels` = S, `from` = K, mask parameter `alpha`.
  subdivision_axis(std::int64_t n, int levels, int from, double alpha);

  [[nodiscard]] std::int64_t size() const noexcept {
    return static_cast<std::int64_t>(taps_.size());
  }
  [[nodiscard]] unsigned taps(std::int64_t x) const noexcept {
    return taps_[static_cast<std::size_t>(x)];
  }
  [[nodiscard]] const double* weights(std::int64_t x) const noexcept {
    return &weights_[static_cast<std::size_t>(x) * max_taps];
  }
  /// Data index of tap 0 of row x.
  [[nodiscard]] std::int32_t first(std::int64_t x) const noexcept {
    return first_[static_cast<std::size_t>(x)];
  }
  /// Data indices between taps: 2^K.
  [[nodiscard]] std::int32_t stride() const noexcept { return stride_; }
  /// Whether row x used no ghost sample (its stencils stayed inside the axis at every level).
  [[nodiscard]] bool ghost_free(std::int64_t x) const noexcept {
    return ghost_free_[static_cast<std::size_t>(x)] != 0;
  }
  /// Data samples the rows of [x0, x1] can reach: [reach_lo(x0), reach_hi(x1)] (a superset,
  /// monotone in both ends, so nested for nested intervals).
  [[nodiscard]] std::int32_t reach_lo(std::int64_t x0) const noexcept {
    return reach_lo_[static_cast<std::size_t>(x0)];
  }
  [[nodiscard]] std::int32_t reach_hi(std::int64_t x1) const noexcept {
    return reach_hi_[static_cast<std::size_t>(x1)];
  }
  /// The largest Σ|w| over the rows.
  [[nodiscard]] double max_abs_sum() const noexcept { return max_abs_sum_; }
  [[nodiscard]] std::size_t byte_size() const noexcept;

 private:
  std::vector<std::int32_t> first_;
  std::vector<std::uint8_t> taps_;
  std::vector<double> weights_;
  std::vector<std::uint8_t> ghost_free_;
  std::vector<std::int32_t> reach_lo_;
  std::vector<std::int32_t> reach_hi_;
  double max_abs_sum_ = 1.0;
  std::int32_t stride_ = 1;
};

class subdivision {
 public:
  subdivision(std::shared_ptr<const volume> data, const smoothing& s);
  subdivision(const subdivision&) = delete;
  subdivision& operator=(const subdivision&) = delete;

  [[nodiscard]] const volume& data() const noexcept { return *data_; }
  [[nodiscard]] const smoothing& spec() const noexcept { return spec_; }
  /// Samples per axis of the fine grid: (n − 1)·2^S + 1.
  [[nodiscard]] const index3& dims() const noexcept { return dims_; }

  /// The fine sample at (x, y, z), each inside the fine grid.
  [[nodiscard]] double at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept;
  /// The fine sample at a linear index (x fastest), through the calling thread's sample cache.
  [[nodiscard]] double at(std::size_t linear) const noexcept;
  /// Whether (x, y, z) takes the rule (inside the region, or everywhere without one).
  [[nodiscard]] bool smoothed_at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept;
  /// Whether no ghost sample entered the fine sample at (x, y, z).
  [[nodiscard]] bool ghost_free(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept;
  /// The data samples that the fine samples of the box [b0, b1] (inclusive, inside the fine
  /// grid) are made from: a box of data indices holding every sample their rows reach, and
  /// whether any of them takes the rule (then their values may overshoot the data's range there
  /// by overshoot() times its width). Nested: a box inside another gets a box inside the
  /// other's, and smoothed only if the other's is.
  struct reach_box {
    index3 lo{};
    index3 hi{};
    bool smoothed = false;
  };
  [[nodiscard]] reach_box reach(const ipoint& b0, const ipoint& b1) const noexcept;
  /// λ: every fine sample lies within [m − λ(M − m), M + λ(M − m)], m and M the data's min and
  /// max over the samples its rows reach; λ = (Π_q L_q − 1) / 2 for the rule, 0 outside the
  /// region (linear interpolation has no negative weights).
  [[nodiscard]] double overshoot() const noexcept { return lambda_; }
  /// Fine samples computed so far (each computation counts; a read the cache answers does not).
  [[nodiscard]] std::uint64_t evaluations() const noexcept;
  /// Bytes held beside the data: the rows.
  [[nodiscard]] std::size_t byte_size() const noexcept;

 private:
  template <unsigned TX, class T>
  double evaluate(const T* f, const std::array<const subdivision_axis*, 3>& axes,
                  const index3& p) const noexcept;
  template <class T>
  double evaluate(const T* f, const std::array<const subdivision_axis*, 3>& axes,
                  const index3& p) const noexcept;
  void count() const noexcept;
  // The fine sample at (x, y, z), computed from the data (at() looks in the cache first).
  [[nodiscard]] double compute(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept;

  std::shared_ptr<const volume> data_;
  std::uint64_t id_;  // unique per subdivision in this process: the sample caches' key
  smoothing spec_;
  index3 dims_{};
  std::array<subdivision_axis, 3> smooth_;   // the rule (K, S, α)
  std::array<subdivision_axis, 3> linear_;   // outside the region: K = 0, α = 0
  std::array<std::int64_t, 3> region_lo_{};  // fine coordinates, inclusive
  std::array<std::int64_t, 3> region_hi_{};
  double lambda_ = 0.0;
  // Evaluation counts: shard k < 63 is written by one thread only (the k-th thread that ever
  // counted, see count()), the last one by all later threads.
  struct alignas(64) shard {
    std::atomic<std::uint64_t> n{0};
  };
  mutable std::array<shard, 64> evaluations_{};
};

/// Min and max of a data volume over boxes of samples: level k holds bricks of (4 << k)³
/// samples; a box takes the merge of the bricks that meet it at the finest level where it spans
/// at most 3 bricks per axis (at most 27 reads). Nested: a box inside another is answered from
/// bricks inside the other's (its level is no coarser, and each brick lies in one brick of
/// every coarser level). Built in one pass, in slabs of 4 planes through `run`.
class data_pyramid {
 public:
  data_pyramid(const volume& data, const parallel_loop& run);
  /// Staged: nothing built yet; build_slabs() over [0, slab_count()), then finish().
  explicit data_pyramid(const volume& data);
  [[nodiscard]] std::size_t slab_count() const noexcept;
  /// Bricks of slabs [first, last) (4 planes of data each; slabs write disjoint bricks, so
  /// different slabs may be built at the same time), through `run`.
  void build_slabs(std::size_t first, std::size_t last, const parallel_loop& run);
  /// The coarser levels, once every slab is built.
  void finish();
  /// [min, max] of a superset of the samples in [d0, d1] (inclusive, inside the data).
  [[nodiscard]] std::array<double, 2> range(const index3& d0, const index3& d1) const noexcept;
  [[nodiscard]] std::size_t byte_size() const noexcept;

 private:
  struct level {
    index3 n{};  // bricks per axis
    std::vector<double> lo;
    std::vector<double> hi;
    [[nodiscard]] std::size_t at(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
      return static_cast<std::size_t>(x + n[0] * (y + n[1] * z));
    }
  };
  const volume* data_ = nullptr;
  std::vector<level> levels_;
};

/// The nested range of a diamond of a smoothed volume whose subtree lies in the box [b0, b1]
/// (inclusive, inside its grid): the data's min and max over what the fine samples' rows reach,
/// widened by the overshoot bound where the box meets the smoothed region; error hi − lo (every
/// split error between values in [lo, hi] is at most that). Nested for nested boxes.
[[nodiscard]] diamond_range subdivided_range(const subdivision& sub, const data_pyramid& data,
                                             const ipoint& b0, const ipoint& b1) noexcept;

/// Samples of a smoothed volume seen like a typed array: s[i] is the fine sample at linear
/// index base + i, and s + k shifts the base (the split code reads data through either).
struct lazy_samples {
  const subdivision* sub;
  std::int64_t base;
  double operator[](std::int64_t i) const noexcept {
    return sub->at(static_cast<std::size_t>(base + i));
  }
  lazy_samples operator+(std::int64_t k) const noexcept { return {sub, base + k}; }
};

/// f(samples) with the volume's typed sample pointer, or lazy_samples for a smoothed volume.
template <class F>
decltype(auto) visit_field(const volume& v, F&& f) {
  if (const subdivision* s = v.subdivided(); s != nullptr) return f(lazy_samples{s, 0});
  return v.visit_samples(f);
}

}  // namespace progiso::detail
