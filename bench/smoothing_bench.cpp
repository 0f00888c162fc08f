// Benchmarks of smoothing: the 4-point subdivision field refined like data.
//
// - BM_smoothed_pipeline/<input>/<field>/<threads>: the command's pipeline (smooth(), range
//   data, refinement, extraction of the full-resolution mesh; extract_isosurface_parallel) from
//   the volume in memory. Counters: triangles, splits, computed (fine samples computed from the
//   data; cached re-reads do not count), ns_per_computed (pipeline time / computed: an upper
//   bound on the cost of one subdivided sample), first_ms, peak_heap_MiB (the largest heap in use
//   during the run beyond what was in use before it: every operator new of the process is
//   counted), heap_per_data_byte, field_samples.
// - BM_subdivided_sample/<input>/<field>: one fine sample on its own. Every iteration makes the
//   field afresh and reads each sample of a box of the fine grid (up to 48³) once: computed_ns
//   (every read a cache miss: the rows applied to the data); then an 8³ corner twice: cached_ns
//   is the second pass (reads the cache answers).
// - BM_smooth_over_data/<input>/<threads>: `--smooth 1 --full` against `--full` on the same
//   volume, in alternating pairs (the order flips every pair): median data_ms, smooth_ms, and
//   ratio (median of the per-pair ratios), with both triangle counts.
// - BM_first_smooth_surface/<input>/<field>: from the data in memory to the first smooth surface:
//   an engine made with engine_options::smooth (it builds the field) and its first snapshot's
//   mesh, as the command shows it.
// - BM_smoothed_contours/<image>/<field>: the 2D pipeline (extract_contours) on smoothed images.
// Fields: data (S 0, K 0), S1, S2, K1 (--smooth-from 1), S1K1. Run:
//   build/release/bench/progiso_smoothing_bench --benchmark_counters_tabular=true
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/io/image_io.hpp>
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <malloc.h>

#include "bench_common.hpp"
#include "heap_meter.hpp"
#include "steady_allocator.hpp"

