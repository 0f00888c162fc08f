// progiso/core/refine/detail/ready_queue.hpp — the queue of diamonds ready to split, shared by the
// 3D refiner, the 2D contour refiner and the engine.
//
// Three disciplines: first in first out (breadth first: coarse to fine), last in first out (depth
// first: the working set stays local), and largest error first for quality-, budget- and
// time-driven refinement. Item needs a member `error`. Not thread-safe.
//
// Largest error first is kept in buckets, not a heap: a bucket holds a quarter of an octave of
// errors (error_bucket below: [1, 1.25), [1.25, 1.5), … times a power of two), buckets are taken
// largest first, and a bucket's items last in first out. A child's nested error is at most its
// parent's, so the children of a split mostly land in the bucket being taken and are split next,
// while their samples and per-vertex entries are still in cache: the order of a depth-first
// refinement inside each band of errors. A binary heap spent a large share of an error-driven
// refinement's time in its sift-down (its deep levels are cache misses) and sent every split to a
// random place in the grid (bench/README.md).
//
// An error target is exact all the same: aim_at(ε) ranks every item of error > ε above every
// other, so `while (top().error > ε) pop-and-split` reaches exactly the diamonds of error > ε.
//
// The items a bucket held when it became the top are its cold ones (top_is_cold, cold_ahead):
// pushed while larger errors were taken, they lie anywhere in the grid, and they are taken in a
// fixed order (the bucket's vector from its end) after whatever is pushed meanwhile, so a
// refinement can ask for a cold item's data a few cold items ahead.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <iterator>
#include <limits>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>

namespace progiso::detail {

enum class queue_discipline { fifo, lifo, largest_error };

/// Mantissa bits of an error key that choose its bucket: 2, four buckets per octave. Coarser
/// buckets keep more children in their parent's bucket and so split somewhat faster (one per
/// octave, say), but order worse, and what a deadline buys falls by much more than the speed
/// gains (bench/README.md).
inline constexpr int error_bucket_bits = 2;
/// The widest and narrowest bucket, as the ratio of its bounds: [1, 1 + 2^-b) and [2 − 2^-b, 2)
/// times a power of two.
inline constexpr double error_bucket_widest = 1.0 + 1.0 / (1 << error_bucket_bits);
inline constexpr double error_bucket_narrowest = 2.0 / (2.0 - 1.0 / (1 << error_bucket_bits));

/// The bucket of an error key: monotone (a larger key never gets a smaller bucket), 0 for keys
/// ≤ 0, the largest for +inf and NaN (an unknown error is taken first).
[[nodiscard]] inline std::uint32_t error_bucket(double e) noexcept {
  if (std::isnan(e)) return (std::uint32_t{0x7ff} << error_bucket_bits) + 2;
  if (!(e > 0.0)) return 0;
  // A positive double's bits order as its value: exponent, then mantissa.
  return static_cast<std::uint32_t>(std::bit_cast<std::uint64_t>(e) >> (52 - error_bucket_bits)) +
         1;
}

/// The errors of bucket b ≥ 1: [first, second).
[[nodiscard]] inline std::pair<double, double> error_bucket_bounds(std::uint32_t b) noexcept {
  const auto at = [](std::uint64_t k) {
    return std::bit_cast<double>(k << (52 - error_bucket_bits));
  };
  return {at(b - 1), at(b)};
}

template <class Item>
class ready_queue {
 public:
  explicit ready_queue(queue_discipline d = queue_discipline::largest_error) : discipline_(d) {}

