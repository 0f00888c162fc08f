// progiso/core/base/detail/flat_map.hpp — open-addressing hash map from 64-bit keys to 32-bit
// values.
//
// Used where extraction deduplicates surface vertices by edge key: linear probing in a
// power-of-two table, no erase, one reserved key (~0). Not thread-safe.
//
// The hash is made for edge keys (three 21-bit doubled coordinates): the keys of one block of
// 2 × 2 × 2 doubled coordinates (one grid cell's edges and faces) land in one run of 8 slots (two
// cache lines), placed at random by a mix of the block's coordinates. Triangles reach their
// vertices in a spatially coherent order, so nearby vertices then share cache lines; with a plain
// mixing hash every first visit of a vertex was a cache miss, which dominated extraction time.
// Runs of 64 slots (4 × 4 × 4 blocks) kept more neighbours together but overflowed into each
// other, and took far more probes per lookup at the refiner's load than runs of 8
// (bench/README.md).
#pragma once

#include <bit>
#include <cstdint>
#include <utility>
#include <vector>

namespace progiso::detail {

class flat_map {
 public:
  static constexpr std::uint64_t empty_key = ~std::uint64_t{0};

  explicit flat_map(std::size_t expected = 16) { rehash(capacity_for(expected)); }

  /// Inserts (key, value) if absent; returns the stored value and whether it was inserted.
  std::pair<std::uint32_t, bool> try_emplace(std::uint64_t key, std::uint32_t value) {
    const auto [stored, inserted] = try_emplace_ref(key, value);
    return {*stored, inserted};
  }

  /// The same, returning the stored value's address: valid until the next insertion.
  std::pair<std::uint32_t*, bool> try_emplace_ref(std::uint64_t key, std::uint32_t value) {
    std::size_t i = hash(key);
    while (true) {
      slot& s = slots_[i];
      if (s.key == key) return {&s.value, false};
      if (s.key == empty_key) break;
      i = (i + 1) & mask_;
    }
    // Absent. Grown before the load passes one half (lookups, the common case, skip this).
    if ((size_ + 1) * 2 > slots_.size()) {
      rehash(slots_.size() * 2);
      i = hash(key);
      while (slots_[i].key != empty_key) i = (i + 1) & mask_;
    }
    slot& s = slots_[i];
    s.key = key;
    s.value = value;
    ++size_;
    return {&s.value, true};
  }

  /// Pointer to the value of key, or nullptr.
  [[nodiscard]] const std::uint32_t* find(std::uint64_t key) const noexcept {
    std::size_t i = hash(key);
    while (true) {
      const slot& s = slots_[i];
      if (s.key == key) return &s.value;
      if (s.key == empty_key) return nullptr;
      i = (i + 1) & mask_;
    }
  }

  [[nodiscard]] std::size_t size() const noexcept { return size_; }

  /// Calls f(key, value) for every entry, in slot order.
  template <class F>
  void for_each(F&& f) const {
    for (const slot& s : slots_) {
      if (s.key != empty_key) f(s.key, s.value);
    }
  }

 private:
  struct slot {
    std::uint64_t key;
    std::uint32_t value;
  };

  static std::size_t capacity_for(std::size_t n) {
    std::size_t c = 16;
    while (c < 2 * n) c *= 2;
    return c;
  }

  // Slot of a key's run (multiplicative hashing of the block's coordinates: the product's top
  // bits depend on all of them) plus its place in the run. Below capacity by construction.
  [[nodiscard]] std::size_t hash(std::uint64_t k) const noexcept {
    constexpr std::uint64_t low = 1 | (std::uint64_t{1} << 21) | (std::uint64_t{1} << 42);
    const std::uint64_t local = (k & 1) | ((k >> 20) & 2) | ((k >> 40) & 4);
    const std::uint64_t run = ((k & ~low) * 0x9E3779B97F4A7C15ULL) >> run_shift_;
    return static_cast<std::size_t>((run << 3) | local);
  }

  void rehash(std::size_t capacity) {
    std::vector<slot> old = std::move(slots_);
    slots_.assign(capacity, slot{empty_key, 0});
    mask_ = capacity - 1;
    run_shift_ = 64 + 3 - std::countr_zero(capacity);  // capacity / 8 runs
    size_ = 0;
    for (const slot& s : old) {
      if (s.key != empty_key) try_emplace(s.key, s.value);
    }
  }

  std::vector<slot> slots_;
  std::size_t mask_ = 0;
  int run_shift_ = 64;
  std::size_t size_ = 0;
};

}  // namespace progiso::detail
