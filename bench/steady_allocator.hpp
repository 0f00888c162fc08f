// bench/steady_allocator.hpp — glibc's allocator held in a steady state for repeated runs.
//
// By default glibc returns freed heap to the kernel once the free top exceeds its trim threshold,
// and that threshold follows the largest block freed so far. A benchmark that repeats an
// extraction then pays page faults for its whole working set on some runs and not on others,
// depending on what ran before: in one binary the full progressive extraction of hipip took
// 7.65 ms alone and 10.6 ms when alternated with the plain extractor, nucleon 5.0 against 6.6 ms
// before the refiner's chunks were sized. That measures glibc's heuristic, not the extractors.
// Fixing both thresholds (the largest mmap threshold glibc accepts, and a 1 GiB trim threshold)
// keeps freed memory for reuse, the same for every side of every comparison. Set
// PROGISO_BENCH_DEFAULT_MALLOC=1 to measure with glibc's defaults instead.
#pragma once

#include <cstdlib>

#include <benchmark/benchmark.h>
#include <malloc.h>

namespace progiso::bench {

inline void steady_allocator() {
  if (const char* e = std::getenv("PROGISO_BENCH_DEFAULT_MALLOC"); e != nullptr && *e == '1') {
    return;
  }
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);  // DEFAULT_MMAP_THRESHOLD_MAX on 64-bit
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
}

/// main() of a benchmark program: the steady allocator, then Google Benchmark, with the
/// benchmarks `register_all` registers at run time (after the flags are parsed) besides the
/// static ones.
inline int run_benchmarks(int argc, char** argv, void (*register_all)() = nullptr) {
  steady_allocator();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (register_all != nullptr) register_all();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

}  // namespace progiso::bench
