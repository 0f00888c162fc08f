// progiso/core/refine/detail/plane_lists.hpp — ready diamonds by grid plane: the order of the
// engine's full refinement, on one thread (scheduler/src/serial_refinement.cpp,
// sweep_on_one_thread) and in tasks (scheduler/src/full_refinement.cpp).
//
// Full refinement splits every straddling diamond in any order that splits parents first. Taken
// from the lowest plane (z) that holds any, last in first out within a plane, the fine levels,
// which hold nearly all the splits, advance as one front through the volume: a split's children
// lie at most its scale away, so the samples and per-vertex words a run touches at a time are
// those of a few planes around the front, and they stay in the cache. The queue's depth-first
// order jumps between subtrees instead and misses on many of the children's words.
//
// Diamonds are kept as grid indices (z-major: the plane is index / plane_size). Not thread-safe:
// each list belongs to one thread at a time (the driver's sweep, or one task).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>

namespace progiso::detail {

class plane_lists {
 public:
  // Empty, for a grid of `planes` planes of `plane_size` vertices each; keeps the lists'
  // capacity when the shape is the same.
  void reset(std::size_t planes, std::uint64_t plane_size) {
    if (lists_.size() != planes) {
      lists_.assign(planes, {});
    } else {
      for (std::vector<std::uint64_t>& l : lists_) l.clear();
    }
    plane_size_ = plane_size;
    lowest_ = planes;
    highest_ = 0;
    size_ = 0;
  }
  [[nodiscard]] bool empty() const noexcept { return size_ == 0; }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }

  void push(std::uint64_t index) {
    const auto z = static_cast<std::size_t>(index / plane_size_);
    PROGISO_ASSERT(z < lists_.size());
    lists_[z].push_back(index);
    lowest_ = std::min(lowest_, z);
    highest_ = std::max(highest_, z);
    ++size_;
  }
  // The last diamond pushed on the lowest plane that has any. Precondition: !empty().
  [[nodiscard]] std::uint64_t pop() noexcept {
    PROGISO_ASSERT(size_ != 0);
    while (lists_[lowest_].empty()) ++lowest_;
    std::vector<std::uint64_t>& list = lists_[lowest_];
    const std::uint64_t index = list.back();
    list.pop_back();
    --size_;
    return index;
  }

  // Moves to `other` (reset to this shape) the diamonds on the planes above the middle of the
  // occupied planes, or, when they all lie on one plane, the older half of its list: the part of
  // the volume ahead of the front, about half of what is left to sweep when the surface is
  // spread evenly. Both keep at least one diamond when this one has two or more.
  void give_upper_half(plane_lists& other) {
    other.reset(lists_.size(), plane_size_);
    if (size_ < 2) return;
    while (lists_[lowest_].empty()) ++lowest_;
    while (lists_[highest_].empty()) --highest_;
    if (lowest_ == highest_) {
      std::vector<std::uint64_t>& list = lists_[lowest_];
      const std::size_t half = list.size() / 2;
      for (std::size_t i = 0; i < half; ++i) other.push(list[i]);
      list.erase(list.begin(), list.begin() + static_cast<std::ptrdiff_t>(half));
      size_ -= half;
      return;
    }
    const std::size_t middle = lowest_ + (highest_ - lowest_ + 1) / 2;  // > lowest_
    for (std::size_t z = middle; z <= highest_; ++z) {
      std::vector<std::uint64_t>& list = lists_[z];
      if (list.empty()) continue;
      size_ -= list.size();
      other.size_ += list.size();
      other.lowest_ = std::min(other.lowest_, z);
      other.highest_ = z;
      std::swap(other.lists_[z], list);
    }
    highest_ = middle - 1;
  }

  // Calls f(index) for every diamond, then empties the lists (keeping their capacity).
  template <class F>
  void drain(F&& f) {
    for (std::vector<std::uint64_t>& list : lists_) {
      for (const std::uint64_t index : list) f(index);
      list.clear();
    }
    lowest_ = lists_.size();
    highest_ = 0;
    size_ = 0;
  }

 private:
  std::vector<std::vector<std::uint64_t>> lists_;
  std::uint64_t plane_size_ = 1;
  std::size_t lowest_ = 0;   // no list below it has diamonds
  std::size_t highest_ = 0;  // no list above it has diamonds
  std::size_t size_ = 0;
};

}  // namespace progiso::detail
