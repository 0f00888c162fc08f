// What the oneTBB runtime offers this process, for the command line and the engine's defaults.
//
// The scheduler runs its split-record tasks on oneTBB's shared worker pool. This header reports
// the pool's size without exposing TBB: callers (the CLI's --threads, tests, benchmarks) include
// it without TBB's headers, and TBB stays a private dependency of progiso::scheduler.
//
// Thread safety: every function here may be called from any thread at any time.
// Cost: a call into the TBB runtime; it may initialise TBB's thread-count detection (affinity
// mask, cgroup limits) on first use, so keep it out of hot paths.
#pragma once

#include <cstddef>
#include <functional>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/base/parallel_loop.hpp>

namespace progiso::scheduler {

/// oneTBB's default number of worker threads for this process (`tbb::info::default_concurrency()`:
/// the CPUs this process may run on, after affinity masks and cgroup limits): the default for
/// `--threads`. Always at least 1.
[[nodiscard]] int default_concurrency() noexcept;

/// Calls f(loop, parts) with a parallel_loop (core/base/parallel_loop.hpp) that runs its pieces
/// on `threads` workers of oneTBB's pool, in an arena of its own (0: default_concurrency()),
/// and the number of pieces to cut the work into (16 per thread, so that pieces of uneven work
/// balance); with one thread, an empty loop (this thread) and 1. For core's direct passes
/// (finest_surface(), vertex normals) run outside an engine. Rethrows what f throws.
void run_on_threads(unsigned threads,
                    const std::function<void(const parallel_loop& loop, std::size_t parts)>& f);

}  // namespace progiso::scheduler
