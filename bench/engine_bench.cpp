// Benchmarks of the concurrent engine. Run:
//   build/release/bench/progiso_engine_bench --benchmark_counters_tabular=true
// Latencies are measured per event with steady_clock into our own sample vectors and reported
// as p50/p99 counters (µs); wall-clock tails on small machines are dominated by the scheduler
// tick, so p99.9 is reported but not a target. Ratios (speedup, throughput with a reader) come
// from runs in this same binary.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <benchmark/benchmark.h>

#include "steady_allocator.hpp"

namespace progiso::bench {
namespace {

// The engine refining by split records (engine_options::uniform_cuts off): what this file
// measures; peer_bench.cpp measures the uniform cuts.
engine_options by_records() {
  engine_options o;
  o.uniform_cuts = false;
  return o;
}

using clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

const volume& ml(std::int64_t n) {
  static const volume v129 = make_marschner_lobb({129, 129, 129});
  static const volume v257 = make_marschner_lobb({257, 257, 257});
  return n == 257 ? v257 : v129;
}

double us(clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

void report_percentiles(benchmark::State& state, std::vector<double>& samples, const char* prefix) {
  if (samples.empty()) return;
  std::sort(samples.begin(), samples.end());
  // Nearest rank: the smallest sample with at least q of all samples at or below it.
  const auto at = [&](double q) {
    const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(samples.size())));
    return samples[std::clamp<std::size_t>(rank, 1, samples.size()) - 1];
  };
  const std::string p(prefix);
  state.counters[p + "p50_us"] = at(0.50);
  state.counters[p + "p99_us"] = at(0.99);
  state.counters[p + "p999_us"] = at(0.999);
  state.counters[p + "max_us"] = samples.back();
  state.counters["samples"] = static_cast<double>(samples.size());
}

// Alternating between two isovalues gives every run a fresh root with all its work ahead.
double next_isovalue(std::uint64_t i) { return i % 2 == 0 ? 0.5 : 0.45; }

// ---------------------------------------------------------------------------------------------
// Snapshot acquisition: engine::snapshot() alone (pin, protect the root, load the watermark).
// Arg: 0 = no writer, 1 = writers on all cores refining continuously.
void BM_snapshot_acquire(benchmark::State& state) {
  const bool writers = state.range(0) != 0;
  engine e(ml(129), 0.5, by_records());
  std::atomic<bool> quit{false};
  std::thread control;
  if (writers) {
    control = std::thread([&] {
      std::uint64_t i = 0;
      // acquire: pairs with the release-store at the end; orders nothing else.
      while (!quit.load(std::memory_order_acquire)) {
        e.set_isovalue(next_isovalue(++i));
        e.refine_full();
      }
    });
    while (e.statistics().refine.splits == 0) std::this_thread::yield();
  }
  std::vector<double> samples;
  samples.reserve(1 << 22);
  const std::uint64_t retries0 = e.statistics().snapshot_retries;
  for (auto _ : state) {
    const auto t0 = clock::now();
    surface_snapshot s = e.snapshot();
    const auto t1 = clock::now();
    benchmark::DoNotOptimize(s.split_count());
    samples.push_back(us(t1 - t0));
  }
  // A pair of clock reads alone, for the timer's share of each sample.
  std::vector<double> timer;
  for (int i = 0; i < 100000; ++i) {
    const auto t0 = clock::now();
    const auto t1 = clock::now();
    timer.push_back(us(t1 - t0));
  }
  std::sort(timer.begin(), timer.end());
  state.counters["timer_p50_us"] = timer[timer.size() / 2];
  state.counters["retries"] = static_cast<double>(e.statistics().snapshot_retries - retries0);
  state.counters["splits_meanwhile"] = static_cast<double>(e.statistics().refine.splits);
  // release: pairs with the control thread's acquire-load.
  quit.store(true, std::memory_order_release);
  if (control.joinable()) {
    e.cancel();
    control.join();
  }
  report_percentiles(state, samples, "");
}
BENCHMARK(BM_snapshot_acquire)->Arg(0)->Arg(1)->Iterations(2000000)->UseRealTime();

// ---------------------------------------------------------------------------------------------
// cancel() → every worker quiet (cancel returns after the driver joined and all tasks ended),
// at a random moment 0.5–4 ms into a full refinement of 129³.
void BM_cancel_quiet(benchmark::State& state) {
  engine e(ml(129), 0.5, by_records());
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> delay_us(500, 4000);
  std::vector<double> samples;
  std::uint64_t i = 0;
  for (auto _ : state) {
    e.set_isovalue(next_isovalue(++i));
    e.start(refine_goal::full());
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us(rng)));
    const bool was_running = e.running();
    const auto t0 = clock::now();
    e.cancel();
    const auto t1 = clock::now();
    if (was_running) samples.push_back(us(t1 - t0));
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
  }
  state.counters["discarded_last"] = static_cast<double>(e.statistics().discarded);
  report_percentiles(state, samples, "cancel_");
}
BENCHMARK(BM_cancel_quiet)->Iterations(300)->UseManualTime()->Unit(benchmark::kMicrosecond);

