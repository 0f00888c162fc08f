// progiso/core/base/parallel_loop.hpp — how core runs independent pieces of work without depending
// on a thread library: the caller (the engine, with oneTBB) passes the loop.
#pragma once

#include <cstddef>
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

}  // namespace progiso