  /// Room for n items before the first reallocation (last in first out; the others grow by
  /// blocks or buckets).
  void reserve(std::size_t n) {
    if (discipline_ == queue_discipline::lifo) items_.reserve(n);
  }
  [[nodiscard]] bool empty() const noexcept { return size() == 0; }
  [[nodiscard]] std::size_t size() const noexcept {
    switch (discipline_) {
      case queue_discipline::fifo:
        return fifo_.size();
      case queue_discipline::lifo:
        return items_.size();
      case queue_discipline::largest_error:
        break;
    }
    return count_;
  }
  [[nodiscard]] queue_discipline discipline() const noexcept { return discipline_; }
  /// Changes the discipline, keeping the items (O(n)). Largest error first hands its items on
  /// smallest bucket first, so last in first out then starts with the largest.
  void set_discipline(queue_discipline d) {
    if (d == discipline_) return;
    std::vector<Item> all = take_all();
    discipline_ = d;
    put_all(std::move(all));
  }
  /// Largest error first: every item of error > max_error is taken before any other, whatever
  /// their buckets (O(n) when the target moves; NaN counts as above).
  void aim_at(double max_error) {
    if (max_error == target_ || (std::isnan(max_error) && std::isnan(target_))) return;
    if (discipline_ != queue_discipline::largest_error) {
      target_ = max_error;
      return;
    }
    std::vector<Item> all = take_all();
    target_ = max_error;
    put_all(std::move(all));
  }
  [[nodiscard]] const Item& top() const noexcept {
    switch (discipline_) {
      case queue_discipline::fifo:
        return fifo_.front();
      case queue_discipline::lifo:
        return items_.back();
      case queue_discipline::largest_error:
        break;
    }
    return buckets_.back().items.back();
  }
  /// The item k places after top(), or nullptr when it is not known without popping (largest
  /// error first looks in the top bucket only). For prefetching.
  [[nodiscard]] const Item* peek(std::size_t k) const noexcept {
    switch (discipline_) {
      case queue_discipline::fifo:
        return k < fifo_.size() ? &fifo_[k] : nullptr;
      case queue_discipline::lifo:
        return k < size() ? &items_[items_.size() - 1 - k] : nullptr;
      case queue_discipline::largest_error:
        break;
    }
    if (buckets_.empty()) return nullptr;
    const std::vector<Item>& top = buckets_.back().items;
    return k < top.size() ? &top[top.size() - 1 - k] : nullptr;
  }
  /// Largest error first: whether top() was already in its bucket when the bucket became the
  /// top one (a cold item: pushed long ago, anywhere in the grid), not pushed since (the last
  /// splits' children, which a depth-first order takes while their data is in cache).
  [[nodiscard]] bool top_is_cold() const noexcept {
    return discipline_ == queue_discipline::largest_error && !buckets_.empty() &&
           buckets_.back().items.size() == cold_;
  }
  /// Largest error first: the cold item that is taken after k more cold items (k = 0: the next
  /// one), or nullptr. Items pushed meanwhile are taken first, but never change which cold item
  /// comes next: for requesting a cold item's data a few cold items ahead.
  [[nodiscard]] const Item* cold_ahead(std::size_t k) const noexcept {
    if (discipline_ != queue_discipline::largest_error || k >= cold_) return nullptr;
    return &buckets_.back().items[cold_ - 1 - k];
  }
  /// Largest error first: the rank of an item of error e (its bucket, above the target first);
  /// items of one rank form a band, taken together. Reads only the target: any thread, while
  /// nothing moves it.
  [[nodiscard]] std::uint64_t rank(double e) const noexcept { return key_of(e); }
  /// Largest error first: the lowest rank of an error above the target (aim_at()): rank(e) is at
  /// least this exactly when e > target or e is NaN.
  [[nodiscard]] static constexpr std::uint64_t above_target_rank() noexcept {
    return std::uint64_t{1} << 32;
  }
  /// Largest error first: the rank of top(). Not empty.
  [[nodiscard]] std::uint64_t top_rank() const noexcept { return buckets_.back().key; }
  void push(const Item& item) {
    if (discipline_ == queue_discipline::fifo) {
      fifo_.push_back(item);
      return;
    }
    if (discipline_ == queue_discipline::lifo) {
      items_.push_back(item);
      return;
    }
    const std::uint64_t key = key_of(item.error);
    ++count_;
    // The common case: a child in its parent's bucket, the one being taken.
    if (!buckets_.empty() && buckets_.back().key == key) {
      buckets_.back().items.push_back(item);
      return;
    }
    bucket_for(key).push_back(item);
  }
  /// Largest error first: the top band whole (every item of top_rank()), in the order pop()
  /// would take them (the next one at the back), as one vector. O(1): the bucket's own storage.
  [[nodiscard]] std::vector<Item> take_top_band() {
    PROGISO_ASSERT(discipline_ == queue_discipline::largest_error && !buckets_.empty());
    std::vector<Item> band = std::move(buckets_.back().items);
    count_ -= band.size();
    buckets_.pop_back();
    // The next bucket's items were all pushed before it became the top: cold.
    cold_ = buckets_.empty() ? 0 : buckets_.back().items.size();
    return band;
  }
  /// Largest error first: pushes items that all have rank `key` (rank(item.error) == key), in
  /// their order: the same queue as push() of each, with one bucket search, and the vector
  /// itself as the bucket when the rank has none (else one copy).
  void push_band(std::uint64_t key, std::vector<Item>&& band) {
    PROGISO_ASSERT(discipline_ == queue_discipline::largest_error);
    if (band.empty()) return;
    for ([[maybe_unused]] const Item& item : band) PROGISO_ASSERT(key_of(item.error) == key);
    count_ += band.size();
    std::vector<Item>& to = bucket_for(key);
    if (to.empty()) {
      if (to.capacity() != 0) spare_.push_back(std::move(to));
      to = std::move(band);
    } else {
      to.insert(to.end(), band.begin(), band.end());
    }
  }
  void pop() {
    switch (discipline_) {
      case queue_discipline::fifo:
        fifo_.pop_front();
        return;
      case queue_discipline::lifo:
        items_.pop_back();
        return;
      case queue_discipline::largest_error:
        break;
    }
    --count_;
    std::vector<Item>& top = buckets_.back().items;
    if (top.size() == cold_) --cold_;
    top.pop_back();
    if (top.empty()) {
      spare_.push_back(std::move(top));
      buckets_.pop_back();
      // The next bucket's items were all pushed before it became the top: cold.
      cold_ = buckets_.empty() ? 0 : buckets_.back().items.size();
    }
  }

