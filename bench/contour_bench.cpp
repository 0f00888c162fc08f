// Benchmarks of 2D progressive contouring: full progressive contouring against plain
// marching triangles in the same binary, and time to first contour on a 4097² generated field;
// the contour engine against the sequential contour refiner, and its isovalue changes.
//   build/release/bench/progiso_contour_bench --benchmark_counters_tabular=true
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/io/image_io.hpp>
#include <progiso/scheduler/contour_engine.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>

#include "bench_common.hpp"
#include "steady_allocator.hpp"

#include "plain_mtri.hpp"

namespace progiso::bench {
namespace {

struct input {
  std::string name;
  std::unique_ptr<volume> img;
  double isovalue;
};

std::unique_ptr<volume> generated(std::int64_t n) {
  std::vector<std::byte> b(static_cast<std::size_t>(n * n) * sizeof(float));
  auto* p = reinterpret_cast<float*>(b.data());
  for (std::int64_t y = 0; y < n; ++y)
    for (std::int64_t x = 0; x < n; ++x) {
      const double u = static_cast<double>(x) / static_cast<double>(n - 1);
      const double v = static_cast<double>(y) / static_cast<double>(n - 1);
      p[x + n * y] = static_cast<float>(std::sin(31.0 * u) * std::cos(23.0 * v) +
                                        0.5 * std::sin(7.0 * (u + v)));
    }
  return std::make_unique<volume>(index3{n, n, 1}, sample_type::f32, std::move(b));
}

const std::vector<input>& inputs() {
  static const std::vector<input> all = [] {
    std::vector<input> v;
    const auto load = [&](const char* name, const char* file, double w) {
      try {
        v.push_back({name, std::make_unique<volume>(read_image(data_dir() / file)), w});
      } catch (const error&) {
      }
    };
    load("camera", "camera_512x512.pgm", 128);
    load("coins", "coins_384x303.pgm", 128);
    load("dem", "jacksboro_dem_403x344_u16.pgm", 600);
    v.push_back({"waves4097", generated(4097), 0.1});
    v.push_back({"waves1025", generated(1025), 0.1});
    return v;
  }();
  return all;
}

void BM_contour_plain_mtri(benchmark::State& state) {
  const input& in = inputs()[static_cast<std::size_t>(state.range(0))];
  state.SetLabel(in.name);
  std::size_t segs = 0;
  for (auto _ : state) {
    const contour_set c = plain_marching_triangles(*in.img, in.isovalue);
    segs = c.segment_count();
    benchmark::DoNotOptimize(c.vertices.data());
  }
  state.counters["segments"] = static_cast<double>(segs);
  state.counters["seg_per_s"] =
      benchmark::Counter(static_cast<double>(segs), benchmark::Counter::kIsIterationInvariantRate);
}

struct prepared {
  hierarchy2d hier;
  range_data2d ranges;
  explicit prepared(const volume& v) : hier(v.dims()[0], v.dims()[1]), ranges(v, hier) {}
};

const prepared& prepare(std::size_t i) {
  static std::map<std::size_t, std::unique_ptr<prepared>> cache;
  auto& p = cache[i];
  if (!p) p = std::make_unique<prepared>(*inputs()[i].img);
  return *p;
}

void BM_contour_progressive_full(benchmark::State& state) {
  const std::size_t i = static_cast<std::size_t>(state.range(0));
  const input& in = inputs()[i];
  const prepared& p = prepare(i);
  state.SetLabel(in.name);
  std::size_t segs = 0;
  contour_statistics st;
  for (auto _ : state) {
    contour_refiner r(*in.img, p.hier, p.ranges, in.isovalue, contour_order::breadth_first);
    r.refine_full();
    const contour_set c = r.extract();
    segs = c.segment_count();
    st = r.statistics();
    benchmark::DoNotOptimize(c.vertices.data());
  }
  state.counters["segments"] = static_cast<double>(segs);
  state.counters["seg_per_s"] =
      benchmark::Counter(static_cast<double>(segs), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["visited_per_pixel"] =
      static_cast<double>(st.visited) / static_cast<double>(in.img->voxel_count());
}

void BM_contour_time_to_first(benchmark::State& state) {
  const std::size_t i = static_cast<std::size_t>(state.range(0));
  const input& in = inputs()[i];
  const prepared& p = prepare(i);
  state.SetLabel(in.name);
  std::size_t segs = 0;
  for (auto _ : state) {
    contour_refiner r(*in.img, p.hier, p.ranges, in.isovalue);
    const contour_set c = r.extract();
    segs = c.segment_count();
    benchmark::DoNotOptimize(c.vertices.data());
  }
  state.counters["segments"] = static_cast<double>(segs);
}

void BM_contour_range_build(benchmark::State& state) {
  const input& in = inputs()[static_cast<std::size_t>(state.range(0))];
  state.SetLabel(in.name);
  std::size_t bytes = 0;
  for (auto _ : state) {
    const hierarchy2d h(in.img->dims()[0], in.img->dims()[1]);
    const range_data2d r(*in.img, h);
    bytes = r.byte_size();
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["bytes_per_image_byte"] =
      static_cast<double>(bytes) / static_cast<double>(in.img->byte_size());
}

// The contour engine (its driver thread) against the sequential contour refiner (breadth first,
// as `progiso contour` runs it): full refinement and the finest contour's polylines in memory,
// range data built beforehand for both, a fresh root (engine) or refiner per run. Pairs
// alternate which runs first; `engine_over_refiner` is the median of the per-pair time ratios.
void BM_contour_engine_over_refiner(benchmark::State& state) {
  using clock = std::chrono::steady_clock;
  const std::size_t i = static_cast<std::size_t>(state.range(0));
  const input& in = inputs()[i];
  const prepared& p = prepare(i);
  state.SetLabel(in.name);
  contour_engine e(*in.img, in.isovalue);
  (void)e.ranges();
  std::vector<double> ratios;
  double engine_s = 0.0;
  double refiner_s = 0.0;
  std::size_t segs = 0;
  for (auto _ : state) {
    double te = 0.0;
    double tr = 0.0;
    const auto run_engine = [&] {
      e.set_isovalue(in.isovalue);  // a fresh root: all the work ahead
      const auto t0 = clock::now();
      e.refine_full();
      const contour_set c = e.snapshot().extract();
      te = std::chrono::duration<double>(clock::now() - t0).count();
      segs = c.segment_count();
      benchmark::DoNotOptimize(c.vertices.data());
    };
    const auto run_refiner = [&] {
      const auto t0 = clock::now();
      contour_refiner r(*in.img, p.hier, p.ranges, in.isovalue, contour_order::breadth_first);
      r.refine_full();
      const contour_set c = r.extract();
      tr = std::chrono::duration<double>(clock::now() - t0).count();
      benchmark::DoNotOptimize(c.vertices.data());
    };
    if (state.iterations() % 2 == 0) {
      run_engine();
      run_refiner();
    } else {
      run_refiner();
      run_engine();
    }
    ratios.push_back(te / tr);
    engine_s += te;
    refiner_s += tr;
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["engine_over_refiner"] = median(ratios);
  state.counters["engine_ms"] = 1e3 * engine_s / n;
  state.counters["refiner_ms"] = 1e3 * refiner_s / n;
  state.counters["segments"] = static_cast<double>(segs);
}

// An isovalue change while a full run is in progress: set_isovalue() (cancel the run, publish
// the new root contour, resume the run) plus the new isovalue's first contour extracted from a
// snapshot; per-change latencies in µs (median and largest).
void BM_contour_isovalue_change(benchmark::State& state) {
  using clock = std::chrono::steady_clock;
  const std::size_t i = static_cast<std::size_t>(state.range(0));
  const input& in = inputs()[i];
  state.SetLabel(in.name);
  contour_engine e(*in.img, in.isovalue);
  (void)e.ranges();
  const auto [lo, hi] = in.img->value_range();
  std::vector<double> us;
  std::uint64_t k = 0;
  for (auto _ : state) {
    e.start(refine_goal::full());
    const double w = in.isovalue + (k++ % 2 == 0 ? 0.01 : -0.01) * (hi - lo);
    const auto t0 = clock::now();
    e.set_isovalue(w);
    const contour_set c = e.snapshot().extract();
    us.push_back(std::chrono::duration<double, std::micro>(clock::now() - t0).count());
    benchmark::DoNotOptimize(c.vertices.data());
  }
  e.cancel();
  std::sort(us.begin(), us.end());
  state.counters["p50_us"] = us[us.size() / 2];
  state.counters["max_us"] = us.back();
}

void all_inputs(benchmark::internal::Benchmark* b) {
  for (std::size_t i = 0; i < inputs().size(); ++i) b->Arg(static_cast<std::int64_t>(i));
}

BENCHMARK(BM_contour_plain_mtri)->Apply(all_inputs)->Unit(benchmark::kMillisecond)->MinTime(0.2);
BENCHMARK(BM_contour_progressive_full)
    ->Apply(all_inputs)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(0.2);
BENCHMARK(BM_contour_time_to_first)->Apply(all_inputs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_contour_range_build)->Apply(all_inputs)->Unit(benchmark::kMillisecond)->MinTime(0.2);
BENCHMARK(BM_contour_engine_over_refiner)
    ->Apply(all_inputs)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_contour_isovalue_change)
    ->Apply(all_inputs)
    ->Iterations(200)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) { return progiso::bench::run_benchmarks(argc, argv); }
