// bench/bench_common.hpp — what the benchmark programs share: where the shared data lies, and
// wall-clock helpers.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace progiso::bench {

/// ../shared/data beside the source tree, or $PROGISO_DATA_DIR.
inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("PROGISO_DATA_DIR")) return env;
  return std::filesystem::path(PROGISO_SOURCE_DIR) / ".." / "shared" / "data";
}

using clock_type = std::chrono::steady_clock;

inline double ms_since(clock_type::time_point t0) {
  return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

/// The upper median (the middle element of the sorted values); 0 for none.
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace progiso::bench