 private:
  struct bucket {
    std::uint64_t key;
    std::vector<Item> items;  // never empty
  };

  // Above the target first, then by bucket.
  [[nodiscard]] std::uint64_t key_of(double e) const noexcept {
    const bool above = !(e <= target_);
    static_assert(error_bucket_bits < 20);  // every bucket below above_target_rank()
    return (above ? above_target_rank() : 0) | error_bucket(e);
  }
  // The bucket of `key`, made if there is none: a few buckets below the top, mostly, so searched
  // from the top down.
  std::vector<Item>& bucket_for(std::uint64_t key) {
    auto at = buckets_.end();
    while (at != buckets_.begin() && std::prev(at)->key >= key) --at;
    // A new top bucket holds no cold item; what the old top held counts as cold when it is the
    // top again (pop()). Below the top, the top's cold items stay as they are.
    if (at == buckets_.end()) cold_ = 0;
    if (at == buckets_.end() || at->key != key) at = buckets_.insert(at, bucket{key, spare()});
    return at->items;
  }
  std::vector<Item> spare() {
    if (spare_.empty()) return {};
    std::vector<Item> v = std::move(spare_.back());
    spare_.pop_back();
    return v;
  }
  std::vector<Item> take_all() {
    std::vector<Item> all;
    if (discipline_ == queue_discipline::largest_error) {
      all.reserve(count_);
      for (bucket& b : buckets_) {
        all.insert(all.end(), b.items.begin(), b.items.end());
        b.items.clear();
        spare_.push_back(std::move(b.items));
      }
      buckets_.clear();
      count_ = 0;
      cold_ = 0;
    } else if (discipline_ == queue_discipline::fifo) {
      all.assign(fifo_.begin(), fifo_.end());
      fifo_.clear();
    } else {
      all = std::move(items_);
      items_.clear();
    }
    return all;
  }
  void put_all(std::vector<Item> all) {
    if (discipline_ == queue_discipline::fifo) {
      fifo_.assign(all.begin(), all.end());
      return;
    }
    if (discipline_ == queue_discipline::lifo) {
      items_ = std::move(all);
      return;
    }
    for (const Item& it : all) push(it);
    cold_ = buckets_.empty() ? 0 : buckets_.back().items.size();
  }

  queue_discipline discipline_;
  // fifo: the items in blocks, emptied blocks freed as the front advances, so memory follows
  // the items queued now (a breadth-first refinement's widest level) and growth copies nothing.
  // (A vector whose consumed front was dropped at half its size held up to twice that and
  // copied it on every doubling. With this, a one-shot 2D full refinement touches markedly
  // fewer fresh pages; bench/README.md.)
  std::deque<Item> fifo_;
  // lifo: the items.
  std::vector<Item> items_;
  // largest_error: non-empty buckets by ascending key (the last is taken first), and the storage
  // of emptied ones, reused.
  std::vector<bucket> buckets_;
  std::vector<std::vector<Item>> spare_;
  std::size_t count_ = 0;
  // Largest error first: of the top bucket's items, the first cold_ (in its vector) were there
  // when it became the top; the rest were pushed since.
  std::size_t cold_ = 0;
  double target_ = -std::numeric_limits<double>::infinity();
};

}  // namespace progiso::detail
