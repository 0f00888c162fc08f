// Peak memory per finest triangle: what each path holds beyond the volume's own bytes.
//
// - BM_peak_memory/<field>/<path>: one run of the path in a child process forked once the volume
//   is made, so that the peak counts every page the run touches (operator new, calloc and mmap
//   alike: the engine's per-vertex words and the finest surface's corner bytes do not all come
//   from operator new), and only the run's: the child's peak resident set (ru_maxrss) minus its
//   resident set when it began (the volume's pages, shared with the parent). Paths:
//   - finest: finest_surface(), the command's --full, the mesh held in memory;
//   - finest_streamed: detail::finest_surface_pieces() into a sink that drops each piece (what
//     the command holds while it streams a PLY: a slab's corner bytes and a slab's output);
//   - refinement: the engine's full refinement and its cut's mesh (extract_isosurface_parallel
//     on the hierarchy's path), range data included;
//   - refinement_error: the engine to an error goal (0.01 on Marschner–Lobb, whose samples lie
//     in [0, 1]; 0.5 grid units on the sphere's distance field);
//   - engine_full: a progiso::engine with its default options refined to a full goal (its
//     uniform cuts: the finest cut published as a root of triangles), the cut held by the engine
//     and no mesh extracted: what an embedder's engine holds for the finest surface.
//   - stride2: the uniform surface at stride 2 (a deadline ladder's step below the finest): its
//     samples read in place from the volume, every other one along each axis.
//   - ladder: a deadline ladder (ladder_surface()) given an hour: every stride, coarse to fine,
//     to the finest surface, each cut's passes in slabs where its grid is large.
//   Counters: triangles, peak_MiB, B_per_triangle (peak / triangles), range_MiB (the range data,
//   within the peak), B_per_triangle_past_range ((peak − range data) / triangles), seconds.
// Fields: Marschner–Lobb 257³ and 513³ (f32, isovalue 0.5), and a sphere of radius 400 in a
// 1024³ f32 grid (isovalue 400). Two threads. Run:
//   build/release/bench/progiso_memory_bench --benchmark_counters_tabular=true
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "steady_allocator.hpp"

namespace progiso::bench {
namespace {

constexpr unsigned threads = 2;

struct field_spec {
  const char* name;
  std::function<volume()> make;
  double isovalue;
  double error;  // refinement_error's goal
};

const std::vector<field_spec>& fields() {
  static const std::vector<field_spec> list = {
      {"ml257",
       [] {
         return make_marschner_lobb({257, 257, 257});
       },
       0.5, 0.01},
      {"ml513",
       [] {
         return make_marschner_lobb({513, 513, 513});
       },
       0.5, 0.01},
      {"sphere1024",
       [] {
         return make_sphere_field({1024, 1024, 1024}, {511.3, 512.6, 511.8});
       },
       400.0, 0.5},
  };
  return list;
}

/// The volume of a field, made once in this (the parent) process and kept: the next field's
/// benchmarks drop the last one's.
const volume& field_volume(const field_spec& f) {
  static std::string made;
  static std::unique_ptr<volume> v;
  if (made != f.name) {
    v.reset();
    v = std::make_unique<volume>(f.make());
    made = f.name;
  }
  return *v;
}

/// The resident set now, in bytes (/proc/self/statm's second field, in pages).
std::uint64_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}

/// What a run reports to the parent.
struct run_figures {
  std::uint64_t triangles = 0;
  std::uint64_t range_bytes = 0;
  std::uint64_t peak_bytes = 0;
  double seconds = 0.0;
  bool ok = false;
};

/// Runs `job` (which returns its triangles and range bytes) in a forked child and returns its
/// figures. The parent never starts oneTBB (the child does), so the fork copies no thread pool.
run_figures in_child(const std::function<std::array<std::uint64_t, 2>()>& job) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid < 0) return {};
  if (pid == 0) {
    close(fds[0]);
    run_figures f;
    const std::uint64_t before = resident_bytes();
    const auto t0 = std::chrono::steady_clock::now();
    const std::array<std::uint64_t, 2> r = job();
    f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rusage use{};
    getrusage(RUSAGE_SELF, &use);
    const auto peak = static_cast<std::uint64_t>(use.ru_maxrss) * 1024;
    f.triangles = r[0];
    f.range_bytes = r[1];
    f.peak_bytes = peak > before ? peak - before : 0;
    f.ok = true;
    const ssize_t written = write(fds[1], &f, sizeof f);
    _exit(written == static_cast<ssize_t>(sizeof f) ? 0 : 1);
  }
  close(fds[1]);
  run_figures f;
  const ssize_t got = read(fds[0], &f, sizeof f);
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (got != static_cast<ssize_t>(sizeof f) || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return {};
  }
  return f;
}

