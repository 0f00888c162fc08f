// progiso/core/refine/detail/ready_queue.hpp — the queue of diamonds ready to split, shared by the
// 3D refiner and the 2D contour refiner.
//
// Three disciplines over one vector: first in first out (breadth first: coarse to fine), last in
// first out (depth first: the working set stays local), and a binary max-heap on (error, then
// coarser depth, then index) for quality-, budget- and time-driven refinement. Item needs
// members `error`, `depth` and `index`. Not thread-safe.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace progiso::detail {

enum class queue_discipline { fifo, lifo, largest_error };

template <class Item>
class ready_queue {
 public:
  explicit ready_queue(queue_discipline d = queue_discipline::largest_error) : discipline_(d) {}

  /// Room for n items before the first reallocation.
  void reserve(std::size_t n) { items_.reserve(n); }
  [[nodiscard]] bool empty() const noexcept { return head_ == items_.size(); }
  [[nodiscard]] std::size_t size() const noexcept { return items_.size() - head_; }
  [[nodiscard]] queue_discipline discipline() const noexcept { return discipline_; }
  /// Changes the discipline, keeping the items (O(n) when switching to largest_error).
  void set_discipline(queue_discipline d) {
    if (d == discipline_) return;
    items_.erase(items_.begin(), items_.begin() + static_cast<std::ptrdiff_t>(head_));
    head_ = 0;
    discipline_ = d;
    if (d == queue_discipline::largest_error) {
      std::make_heap(items_.begin(), items_.end(), ranks_below{});
    }
  }
  [[nodiscard]] const Item& top() const noexcept {
    switch (discipline_) {
      case queue_discipline::fifo:
        return items_[head_];
      case queue_discipline::lifo:
        return items_.back();
      case queue_discipline::largest_error:
        break;
    }
    return items_.front();
  }
  /// The item k places after top() in fifo or lifo order, or nullptr (largest_error: unknown
  /// without popping). For prefetching.
  [[nodiscard]] const Item* peek(std::size_t k) const noexcept {
    switch (discipline_) {
      case queue_discipline::fifo:
        return head_ + k < items_.size() ? &items_[head_ + k] : nullptr;
      case queue_discipline::lifo:
        return k < size() ? &items_[items_.size() - 1 - k] : nullptr;
      case queue_discipline::largest_error:
        break;
    }
    return nullptr;
  }
  void push(const Item& item) {
    items_.push_back(item);
    if (discipline_ == queue_discipline::largest_error) {
      std::push_heap(items_.begin(), items_.end(), ranks_below{});
    }
  }
  void pop() {
    switch (discipline_) {
      case queue_discipline::fifo:
        if (++head_ == items_.size()) {
          items_.clear();
          head_ = 0;
        } else if (head_ >= 4096 && 2 * head_ >= items_.size()) {
          // Drop the consumed front once it is half the vector: memory stays within twice the
          // ready items (a full refinement otherwise keeps every item it ever queued), at an
          // amortised O(1) move per item.
          items_.erase(items_.begin(), items_.begin() + static_cast<std::ptrdiff_t>(head_));
          head_ = 0;
        }
        return;
      case queue_discipline::lifo:
        items_.pop_back();
        return;
      case queue_discipline::largest_error:
        std::pop_heap(items_.begin(), items_.end(), ranks_below{});
        items_.pop_back();
        return;
    }
  }

 private:
  // A function object, not a function: the heap algorithms inline it.
  struct ranks_below {
    bool operator()(const Item& a, const Item& b) const noexcept {
      if (a.error != b.error) return a.error < b.error;
      if (a.depth != b.depth) return a.depth > b.depth;
      return a.index > b.index;
    }
  };

  queue_discipline discipline_;
  std::vector<Item> items_;
  std::size_t head_ = 0;
};

}  // namespace progiso::detail