// What deadlines buy right after the isovalue moves away from a fully refined surface (a user
// who refined fully, then drags the isovalue): each iteration refines ML 257³ fully (untimed),
// then changes the isovalue four times, each change followed by a run of τ = 16 ms. The first
// retired root is the big one, and the engine's reclaimer clears it while the next roots refine.
// Reports the splits of the runs: mean, least, and the mean of each run's place (run_1 … run_4).
// Arg: threads.
void BM_deadline_after_full(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(0));
  engine e(ml(257), 0.5, o);
  e.refine(refine_goal::triangles(1));  // the range data, built once per volume
  constexpr int runs = 4;
  const auto budget = std::chrono::milliseconds(16);
  std::vector<double> all;
  std::array<double, runs> by_place{};
  std::uint64_t i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    e.set_isovalue(next_isovalue(++i));
    e.refine_full();
    state.ResumeTiming();
    for (int k = 0; k < runs; ++k) {
      e.set_isovalue(next_isovalue(++i));
      e.refine(refine_goal::until(clock::now() + budget));
      const auto n = static_cast<double>(e.statistics().refine.splits);
      all.push_back(n);
      by_place[static_cast<std::size_t>(k)] += n;
    }
  }
  double total = 0.0;
  for (const double n : all) total += n;
  const auto iterations = static_cast<double>(state.iterations());
  state.counters["splits_by_deadline"] = total / static_cast<double>(all.size());
  state.counters["splits_min"] = *std::min_element(all.begin(), all.end());
  for (int k = 0; k < runs; ++k) {
    state.counters["run_" + std::to_string(k + 1)] =
        by_place[static_cast<std::size_t>(k)] / iterations;
  }
}
BENCHMARK(BM_deadline_after_full)->Arg(1)->Arg(2)->Iterations(12)->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------------
// Isovalue change while refining: set_isovalue() publishes the new isovalue's root surface,
// stops the run, retires the old root and resumes the goal. Measured at a random moment 1–20 ms
// into a full refinement of ML 257³, from the call: until the new surface is visible to
// snapshots (`surface_` counters: engine_statistics::surface_published_at, stamped just before
// the store that publishes it), and until the call returns (`change_` counters, the manual time;
// an upper bound on the first). Every sample checks that the snapshot right after the call holds
// the new isovalue's surface. Arg: threads.
void BM_isovalue_change(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(0));
  engine e(ml(257), 0.5, o);
  e.refine(refine_goal::triangles(1));  // the range data, built once per volume, not per change
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> delay_us(1000, 20000);
  std::vector<double> calls;
  std::vector<double> surfaces;
  std::uint64_t i = 0;
  for (auto _ : state) {
    e.start(refine_goal::full());
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us(rng)));
    const double w = next_isovalue(++i);
    const auto t0 = clock::now();
    e.set_isovalue(w);
    const auto t1 = clock::now();
    const surface_snapshot s = e.snapshot();
    if (s.isovalue() != w || s.triangle_count() == 0) state.SkipWithError("no new surface");
    const auto published = e.statistics().surface_published_at;
    if (published < t0 || published > t1) state.SkipWithError("published outside the call");
    calls.push_back(us(t1 - t0));
    surfaces.push_back(us(published - t0));
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    e.cancel();
  }
  report_percentiles(state, calls, "change_");
  report_percentiles(state, surfaces, "surface_");
}
BENCHMARK(BM_isovalue_change)
    ->Arg(1)
    ->Arg(2)
    ->Iterations(100)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------------------------------------
