// progiso/concurrent/detail/memory_order.hpp — the one ThreadSanitizer switch of concurrent/.
//
// ThreadSanitizer does not model std::atomic_thread_fence: it reports races that a fence rules
// out, and gcc 12 warns (-Wtsan) about every fence it compiles. So code in concurrent/ never
// names a fence, nor the weak order of an access that a fence orders; it uses the names below.
//
// * Normal builds: the orders and seq_cst fences of the published algorithm (fence-based, as
//   crossbeam-epoch and xenium do it: cheap weak accesses, one full fence where a store must be
//   ordered before a later load of another location).
// * PROGISO_TSAN builds (cmake/progiso_options.cmake defines PROGISO_TSAN with -fsanitize=thread;
//   this header also defines it when the compiler reports ThreadSanitizer): the fences vanish and
//   every access they ordered becomes seq_cst, so each ordering argument is carried by the single
//   total order S of seq_cst operations instead, and ThreadSanitizer sees the same accesses as
//   release/acquire pairs. Nothing is suppressed.
//
// Each use site says which variant its argument needs; see the "Memory ordering" paragraph of
// progiso/concurrent/epoch.hpp.
#pragma once

#include <atomic>

#if !defined(PROGISO_TSAN)
#if defined(__SANITIZE_THREAD__)
#define PROGISO_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define PROGISO_TSAN 1
#endif
#endif
#endif

namespace progiso::detail {

#if defined(PROGISO_TSAN)
inline constexpr bool tsan_build = true;
#else
inline constexpr bool tsan_build = false;
#endif

/// An access ordered by a neighbouring seq_cst_fence(): relaxed, or seq_cst under TSan.
inline constexpr std::memory_order fenced_relaxed =
    tsan_build ? std::memory_order_seq_cst : std::memory_order_relaxed;
/// An acquire-load ordered by a preceding seq_cst_fence(): acquire, or seq_cst under TSan.
inline constexpr std::memory_order fenced_acquire =
    tsan_build ? std::memory_order_seq_cst : std::memory_order_acquire;
/// A release-store ordered by a following seq_cst_fence(): release, or seq_cst under TSan.
inline constexpr std::memory_order fenced_release =
    tsan_build ? std::memory_order_seq_cst : std::memory_order_release;

/// A seq_cst fence; nothing under TSan, where the accesses it ordered are seq_cst instead.
inline void seq_cst_fence() noexcept {
#if !defined(PROGISO_TSAN)
  std::atomic_thread_fence(std::memory_order_seq_cst);
#endif
}

}  // namespace progiso::detail
