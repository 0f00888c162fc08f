// The engine across ranks after an isovalue change: from set_isovalue() on the root until the
// root shows the first refined round of the new isovalue (first_round_ms), and until it shows the
// goal's cut (the time), against the one-process engine (progiso::engine) on the root with all
// the job's threads, in this binary, the two interleaved. mesh_ms: a reader's cost of the final
// snapshot's mesh, outside the time, for both. Run it under mpiexec:
//   mpiexec -np N build/release/bench/progiso_mpi_engine_bench
//       --benchmark_enable_random_interleaving=true --benchmark_repetitions=3
//       --benchmark_counters_tabular=true
// Field: Marschner–Lobb 257³ at 0.5, goal refine_goal::error(goal_error); isovalues alternate
// between two values, so each change starts from the root surface. Threads per rank: 2 / N, at
// least 1 (PROGISO_BENCH_THREADS sets it); the one-process engine gets ranks × threads.
// Only the root runs the benchmarks (the engine takes commands on the root alone); the other
// ranks serve its engine until the root destroys it.
#include <progiso/core/field/analytic.hpp>
#include <progiso/mpi/distributed_engine.hpp>
#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <thread>

#include <benchmark/benchmark.h>
#include <mpi.h>

namespace progiso::bench {
namespace {

using clock = std::chrono::steady_clock;

constexpr double goal_error = 0.002;
constexpr double isovalues[2] = {0.5, 0.45};

int ranks = 1;
unsigned threads_per_rank = 1;
const volume* field = nullptr;
distributed_engine* across = nullptr;

double ms_between(clock::time_point a, clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

void BM_ranks_isovalue_change(benchmark::State& state) {
  double first_ms = 0.0, mesh_ms = 0.0;
  std::size_t triangles = 0, rounds = 0;
  std::uint64_t k = 0;
  for (auto _ : state) {
    const std::uint64_t changes = across->snapshot()->isovalue_changes + 1;
    const double w = isovalues[k++ % 2];
    const auto t0 = clock::now();
    // A reader polls (every 100 µs) for the first refined round of the new isovalue.
    std::atomic<bool> done{false};
    std::thread reader([&] {
      // done: acquire pairs with the release below.
      while (!done.load(std::memory_order_acquire)) {
        const std::shared_ptr<const distributed_snapshot> s = across->snapshot();
        if (s->isovalue_changes == changes && s->round > 0) {
          first_ms += ms_between(t0, clock::now());
          return;
        }
        std::this_thread::sleep_for(std::chrono::microseconds(100));
      }
    });
    across->set_isovalue(w);
    across->wait();
    const auto t1 = clock::now();
    done.store(true, std::memory_order_release);  // partner: the reader's acquire load
    reader.join();
    state.SetIterationTime(ms_between(t0, t1) / 1000.0);
    const std::shared_ptr<const distributed_snapshot> s = across->snapshot();
    if (s->isovalue_changes != changes || s->isovalue != w) state.SkipWithError("not the new cut");
    const auto m0 = clock::now();
    triangles = s->mesh()->triangles.size();
    mesh_ms += ms_between(m0, clock::now());
    rounds = static_cast<std::size_t>(s->round);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["first_round_ms"] = first_ms / n;
  state.counters["mesh_ms"] = mesh_ms / n;
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["rounds"] = static_cast<double>(rounds);
  state.counters["ranks"] = ranks;
}
BENCHMARK(BM_ranks_isovalue_change)->Iterations(6)->UseManualTime()->Unit(benchmark::kMillisecond);

void BM_one_process_isovalue_change(benchmark::State& state) {
  engine_options o;
  o.threads = static_cast<unsigned>(ranks) * threads_per_rank;
  engine e(*field, isovalues[1], o);
  e.refine(refine_goal::error(goal_error));  // the range data, built once, as the ranks' is
  std::uint64_t k = 0;
  std::size_t triangles = 0;
  double mesh_ms = 0.0;
  for (auto _ : state) {
    const double w = isovalues[k++ % 2];
    const auto t0 = clock::now();
    e.set_isovalue(w);
    e.refine(refine_goal::error(goal_error));
    state.SetIterationTime(ms_between(t0, clock::now()) / 1000.0);
    const auto m0 = clock::now();
    triangles = e.snapshot().mesh().triangles.size();
    mesh_ms += ms_between(m0, clock::now());
  }
  state.counters["mesh_ms"] = mesh_ms / static_cast<double>(state.iterations());
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["ranks"] = 1;
}
BENCHMARK(BM_one_process_isovalue_change)
    ->Iterations(6)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) {
  using namespace progiso::bench;
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_MULTIPLE, &provided);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const char* t = std::getenv("PROGISO_BENCH_THREADS");
  threads_per_rank = t != nullptr ? static_cast<unsigned>(std::max(1, std::atoi(t)))
                                  : static_cast<unsigned>(std::max(1, 2 / ranks));
  int status = 0;
  {
    const progiso::volume v = progiso::make_marschner_lobb({257, 257, 257});
    field = &v;
    progiso::distributed_engine::options o;
    o.threads = threads_per_rank;
    progiso::distributed_engine e(MPI_COMM_WORLD, v, isovalues[1], o);
    across = &e;
    if (e.is_root()) {
      e.start(progiso::refine_goal::error(goal_error));
      e.wait();  // the range data, built once
      benchmark::Initialize(&argc, argv);
      if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
        status = 1;
      } else {
        benchmark::RunSpecifiedBenchmarks();
        benchmark::Shutdown();
      }
    }
  }  // the root's engine ends every rank's
  MPI_Finalize();
  return status;
}
