// A volume larger than the memory the process may allocate: a raw input of at least
// detail::map_min_bytes is mapped, not read, and the engine's per-vertex words follow what it
// writes (vertex_pages), so the command refines it under an RLIMIT_DATA below the volume's size,
// and writes the same surface as without the limit (an error goal), or by a deadline the finest
// cut that fits under it.
// The same bytes as an input that must be read (big-endian 16-bit samples, swapped into memory)
// are refused under that limit: the limit is real, and the mapping is what lets the first run
// through. The finest surface of a grid beyond detail::finest_whole_grid_bytes points is made in
// slabs and streamed to the PLY through scratch files, under the same limit: the file is the one
// the whole surface gives; with --normals it is held whole, its passes still in slabs. A Zarr
// level, which must be decoded, is read in windows of planes for its finest surface under the
// same limit (and refused whole).

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/io/mesh_io.hpp>
#include <progiso/io/volume_io.hpp>

#include "support/bounded_run.hpp"
#include "support/scratch_dir.hpp"
#include "support/zarr_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

constexpr int n = 576;  // 576³ bytes: 182 MiB
[[maybe_unused]] constexpr std::uint64_t volume_bytes = std::uint64_t{n} * n * n;
[[maybe_unused]] constexpr std::uint64_t cap = std::uint64_t{150} << 20;

