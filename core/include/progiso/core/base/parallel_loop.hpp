// progiso/core/base/parallel_loop.hpp — how core runs independent pieces of work without depending
// on a thread library: the caller (the engine, with oneTBB) passes the loop.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>

namespace progiso {

/// run(n, body) calls body(i) once for every i in [0, n), in any order and on any threads, and
/// returns when all calls have returned. An empty loop means: one after another, on this thread.
using parallel_loop = std::function<void(std::size_t, const std::function<void(std::size_t)>&)>;

/// Runs body(0) … body(n − 1) through `run`, or on this thread when `run` is empty.
inline void run_loop(const parallel_loop& run, std::size_t n,
                     const std::function<void(std::size_t)>& body) {
  if (run) {
    run(n, body);
  } else {
    for (std::size_t i = 0; i < n; ++i) body(i);
  }
}

/// The first of `items` items in piece k of `parts` near-equal pieces, in order (piece k is
/// [piece_begin(items, parts, k), piece_begin(items, parts, k + 1))).
[[nodiscard]] constexpr std::uint64_t piece_begin(std::uint64_t items, std::uint64_t parts,
                                                  std::uint64_t k) noexcept {
  return k * (items / parts) + std::min(k, items % parts);
}

}  // namespace progiso
