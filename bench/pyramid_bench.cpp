// Coarse first: from opening a resolution pyramid to a surface on screen. The pyramid engine
// (pyramid_engine: its coarsest level read, then each finer one read and refined out of sight)
// against one engine on the finest level (that level read whole, then refined), in this binary,
// the two interleaved:
//   build/release/bench/progiso_pyramid_bench --benchmark_enable_random_interleaving=true
//       --benchmark_repetitions=4 --benchmark_counters_tabular=true
// The pyramid is an OME-Zarr image of four levels (every level a subsampling by two, chunks of
// 64³, uncompressed: the reads cost file reads, not decoding) of a bumpy ball of 512³ u8 samples,
// written into a scratch directory at start-up and removed at exit.
//   first_surface: until a snapshot holds a surface of at least 10 000 triangles (the root
//   surfaces hold a few dozen).
//   finest_surface: until the finest level's full surface is shown (the pyramid pays for its
//   coarse levels here).
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/pyramid_engine.hpp>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <benchmark/benchmark.h>

namespace progiso::bench {
namespace {

namespace fs = std::filesystem;
using clock = std::chrono::steady_clock;

constexpr std::int64_t side = 512;
constexpr std::int64_t chunk = 64;
constexpr std::size_t levels = 4;
constexpr double isovalue = 120.0;
constexpr std::uint64_t first_triangles = 10000;

std::uint8_t ball(std::int64_t x, std::int64_t y, std::int64_t z) {
  const double c = static_cast<double>(side) / 2.0 + 0.3;
  const double dx = static_cast<double>(x) - c, dy = static_cast<double>(y) - c,
               dz = static_cast<double>(z) - c;
  const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double bumps = 9.0 * std::sin(dx * 0.09) * std::sin(dy * 0.07) * std::sin(dz * 0.08);
  return static_cast<std::uint8_t>(std::clamp(255.0 - (r + bumps), 0.0, 255.0));
}

/// The pyramid's directory, written once; removed at exit.
class pyramid_files {
 public:
  pyramid_files() {
    dir_ = fs::temp_directory_path() / ("progiso-pyramid-bench-" + std::to_string(getpid()));
    fs::create_directories(dir_);
    std::string datasets;
    for (std::size_t k = 0; k < levels; ++k) {
      const std::int64_t step = std::int64_t{1} << k;
      const std::int64_t n = side / step;
      const fs::path level = dir_ / std::to_string(k);
      fs::create_directories(level);
      std::ofstream(level / ".zarray")
          << "{\"zarr_format\": 2, \"shape\": [" << n << ", " << n << ", " << n
          << "], \"chunks\": [" << chunk << ", " << chunk << ", " << chunk
          << "], \"dtype\": \"|u1\", \"compressor\": null, \"fill_value\": 0, \"order\": \"C\", "
             "\"filters\": null}";
      std::vector<char> bytes(static_cast<std::size_t>(chunk * chunk * chunk));
      for (std::int64_t kz = 0; kz * chunk < n; ++kz) {
        for (std::int64_t ky = 0; ky * chunk < n; ++ky) {
          for (std::int64_t kx = 0; kx * chunk < n; ++kx) {
            std::size_t i = 0;
            for (std::int64_t z = 0; z < chunk; ++z) {
              for (std::int64_t y = 0; y < chunk; ++y) {
                for (std::int64_t x = 0; x < chunk; ++x) {
                  bytes[i++] = static_cast<char>(ball(
                      (kx * chunk + x) * step, (ky * chunk + y) * step, (kz * chunk + z) * step));
                }
              }
            }
            std::ofstream(
                level / (std::to_string(kz) + "." + std::to_string(ky) + "." + std::to_string(kx)),
                std::ios::binary)
                .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
          }
        }
      }
      const double s = static_cast<double>(step);
      datasets += std::string(k == 0 ? "" : ", ") + "{\"path\": \"" + std::to_string(k) +
                  "\", \"coordinateTransformations\": [{\"type\": \"scale\", \"scale\": [" +
                  std::to_string(s) + ", " + std::to_string(s) + ", " + std::to_string(s) + "]}]}";
    }
    std::ofstream(dir_ / ".zattrs")
        << "{\"multiscales\": [{\"version\": \"0.4\", \"datasets\": [" << datasets
        << "], \"axes\": [{\"name\": \"z\", \"type\": \"space\"}, {\"name\": \"y\", \"type\": "
           "\"space\"}, {\"name\": \"x\", \"type\": \"space\"}]}]}";
  }
  ~pyramid_files() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  pyramid_files(const pyramid_files&) = delete;
  pyramid_files& operator=(const pyramid_files&) = delete;
  [[nodiscard]] const fs::path& dir() const { return dir_; }

 private:
  fs::path dir_;
};

const fs::path& pyramid() {
  static const pyramid_files files;
  return files.dir();
}

/// Until `done()` answers true, looking every 200 µs.
template <class Done>
void until(const Done& done) {
  while (!done()) std::this_thread::sleep_for(std::chrono::microseconds(200));
}

/// The pyramid engine over `src`, its coarsest level read, refining towards the full surface.
std::unique_ptr<pyramid_engine> open_pyramid(volume_source& src) {
  auto p = std::make_unique<pyramid_engine>(
      [&src](std::size_t k, const std::function<bool()>& stop) {
        return src.read_level(k, std::nullopt, stop);
      },
      src.levels(), isovalue);
  p->start(refine_goal::full());
  return p;
}

// 0: the pyramid engine; 1: one engine on the finest level.
void BM_first_surface(benchmark::State& state) {
  const bool pyramid_engine_path = state.range(0) == 0;
  std::uint64_t triangles = 0;
  std::size_t level = 0;
  for (auto _ : state) {
    volume_source src(pyramid(), std::nullopt);
    if (pyramid_engine_path) {
      const std::unique_ptr<pyramid_engine> p = open_pyramid(src);
      until([&] { return p->snapshot().surface.triangle_count() >= first_triangles; });
      state.PauseTiming();
      const pyramid_snapshot s = p->snapshot();
      triangles = s.surface.triangle_count();
      level = s.level;
    } else {
      engine e(*src.read_level(0), isovalue);
      e.start(refine_goal::full());
      until([&] { return e.snapshot().triangle_count() >= first_triangles; });
      state.PauseTiming();
      triangles = e.snapshot().triangle_count();
      level = 0;
    }
    state.ResumeTiming();
  }
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["level"] = static_cast<double>(level);
}
BENCHMARK(BM_first_surface)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_finest_surface(benchmark::State& state) {
  const bool pyramid_engine_path = state.range(0) == 0;
  std::uint64_t triangles = 0;
  for (auto _ : state) {
    volume_source src(pyramid(), std::nullopt);
    if (pyramid_engine_path) {
      const std::unique_ptr<pyramid_engine> p = open_pyramid(src);
      p->wait();
      state.PauseTiming();
      triangles = p->snapshot().surface.triangle_count();
    } else {
      engine e(*src.read_level(0), isovalue);
      e.refine_full();
      state.PauseTiming();
      triangles = e.snapshot().triangle_count();
    }
    state.ResumeTiming();
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}
BENCHMARK(BM_finest_surface)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  (void)progiso::bench::pyramid();  // written before any benchmark runs
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
