// A volume larger than the memory the process may allocate: a raw input of at least
// detail::map_min_bytes is mapped, not read, and the engine's per-vertex words follow what it
// writes (vertex_pages), so the command refines it under an RLIMIT_DATA below the volume's size,
// and writes the same surface as without the limit (an error goal), or a surface by a deadline.
// (The finest surface's one-shot path still keeps a byte per sample: not run here.) The same bytes
// as an input that must be read (big-endian 16-bit samples, swapped into memory) are refused under
// that limit: the limit is real, and the mapping is what lets the first run through.

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "support/bounded_run.hpp"
#include "support/scratch_dir.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

constexpr int n = 576;  // 576³ bytes: 182 MiB
[[maybe_unused]] constexpr std::uint64_t volume_bytes = std::uint64_t{n} * n * n;
[[maybe_unused]] constexpr std::uint64_t cap = std::uint64_t{150} << 20;

// A ball of radius about 44 at the isovalue 40 (samples 0.9 × the distance from an off-grid
// centre), written slice by slice.
[[maybe_unused]] void write_ball(const fs::path& p) {
  std::ofstream out(p, std::ios::binary);
  std::vector<char> slice(static_cast<std::size_t>(n) * n);
  const double c = n / 2.0 + 0.3;
  for (int z = 0; z < n; ++z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const double r = std::sqrt((x - c) * (x - c) + (y - c) * (y - c) + (z - c) * (z - c));
        slice[static_cast<std::size_t>(y) * n + static_cast<std::size_t>(x)] =
            static_cast<char>(static_cast<unsigned char>(std::min(255.0, 0.9 * r)));
      }
    }
    out.write(slice.data(), static_cast<std::streamsize>(slice.size()));
  }
  ASSERT_TRUE(out.good());
}

TEST(OutOfCore, a_mapped_volume_larger_than_the_allowed_memory_refines_to_the_same_surface) {
#if defined(PROGISO_SANITIZER_BUILD)
  GTEST_SKIP() << "sanitizer builds run without memory limits (their shadow memory)";
#else
  static_assert(cap < volume_bytes);
  const test::scratch_dir dir("progiso-out-of-core-");
  const test::scratch_dir runs("progiso-out-of-core-runs-");
  const fs::path input = dir.path() / "ball.raw";
  write_ball(input);
  ASSERT_EQ(fs::file_size(input), volume_bytes);
  const std::string dims = std::to_string(n) + "," + std::to_string(n) + "," + std::to_string(n);
  test::bounds capped = test::limited(std::chrono::seconds(240));
  capped.data_bytes = cap;

  const auto args = [&](const std::string& goal, const std::string& value, const std::string& out) {
    return std::vector<std::string>{"extract",   input.string(),
                                    "--dims",    dims,
                                    "--type",    "u8",
                                    "--iso",     "40",
                                    goal,        value,
                                    "--threads", "2",
                                    "-o",        (dir.path() / out).string()};
  };
  // An error goal: the same split set under the cap as without it, so the same file.
  const test::bounded_result free_run =
      test::run_bounded(PROGISO_CLI, args("--error", "0.5", "free.ply"), runs.path());
  ASSERT_EQ(free_run.status, 0) << free_run.err;
  const test::bounded_result capped_run =
      test::run_bounded(PROGISO_CLI, args("--error", "0.5", "capped.ply"), runs.path(), capped);
  ASSERT_EQ(capped_run.status, 0) << capped_run.err;
  const std::string a = test::read_whole(dir.path() / "free.ply");
  EXPECT_GT(a.size(), 10000U);
  EXPECT_TRUE(a == test::read_whole(dir.path() / "capped.ply"))
      << "the capped run wrote another surface";
  // A deadline short of the finest cut (a uniform cut of a subsampled copy): a surface by then.
  const test::bounded_result deadline_run =
      test::run_bounded(PROGISO_CLI, args("--time-ms", "50", "deadline.ply"), runs.path(), capped);
  ASSERT_EQ(deadline_run.status, 0) << deadline_run.err;
  EXPECT_GT(fs::file_size(dir.path() / "deadline.ply"), 1000U);

  // The same bytes read into memory (swapped from big-endian) do not fit under the cap.
  const std::string half =
      std::to_string(n) + "," + std::to_string(n) + "," + std::to_string(n / 2);
  const test::bounded_result read_run =
      test::run_bounded(PROGISO_CLI,
                        {"extract", input.string(), "--dims", half, "--type", "u16", "--big-endian",
                         "--iso", "40", "--error", "0.5", "-o", (dir.path() / "read.ply").string()},
                        runs.path(), capped);
  EXPECT_NE(read_run.status, 0);
  EXPECT_NE(read_run.err.find("out of memory"), std::string::npos) << read_run.err;
  EXPECT_FALSE(fs::exists(dir.path() / "read.ply"));
#endif
}

}  // namespace
}  // namespace progiso
