// progiso/core/base/detail/prefault.hpp — mapping the pages of a large buffer about to be filled
// from end to end, in one call instead of one fault per page; and handing a large buffer's pages
// back by slices over the threads before it is freed.
//
// A fresh anonymous page costs a fault on first touch, so a large buffer spends a noticeable part
// of its first fill in the kernel before it holds anything, far more than writing it again costs.
// madvise(MADV_POPULATE_WRITE) (Linux 5.14) maps a whole range at once, because one mapping call
// costs less than a fault per page, and two threads each taking half map it faster still
// (bench/README.md). Only for buffers that will be written everywhere (mesh arrays, the
// extraction's per-split arrays): a buffer touched sparsely, like the per-grid-vertex arrays of a
// coarse cut, would pay for pages it never uses. Huge pages (MADV_HUGEPAGE) were tried too and
// left out: in a fresh process they cost more than they save, since the kernel takes them from
// memory the host has not backed yet (bench/README.md).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include <progiso/core/base/parallel_loop.hpp>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace progiso::detail {

/// Buffers below this many bytes are left to fault page by page (the call costs more than the
/// faults it saves, and small buffers usually come from memory the allocator already holds).
inline constexpr std::size_t prefault_min_bytes = std::size_t{1} << 20;

#if defined(__linux__)
/// The whole pages of [p, p + bytes): [first, last), empty when none lies wholly inside.
struct page_span {
  std::uintptr_t first;
  std::uintptr_t last;
  std::uintptr_t page;
};
inline page_span inner_pages(const void* p, std::size_t bytes) noexcept {
  static const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto begin = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t first = (begin + page - 1) & ~(page - 1);
  const std::uintptr_t last = (begin + bytes) & ~(page - 1);
  return {first, std::max(first, last), page};
}
#endif

/// Maps the whole pages of [p, p + bytes) for writing, before the first write. A no-op below
/// prefault_min_bytes, where the kernel does not offer it, or off Linux; pages already mapped
/// cost only the walk.
inline void prefault(const void* p, std::size_t bytes) noexcept {
#if defined(__linux__)
  constexpr int populate_write = 23;  // MADV_POPULATE_WRITE, Linux 5.14; EINVAL before it
  if (p == nullptr || bytes < prefault_min_bytes) return;
  const auto [first, last, page] = inner_pages(p, bytes);
  if (last == first) return;
  // Advice only: a failure (an older kernel, memory short) leaves the pages to fault as usual.
  (void)madvise(reinterpret_cast<void*>(first), last - first, populate_write);
#else
  (void)p;
  (void)bytes;
#endif
}

/// prefault() of [p, p + bytes) in up to `parts` slices through `run`, each of at least
/// prefault_min_bytes (below it prefault() does nothing), so that a buffer of a few MiB still
/// spreads over the threads: a mapped range costs less per page than a fault per page, and
/// threads populating their own slices finish sooner than one thread mapping it all
/// (bench/README.md).
inline void prefault_in_parts(const parallel_loop& run, std::size_t parts, const void* p,
                              std::size_t bytes) {
  const std::size_t slices = std::min(parts, bytes / prefault_min_bytes);
  if (slices <= 1) {
    prefault(p, bytes);
    return;
  }
  const std::size_t slice = (bytes / slices + 4095) & ~std::size_t{4095};
  const auto* at = static_cast<const unsigned char*>(p);
  run_loop(run, slices, [&](std::size_t k) {
    const std::size_t lo = std::min(bytes, k * slice);
    const std::size_t hi = std::min(bytes, lo + slice);
    if (hi > lo) prefault(at + lo, hi - lo);
  });
}

/// The smallest buffer release_in_parts() hands back: glibc's largest mmap threshold (32 MiB on
/// 64-bit), above which malloc always maps a block on its own and free() unmaps it. A smaller
/// block may sit in the heap, where free() keeps its pages for the next allocation: releasing
/// them would make that allocation fault them again, and the benchmarks show the next runs in
/// the process slowing down when such a block is released (bench/README.md).
inline constexpr std::size_t release_min_bytes = std::size_t{32} << 20;

/// Hands the whole pages of [p, p + bytes) back to the kernel (MADV_DONTNEED), in up to `parts`
/// slices through `run`, for a buffer that is about to be freed and will not be read again
/// (reads would find zeros). free() unmaps a large block's pages one by one on the freeing
/// thread, so a large grid's corner bytes cost a serial tail at the end of every finest surface
/// whatever the thread count (bench/README.md); released in slices, each thread frees its own,
/// and free() finds nothing left to unmap. Only pages wholly inside the range go, so the
/// allocator's own words around a block are untouched. A no-op below release_min_bytes, for
/// slices below prefault_min_bytes (one part), and off Linux.
inline void release_in_parts(const parallel_loop& run, std::size_t parts, void* p,
                             std::size_t bytes) {
#if defined(__linux__)
  const std::size_t slices = std::min(parts, bytes / prefault_min_bytes);
  if (p == nullptr || bytes < release_min_bytes || slices <= 1) return;
  // Named fields, not a structured binding: the lambda below reads them (C++20 allows capturing
  // bindings, clang 14 does not).
  const page_span pages = inner_pages(p, bytes);
  const std::uintptr_t first = pages.first;
  const std::uintptr_t last = pages.last;
  const std::uintptr_t page = pages.page;
  if (last == first) return;
  const std::uintptr_t slice = ((last - first) / slices + page - 1) & ~(page - 1);
  run_loop(run, slices, [&](std::size_t k) {
    const std::uintptr_t lo = std::min(last, first + k * slice);
    const std::uintptr_t hi = std::min(last, lo + slice);
    // Advice only: a failure leaves the pages to the free() that follows.
    if (hi > lo) (void)madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_DONTNEED);
  });
#else
  (void)run;
  (void)parts;
  (void)p;
  (void)bytes;
#endif
}

/// v.reserve(n), with the new buffer's pages mapped at once when it is freshly allocated.
template <class Vector>
void reserve_prefaulted(Vector& v, std::size_t n) {
  if (n <= v.capacity()) return;
  v.reserve(n);
  prefault(v.data(), v.capacity() * sizeof(typename Vector::value_type));
}

}  // namespace progiso::detail
