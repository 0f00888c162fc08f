// progiso/core/base/detail/chunked_store.hpp — append-only storage in fixed chunks, shared by
// the sequential refiner (records, packed groups) and the engine (packed groups of a root).
//
// Growth never moves what is stored: no reallocation copy of tens or hundreds of megabytes, no
// second set of fresh pages, and pointers into the store stay valid (the engine's published
// records point into it). Chunks are a power of two, 4 K to 64 K elements, chosen from the
// grid's size (bits_for), so a small volume's refinement stays small enough for the allocator
// to keep reusing its memory.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <type_traits>
#include <vector>

namespace progiso::detail {

template <class T>
class chunked_store {
 public:
  // Splits run to a modest fraction of the voxels on the shared volumes and test fields
  // (bench/README.md); a chunk of a thirty-second keeps the number of chunks small without
  // reserving much more than a small refinement uses.
  [[nodiscard]] static int bits_for(std::uint64_t voxels) noexcept {
    const std::uint64_t want = voxels / 32;
    int bits = 12;
    while (bits < 16 && (std::uint64_t{1} << bits) < want) ++bits;
    return bits;
  }

  explicit chunked_store(int chunk_bits) noexcept
      : bits_(chunk_bits), mask_((std::size_t{1} << chunk_bits) - 1) {}
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  void push_back(const T& v) {
    grow_if_full();
    chunks_[size_ >> bits_][size_ & mask_] = v;
    ++size_;
  }
  // Appends n elements, across chunks where they do not fit in one.
  void append(const T* v, std::size_t n) {
    while (n > 0) {
      grow_if_full();
      const std::size_t room = mask_ + 1 - (size_ & mask_);
      const std::size_t k = n < room ? n : room;
      std::copy(v, v + k, chunks_[size_ >> bits_].get() + (size_ & mask_));
      size_ += k;
      v += k;
      n -= k;
    }
  }
  // Appends n ≤ chunk_size() elements in one piece and returns where they are: when they do not
  // fit in what is left of the current chunk, that rest stays unused (its indices hold nothing).
  const T* append_contiguous(const T* v, std::size_t n) {
    T* at = reserve_contiguous(n);
    std::copy(v, v + n, at);
    return at;
  }
  // As append_contiguous, but the n elements are left for the caller to write: it may do so
  // later, from another thread, while others append (chunks never move).
  T* reserve_contiguous(std::size_t n) {
    if (n > mask_ + 1 - (size_ & mask_)) size_ = (size_ + mask_) & ~mask_;
    grow_if_full();
    T* at = chunks_[size_ >> bits_].get() + (size_ & mask_);
    size_ += n;
    return at;
  }
  // Drops the last n elements (n ≤ what the last reserve_contiguous() gave): a writer that
  // reserved room for the most it could write gives back what it did not use.
  void trim(std::size_t n) noexcept { size_ -= n; }
  [[nodiscard]] T& operator[](std::size_t i) noexcept { return chunks_[i >> bits_][i & mask_]; }
  [[nodiscard]] const T& operator[](std::size_t i) const noexcept {
    return chunks_[i >> bits_][i & mask_];
  }
  [[nodiscard]] std::size_t chunk_size() const noexcept { return mask_ + 1; }
  [[nodiscard]] std::size_t byte_size() const noexcept {
    return chunks_.size() * chunk_size() * sizeof(T);
  }
  // Overwrites every chunk with `byte` (poisoning retired storage; the elements are then garbage).
  void overwrite(unsigned char byte) noexcept {
    for (auto& c : chunks_)
      std::memset(static_cast<void*>(c.get()), byte, chunk_size() * sizeof(T));
  }

 private:
  // Chunks are raw storage: elements are written before they are read, and a type with default
  // member initialisers (a 2D segment's owner) would otherwise have every element of a fresh
  // chunk written once for nothing. T is an implicit-lifetime type, so the allocation holds its
  // objects (C++20).
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);
  struct free_chunk {
    void operator()(T* p) const noexcept {
      ::operator delete (static_cast<void*>(p), std::align_val_t{alignof(T)});
    }
  };
  void grow_if_full() {
    if ((size_ & mask_) == 0 && (size_ >> bits_) == chunks_.size()) {
      chunks_.emplace_back(
          static_cast<T*>(::operator new ((mask_ + 1) * sizeof(T), std::align_val_t{alignof(T)})));
    }
  }
  int bits_;
  std::size_t mask_;
  std::vector<std::unique_ptr<T[], free_chunk>> chunks_;
  std::size_t size_ = 0;
};

}  // namespace progiso::detail
