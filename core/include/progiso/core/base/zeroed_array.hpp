// progiso/core/base/zeroed_array.hpp — a large zero-filled array whose pages cost nothing until
// touched. Public (not core/detail) because concurrent/append_log.hpp keeps its chunk table in
// one, and concurrent/ depends only on core's public headers.
//
// The refiners keep a few bytes per grid vertex but touch only the vertices near the surface.
// calloc() zero-fills eagerly once glibc has raised its mmap threshold (it does after large frees),
// which costs time in proportion to the whole grid and would spoil the time to first surface; an
// anonymous mapping is zeroed lazily by the kernel, page by page, on first touch. Small arrays
// (up to 4 MiB) come from calloc() all the same: zeroing them is cheap, while the page faults of
// a fresh mapping, which a refinement touching most pages pays on every run, cost more than the
// zeroing would (bench/README.md). A page first read, then written, costs more: the read
// maps the shared zero page and the write replaces it, which flushes the TLB of every core running
// the process (an interrupt each). Owners that touch many pages on every use keep the array and
// zero() it, or clear what they wrote, instead of mapping a fresh one. Not thread-safe to create or
// destroy; elements follow T's own rules.
#pragma once

#include <sys/mman.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <type_traits>
#include <utility>

// ThreadSanitizer builds take add_in_place()'s atomic_ref form (cmake/progiso_options.cmake
// defines PROGISO_TSAN; the compiler's own macros as concurrent/detail/memory_order.hpp reads
// them).
#if defined(PROGISO_TSAN) || defined(__SANITIZE_THREAD__)
#define PROGISO_ADD_IN_PLACE_ATOMIC 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define PROGISO_ADD_IN_PLACE_ATOMIC 1
#endif
#endif
#if !defined(PROGISO_ADD_IN_PLACE_ATOMIC)
#define PROGISO_ADD_IN_PLACE_ATOMIC 0
#endif

namespace progiso {

template <class T>
class zeroed_array {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  static constexpr std::size_t heap_max_bytes = std::size_t{4} << 20;

  explicit zeroed_array(std::size_t n) : bytes_(n * sizeof(T)) {
    if (bytes_ == 0) return;
    if (bytes_ <= heap_max_bytes) {
      data_ = static_cast<T*>(std::calloc(n, sizeof(T)));
      if (data_ == nullptr) throw std::bad_alloc();
      return;
    }
    void* p = mmap(nullptr, bytes_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = static_cast<T*>(p);
  }
  zeroed_array(const zeroed_array&) = delete;
  zeroed_array& operator=(const zeroed_array&) = delete;
  zeroed_array(zeroed_array&& o) noexcept : bytes_(o.bytes_), data_(o.data_) {
    o.bytes_ = 0;
    o.data_ = nullptr;
  }
  zeroed_array& operator=(zeroed_array&& o) noexcept {
    std::swap(bytes_, o.bytes_);
    std::swap(data_, o.data_);
    return *this;
  }
  ~zeroed_array() { release(); }

  [[nodiscard]] std::size_t size() const noexcept { return bytes_ / sizeof(T); }
  /// Zeroes every element (touches every page).
  void zero() noexcept {
    if (data_ != nullptr) std::memset(static_cast<void*>(data_), 0, bytes_);
  }

  [[nodiscard]] T* get() const noexcept { return data_; }
  T& operator[](std::size_t i) const noexcept { return data_[i]; }

 private:
  void release() noexcept {
    if (data_ == nullptr) return;
    if (bytes_ <= heap_max_bytes) {
      std::free(data_);
    } else {
      munmap(data_, bytes_);
    }
    data_ = nullptr;
  }

  std::size_t bytes_;
  T* data_ = nullptr;
};

/// Adds `delta` to `word` (wrapping) and returns the new value, with one read-modify-write
/// instruction where the target has one (x86-64), so that the first touch of a fresh page of a
/// zeroed_array is a write: one page fault, which maps a fresh page. A load and then a store take
/// two: the load maps the shared zero page, and the store's fault replaces it and flushes the TLB
/// of every core running one of the process's threads (an interrupt to each; on a virtual
/// machine an exit each). A refiner counting parents in per-vertex words touches every page of
/// them this way; while a second thread of the process was busy (the engine's reclaimer clearing
/// a fully refined root after an isovalue change), the interrupts left a short one-thread
/// deadline run a small fraction of the splits it makes otherwise (bench/engine_bench.cpp,
/// BM_deadline_after_full; bench/README.md).
/// Not an atomic read-modify-write: the caller must be the word's only writer. Relaxed atomic
/// loads of the word from other threads read the old or the new value (one aligned access); under
/// ThreadSanitizer the add is an atomic_ref load and store instead, which the tool sees.
template <class T>
T add_in_place(T& word, T delta) noexcept {
  static_assert(std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint32_t>);
#if defined(__x86_64__) && !PROGISO_ADD_IN_PLACE_ATOMIC
  if constexpr (sizeof(T) == 1) {
    asm volatile("addb %1, %0" : "+m"(word) : "iq"(delta) : "cc");
  } else {
    asm volatile("addl %1, %0" : "+m"(word) : "ir"(delta) : "cc");
  }
  return std::atomic_ref<T>(word).load(std::memory_order_relaxed);  // relaxed: only writer
#else
  const std::atomic_ref<T> w(word);
  const auto sum = static_cast<T>(w.load(std::memory_order_relaxed) + delta);  // relaxed: as above
  w.store(sum, std::memory_order_relaxed);                                     // relaxed: as above
  return sum;
#endif
}

}  // namespace progiso
