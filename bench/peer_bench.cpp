// progiso against its peer, VTK's Flying Edges, in one binary: vtkFlyingEdges3D on
// every 3D volume of ../shared/data, 257³ and 513³ smooth fields (Marschner–Lobb) and the busy
// vtkRTAnalyticSource wavelet at 256³ and 512³; vtkFlyingEdges2D on every image. Both sides
// start from the volume in memory (FE reads progiso's own sample array, wrapped without a copy)
// and end with the surface in memory: FE's vtkPolyData (normals, gradients and scalars off),
// progiso's pipeline — range data, refinement and extraction of the finest cut into an indexed
// mesh (extract_isosurface_parallel, as the command runs it: a full run's finest cut by
// finest_surface(), BM_peer_refined by refining the hierarchy), or the contour polylines in 2D.
// vtkSMPTools runs on the same thread count as progiso. BM_deadline_quality measures what a
// deadline buys (see there), BM_peer_scaling the pipeline's speed-up from one thread (see there),
// BM_peer_normals both sides with vertex normals (see there), BM_follow a render thread that
// follows a full run by its changes (see there), BM_finest_buffers an engine's finest cut in a
// renderer's buffers, fresh and after an isovalue change (see there), BM_stream_cut a cut made
// from a hierarchy stream without the volume (see there).
//
// Each benchmark runs both sides in alternating pairs (the order flips every pair) and reports
// medians: fe_ms, progiso_ms with its phases (range_ms, refine_ms, extract_ms; first_ms, the root
// surface from the volume in memory; splits and visited diamonds), both triangle
// (segment) counts, and `ratio`, the median of the per-pair ratios progiso / FE. The iteration
// time Google Benchmark prints is progiso's. Built only when CMake finds VTK
// (scripts/install-deps.sh --peers). Run:
//   build/release/bench/progiso_peer_bench --benchmark_counters_tabular=true
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/io/image_io.hpp>
#include <progiso/io/volume_io.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/frame_feed.hpp>
#include <progiso/scheduler/hierarchy_export.hpp>
#include <progiso/scheduler/tbb_environment.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench_common.hpp"
#include "steady_allocator.hpp"
#include "surface_distance.hpp"
#include "vtk_peer.hpp"