// A ball of radius about 44 at the isovalue 40 (samples 0.9 × the distance from an off-grid
// centre) in an n³ grid, written slice by slice.
[[maybe_unused]] void write_ball(const fs::path& p, std::size_t side = n) {
  std::ofstream out(p, std::ios::binary);
  std::vector<char> slice(side * side);
  const double c = static_cast<double>(side) / 2.0 + 0.3;
  for (std::size_t z = 0; z < side; ++z) {
    for (std::size_t y = 0; y < side; ++y) {
      for (std::size_t x = 0; x < side; ++x) {
        const double dx = static_cast<double>(x) - c, dy = static_cast<double>(y) - c,
                     dz = static_cast<double>(z) - c;
        const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
        slice[y * side + x] =
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
  // A deadline with time for every cut: the finest cut's corner bytes (one byte per grid point,
  // one slab) do not fit under the cap, every coarser cut reads the samples in place. The ladder
  // gives up the finest cut for its memory, not its time, and writes the cut of every 2nd sample:
  // whatever the machine's load, since time never runs out.
  std::vector<std::string> deadline_args = args("--time-ms", "600000", "deadline.ply");
  deadline_args.push_back("--stats-json");
  deadline_args.push_back((dir.path() / "deadline.json").string());
  const test::bounded_result deadline_run =
      test::run_bounded(PROGISO_CLI, deadline_args, runs.path(), capped);
  ASSERT_EQ(deadline_run.status, 0) << deadline_run.err;
  EXPECT_NE(deadline_run.out.find("every 2nd sample by the deadline (the next finer cut did not "
                                  "fit in memory)"),
            std::string::npos)
      << deadline_run.out;
  const std::string stats = test::read_whole(dir.path() / "deadline.json");
  EXPECT_NE(stats.find("\"stride\": 2,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"out_of_memory\": true"), std::string::npos) << stats;
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

TEST(OutOfCore, a_zarr_level_larger_than_the_allowed_memory_is_read_in_windows_to_its_surface) {
#if defined(PROGISO_SANITIZER_BUILD)
  GTEST_SKIP() << "sanitizer builds run without memory limits (their shadow memory)";
#else
  // The ball of the first test as a Zarr array (uncompressed chunks of 32 planes, two per row):
  // nothing maps a chunked level, so its samples must be decoded into memory. The finest surface
  // is made share by share over windows of planes, under the same limit, to the file the raw
  // input gives; an error goal, which reads the level whole, cannot run under it.
  const test::scratch_dir dir("progiso-out-of-core-");
  const test::scratch_dir runs("progiso-out-of-core-runs-");
  const fs::path raw = dir.path() / "ball.raw";
  write_ball(raw);
  const fs::path zarr = dir.path() / "ball.zarr";
  {
    const std::string bytes = test::read_whole(raw);
    test::write_zarr_array(
        zarr, {n, n, n}, {n, n / 2, 32}, "|u1", 1,
        [&](std::int64_t x, std::int64_t y, std::int64_t z, std::byte* out) {
          *out = static_cast<std::byte>(bytes[static_cast<std::size_t>((z * n + y) * n + x)]);
        });
  }
  test::bounds capped = test::limited(std::chrono::seconds(240));
  capped.data_bytes = cap;
  const std::string dims = std::to_string(n) + "," + std::to_string(n) + "," + std::to_string(n);
  const test::bounded_result from_raw =
      test::run_bounded(PROGISO_CLI,
                        {"extract", raw.string(), "--dims", dims, "--type", "u8", "--iso", "40",
                         "--full", "-o", (dir.path() / "raw.ply").string()},
                        runs.path());
  ASSERT_EQ(from_raw.status, 0) << from_raw.err;
  const auto zarr_args = [&](const std::string& goal, const std::string& out) {
    std::vector<std::string> a{"extract", zarr.string(), "--iso", "40", goal};
    if (goal == "--error") a.emplace_back("0.5");
    a.insert(a.end(), {"--threads", "2", "-o", (dir.path() / out).string(), "--stats-json",
                       (dir.path() / (out + ".json")).string()});
    return a;
  };
  const test::bounded_result windowed =
      test::run_bounded(PROGISO_CLI, zarr_args("--full", "zarr.ply"), runs.path(), capped);
  ASSERT_EQ(windowed.status, 0) << windowed.err;
  EXPECT_TRUE(test::read_whole(dir.path() / "zarr.ply") == test::read_whole(dir.path() / "raw.ply"))
      << "the windowed Zarr level gave another surface than its raw samples";
  const std::string stats = test::read_whole(dir.path() / "zarr.ply.json");
  EXPECT_NE(stats.find("\"windowed\": true"), std::string::npos) << stats;
  const std::size_t at = stats.find("\"window_peak_bytes\": ");
  ASSERT_NE(at, std::string::npos) << stats;
  const std::uint64_t peak = std::stoull(stats.substr(at + 21));
  EXPECT_GT(peak, 0U);
  EXPECT_LT(peak, volume_bytes / 2) << stats;

  const test::bounded_result whole =
      test::run_bounded(PROGISO_CLI, zarr_args("--error", "whole.ply"), runs.path(), capped);
  EXPECT_NE(whole.status, 0);
  EXPECT_NE(whole.err.find("out of memory"), std::string::npos) << whole.err;
  EXPECT_FALSE(fs::exists(dir.path() / "whole.ply"));

  // A window larger than the limit allows (the whole level, asked for through the tests' knob):
  // one error, when a window's planes or a chunk's buffer cannot be had, and no output.
  setenv("PROGISO_WINDOW_BYTES", "1073741824", 1);
  const test::bounded_result too_wide =
      test::run_bounded(PROGISO_CLI, zarr_args("--full", "wide.ply"), runs.path(), capped);
  unsetenv("PROGISO_WINDOW_BYTES");
  EXPECT_EQ(too_wide.status, 2) << too_wide.err;
  const bool named = too_wide.err.find("progiso: error: " + zarr.string() +
                                       ": cannot hold planes ") != std::string::npos;
  EXPECT_TRUE(named || too_wide.err.find("progiso: error: out of memory") != std::string::npos)
      << too_wide.err;
  EXPECT_EQ(too_wide.err.find("error:"), too_wide.err.rfind("error:")) << too_wide.err;
  EXPECT_FALSE(fs::exists(dir.path() / "wide.ply"));
#endif
}

TEST(OutOfCore, the_finest_surface_of_a_volume_larger_than_the_allowed_memory_streams_to_a_ply) {
#if defined(PROGISO_SANITIZER_BUILD)
  GTEST_SKIP() << "sanitizer builds run without memory limits (their shadow memory)";
#else
  constexpr int big = 648;  // 648³ bytes: 259 MiB, past finest_whole_grid_bytes
  static_assert(std::uint64_t{big} * big * big > detail::finest_whole_grid_bytes);
  static_assert(cap < std::uint64_t{big} * big * big);
  const test::scratch_dir dir("progiso-out-of-core-");
  const test::scratch_dir runs("progiso-out-of-core-runs-");
  const fs::path input = dir.path() / "ball.raw";
  write_ball(input, big);
  const std::string dims =
      std::to_string(big) + "," + std::to_string(big) + "," + std::to_string(big);
  test::bounds capped = test::limited(std::chrono::seconds(240));
  capped.data_bytes = cap;
  const auto args = [&](const std::string& out) {
    return std::vector<std::string>{"extract",
                                    input.string(),
                                    "--dims",
                                    dims,
                                    "--type",
                                    "u8",
                                    "--iso",
                                    "40",
                                    "--full",
                                    "--threads",
                                    "2",
                                    "-o",
                                    (dir.path() / out).string(),
                                    "--stats-json",
                                    (dir.path() / (out + ".json")).string()};
  };
  const test::bounded_result streamed =
      test::run_bounded(PROGISO_CLI, args("streamed.ply"), runs.path(), capped);
  ASSERT_EQ(streamed.status, 0) << streamed.err;
  const std::string stats = test::read_whole(dir.path() / "streamed.ply.json");
  EXPECT_NE(stats.find("\"streamed\": true"), std::string::npos) << stats;
  // No scratch file left beside the output: the PLY and its statistics alone.
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++files;
  EXPECT_EQ(files, 3U);

  // The file write_ply() writes for the whole surface (made here, without a limit).
  const volume v = read_raw(input, raw_layout{{big, big, big}, sample_type::u8});
  const triangle_mesh whole = finest_surface(v, 40.0);
  EXPECT_GT(whole.triangles.size(), 10000U);
  write_ply(dir.path() / "whole.ply", whole);
  EXPECT_TRUE(test::read_whole(dir.path() / "streamed.ply") ==
              test::read_whole(dir.path() / "whole.ply"))
      << "the streamed PLY is not the whole surface's";

  // --normals holds the surface whole in memory (normals need the triangles around a vertex
  // where the gradient vanishes, some in another slab); its passes still go slab by slab, so it
  // runs under the limit too, to the same vertices and triangles.
  std::vector<std::string> whole_args = args("normals.ply");
  whole_args.emplace_back("--normals");
  const test::bounded_result in_memory =
      test::run_bounded(PROGISO_CLI, whole_args, runs.path(), capped);
  ASSERT_EQ(in_memory.status, 0) << in_memory.err;
  EXPECT_NE(test::read_whole(dir.path() / "normals.ply.json").find("\"streamed\": false"),
            std::string::npos);
  const triangle_mesh with_normals = read_ply(dir.path() / "normals.ply");
  EXPECT_EQ(with_normals.normals.size(), with_normals.vertices.size());
  EXPECT_EQ(with_normals.triangles, whole.triangles);
  ASSERT_EQ(with_normals.vertices.size(), whole.vertices.size());
  for (std::size_t i = 0; i < whole.vertices.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) {
      ASSERT_EQ(with_normals.vertices[i][a],
                static_cast<double>(static_cast<float>(whole.vertices[i][a])));
    }
  }
#endif
}

TEST(OutOfCore, refinement_beyond_the_allowed_memory_ends_with_one_error_and_no_output) {
#if defined(PROGISO_SANITIZER_BUILD)
  GTEST_SKIP() << "sanitizer builds run without memory limits (their shadow memory)";
#else
  // Noise: full refinement makes a surface in nearly every cell, its records far beyond the
  // limit, in the engine's driver thread. That failure reaches the command (wait() rethrows it)
  // as one line and exit status 2, with no output, not a terminate() from the thread.
  constexpr std::size_t side = 192;
  const test::scratch_dir dir("progiso-out-of-core-");
  const test::scratch_dir runs("progiso-out-of-core-runs-");
  const fs::path input = dir.path() / "noise.raw";
  {
    std::string bytes(side * side * side, '\0');
    std::uint32_t x = 12345;
    for (char& c : bytes) {
      x = x * 1664525u + 1013904223u;
      c = static_cast<char>(x >> 24);
    }
    std::ofstream(input, std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  test::bounds capped = test::limited(std::chrono::seconds(240));
  capped.data_bytes = std::uint64_t{96} << 20;
  const std::string dims =
      std::to_string(side) + "," + std::to_string(side) + "," + std::to_string(side);
  for (const std::string threads : {"1", "2"}) {
    SCOPED_TRACE(threads + " threads");
    const test::bounded_result run = test::run_bounded(
        PROGISO_CLI,
        {"extract", input.string(), "--dims", dims, "--type", "u8", "--iso", "127.5", "--error",
         "0", "--threads", threads, "-o", (dir.path() / "noise.ply").string()},
        runs.path(), capped);
    EXPECT_EQ(run.status, 2) << run.err;
    EXPECT_NE(run.err.find("progiso: error: out of memory"), std::string::npos) << run.err;
    EXPECT_EQ(run.err.find("terminate"), std::string::npos) << run.err;
    std::size_t files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++files;
    EXPECT_EQ(files, 1U) << "an output or a temporary was left";
  }
#endif
}

}  // namespace
}  // namespace progiso
