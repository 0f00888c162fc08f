// progiso/core/base/detail/cut_index.hpp — the split diamonds of a cut by grid index, with their
// ranks in grid index order: what the 3D cut mesher numbers vertices by, and what the 2D
// extractions mark a cut's splits with.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <progiso/core/base/parallel_loop.hpp>

namespace progiso::detail {

/// Bits set in x. Without a popcnt instruction in the baseline, std::popcount is a call.
[[nodiscard]] constexpr unsigned bit_count(std::uint64_t x) noexcept {
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0FULL;
  return static_cast<unsigned>((x * 0x0101010101010101ULL) >> 56);
}

/// The split diamonds of a cut by grid index, with their ranks in grid index order. Dense: one
/// bit per grid vertex and the count of set bits before each 64-bit word (an eighth and a
/// sixteenth of a byte per vertex). Sparse: the sorted indices (binary search).
class cut_index {
 public:
  /// A dense index over `vertices` grid vertices, empty.
  static cut_index dense(std::uint64_t vertices) {
    cut_index c;
    c.dense_ = true;
    c.bits_.assign((vertices + 63) / 64, 0);
    return c;
  }
  /// A sparse index of these grid indices (any order; sorted here).
  static cut_index sparse(std::vector<std::uint64_t> indices) {
    cut_index c;
    std::sort(indices.begin(), indices.end());
    c.sorted_ = std::move(indices);
    c.size_ = c.sorted_.size();
    return c;
  }
  /// Dense only: adds grid index v, for one writer (before finish()).
  void add_on_one_thread(std::uint64_t v) noexcept {
    bits_[v >> 6] |= std::uint64_t{1} << (v & 63);
  }
  /// Dense only: adds grid index v. Safe from several threads at once (before finish()).
  void add(std::uint64_t v) noexcept {
    std::atomic_ref<std::uint64_t>(bits_[v >> 6])
        // relaxed: the parallel loop's join orders these writes before finish() and the reads.
        .fetch_or(std::uint64_t{1} << (v & 63), std::memory_order_relaxed);
  }
  /// Dense only: the counts per word, in `parts` pieces through `run`.
  void finish(const parallel_loop& run, std::size_t parts) {
    const std::size_t words = bits_.size();
    before_.resize(words);
    parts = std::clamp<std::size_t>(parts, 1, std::max<std::size_t>(words, 1));
    std::vector<std::uint64_t> sums(parts + 1, 0);
    const auto first = [&](std::size_t k) { return piece_begin(words, parts, k); };
    run_loop(run, parts, [&](std::size_t k) {
      std::uint64_t n = 0;
      for (std::size_t w = first(k); w < first(k + 1); ++w) n += bit_count(bits_[w]);
      sums[k + 1] = n;
    });
    for (std::size_t k = 0; k < parts; ++k) sums[k + 1] += sums[k];
    run_loop(run, parts, [&](std::size_t k) {
      std::uint64_t n = sums[k];
      for (std::size_t w = first(k); w < first(k + 1); ++w) {
        before_[w] = static_cast<std::uint32_t>(n);
        n += bit_count(bits_[w]);
      }
    });
    size_ = sums[parts];
  }
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  [[nodiscard]] bool contains(std::uint64_t v) const noexcept {
    if (dense_) return ((bits_[v >> 6] >> (v & 63)) & 1u) != 0;
    return std::binary_search(sorted_.begin(), sorted_.end(), v);
  }
  /// The rank of v, which the index contains.
  [[nodiscard]] std::uint32_t rank(std::uint64_t v) const noexcept {
    if (dense_) {
      const std::uint64_t below = (std::uint64_t{1} << (v & 63)) - 1;
      return before_[v >> 6] + bit_count(bits_[v >> 6] & below);
    }
    return static_cast<std::uint32_t>(std::lower_bound(sorted_.begin(), sorted_.end(), v) -
                                      sorted_.begin());
  }

  /// The grid indices of ranks first, first + 1, ... in turn, each next() one more; first must
  /// be below size(). What a pass over a range of ranks reads instead of keeping each split's
  /// grid point in an array by rank.
  class walk {
   public:
    walk(const cut_index& c, std::uint64_t first) noexcept : c_(&c) {
      if (!c.dense_) {
        at_ = first;
        return;
      }
      // The word holding rank `first`: the last whose count before it is at most `first`.
      const auto it =
          std::upper_bound(c.before_.begin(), c.before_.end(), static_cast<std::uint32_t>(first));
      at_ = static_cast<std::uint64_t>(it - c.before_.begin()) - 1;
      bits_ = c.bits_[at_];
      for (std::uint64_t skip = first - c.before_[at_]; skip != 0; --skip) bits_ &= bits_ - 1;
    }
    /// The next rank's grid index.
    [[nodiscard]] std::uint64_t next() noexcept {
      if (!c_->dense_) return c_->sorted_[at_++];
      while (bits_ == 0) bits_ = c_->bits_[++at_];
      const std::uint64_t v = at_ * 64 + static_cast<std::uint64_t>(std::countr_zero(bits_));
      bits_ &= bits_ - 1;
      return v;
    }

   private:
    const cut_index* c_;
    std::uint64_t at_ = 0;    // sparse: the next rank; dense: the word being read
    std::uint64_t bits_ = 0;  // dense: that word's bits not yet handed out
  };

 private:
  bool dense_ = false;
  std::vector<std::uint64_t> bits_;
  std::vector<std::uint32_t> before_;
  std::vector<std::uint64_t> sorted_;
  std::uint64_t size_ = 0;
};

}  // namespace progiso::detail
