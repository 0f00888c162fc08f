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

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso::scheduler {

/// oneTBB's default number of worker threads for this process (`tbb::info::default_concurrency()`:
/// the CPUs this process may run on, after affinity masks and cgroup limits): the default for
/// `--threads`. Always at least 1.
[[nodiscard]] int default_concurrency() noexcept;

}  // namespace progiso::scheduler