// Deadline overshoot: refine_for(τ) returns at most this long after the deadline, with the
// surface published by the deadline. Every run follows an isovalue change, so the old root is
// being reclaimed while the new one refines: the splits a deadline buys then (mean, and the
// 10th percentile and least of the runs) show whether the reclaimer's work slows the run.
// Args: τ in ms (ML 257³ never finishes within 33 ms), threads.
void BM_deadline_overshoot(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(1));
  engine e(ml(257), 0.5, o);
  const auto budget = std::chrono::milliseconds(state.range(0));
  std::vector<double> samples;
  std::vector<double> split_counts;
  std::uint64_t i = 0;
  for (auto _ : state) {
    e.set_isovalue(next_isovalue(++i));
    const auto deadline = clock::now() + budget;
    e.refine(refine_goal::until(deadline));
    const auto back = clock::now();
    samples.push_back(us(back - deadline));
    split_counts.push_back(static_cast<double>(e.statistics().refine.splits));
    state.SetIterationTime(std::chrono::duration<double>(back - deadline + budget).count());
  }
  double total = 0.0;
  for (const double n : split_counts) total += n;
  std::sort(split_counts.begin(), split_counts.end());
  state.counters["splits_by_deadline"] = total / static_cast<double>(split_counts.size());
  state.counters["splits_p10"] = split_counts[split_counts.size() / 10];
  state.counters["splits_min"] = split_counts.front();
  report_percentiles(state, samples, "overshoot_");
}
BENCHMARK(BM_deadline_overshoot)
    ->ArgsProduct({{8, 16, 33}, {1, 2}})
    ->Iterations(300)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------------