namespace progiso::bench {
namespace {

struct field_spec {
  const char* name;
  smoothing s;
};
const std::vector<field_spec>& fields() {
  static const std::vector<field_spec> all{
      {"data", {0, 0, std::nullopt, 1.0}}, {"S1", {1, 0, std::nullopt, 1.0}},
      {"S2", {2, 0, std::nullopt, 1.0}},   {"K1", {0, 1, std::nullopt, 1.0}},
      {"S1K1", {1, 1, std::nullopt, 1.0}},
  };
  return all;
}

/// One input, loaded when its first benchmark runs.
struct input {
  std::string name;
  std::function<volume()> make;
  double isovalue;
  int max_levels;  // the largest S benchmarked on it (S2 of a large volume takes minutes)
  std::shared_ptr<const volume> made;
  const std::shared_ptr<const volume>& get() {
    if (!made) made = std::make_shared<const volume>(make());
    return made;
  }
};

std::vector<input>& volumes() {
  static std::vector<input> all = [] {
    std::vector<input> v;
    const auto raw = [&](std::string name, const char* file, index3 dims, sample_type t,
                         std::array<double, 3> spacing, double w, int max_levels) {
      const std::filesystem::path p = data_dir() / file;
      if (!std::filesystem::exists(p)) return;
      v.push_back({std::move(name),
                   [=] {
                     return read_raw(p, {dims, t, false}, spacing);
                   },
                   w, max_levels, nullptr});
    };
    raw("bucky", "bucky_32x32x32_uint8.raw", {32, 32, 32}, sample_type::u8, {1, 1, 1}, 51, 2);
    raw("headsq", "headsq_64x64x93_int16le.raw", {64, 64, 93}, sample_type::i16, {3.2, 3.2, 1.5},
        1150, 2);
    raw("brainsmall", "brainsmall_128x128x84_uint8.raw", {128, 128, 84}, sample_type::u8, {1, 1, 1},
        50, 1);
    return v;
  }();
  return all;
}

std::vector<input>& images() {
  static std::vector<input> all = [] {
    std::vector<input> v;
    const auto image = [&](std::string name, const char* file, double w) {
      const std::filesystem::path p = data_dir() / file;
      if (std::filesystem::exists(p))
        v.push_back({std::move(name), [=] { return read_image(p); }, w, 2, nullptr});
    };
    image("camera", "camera_512x512.pgm", 100);
    image("coins", "coins_384x303.pgm", 128);
    return v;
  }();
  return all;
}

std::uint64_t computed(const volume& field) {
  const detail::subdivision* sub = field.subdivided();
  return sub == nullptr ? 0 : sub->evaluations();
}

double field_samples(const volume& field) {
  const index3& d = field.dims();
  return static_cast<double>(d[0]) * static_cast<double>(d[1]) * static_cast<double>(d[2]);
}

// ---- 3D pipeline.

struct pipeline_run {
  double ms = 0.0;
  double first_ms = 0.0;
  std::size_t triangles = 0;
  std::uint64_t splits = 0;
  std::uint64_t computed = 0;
  double field_samples = 0.0;
};

pipeline_run run_pipeline(const std::shared_ptr<const volume>& data, const smoothing& s,
                          double isovalue, unsigned threads) {
  pipeline_run r;
  const auto t0 = clock_type::now();
  std::optional<volume> field;
  if (s.active()) field.emplace(smooth(data, s));
  const volume& v = field ? *field : *data;
  const extract_result x = extract_isosurface_parallel(v, isovalue, extract_options{}, threads);
  r.ms = ms_since(t0);
  r.first_ms = x.first_surface_seconds * 1e3;
  r.triangles = x.mesh.triangles.size();
  r.splits = x.stats.splits;
  r.computed = computed(v);
  r.field_samples = field_samples(v);
  benchmark::DoNotOptimize(x.mesh.vertices.data());
  return r;
}

void BM_smoothed_pipeline(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const field_spec& f = fields()[static_cast<std::size_t>(state.range(1))];
  const auto threads = static_cast<unsigned>(state.range(2));
  const auto& data = in.get();
  state.SetLabel(in.name + " " + f.name + " " + std::to_string(threads) + " thr");
  pipeline_run r;
  double peak = 0.0;
  for (auto _ : state) {
    const heap_window heap;
    r = run_pipeline(data, f.s, in.isovalue, threads);
    peak = std::max(peak, heap.peak_mib());
    state.SetIterationTime(r.ms / 1e3);
  }
  state.counters["triangles"] = static_cast<double>(r.triangles);
  state.counters["splits"] = static_cast<double>(r.splits);
  state.counters["computed"] = static_cast<double>(r.computed);
  state.counters["ns_per_computed"] =
      r.computed == 0 ? 0.0 : r.ms * 1e6 / static_cast<double>(r.computed);
  state.counters["first_ms"] = r.first_ms;
  state.counters["peak_heap_MiB"] = peak;
  state.counters["heap_per_data_byte"] = peak * (1 << 20) / static_cast<double>(data->byte_size());
  state.counters["field_samples"] = r.field_samples;
}

// ---- One fine sample.

void BM_subdivided_sample(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const field_spec& f = fields()[static_cast<std::size_t>(state.range(1))];
  const auto& data = in.get();
  state.SetLabel(in.name + " " + f.name);
  std::vector<double> first;
  std::vector<double> second;
  double samples = 0.0;
  for (auto _ : state) {
    const volume field = smooth(data, f.s);
    const index3& d = field.dims();
    // A box of up to 48³ fine samples in the middle of the grid.
    std::array<std::int64_t, 3> lo{};
    std::array<std::int64_t, 3> hi{};
    for (std::size_t q = 0; q < 3; ++q) {
      const std::int64_t n = std::min<std::int64_t>(48, d[q]);
      lo[q] = (d[q] - n) / 2;
      hi[q] = lo[q] + n;
    }
    const auto pass = [&](std::int64_t edge) {
      double sum = 0.0;
      const auto t0 = clock_type::now();
      for (std::int64_t z = lo[2]; z < std::min(hi[2], lo[2] + edge); ++z)
        for (std::int64_t y = lo[1]; y < std::min(hi[1], lo[1] + edge); ++y)
          for (std::int64_t x = lo[0]; x < std::min(hi[0], lo[0] + edge); ++x) {
            sum += field.at(field.linear(x, y, z));
          }
      benchmark::DoNotOptimize(sum);
      return ms_since(t0);
    };
    const auto count = [&](std::int64_t edge) {
      double n = 1.0;
      for (std::size_t q = 0; q < 3; ++q) n *= static_cast<double>(std::min(hi[q] - lo[q], edge));
      return n;
    };
    // The whole box once: every read computes. Then an 8³ corner of it twice: the second pass
    // reads samples the first left in the cache (8³ = 512 of its 4096 entries).
    samples = count(48);
    const double all_ms = pass(48);
    first.push_back(all_ms * 1e6 / samples);
    (void)pass(8);
    second.push_back(pass(8) * 1e6 / count(8));
    state.SetIterationTime(all_ms / 1e3);
  }
  state.counters["computed_ns"] = median(first);
  state.counters["cached_ns"] = median(second);
  state.counters["box_samples"] = samples;
}

// ---- --smooth 1 --full against --full, in alternating pairs.

void BM_smooth_over_data(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const auto threads = static_cast<unsigned>(state.range(1));
  const auto& data = in.get();
  state.SetLabel(in.name + " " + std::to_string(threads) + " thr");
  const smoothing none{};
  const smoothing s1{1, 0, std::nullopt, 1.0};
  std::vector<double> data_ms;
  std::vector<double> smooth_ms;
  std::vector<double> ratio;
  pipeline_run d;
  pipeline_run s;
  int pair = 0;
  for (auto _ : state) {
    if (pair++ % 2 == 0) {
      d = run_pipeline(data, none, in.isovalue, threads);
      s = run_pipeline(data, s1, in.isovalue, threads);
    } else {
      s = run_pipeline(data, s1, in.isovalue, threads);
      d = run_pipeline(data, none, in.isovalue, threads);
    }
    data_ms.push_back(d.ms);
    smooth_ms.push_back(s.ms);
    ratio.push_back(s.ms / d.ms);
    state.SetIterationTime((d.ms + s.ms) / 1e3);
  }
  state.counters["data_ms"] = median(data_ms);
  state.counters["smooth_ms"] = median(smooth_ms);
  state.counters["ratio"] = median(ratio);
  state.counters["data_triangles"] = static_cast<double>(d.triangles);
  state.counters["smooth_triangles"] = static_cast<double>(s.triangles);
}

// ---- First surface, from the volume in memory.

void BM_first_smooth_surface(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const field_spec& f = fields()[static_cast<std::size_t>(state.range(1))];
  const auto& data = in.get();
  state.SetLabel(in.name + " " + f.name);
  std::size_t tris = 0;
  for (auto _ : state) {
    engine_options options;
    options.threads = 1;
    options.smooth = f.s;
    const engine e(*data, in.isovalue, std::move(options));
    const triangle_mesh m = e.snapshot().mesh();
    tris = m.triangles.size();
    benchmark::DoNotOptimize(m.vertices.data());
  }
  state.counters["triangles"] = static_cast<double>(tris);
}

// ---- 2D.

void BM_smoothed_contours(benchmark::State& state) {
  input& in = images()[static_cast<std::size_t>(state.range(0))];
  const field_spec& f = fields()[static_cast<std::size_t>(state.range(1))];
  const auto& data = in.get();
  state.SetLabel(in.name + " " + f.name);
  std::size_t segments = 0;
  std::uint64_t n = 0;
  double peak = 0.0;
  for (auto _ : state) {
    const heap_window heap;
    std::optional<volume> field;
    if (f.s.active()) field.emplace(smooth(data, f.s));
    const volume& v = field ? *field : *data;
    const contour_result r = extract_contours(v, {in.isovalue}, contour_options{});
    segments = r.contours.segment_count();
    n = computed(v);
    peak = std::max(peak, heap.peak_mib());
    benchmark::DoNotOptimize(r.contours.vertices.data());
  }
  state.counters["segments"] = static_cast<double>(segments);
  state.counters["computed"] = static_cast<double>(n);
  state.counters["peak_heap_MiB"] = peak;
}

void register_all() {
  for (std::size_t i = 0; i < volumes().size(); ++i) {
    const input& in = volumes()[i];
    for (std::size_t k = 0; k < fields().size(); ++k) {
      const field_spec& f = fields()[k];
      if (f.s.levels > in.max_levels) continue;
      const std::string id = in.name + "/" + f.name;
      const auto args = [&](std::int64_t extra) {
        return std::vector<std::int64_t>{static_cast<std::int64_t>(i), static_cast<std::int64_t>(k),
                                         extra};
      };
      for (const std::int64_t t : {1, 2}) {
        benchmark::RegisterBenchmark(
            ("BM_smoothed_pipeline/" + id + "/" + std::to_string(t)).c_str(), BM_smoothed_pipeline)
            ->Args(args(t))
            ->Iterations(f.s.levels >= 2 ? 1 : 5)
            ->UseManualTime()
            ->Unit(benchmark::kMillisecond);
      }
      if (f.s.active()) {
        benchmark::RegisterBenchmark(("BM_subdivided_sample/" + id).c_str(), BM_subdivided_sample)
            ->Args({static_cast<std::int64_t>(i), static_cast<std::int64_t>(k)})
            ->Iterations(5)
            ->UseManualTime()
            ->Unit(benchmark::kMillisecond);
      }
      benchmark::RegisterBenchmark(("BM_first_smooth_surface/" + id).c_str(),
                                   BM_first_smooth_surface)
          ->Args({static_cast<std::int64_t>(i), static_cast<std::int64_t>(k)})
          ->Unit(benchmark::kMicrosecond);
    }
    for (const std::int64_t t : {1, 2}) {
      benchmark::RegisterBenchmark(
          ("BM_smooth_over_data/" + in.name + "/" + std::to_string(t)).c_str(), BM_smooth_over_data)
          ->Args({static_cast<std::int64_t>(i), t})
          ->Iterations(7)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond);
    }
  }
  for (std::size_t i = 0; i < images().size(); ++i) {
    for (std::size_t k = 0; k < fields().size(); ++k) {
      benchmark::RegisterBenchmark(
          ("BM_smoothed_contours/" + images()[i].name + "/" + fields()[k].name).c_str(),
          BM_smoothed_contours)
          ->Args({static_cast<std::int64_t>(i), static_cast<std::int64_t>(k)})
          ->Unit(benchmark::kMillisecond);
    }
  }
}

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) {
  return progiso::bench::run_benchmarks(argc, argv, progiso::bench::register_all);
}