namespace progiso::bench {
namespace {

/// One input: made when its first benchmark runs (a filtered run builds only what it uses;
/// the 513³ fields alone take seconds and 0.5–1 GB).
struct input {
  std::string name;
  std::function<volume()> make;
  double isovalue;
  int pairs;  // alternating pairs per benchmark run
  std::shared_ptr<const volume> made;
  const volume& get() {
    if (!made) made = std::make_shared<const volume>(make());
    return *made;
  }
};

/// The wavelet of vtkRTAnalyticSource (its defaults) on n³ samples, as a progiso volume.
volume wavelet(int n) {
  const std::vector<float> w = vtk_wavelet(n);
  std::vector<std::byte> bytes(w.size() * sizeof(float));
  std::memcpy(bytes.data(), w.data(), bytes.size());
  return volume(index3{n, n, n}, sample_type::f32, std::move(bytes));
}

std::vector<input>& volumes() {
  static std::vector<input> all = [] {
    std::vector<input> v;
    const auto raw = [&](std::string name, const char* file, index3 dims, sample_type t,
                         std::array<double, 3> spacing, double w) {
      const std::filesystem::path p = data_dir() / file;
      if (!std::filesystem::exists(p)) return;
      v.push_back({std::move(name),
                   [=] {
                     return read_raw(p, {dims, t, false}, spacing);
                   },
                   w, 21, nullptr});
    };
    raw("bucky", "bucky_32x32x32_uint8.raw", {32, 32, 32}, sample_type::u8, {1, 1, 1}, 51);
    raw("nucleon", "nucleon_41x41x41_uint8.raw", {41, 41, 41}, sample_type::u8, {1, 1, 1}, 60);
    raw("neghip", "neghip_66x66x66_uint8.raw", {66, 66, 66}, sample_type::u8, {1, 1, 1}, 30);
    raw("hipip", "hipip_68x68x68_uint8.raw", {68, 68, 68}, sample_type::u8, {1, 1, 1}, 128);
    raw("headsq", "headsq_64x64x93_int16le.raw", {64, 64, 93}, sample_type::i16, {3.2, 3.2, 1.5},
        500);
    raw("brainsmall", "brainsmall_128x128x84_uint8.raw", {128, 128, 84}, sample_type::u8, {1, 1, 1},
        50);
    v.push_back({"ml257", [] { return make_marschner_lobb({257, 257, 257}); }, 0.5, 7, nullptr});
    v.push_back({"ml513", [] { return make_marschner_lobb({513, 513, 513}); }, 0.5, 3, nullptr});
    v.push_back({"wavelet256", [] { return wavelet(256); }, 157.0, 7, nullptr});
    v.push_back({"wavelet512", [] { return wavelet(512); }, 157.0, 3, nullptr});
    return v;
  }();
  return all;
}

std::vector<input>& images() {
  static std::vector<input> all = [] {
    std::vector<input> v;
    const auto image = [&](std::string name, const char* file, double w) {
      const std::filesystem::path p = data_dir() / file;
      if (std::filesystem::exists(p)) {
        v.push_back({std::move(name), [=] { return read_image(p); }, w, 41, nullptr});
      }
    };
    image("camera", "camera_512x512.pgm", 128);
    image("coins", "coins_384x303.pgm", 128);
    image("dem", "jacksboro_dem_403x344_u16.pgm", 600);
    return v;
  }();
  return all;
}

/// Flying Edges on progiso's own samples (read in place), with vertex normals when asked.
std::unique_ptr<flying_edges> peer(const volume& v, double isovalue, bool normals = false) {
  const int dims[3] = {static_cast<int>(v.dims()[0]), static_cast<int>(v.dims()[1]),
                       static_cast<int>(v.dims()[2])};
  return std::make_unique<flying_edges>(dims, v.spacing().data(), v.origin().data(),
                                        static_cast<vtk_sample>(v.type()), v.bytes(), isovalue,
                                        normals);
}

struct pair_stats {
  std::vector<double> fe, mine, ratio, range, refine, extract, first;
  double splits = 0.0;
  double visited = 0.0;
  double fe_cells = 0.0;
  double mine_cells = 0.0;
};

void report(benchmark::State& state, const pair_stats& s, const char* cells) {
  state.counters["fe_ms"] = median(s.fe);
  state.counters["progiso_ms"] = median(s.mine);
  state.counters["ratio"] = median(s.ratio);
  if (!s.range.empty()) {
    state.counters["range_ms"] = median(s.range);
    state.counters["refine_ms"] = median(s.refine);
    state.counters["extract_ms"] = median(s.extract);
    state.counters["first_ms"] = median(s.first);
    state.counters["splits"] = s.splits;
    state.counters["visited"] = s.visited;
  }
  state.counters[std::string("fe_") + cells] = s.fe_cells;
  state.counters[std::string("progiso_") + cells] = s.mine_cells;
}

/// Runs Flying Edges and `mine` (which returns its milliseconds and records its own counters in
/// `s`) in alternating pairs, one pair per benchmark iteration, the order flipping every pair;
/// progiso's time is the iteration time.
template <class Mine>
void run_pairs(benchmark::State& state, flying_edges& fe, pair_stats& s, Mine&& mine) {
  int pair = 0;
  for (auto _ : state) {
    double fe_ms = 0.0;
    double mine_ms = 0.0;
    const auto run_fe = [&] {
      const auto t0 = clock_type::now();
      const std::size_t cells = fe.run();
      fe_ms = ms_since(t0);
      s.fe_cells = static_cast<double>(cells);
    };
    if (pair++ % 2 == 0) {
      run_fe();
      mine_ms = mine();
    } else {
      mine_ms = mine();
      run_fe();
    }
    s.fe.push_back(fe_ms);
    s.mine.push_back(mine_ms);
    s.ratio.push_back(mine_ms / fe_ms);
    state.SetIterationTime(mine_ms / 1e3);
  }
}

// ---- 3D: vtkFlyingEdges3D against the progiso pipeline.

// A 3D benchmark's setup: its input (args 0) and thread count (arg 1), VTK's SMP on that count,
// the label, and Flying Edges on the input.
struct volume_case {
  input& in;
  const volume& vol;
  unsigned threads;
  std::unique_ptr<flying_edges> fe;
};
volume_case volume_setup(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const volume& vol = in.get();
  const auto threads = static_cast<unsigned>(state.range(1));
  const std::string backend = vtk_threads(static_cast<int>(threads));
  state.SetLabel(in.name + " " + std::to_string(threads) + " thr, VTK SMP " + backend);
  return {in, vol, threads, peer(vol, in.isovalue)};
}

// The pipeline of a full run: by default its finest cut by finest_surface() (two passes over
// the samples; refine_ms and range_ms are 0); BM_peer_refined takes the hierarchy's path instead
// (range data, full refinement, extraction of the cut), the same surface.
void peer_volume(benchmark::State& state, bool finest_direct) {
  auto [in, vol, threads, fe] = volume_setup(state);
  const extract_options options;  // full
  pair_stats s;
  run_pairs(state, *fe, s, [&] {
    const auto t0 = clock_type::now();
    const extract_result r = progiso::detail::extract_isosurface_parallel(
        vol, in.isovalue, options, threads, progiso::detail::path_choice{finest_direct});
    const double ms = ms_since(t0);
    s.range.push_back(r.range_build_seconds * 1e3);
    s.refine.push_back(r.refine_seconds * 1e3);
    s.extract.push_back(r.extract_seconds * 1e3);
    s.first.push_back(r.first_surface_seconds * 1e3);
    s.splits = static_cast<double>(r.stats.splits);
    s.visited = static_cast<double>(r.stats.visited);
    s.mine_cells = static_cast<double>(r.mesh.triangles.size());
    benchmark::DoNotOptimize(r.mesh.vertices.data());
    return ms;
  });
  report(state, s, "triangles");
}
void BM_peer_volume(benchmark::State& state) { peer_volume(state, true); }
void BM_peer_refined(benchmark::State& state) { peer_volume(state, false); }

// ---- Shading: the same with vertex normals on both sides (vtkFlyingEdges3D's ComputeNormals;
// progiso's extract_options::normals, gradient normals of the finest cut's vertices, computed
// after the pipeline on the same threads). `normals_ms` is progiso's normal pass alone; the
// ratio is of the whole runs, normals included.
void BM_peer_normals(benchmark::State& state) {
  auto [in, vol, threads, plain_fe] = volume_setup(state);
  const std::unique_ptr<flying_edges> fe = peer(vol, in.isovalue, true);
  extract_options options;  // full
  options.normals = true;
  pair_stats s;
  std::vector<double> normals;
  run_pairs(state, *fe, s, [&] {
    const auto t0 = clock_type::now();
    const extract_result r = extract_isosurface_parallel(vol, in.isovalue, options, threads);
    const double ms = ms_since(t0);
    normals.push_back(r.normals_seconds * 1e3);
    s.mine_cells = static_cast<double>(r.mesh.triangles.size());
    benchmark::DoNotOptimize(r.mesh.normals.data());
    return ms;
  });
  report(state, s, "triangles");
  state.counters["normals_ms"] = median(normals);
}

// ---- Following a refinement (BM_follow): a render thread that keeps the engine's surface in a
// slot pool while a full run refines it from the root, frame by frame at 60 Hz, through a
// frame_feed (its producer thread makes each frame's change, or a whole pool for a rebuilt cut,
// and hands it over a Boost.Lockfree queue): each frame calls update(). The pair's progiso side
// is the sum of the render thread's update times over the whole run (`progiso_ms`, `ratio`
// against Flying Edges). Also: the update times (`frame_p50_ms`, `frame_p99_ms`,
// `frame_max_ms`, nearest rank over every frame of every pair), frames per run, the producer's
// time making frames (`producer_ms`), and the whole finest cut into a fresh pool on one thread
// (`cut_ms`, a rebuilt change applied; `cut_ratio` against Flying Edges) beside mesh_into()'s
// indexed buffers (`mesh_into_ms`, `into_ratio`). BM_follow is the default engine (a full run
// makes the finest cut by the passes: one rebuilt frame); BM_follow_records follows full
// refinement by split records (engine_options::uniform_cuts off: a change per frame).

double nearest_rank(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

void follow(benchmark::State& state, bool uniform_cuts) {
  auto [in, vol, threads, fe] = volume_setup(state);
  engine_options o;
  o.threads = threads;
  o.uniform_cuts = uniform_cuts;
  pair_stats s;
  std::vector<double> frames;
  std::vector<double> runs_frames;
  std::vector<double> producer;
  std::vector<double> cut;
  std::vector<double> into;
  surface_change change;
  render_buffers buffers;
  run_pairs(state, *fe, s, [&] {
    engine e(vol, in.isovalue, o);
    frame_feed feed(e);
    double total = 0.0;
    std::size_t count = 0;
    e.start(refine_goal::full());
    auto next = clock_type::now();
    while (true) {
      // Read first: a frame after the run's end that finds the feed at the last cut ends it.
      const bool idle = !e.running();
      const auto t0 = clock_type::now();
      feed.update();
      const double ms = ms_since(t0);
      frames.push_back(ms);
      total += ms;
      ++count;
      if (idle) {
        const cut_mark last = e.snapshot().mark();
        const cut_mark held = feed.mark();
        if (held.root == last.root && held.records == last.records) break;
      }
      next += std::chrono::microseconds(16667);
      std::this_thread::sleep_until(next);
    }
    runs_frames.push_back(static_cast<double>(count));
    producer.push_back(feed.statistics().producer_seconds * 1e3);
    s.mine_cells = static_cast<double>(feed.surface().triangle_count());
    {
      const surface_snapshot snap = e.snapshot();
      render_slots fresh;
      const auto t0 = clock_type::now();
      snap.change_since({}, change);
      fresh.apply(change);
      cut.push_back(ms_since(t0));
      const auto t1 = clock_type::now();
      snap.mesh_into(buffers);
      into.push_back(ms_since(t1));
      benchmark::DoNotOptimize(fresh.positions().data());
    }
    return total;
  });
  report(state, s, "triangles");
  std::vector<double> cut_ratio;
  std::vector<double> into_ratio;
  for (std::size_t i = 0; i < cut.size(); ++i) {
    cut_ratio.push_back(cut[i] / s.fe[i]);
    into_ratio.push_back(into[i] / s.fe[i]);
  }
  state.counters["frame_p50_ms"] = nearest_rank(frames, 0.5);
  state.counters["frame_p99_ms"] = nearest_rank(frames, 0.99);
  state.counters["frame_max_ms"] = nearest_rank(frames, 1.0);
  state.counters["frames"] = median(runs_frames);
  state.counters["producer_ms"] = median(producer);
  state.counters["cut_ms"] = median(cut);
  state.counters["cut_ratio"] = median(cut_ratio);
  state.counters["mesh_into_ms"] = median(into);
  state.counters["into_ratio"] = median(into_ratio);
}
void BM_follow(benchmark::State& state) { follow(state, true); }
void BM_follow_records(benchmark::State& state) { follow(state, false); }

// ---- Cuts without the volume (BM_stream_cut): the engine's full refinement by records
// (uniform_cuts off) exported as a hierarchy stream once (`bytes_per_triangle`), then in
// alternating pairs with Flying Edges: the stream decoded and validated and its full cut meshed
// (`progiso_ms`: hierarchy_stream::decode() then mesh(all()), no volume; `decode_ms`, `cut_ms`),
// beside the engine's own snapshot().mesh() of the same records (`engine_mesh_ms`).

void BM_stream_cut(benchmark::State& state) {
  auto [in, vol, threads, fe] = volume_setup(state);
  engine_options o;
  o.threads = threads;
  o.uniform_cuts = false;
  engine e(vol, in.isovalue, o);
  e.refine_full();
  std::vector<std::byte> bytes;
  {
    hierarchy_exporter x(e, [&bytes](std::span<const std::byte> b) {
      bytes.insert(bytes.end(), b.begin(), b.end());
    });
    const surface_snapshot snap = e.snapshot();
    x.write(snap);
    x.finish();
  }
  pair_stats s;
  std::vector<double> decode_ms;
  std::vector<double> cut_ms;
  std::vector<double> engine_ms;
  double triangles = 0.0;
  run_pairs(state, *fe, s, [&] {
    const auto t0 = clock_type::now();
    const hierarchy_stream h = hierarchy_stream::decode(bytes);
    decode_ms.push_back(ms_since(t0));
    const auto t1 = clock_type::now();
    const triangle_mesh m = h.mesh(h.all());
    cut_ms.push_back(ms_since(t1));
    const double ms = ms_since(t0);
    triangles = static_cast<double>(m.triangles.size());
    s.mine_cells = triangles;
    benchmark::DoNotOptimize(m.vertices.data());
    const auto t2 = clock_type::now();
    {
      const surface_snapshot snap = e.snapshot();
      const triangle_mesh em = snap.mesh();
      benchmark::DoNotOptimize(em.vertices.data());
    }
    engine_ms.push_back(ms_since(t2));
    return ms;
  });
  report(state, s, "triangles");
  state.counters["decode_ms"] = median(decode_ms);
  state.counters["cut_ms"] = median(cut_ms);
  state.counters["engine_mesh_ms"] = median(engine_ms);
  state.counters["stream_bytes"] = static_cast<double>(bytes.size());
  state.counters["bytes_per_triangle"] = static_cast<double>(bytes.size()) / triangles;
}

// ---- Scaling: the pipeline on one thread and on `threads` (arg 1), alternated in one benchmark
// (the order flips every pair), and Flying Edges on the same two counts in the same iteration.
// `speedup` is the median of the per-pair ratios progiso(1 thread) / progiso(threads), the
// two-thread speed-up figure; `fe_speedup` is Flying Edges' over the same pairs, which
// says what this machine gave a second thread at the time (on a shared virtual machine, not
// always a whole core). Separate runs at each count (BM_peer_volume) drift apart with the
// machine; these pairs do not. The iteration time is progiso's two runs.

void BM_peer_scaling(benchmark::State& state) {
  input& in = volumes()[static_cast<std::size_t>(state.range(0))];
  const volume& vol = in.get();
  const auto threads = static_cast<unsigned>(state.range(1));
  const std::unique_ptr<flying_edges> fe = peer(vol, in.isovalue);
  state.SetLabel(in.name + " 1 / " + std::to_string(threads) + " thr, VTK SMP " + vtk_threads(1));
  std::vector<double> one, many, fe_one, fe_many, speedup, fe_speedup;
  const auto mine = [&](unsigned t) {
    const auto t0 = clock_type::now();
    const extract_result r = extract_isosurface_parallel(vol, in.isovalue, extract_options{}, t);
    const double ms = ms_since(t0);
    benchmark::DoNotOptimize(r.mesh.vertices.data());
    return ms;
  };
  const auto flying = [&](unsigned t) {
    (void)vtk_threads(static_cast<int>(t));
    const auto t0 = clock_type::now();
    (void)fe->run();
    return ms_since(t0);
  };
  int pair = 0;
  for (auto _ : state) {
    double a = 0.0;
    double b = 0.0;
    double c = 0.0;
    double d = 0.0;
    if (pair++ % 2 == 0) {
      a = mine(1);
      b = mine(threads);
      c = flying(1);
      d = flying(threads);
    } else {
      d = flying(threads);
      c = flying(1);
      b = mine(threads);
      a = mine(1);
    }
    one.push_back(a);
    many.push_back(b);
    fe_one.push_back(c);
    fe_many.push_back(d);
    speedup.push_back(a / b);
    fe_speedup.push_back(c / d);
    state.SetIterationTime((a + b) / 1e3);
  }
  state.counters["ms_1"] = median(one);
  state.counters["ms_n"] = median(many);
  state.counters["speedup"] = median(speedup);
  state.counters["fe_ms_1"] = median(fe_one);
  state.counters["fe_ms_n"] = median(fe_many);
  state.counters["fe_speedup"] = median(fe_speedup);
}

// ---- The quality a deadline buys: the fraction of the full-resolution surface's area within one
// voxel (the largest spacing) of the surface shown by a deadline of 1/8, 1/4, 1/2, 1 and 2 ×
// Flying Edges' full time (FE's median over 5 runs, same thread count), for three users:
//  - the ladder (area_): the one-shot command's --time-ms path, uniform cuts from scratch
//    (extract_isosurface_parallel with a deadline), from the volume in memory;
//  - a fresh engine (engine_area_): made from the volume in memory, refined to the deadline
//    (refine(until)), then snapshot().mesh();
//  - after a change (change_area_): a warm engine, fully refined at another isovalue
//    (1.1 × the input's), then set_isovalue() and refined to the deadline, counted from
//    set_isovalue().
// Per deadline and user: the median over 3 runs (rotated, so that no user always goes first) of
// the fraction (100 000 points drawn by area on the full surface, exact distances to the cut
// from a CGAL AABB tree) and of the cut's triangles (tri_, engine_tri_, change_tri_); the
// ladder's stride reached (stride_) and the engine's (engine_stride_: 0 when it shows records or
// its root surface); late_ms_, the latest return after the deadline of any engine run (negative:
// all early).

void BM_deadline_quality(benchmark::State& state) {
  auto [in, vol, threads, fe] = volume_setup(state);
  const auto& sp = vol.spacing();
  const double voxel = std::max({sp[0], sp[1], sp[2]});
  const double other = in.isovalue * 1.1;
  static constexpr std::array<double, 5> fractions{0.125, 0.25, 0.5, 1.0, 2.0};
  static constexpr std::array<const char*, 5> names{"1/8", "1/4", "1/2", "1", "2"};
  engine_options eo;
  eo.threads = threads;
  for (auto _ : state) {
    std::vector<double> fe_ms;
    for (int k = 0; k < 5; ++k) {
      const auto t0 = clock_type::now();
      (void)fe->run();
      fe_ms.push_back(ms_since(t0));
    }
    const double fe_full = median(fe_ms);
    const triangle_mesh full =
        extract_isosurface_parallel(vol, in.isovalue, extract_options{}, threads).mesh;
    state.counters["fe_ms"] = fe_full;
    state.counters["full_triangles"] = static_cast<double>(full.triangles.size());
    engine warm(vol, other, eo);
    warm.refine_full();
    for (std::size_t d = 0; d < fractions.size(); ++d) {
      const auto budget = std::chrono::duration_cast<clock_type::duration>(
          std::chrono::duration<double, std::milli>(fe_full * fractions[d]));
      std::array<std::vector<double>, 3> fraction;
      std::array<std::vector<double>, 3> triangles;
      std::vector<double> strides;
      std::vector<double> engine_strides;
      std::vector<double> late;
      const auto measure = [&](std::size_t user) {
        triangle_mesh m;
        if (user == 0) {
          extract_options o;
          o.goal = refine_goal::within(budget);
          const extract_result r = extract_isosurface_parallel(vol, in.isovalue, o, threads);
          strides.push_back(r.ladder_stride);
          m = r.mesh;
        } else if (user == 1) {
          const auto t0 = clock_type::now();
          engine e(vol, in.isovalue, eo);
          e.refine(refine_goal::until(t0 + budget));
          late.push_back(ms_since(t0) - fe_full * fractions[d]);
          const surface_snapshot snap = e.snapshot();
          engine_strides.push_back(snap.uniform_stride());
          m = snap.mesh();
        } else {
          const auto t0 = clock_type::now();
          warm.set_isovalue(in.isovalue);
          warm.refine(refine_goal::until(t0 + budget));
          late.push_back(ms_since(t0) - fe_full * fractions[d]);
          {
            const surface_snapshot snap = warm.snapshot();
            m = snap.mesh();
          }
          warm.set_isovalue(other);
          warm.refine_full();
        }
        fraction[user].push_back(area_within(full, m, voxel, 100000).fraction);
        triangles[user].push_back(static_cast<double>(m.triangles.size()));
      };
      for (std::size_t k = 0; k < 3; ++k) {
        for (std::size_t j = 0; j < 3; ++j) measure((k + j) % 3);
      }
      const std::string at = names[d];
      state.counters["area_" + at] = median(fraction[0]);
      state.counters["tri_" + at] = median(triangles[0]);
      state.counters["stride_" + at] = median(strides);
      state.counters["engine_area_" + at] = median(fraction[1]);
      state.counters["engine_tri_" + at] = median(triangles[1]);
      state.counters["engine_stride_" + at] = median(engine_strides);
      state.counters["change_area_" + at] = median(fraction[2]);
      state.counters["change_tri_" + at] = median(triangles[2]);
      state.counters["late_ms_" + at] = *std::max_element(late.begin(), late.end());
    }
  }
}

// ---- The finest cut in a renderer's buffers (BM_finest_buffers): from the volume in memory, an
// engine made, refine_full(), then snapshot().mesh_into(buffers) (`progiso_ms`, `ratio` against
// Flying Edges); and after a change (`change_ms`, `change_ratio`): a warm engine, fully refined
// at another isovalue (1.1 × the input's), set_isovalue(), refine_full(), mesh_into(), counted
// from set_isovalue(). The three run in rotated order within each pair.

void BM_finest_buffers(benchmark::State& state) {
  auto [in, vol, threads, fe] = volume_setup(state);
  const double other = in.isovalue * 1.1;
  engine_options eo;
  eo.threads = threads;
  engine warm(vol, other, eo);
  warm.refine_full();
  render_buffers buffers;
  render_buffers warm_buffers;
  std::vector<double> fe_ms, fresh_ms, change_ms, ratio, change_ratio;
  double triangles = 0.0;
  int pair = 0;
  for (auto _ : state) {
    double f = 0.0, a = 0.0, c = 0.0;
    const auto run = [&](int which) {
      const auto t0 = clock_type::now();
      if (which == 0) {
        (void)fe->run();
        f = ms_since(t0);
      } else if (which == 1) {
        engine e(vol, in.isovalue, eo);
        e.refine_full();
        e.snapshot().mesh_into(buffers);
        a = ms_since(t0);
        triangles = static_cast<double>(buffers.triangle_count());
      } else {
        warm.set_isovalue(in.isovalue);
        warm.refine_full();
        warm.snapshot().mesh_into(warm_buffers);
        c = ms_since(t0);
        warm.set_isovalue(other);
        warm.refine_full();
      }
    };
    for (int j = 0; j < 3; ++j) run((pair + j) % 3);
    ++pair;
    fe_ms.push_back(f);
    fresh_ms.push_back(a);
    change_ms.push_back(c);
    ratio.push_back(a / f);
    change_ratio.push_back(c / f);
    state.SetIterationTime(a / 1e3);
  }
  state.counters["fe_ms"] = median(fe_ms);
  state.counters["progiso_ms"] = median(fresh_ms);
  state.counters["ratio"] = median(ratio);
  state.counters["change_ms"] = median(change_ms);
  state.counters["change_ratio"] = median(change_ratio);
  state.counters["progiso_triangles"] = triangles;
}

// ---- 2D: vtkFlyingEdges2D against progiso's contours (polylines in memory).

void BM_peer_image(benchmark::State& state) {
  input& in = images()[static_cast<std::size_t>(state.range(0))];
  const volume& vol = in.get();
  (void)vtk_threads(1);
  state.SetLabel(in.name);
  const std::unique_ptr<flying_edges> fe = peer(vol, in.isovalue);
  contour_options options;  // full
  pair_stats s;
  run_pairs(state, *fe, s, [&] {
    const auto t0 = clock_type::now();
    const contour_result r = extract_contours(vol, {in.isovalue}, options);
    const double ms = ms_since(t0);
    s.mine_cells = static_cast<double>(r.contours.segment_count());
    benchmark::DoNotOptimize(r.contours.vertices.data());
    return ms;
  });
  report(state, s, "segments");
}

/// 1, 2, 4, … doubling below `cores`, then `cores` itself: {1, 2} on two cores, {1, 2, 4, 8, 16}
/// on sixteen, {1, 2, 4, 6} on six.
std::vector<unsigned> thread_counts(unsigned cores) {
  std::vector<unsigned> counts;
  for (unsigned t = 1; t < cores; t *= 2) counts.push_back(t);
  counts.push_back(cores);
  return counts;
}

void register_all() {
  const unsigned cores = std::max(1u, static_cast<unsigned>(scheduler::default_concurrency()));
  // A paired benchmark on every volume at every thread count from `lowest` on.
  const auto per_volume = [&](const char* name, void (*fn)(benchmark::State&), unsigned lowest) {
    for (std::size_t i = 0; i < volumes().size(); ++i) {
      for (const unsigned t : thread_counts(cores)) {
        if (t < lowest) continue;
        benchmark::RegisterBenchmark((std::string(name) + "/" + volumes()[i].name).c_str(), fn)
            ->Args({static_cast<std::int64_t>(i), static_cast<std::int64_t>(t)})
            ->Iterations(volumes()[i].pairs)
            ->UseManualTime()
            ->Unit(benchmark::kMillisecond);
      }
    }
  };
  per_volume("BM_peer_volume", BM_peer_volume, 1);
  per_volume("BM_peer_refined", BM_peer_refined, 1);
  per_volume("BM_peer_normals", BM_peer_normals, 1);
  per_volume("BM_peer_scaling", BM_peer_scaling, 2);
  per_volume("BM_follow", BM_follow, 1);
  per_volume("BM_follow_records", BM_follow_records, 1);
  per_volume("BM_finest_buffers", BM_finest_buffers, 1);
  per_volume("BM_stream_cut", BM_stream_cut, 1);
  for (std::size_t i = 0; i < volumes().size(); ++i) {
    for (std::int64_t t = 1; t <= 2; ++t) {
      benchmark::RegisterBenchmark(("BM_deadline_quality/" + volumes()[i].name).c_str(),
                                   BM_deadline_quality)
          ->Args({static_cast<std::int64_t>(i), t})
          ->Iterations(1)
          ->Unit(benchmark::kMillisecond);
    }
  }
  for (std::size_t i = 0; i < images().size(); ++i) {
    benchmark::RegisterBenchmark(("BM_peer_image/" + images()[i].name).c_str(), BM_peer_image)
        ->Args({static_cast<std::int64_t>(i)})
        ->Iterations(images()[i].pairs)
        ->UseManualTime()
        ->Unit(benchmark::kMillisecond);
  }
}

}  // namespace
}  // namespace progiso::bench

int main(int argc, char** argv) {
  return progiso::bench::run_benchmarks(argc, argv, progiso::bench::register_all);
}
