// bench/heap_meter.hpp — every operator new and delete of a benchmark program counted, for
// peak-heap counters. It replaces the global operator new and delete: include it in one source
// file of a program, and only in a benchmark program.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

#include <malloc.h>

// ---- Heap meter: every operator new and delete of the process, counted by the block's usable
// size; the peak is reset before a measured run. Relaxed atomics: the counts are read on the
// benchmark thread after the run's threads have joined (the engine's join orders them).
namespace progiso::bench::heap {
inline std::atomic<std::int64_t> heap_live{0};
inline std::atomic<std::int64_t> heap_peak{0};

inline void note_alloc(void* p) noexcept {
  if (p == nullptr) return;
  const auto n = static_cast<std::int64_t>(malloc_usable_size(p));
  // relaxed: see above.
  const std::int64_t live = heap_live.fetch_add(n, std::memory_order_relaxed) + n;
  std::int64_t peak = heap_peak.load(std::memory_order_relaxed);
  // relaxed: see above.
  while (live > peak && !heap_peak.compare_exchange_weak(peak, live, std::memory_order_relaxed)) {
  }
}
inline void note_free(void* p) noexcept {
  if (p == nullptr) return;
  // relaxed: see above.
  heap_live.fetch_sub(static_cast<std::int64_t>(malloc_usable_size(p)), std::memory_order_relaxed);
}
inline void* counted_alloc(std::size_t n, std::size_t align) {
  void* p = nullptr;
  if (align <= alignof(std::max_align_t)) {
    p = std::malloc(n == 0 ? 1 : n);
  } else if (posix_memalign(&p, align, n == 0 ? align : n) != 0) {
    p = nullptr;
  }
  if (p == nullptr) throw std::bad_alloc();
  note_alloc(p);
  return p;
}
inline void counted_free(void* p) noexcept {
  note_free(p);
  std::free(p);
}
}  // namespace progiso::bench::heap

using progiso::bench::heap::counted_alloc;
using progiso::bench::heap::counted_free;

void* operator new(std::size_t n) { return counted_alloc(n, 1); }
void* operator new[](std::size_t n) { return counted_alloc(n, 1); }
void* operator new(std::size_t n, std::align_val_t a) {
  return counted_alloc(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return counted_alloc(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n, 1);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n, 1);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept { counted_free(p); }
void operator delete[](void* p) noexcept { counted_free(p); }
void operator delete(void* p, std::size_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { counted_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { counted_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { counted_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { counted_free(p); }

namespace progiso::bench {

/// Starts a heap measurement; peak() is the most heap in use since, beyond the start's.
class heap_window {
 public:
  heap_window() : base_(heap::heap_live.load(std::memory_order_relaxed)) {
    // relaxed: single-threaded here (no run in flight).
    heap::heap_peak.store(base_, std::memory_order_relaxed);
  }
  [[nodiscard]] double peak_mib() const { return static_cast<double>(peak_bytes()) / (1 << 20); }
  [[nodiscard]] std::int64_t peak_bytes() const {
    // relaxed: read after the run's threads joined.
    return heap::heap_peak.load(std::memory_order_relaxed) - base_;
  }

 private:
  std::int64_t base_;
};

}  // namespace progiso::bench