// Full refinement on N threads (speedup = time(1) / time(N)), and the sequential refiner on the
// same volume as a baseline for the engine's own overhead. Arg: threads (0 = sequential refiner).
void BM_full_refine(benchmark::State& state) {
  // Like for like: each iteration starts from a fresh refiner or engine (fresh per-vertex
  // state, no records), at the same isovalue, with the range data built beforehand and the
  // teardown untimed.
  const auto n = static_cast<unsigned>(state.range(0));
  const volume& v = ml(state.range(1));
  if (n == 0) {
    const hierarchy h(v.dims());
    const range_data ranges(v, h);
    std::uint64_t splits = 0;
    for (auto _ : state) {
      auto r = std::make_unique<refiner>(v, h, ranges, 0.5, refine_order::depth_first);
      r->refine_full();
      state.PauseTiming();
      splits = r->statistics().splits;
      r.reset();
      state.ResumeTiming();
    }
    state.counters["splits"] = static_cast<double>(splits);
    return;
  }
  engine_options o = by_records();
  o.threads = n;
  std::uint64_t splits = 0;
  std::uint64_t batches = 0;
  unsigned threads = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto e = std::make_unique<engine>(v, 0.5, o);
    (void)e->ranges();
    state.ResumeTiming();
    e->refine_full();
    state.PauseTiming();
    splits = e->statistics().refine.splits;
    batches = e->statistics().batches;
    threads = e->threads();
    e.reset();
    state.ResumeTiming();
  }
  state.counters["threads"] = threads;
  state.counters["splits"] = static_cast<double>(splits);
  state.counters["batches"] = static_cast<double>(batches);
}
BENCHMARK(BM_full_refine)
    ->ArgsProduct({{0, 1, 2}, {129, 257}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

// ---------------------------------------------------------------------------------------------
// The one-thread engine against the sequential refiner, in pairs: every
// iteration refines fully with a fresh refiner and a fresh one-thread engine (range data built
// beforehand, construction and teardown untimed), the order alternating, and the counter is
// the median of the per-pair ratios engine / refiner. Arg: volume side.
void BM_engine_over_refiner(benchmark::State& state) {
  const volume& v = ml(state.range(0));
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  engine_options o = by_records();
  o.threads = 1;
  std::vector<double> ratios;
  double refiner_s = 0.0;
  double engine_s = 0.0;
  bool engine_first = false;
  for (auto _ : state) {
    double t_refiner = 0.0;
    double t_engine = 0.0;
    const auto run_refiner = [&] {
      auto r = std::make_unique<refiner>(v, h, ranges, 0.5, refine_order::depth_first);
      const auto t0 = clock::now();
      r->refine_full();
      t_refiner = std::chrono::duration<double>(clock::now() - t0).count();
    };
    const auto run_engine = [&] {
      auto e = std::make_unique<engine>(v, 0.5, o);
      (void)e->ranges();
      const auto t0 = clock::now();
      e->refine_full();
      t_engine = std::chrono::duration<double>(clock::now() - t0).count();
    };
    if (engine_first) {
      run_engine();
      run_refiner();
    } else {
      run_refiner();
      run_engine();
    }
    engine_first = !engine_first;
    ratios.push_back(t_engine / t_refiner);
    refiner_s += t_refiner;
    engine_s += t_engine;
    state.SetIterationTime(t_engine);
  }
  std::sort(ratios.begin(), ratios.end());
  const auto n = static_cast<double>(ratios.size());
  state.counters["ratio_median"] = ratios[ratios.size() / 2];
  state.counters["refiner_ms"] = refiner_s / n * 1e3;
  state.counters["engine_ms"] = engine_s / n * 1e3;
}
BENCHMARK(BM_engine_over_refiner)
    ->Arg(257)
    ->Iterations(15)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------------
// Extraction of the finest cut from a snapshot (mesh()), on N threads, after one full run:
// the extraction phase of the pipeline alone. Args: threads, volume side.
void BM_snapshot_mesh(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(0));
  engine e(ml(state.range(1)), 0.5, o);
  e.refine_full();
  const surface_snapshot s = e.snapshot();
  std::size_t triangles = 0;
  for (auto _ : state) {
    const triangle_mesh m = s.mesh();
    triangles = m.triangles.size();
    benchmark::DoNotOptimize(m.vertices.data());
  }
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["ns_per_triangle"] = benchmark::Counter(
      static_cast<double>(triangles),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_snapshot_mesh)
    ->ArgsProduct({{1, 2}, {257}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

// ---------------------------------------------------------------------------------------------
// Refinement by priority against full refinement: splits per second of a
// run that takes the largest error first (a deadline, an error target, a triangle budget),
// over splits per second of full refinement (depth first), on one engine, the same isovalue
// and a fresh root for each run; pairs alternate which runs first, and the counter is the
// median of the per-pair ratios. Mode 0: a deadline at half the pair's full time. Mode 1: the
// error target that leaves about half of the full splits (found once by bisection). Mode 2: a
// budget of half the full surface's triangles. Mode 3: mode 1's error target in any order
// (refine_goal::error_in_any_order: by grid plane, the same split set). Args: threads, mode,
// schedule of the priority runs on more than one thread (0: tasks by bands, the default; 1: the
// flow graph). Also the diamonds each examines per split (`visited`: straddle test and, by
// priority, error, for every diamond made ready): a partial run also examines the ready
// diamonds it leaves unsplit, which full refinement splits; `visited_ratio_median` is the
// median ratio of diamonds examined per second.
void BM_priority_over_full(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(0));
  o.schedule = state.range(2) == 0 ? refinement_schedule::tasks : refinement_schedule::flow_graph;
  const int mode = static_cast<int>(state.range(1));
  engine e(ml(257), 0.5, o);
  e.refine(refine_goal::triangles(1));  // the range data, built once per volume
  e.refine_full();
  const std::uint64_t full_splits = e.statistics().refine.splits;
  const std::uint64_t full_triangles = e.statistics().refine.triangles;
  const auto full_visited = static_cast<double>(e.statistics().refine.visited);
  double epsilon = 0.0;
  if (mode == 1 || mode == 3) {
    double lo = 1e-9;
    double hi = 1e3;
    for (int k = 0; k < 30; ++k) {
      const double mid = std::sqrt(lo * hi);
      e.set_isovalue(0.5);
      e.refine(refine_goal::error(mid));
      (e.statistics().refine.splits > full_splits / 2 ? lo : hi) = mid;
    }
    epsilon = hi;
  }
  std::vector<double> ratios;
  std::vector<double> visited_ratios;
  double priority_splits = 0.0;
  double priority_visited = 0.0;
  double priority_seconds = 0.0;
  double full_seconds = 0.0;
  for (auto _ : state) {
    double t_full = 0.0;
    double rate_full = 0.0;
    double rate_priority = 0.0;
    double visited_rate_priority = 0.0;
    const auto run_full = [&] {
      e.set_isovalue(0.5);
      const auto t0 = clock::now();
      e.refine_full();
      t_full = std::chrono::duration<double>(clock::now() - t0).count();
      rate_full = static_cast<double>(e.statistics().refine.splits) / t_full;
      full_seconds += t_full;
    };
    const auto run_priority = [&](double budget_seconds) {
      e.set_isovalue(0.5);
      const auto t0 = clock::now();
      if (mode == 0) {
        e.refine(refine_goal::until(t0 + std::chrono::duration_cast<clock::duration>(
                                             std::chrono::duration<double>(budget_seconds))));
      } else if (mode == 1) {
        e.refine(refine_goal::error(epsilon));
      } else if (mode == 3) {
        e.refine(refine_goal::error_in_any_order(epsilon));
      } else {
        e.refine(refine_goal::triangles(full_triangles / 2));
      }
      const double t = std::chrono::duration<double>(clock::now() - t0).count();
      const auto splits = static_cast<double>(e.statistics().refine.splits);
      rate_priority = splits / t;
      const auto visited = static_cast<double>(e.statistics().refine.visited);
      visited_rate_priority = visited / t;
      priority_splits += splits;
      priority_visited += visited;
      priority_seconds += t;
    };
    if (state.iterations() % 2 == 0) {
      run_full();
      run_priority(t_full / 2);
    } else {
      // The deadline of a pair that starts with the priority run comes from the last full run.
      run_priority(full_seconds > 0.0 ? full_seconds / static_cast<double>(state.iterations()) / 2
                                      : 0.2);
      run_full();
    }
    ratios.push_back(rate_priority / rate_full);
    visited_ratios.push_back(visited_rate_priority / (full_visited / t_full));
  }
  std::sort(ratios.begin(), ratios.end());
  std::sort(visited_ratios.begin(), visited_ratios.end());
  state.counters["visited_ratio_median"] = visited_ratios[visited_ratios.size() / 2];
  state.counters["full_visited_per_split"] = full_visited / static_cast<double>(full_splits);
  state.counters["priority_visited_per_split"] = priority_visited / priority_splits;
  state.counters["threads"] = e.threads();
  state.counters["ratio_median"] = ratios[ratios.size() / 2];
  state.counters["priority_Msplits_s"] = priority_splits / priority_seconds / 1e6;
  state.counters["full_Msplits_s"] = static_cast<double>(full_splits) *
                                     static_cast<double>(state.iterations()) / full_seconds / 1e6;
  state.counters["priority_splits"] = priority_splits / static_cast<double>(state.iterations());
  state.counters["full_splits"] = static_cast<double>(full_splits);
}
BENCHMARK(BM_priority_over_full)
    ->ArgsProduct({{1, 2}, {0, 1, 2, 3}, {0}})
    ->ArgsProduct({{2}, {0, 1, 2}, {1}})
    ->Iterations(8)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// ---------------------------------------------------------------------------------------------
// Writer throughput (splits per second of a full refinement) with one reader taking and walking
// snapshots (every triangle of the cut) continuously, against none. Paired: every iteration
// refines twice, once with the reader walking and once with it asleep, in alternating order, so
// both halves of a pair see the same machine (a shared VM's speed drifts by ±15% over seconds).
// Reports the median of the per-pair ratios. Arg: writer threads.
void BM_writer_with_reader(benchmark::State& state) {
  engine_options o = by_records();
  o.threads = static_cast<unsigned>(state.range(0));
  engine e(ml(129), 0.5, o);
  // 0 = asleep, 1 = walking, 2 = quit. The reader acknowledges each change through `at`.
  std::atomic<int> mode{0};
  std::atomic<int> at{0};
  std::atomic<std::uint64_t> walks{0};
  std::atomic<std::uint64_t> walked{0};
  std::thread r([&] {
    for (;;) {
      // acquire: pairs with the release-stores of `mode` below.
      const int m = mode.load(std::memory_order_acquire);
      at.store(m, std::memory_order_release);  // release: pairs with set_mode()'s acquire
      if (m == 2) return;
      if (m == 0) {
        std::this_thread::sleep_for(50us);
        continue;
      }
      const surface_snapshot s = e.snapshot();
      std::uint64_t t = 0;
      s.for_each_triangle([&t](const owned_triangle&) { ++t; });
      benchmark::DoNotOptimize(t);
      walks.fetch_add(1, std::memory_order_relaxed);   // relaxed: read after join
      walked.fetch_add(t, std::memory_order_relaxed);  // relaxed: read after join
    }
  });
  const auto set_mode = [&](int m) {
    mode.store(m, std::memory_order_release);  // release: pairs with the reader's acquire
    // acquire: pairs with the reader's release-store of `at`.
    while (at.load(std::memory_order_acquire) != m) std::this_thread::yield();
  };
  std::vector<double> ratios;
  double alone_s = 0;
  double with_s = 0;
  std::uint64_t alone_splits = 0;
  std::uint64_t with_splits = 0;
  std::uint64_t i = 0;
  int first = 0;
  for (auto _ : state) {
    std::array<double, 2> rate{};
    first ^= 1;
    for (int half = 0; half < 2; ++half) {
      const int reading = half ^ first;
      e.set_isovalue(next_isovalue(++i));
      set_mode(reading);
      const auto t0 = clock::now();
      e.refine_full();
      const double secs = std::chrono::duration<double>(clock::now() - t0).count();
      set_mode(0);
      const std::uint64_t n = e.statistics().refine.splits;
      rate[static_cast<std::size_t>(reading)] = static_cast<double>(n) / secs;
      (reading ? with_s : alone_s) += secs;
      (reading ? with_splits : alone_splits) += n;
    }
    ratios.push_back(rate[1] / rate[0]);
    state.SetIterationTime(0);
  }
  set_mode(2);
  r.join();
  std::sort(ratios.begin(), ratios.end());
  state.counters["ratio_median"] = ratios[ratios.size() / 2];
  state.counters["ratio_min"] = ratios.front();
  state.counters["ratio_max"] = ratios.back();
  state.counters["alone_Msplits_s"] = static_cast<double>(alone_splits) / alone_s / 1e6;
  state.counters["with_Msplits_s"] = static_cast<double>(with_splits) / with_s / 1e6;
  // relaxed: the reader has been joined.
  state.counters["reader_walks"] = static_cast<double>(walks.load(std::memory_order_relaxed));
  state.counters["reader_Mtri_s"] =
      static_cast<double>(walked.load(std::memory_order_relaxed)) / with_s / 1e6;
}
BENCHMARK(BM_writer_with_reader)->Arg(1)->Arg(2)->Iterations(15)->UseManualTime();

// ---------------------------------------------------------------------------------------------
// Memory pinned by a reader stalled inside one snapshot for a whole run of 20 isovalue changes,
// each refined fully: interval-based reclamation (Arg 1) against plain EBR (Arg 0).
void BM_stalled_reader_memory(benchmark::State& state) {
  engine_options o = by_records();
  o.reclamation.interval_based = state.range(0) != 0;
  std::uint64_t peak = 0;
  std::uint64_t root = 0;
  std::uint64_t pending = 0;
  for (auto _ : state) {
    engine e(ml(129), 0.5, o);
    e.refine_full();
    // The stalled reader: its own thread takes one snapshot and holds it, without another
    // call into the engine, until the run is over.
    std::atomic<int> phase{0};
    std::thread stalled([&] {
      const surface_snapshot s = e.snapshot();
      phase.store(1, std::memory_order_release);  // release: pairs with the acquire below
      phase.notify_all();
      phase.wait(1, std::memory_order_acquire);  // acquire: pairs with the release-store of 2
      benchmark::DoNotOptimize(s.split_count());
    });
    phase.wait(0, std::memory_order_acquire);  // acquire: pairs with the release-store of 1
    for (int k = 1; k <= 20; ++k) {
      e.set_isovalue(next_isovalue(static_cast<std::uint64_t>(k)));
      e.refine_full();
      pending = std::max(pending, e.statistics().reclamation.pending);
    }
    phase.store(2, std::memory_order_release);  // release: pairs with the stalled acquire
    phase.notify_all();
    stalled.join();
    const engine_statistics st = e.statistics();
    peak = st.peak_retired_bytes;
    root = st.root_bytes;
  }
  state.counters["peak_retired_MiB"] = static_cast<double>(peak) / (1 << 20);
  state.counters["root_MiB"] = static_cast<double>(root) / (1 << 20);
  state.counters["peak_pending_roots"] = static_cast<double>(pending);
}
BENCHMARK(BM_stalled_reader_memory)->Arg(1)->Arg(0)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) { return progiso::bench::run_benchmarks(argc, argv); }