enum class path {
  finest,
  finest_streamed,
  refinement,
  refinement_error,
  engine_full,
  stride2,
  ladder
};

std::array<std::uint64_t, 2> run_path(path p, const volume& v, double w, double error) {
  switch (p) {
    case path::finest: {
      std::uint64_t t = 0;
      scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
        t = finest_surface(v, w, loop, parts).triangles.size();
      });
      return {t, 0};
    }
    case path::finest_streamed: {
      std::uint64_t t = 0;
      scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
        detail::finest_surface_pieces(v, w, loop, parts, {},
                                      [&t](triangle_mesh& piece, std::uint64_t) {
                                        t += piece.triangles.size();
                                        benchmark::DoNotOptimize(piece.vertices.data());
                                      });
      });
      return {t, 0};
    }
    case path::refinement:
    case path::refinement_error: {
      extract_options o;
      o.goal = p == path::refinement ? refine_goal::full() : refine_goal::error(error);
      const extract_result r =
          detail::extract_isosurface_parallel(v, w, o, threads, detail::path_choice{false});
      return {r.mesh.triangles.size(), r.range_bytes};
    }
    case path::engine_full: {
      engine_options o;
      o.threads = threads;
      engine e(v, w, o);
      e.refine(refine_goal::full());
      return {e.snapshot().triangle_count(), 0};
    }
    case path::stride2: {
      std::uint64_t t = 0;
      scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
        t = uniform_surface(v, w, 2, loop, parts).triangles.size();
      });
      return {t, 0};
    }
    case path::ladder: {
      std::uint64_t t = 0;
      const auto far = std::chrono::steady_clock::now() + std::chrono::hours(1);
      scheduler::run_on_threads(threads, [&](const parallel_loop& loop, std::size_t parts) {
        t = ladder_surface(v, w, far, loop, parts).mesh.triangles.size();
      });
      return {t, 0};
    }
  }
  return {0, 0};
}

void BM_peak_memory(benchmark::State& state, const field_spec& f, path p) {
  const volume& v = field_volume(f);
  run_figures figures;
  for (auto _ : state) {
    figures = in_child([&] { return run_path(p, v, f.isovalue, f.error); });
    if (!figures.ok) {
      state.SkipWithError("the child run failed");
      return;
    }
  }
  const auto mib = [](std::uint64_t b) { return static_cast<double>(b) / (1 << 20); };
  const double t = static_cast<double>(std::max<std::uint64_t>(1, figures.triangles));
  state.counters["triangles"] = static_cast<double>(figures.triangles);
  state.counters["peak_MiB"] = mib(figures.peak_bytes);
  state.counters["B_per_triangle"] = static_cast<double>(figures.peak_bytes) / t;
  state.counters["range_MiB"] = mib(figures.range_bytes);
  state.counters["B_per_triangle_past_range"] =
      static_cast<double>(figures.peak_bytes - std::min(figures.peak_bytes, figures.range_bytes)) /
      t;
  state.counters["seconds"] = figures.seconds;
  state.counters["volume_MiB"] = mib(v.byte_size());
}

void register_all() {
  const std::array<std::pair<const char*, path>, 7> paths{
      {{"finest", path::finest},
       {"finest_streamed", path::finest_streamed},
       {"refinement", path::refinement},
       {"refinement_error", path::refinement_error},
       {"engine_full", path::engine_full},
       {"stride2", path::stride2},
       {"ladder", path::ladder}}};
  for (const field_spec& f : fields()) {
    for (const auto& [name, p] : paths) {
      benchmark::RegisterBenchmark((std::string("BM_peak_memory/") + f.name + "/" + name).c_str(),
                                   [&f, p = p](benchmark::State& s) { BM_peak_memory(s, f, p); })
          ->Iterations(1)
          ->Unit(benchmark::kMillisecond);
    }
  }
}

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) {
  return progiso::bench::run_benchmarks(argc, argv, progiso::bench::register_all);
}
