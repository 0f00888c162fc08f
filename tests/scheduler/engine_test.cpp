// The concurrent engine: the four scenarios, snapshots, determinism, reclamation of roots.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/scheduler/engine.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"

namespace progiso {
namespace {

using namespace std::chrono_literals;

// The sequential refiner's surface for exactly the snapshot's split set.
// The sequential path replays the straddling part of the snapshot's split set (a deadline run
// before the range data is complete also splits diamonds without surface: they change nothing).
triangle_mesh replay(const engine& e, const surface_snapshot& s) {
  std::unordered_set<std::uint64_t> split;
  std::size_t straddling = 0;
  const range_data& rd = e.ranges();
  s.for_each_split([&](std::uint64_t d) {
    split.insert(d);
    straddling += rd.get(e.hierarchy_of().point(d)).straddles(s.isovalue()) ? 1U : 0U;
  });
  refiner r(e.field(), e.hierarchy_of(), rd, s.isovalue(), refine_order::breadth_first);
  r.refine_set([&](std::uint64_t d) { return split.count(d) != 0; });
  EXPECT_EQ(r.statistics().splits, straddling) << "the split set is not parent-closed";
  return r.extract();
}

engine_options with_threads(unsigned n) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = n;
  return o;
}

TEST(Engine, root_surface_is_published_at_construction) {
  const volume v = make_marschner_lobb({33, 33, 33});
  engine e(v, 0.5, with_threads(2));
  const surface_snapshot s = e.snapshot();
  ASSERT_TRUE(s.valid());
  EXPECT_EQ(s.isovalue(), 0.5);
  EXPECT_EQ(s.generation(), 0u);
  EXPECT_EQ(s.split_count(), 0u);
  refiner r(e.field(), e.hierarchy_of(), e.ranges(), 0.5);
  EXPECT_TRUE(test::same_surface(s.mesh(), r.extract()));
  EXPECT_FALSE(e.done());
  EXPECT_THROW(engine(v, std::nan(""), {}), error);
}

// Whether oneTBB's scheduler has started in this process: its first use loads the scalable
// allocator library (libtbbmalloc), which then shows in /proc/self/maps. nullopt where the maps
// cannot be read.
std::optional<bool> onetbb_started() {
  std::ifstream maps("/proc/self/maps");
  if (!maps) return std::nullopt;
  std::string line;
  while (std::getline(maps, line)) {
    if (line.find("libtbbmalloc") != std::string::npos) return true;
  }
  return false;
}

// oneTBB's first use in a process (its scheduler, allocator library, worker threads) costs
// 0.4–0.9 ms, more than the root surface, which needs none of it: the first surface leaves it
// unstarted, the first run starts it. (ctest runs each test in a fresh process; where a build's
// oneTBB never loads the library, the test has nothing to see and skips.)
TEST(Engine, the_first_surface_does_not_start_onetbb) {
  if (onetbb_started() != std::optional<bool>(false)) GTEST_SKIP() << "oneTBB already started";
  const volume v = make_marschner_lobb({33, 33, 33});
  engine_options o;
  o.threads = 2;
  engine e(v, 0.5, o);
  const triangle_mesh first = e.snapshot().mesh();
  EXPECT_FALSE(first.empty());
  const std::optional<bool> at_first = onetbb_started();
  e.refine_full();
  if (onetbb_started() != std::optional<bool>(true)) GTEST_SKIP() << "no libtbbmalloc to see";
  EXPECT_EQ(at_first, std::optional<bool>(false));
}

TEST(Engine, full_refinement_equals_marching_tetrahedra_for_every_thread_count) {
  for (const auto& [name, v, w] :
       {std::tuple{"sphere", make_sphere_field({33, 29, 31}, {15.2, 14.1, 15.7}), 9.3},
        std::tuple{"marschner-lobb", make_marschner_lobb({41, 41, 41}), 0.5},
        std::tuple{"blobs", make_gaussian_blobs({37, 33, 35}, 6, 5u), 0.4}}) {
    SCOPED_TRACE(name);
    const test::reference_surface ref = test::reference_marching_tetrahedra(v, w);
    for (const unsigned n : {1u, 2u, 3u}) {
      SCOPED_TRACE(n);
      engine e(v, w, with_threads(n));
      EXPECT_TRUE(e.refine_full());
      EXPECT_TRUE(e.done());
      const surface_snapshot s = e.snapshot();
      EXPECT_TRUE(test::same_surface(s.mesh(), ref.mesh));
      EXPECT_TRUE(s.check_integrity());
    }
  }
}

TEST(Engine, mesh_is_byte_identical_whatever_the_thread_count_and_batch_size) {
  const volume v = make_gaussian_blobs({45, 41, 43}, 7, 11u);
  std::vector<triangle_mesh> meshes;
  for (const auto& [n, b] : {std::pair{1u, 32u}, std::pair{2u, 32u}, std::pair{2u, 1u},
                             std::pair{3u, 7u}, std::pair{4u, 64u}}) {
    engine_options o;
    o.threads = n;
    o.batch = b;
    engine e(v, 0.45, o);
    e.refine_full();
    meshes.push_back(e.snapshot().mesh());
  }
  for (std::size_t i = 1; i < meshes.size(); ++i) {
    EXPECT_EQ(meshes[i].vertices, meshes[0].vertices) << i;
    EXPECT_EQ(meshes[i].triangles, meshes[0].triangles) << i;
  }
}

// A renderer's buffers: the snapshot's mesh as floats, and storage kept
// from frame to frame: a coarser cut after a finer one allocates nothing.
TEST(Engine, render_buffers_hold_the_mesh_as_floats_and_keep_their_storage_frame_after_frame) {
  const volume v = make_marschner_lobb({33, 33, 33});
  engine e(v, 0.5, with_threads(2));
  render_buffers out;
  const auto same = [](const triangle_mesh& m, const render_buffers& b) {
    if (b.vertex_count() != m.vertices.size() || b.triangle_count() != m.triangles.size()) {
      return false;
    }
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      for (std::size_t k = 0; k < 3; ++k) {
        if (b.positions[3 * i + k] != static_cast<float>(m.vertices[i][k])) return false;
      }
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        if (b.indices[3 * t + k] != m.triangles[t][k]) return false;
      }
    }
    return true;
  };
  // Frame 0: the root surface.
  e.snapshot().mesh_into(out);
  EXPECT_TRUE(same(e.snapshot().mesh(), out));
  ASSERT_GT(out.triangle_count(), 0u);
  // Frames while the surface grows, then the finest.
  for (const double eps : {0.1, 0.01}) {
    e.refine_until(eps);
    const surface_snapshot s = e.snapshot();
    s.mesh_into(out);
    EXPECT_TRUE(same(s.mesh(), out)) << eps;
  }
  e.refine_full();
  const surface_snapshot fine = e.snapshot();
  fine.mesh_into(out);
  EXPECT_TRUE(same(fine.mesh(), out));
  const float* positions = out.positions.data();
  const std::uint32_t* indices = out.indices.data();
  const std::size_t fine_triangles = out.triangle_count();
  // Coarser cuts and the finest again: the same storage.
  for (const double eps : {0.05, 0.2, 0.0}) {
    fine.mesh_cut_into(eps, out);
    EXPECT_TRUE(same(fine.mesh_cut(eps), out)) << eps;
    EXPECT_EQ(out.positions.data(), positions) << eps;
    EXPECT_EQ(out.indices.data(), indices) << eps;
  }
  EXPECT_EQ(out.triangle_count(), fine_triangles);
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(fine.mesh_cut(0.2), box[0], box[1]));
}

// A renderer asks for normals with its buffers: they are add_vertex_normals() of the snapshot's
// mesh, as floats, on the engine's threads (the same for one thread and two); the buffers keep
// their storage, and a frame without normals empties out.normals but keeps its storage too.
// extract_isosurface_parallel gives the sequential path's normals.
TEST(Engine, render_buffers_take_the_gradient_normals_of_the_cut_when_asked) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine one(v, 0.5, with_threads(1));
  engine two(v, 0.5, with_threads(2));
  one.refine_full();
  two.refine_full();
  render_buffers a;
  render_buffers b;
  one.snapshot().mesh_into(a, vertex_normals::gradient);
  two.snapshot().mesh_into(b, vertex_normals::gradient);
  triangle_mesh m = two.snapshot().mesh();
  ASSERT_GT(m.vertices.size(), 2u * 16384u);  // pieces on both threads
  add_vertex_normals(m, v);
  ASSERT_EQ(b.normals.size(), 3 * m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    for (std::size_t k = 0; k < 3; ++k) {
      ASSERT_EQ(b.normals[3 * i + k], static_cast<float>(m.normals[i][k])) << i;
    }
  }
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.positions, b.positions);
  // A coarser cut with normals, then a frame without: the same storage throughout.
  const float* normals = b.normals.data();
  two.snapshot().mesh_cut_into(0.05, b, vertex_normals::gradient);
  triangle_mesh coarse = two.snapshot().mesh_cut(0.05);
  two.add_normals(coarse);
  ASSERT_EQ(b.normals.size(), 3 * coarse.vertices.size());
  EXPECT_EQ(b.normals[0], static_cast<float>(coarse.normals[0][0]));
  EXPECT_EQ(b.normals.data(), normals);
  two.snapshot().mesh_into(b);
  EXPECT_TRUE(b.normals.empty());
  EXPECT_GE(b.normals.capacity(), 3 * m.vertices.size());

  extract_options o;
  o.normals = true;
  // The hierarchy's cut, numbered as the sequential path numbers it.
  const detail::path_choice hierarchy_path{false};
  const extract_result seq = detail::extract_isosurface(v, 0.5, o, hierarchy_path);
  const extract_result par = detail::extract_isosurface_parallel(v, 0.5, o, 2, hierarchy_path);
  ASSERT_EQ(seq.mesh.vertices, par.mesh.vertices);
  EXPECT_EQ(seq.mesh.normals, par.mesh.normals);
  EXPECT_EQ(par.mesh.normals, m.normals);
  EXPECT_GT(par.normals_seconds, 0.0);
  o.normals = false;
  EXPECT_TRUE(extract_isosurface_parallel(v, 0.5, o, 2).mesh.normals.empty());
}

// Full refinement tests children by their ranges alone and queues them by placeholder (no
// errors). A run by error after an interrupted full run re-keys what is left by the real
// errors: it splits the sequential set for its target and stops there, not everything; the
// progress callback reports real errors in full runs too.
TEST(Engine, an_error_run_after_an_interrupted_full_run_orders_by_real_errors) {
  const volume v = make_marschner_lobb({41, 41, 41});
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  const auto [lo, hi] = v.value_range();
  engine full(v, 0.5, with_threads(2));
  ASSERT_TRUE(full.refine_full());
  const std::uint64_t all = full.snapshot().split_count();
  const double eps = 0.05;
  refiner seq(v, h, ranges, 0.5);
  seq.refine_to_error(eps);
  ASSERT_LT(seq.statistics().splits, all) << "the target must leave some unsplit";
  for (const unsigned threads : {1u, 2u}) {
    SCOPED_TRACE(threads);
    engine* self = nullptr;
    std::atomic<bool> cancel_now{true};
    std::vector<double> reported;
    engine_options o = with_threads(threads);
    o.progress_interval = 64;
    o.progress = [&](const engine_progress& p) {
      reported.push_back(p.next_error);
      if (cancel_now.load() && p.splits >= all / 8) self->cancel();
    };
    engine e(v, 0.5, o);
    self = &e;
    (void)e.ranges();  // exact errors first: only the placeholders need re-keying
    EXPECT_FALSE(e.refine_full());
    std::vector<bool> before(h.vertex_count(), false);
    std::uint64_t interrupted = 0;
    {
      const surface_snapshot cut = e.snapshot();
      cut.for_each_split([&](std::uint64_t d) { before[d] = true; });
      interrupted = cut.split_count();
    }
    ASSERT_LT(interrupted, all / 2);
    ASSERT_FALSE(reported.empty());
    for (const double r : reported) {
      EXPECT_GE(r, 0.0);
      EXPECT_LE(r, hi - lo) << "a placeholder key reported as an error";
    }
    cancel_now = false;
    EXPECT_TRUE(e.refine_until(eps));
    const surface_snapshot s = e.snapshot();
    // Nested errors: what the error run adds is exactly the sequential set for its target, so
    // the cut is the union of the interrupted cut and that set; splitting by placeholder keys
    // would add the interrupted run's whole frontier.
    std::uint64_t expected = 0;
    std::uint64_t missing = 0;
    for (std::uint64_t d = 0; d < h.vertex_count(); ++d) {
      const bool in_seq = seq.is_split(h.point(d));
      expected += (in_seq || before[d]) ? 1U : 0U;
      missing += (in_seq && !s.is_split(d)) ? 1U : 0U;
    }
    EXPECT_EQ(missing, 0u) << "the sequential set for the target is not all split";
    EXPECT_EQ(s.split_count(), expected) << "the error run split beyond its target";
    const auto box = test::data_box(v);
    EXPECT_TRUE(test::check_valid_cut(s.mesh_cut(eps * 2), box[0], box[1]));
    self = nullptr;
  }
}

TEST(Engine, quality_driven_splits_exactly_the_sequential_set) {
  const volume v = make_marschner_lobb({33, 33, 33});
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  for (const double eps : {0.2, 0.05, 0.01}) {
    SCOPED_TRACE(eps);
    refiner r(v, h, ranges, 0.5);
    r.refine_to_error(eps);
    engine e(v, 0.5, with_threads(2));
    EXPECT_TRUE(e.refine_until(eps));
    const surface_snapshot s = e.snapshot();
    EXPECT_EQ(s.split_count(), r.statistics().splits);
    EXPECT_TRUE(test::same_surface(s.mesh(), r.extract()));
    // and the coarser cuts by error agree with the sequential ones
    EXPECT_TRUE(test::same_surface(s.mesh_cut(eps * 4), r.extract_cut(eps * 4)));
  }
}

TEST(Engine, smoothed_field_refines_to_the_sequential_surface_on_every_thread_count) {
  // engine_options::smooth: the engine refines the smoothed field (smoothing.hpp); full
  // refinement gives the sequential path's surface on the same field, byte for byte across
  // thread counts; budgets, deadlines and an isovalue change give valid cuts.
  const auto data = std::make_shared<const volume>(make_gaussian_blobs({21, 19, 20}, 5, 4u));
  for (const smoothing& sm :
       {smoothing{1, 0, std::nullopt, 1.0}, smoothing{1, 1, std::nullopt, 0.8},
        smoothing{2, 0, std::array<std::int64_t, 6>{3, 3, 3, 12, 15, 10}, 1.0}}) {
    SCOPED_TRACE(sm.levels * 10 + sm.from);
    const volume field = smooth(data, sm);
    const hierarchy h(field.dims());
    const range_data ranges(field, h);
    refiner r(field, h, ranges, 0.4);
    r.refine_full();
    const triangle_mesh sequential = r.extract();
    std::vector<triangle_mesh> meshes;
    for (const unsigned n : {1u, 2u, 3u}) {
      engine_options o = with_threads(n);
      o.smooth = sm;
      engine e(*data, 0.4, o);
      EXPECT_EQ(e.field().dims(), field.dims());
      EXPECT_TRUE(e.refine_full());
      meshes.push_back(e.snapshot().mesh());
      EXPECT_TRUE(test::same_surface(meshes.back(), sequential));
    }
    for (std::size_t i = 1; i < meshes.size(); ++i) {
      EXPECT_EQ(meshes[i].vertices, meshes[0].vertices) << i;
      EXPECT_EQ(meshes[i].triangles, meshes[0].triangles) << i;
    }
    const auto box = test::data_box(field);
    engine_options o = with_threads(2);
    o.smooth = sm;
    engine e(data, 0.4, o);
    EXPECT_TRUE(e.refine(refine_goal::triangles(2000)));
    EXPECT_LE(e.snapshot().triangle_count(), 2000u);
    EXPECT_TRUE(test::check_valid_cut(e.snapshot().mesh(), box[0], box[1]));
    (void)e.refine_for(3ms);
    EXPECT_TRUE(test::check_valid_cut(e.snapshot().mesh(), box[0], box[1]));
    e.set_isovalue(0.3);
    EXPECT_TRUE(e.refine(refine_goal::triangles(5000)));
    const surface_snapshot s = e.snapshot();
    EXPECT_EQ(s.isovalue(), 0.3);
    EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
    EXPECT_TRUE(test::same_surface(s.mesh(), replay(e, s)));
  }
  engine_options bad;
  bad.smooth = {1, 0, std::nullopt, 3.0};
  EXPECT_THROW(engine(*data, 0.4, bad), error);
}

// Runs by priority on several threads, on both schedules: an error target splits exactly the
// sequential set; a budget is respected, and on tasks (band by band of the queue) it stops
// inside one band: every diamond of a larger band is split (the sequential cut by that band's
// upper bound lies in the budgeted cut); a deadline leaves a valid cut that the statistics
// count exactly.
TEST(Engine, runs_by_priority_reach_their_goals_on_tasks_and_on_the_flow_graph) {
  const volume v = make_gaussian_blobs({37, 35, 33}, 9, 5u);
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  const auto box = test::data_box(v);
  const double w = 0.4;
  for (const refinement_schedule schedule :
       {refinement_schedule::tasks, refinement_schedule::flow_graph}) {
    for (const unsigned n : {2u, 3u}) {
      SCOPED_TRACE(static_cast<int>(schedule) * 10 + static_cast<int>(n));
      engine_options o = with_threads(n);
      o.schedule = schedule;
      for (const double eps : {0.1, 0.02}) {
        refiner r(v, h, ranges, w);
        r.refine_to_error(eps);
        engine e(v, w, o);
        EXPECT_TRUE(e.refine_until(eps));
        const surface_snapshot s = e.snapshot();
        EXPECT_EQ(s.split_count(), r.statistics().splits);
        EXPECT_TRUE(test::same_surface(s.mesh(), r.extract()));
      }
      for (const std::uint64_t k : {300u, 4000u}) {
        engine e(v, w, o);
        EXPECT_TRUE(e.refine(refine_goal::triangles(k)));
        const surface_snapshot s = e.snapshot();
        EXPECT_LE(s.triangle_count(), k);
        EXPECT_EQ(s.mesh().triangles.size(), s.triangle_count());
        EXPECT_EQ(e.statistics().refine.splits, s.split_count());
        ASSERT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
        if (schedule != refinement_schedule::tasks) continue;
        double smallest = std::numeric_limits<double>::infinity();
        s.for_each_split(
            [&](std::uint64_t d) { smallest = std::min(smallest, ranges.get(h.point(d)).error); });
        const double band_top = detail::error_bucket_bounds(detail::error_bucket(smallest)).second;
        refiner above(v, h, ranges, w);
        above.refine_to_error(std::nextafter(band_top, 0.0));  // every error ≥ band_top
        std::uint64_t missing = 0;
        for (std::uint64_t d = 0; d < h.vertex_count(); ++d) {
          missing += (above.is_split(h.point(d)) && !s.is_split(d)) ? 1U : 0U;
        }
        EXPECT_EQ(missing, 0u) << "a diamond of a larger band left unsplit";
        if (k == 4000u) {
          EXPECT_GT(above.statistics().splits, 0u) << "a budget within one band";
        }
      }
      engine e(v, w, o);
      (void)e.ranges();
      (void)e.refine_for(2ms);
      const surface_snapshot s = e.snapshot();
      EXPECT_EQ(e.statistics().refine.splits, s.split_count());
      EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
      EXPECT_TRUE(e.refine_full());
      refiner r(v, h, ranges, w);
      r.refine_full();
      EXPECT_TRUE(test::same_surface(e.snapshot().mesh(), r.extract()));
    }
  }
}

// An error target in any order (refine_goal::error_in_any_order) takes its diamonds by grid
// plane, on one thread and on tasks, and ends on exactly the split set of the target by priority
// (the sequential refiner's), diamond by diamond. The order is not the priority order: by
// priority on one thread the records' error bands never rise (a child's error is at most its
// parent's, and a band is taken only when every larger one is empty); by plane they do. What
// the run leaves below the target is keyed by its errors, so a smaller target afterwards reaches
// its own set; stopped part way, what is left is handed back and the target still reached.
TEST(Engine, an_error_target_in_any_order_splits_the_targets_set_by_plane) {
  const volume v = make_gaussian_blobs({37, 35, 33}, 9, 5u);
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  const auto box = test::data_box(v);
  const double w = 0.4;
  const auto same_set = [&](const surface_snapshot& s, const refiner& r) {
    std::uint64_t differ = 0;
    for (std::uint64_t d = 0; d < h.vertex_count(); ++d) {
      differ += (r.is_split(h.point(d)) != s.is_split(d)) ? 1U : 0U;
    }
    return differ;
  };
  // Whether the error bands of the records rise anywhere in publication order.
  const auto bands_rise = [&](const surface_snapshot& s) {
    std::uint32_t last = std::numeric_limits<std::uint32_t>::max();
    bool rose = false;
    s.for_each_split([&](std::uint64_t d) {
      const std::uint32_t b = detail::error_bucket(ranges.get(h.point(d)).error);
      rose = rose || b > last;
      last = b;
    });
    return rose;
  };
  refiner all(v, h, ranges, w);
  all.refine_full();
  for (const unsigned n : {1u, 2u, 3u}) {
    SCOPED_TRACE(n);
    for (const double eps : {0.1, 0.02}) {
      SCOPED_TRACE(eps);
      refiner r(v, h, ranges, w);
      r.refine_to_error(eps);
      engine e(v, w, with_threads(n));
      EXPECT_TRUE(e.refine(refine_goal::error_in_any_order(eps)));
      const surface_snapshot s = e.snapshot();
      EXPECT_EQ(s.split_count(), r.statistics().splits);
      EXPECT_EQ(same_set(s, r), 0u);
      EXPECT_TRUE(test::same_surface(s.mesh(), r.extract()));
      EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
      if (n == 1) {
        EXPECT_TRUE(bands_rise(s)) << "the run took its diamonds by priority";
        engine by_priority(v, w, with_threads(1));
        EXPECT_TRUE(by_priority.refine(refine_goal::error(eps)));
        EXPECT_FALSE(bands_rise(by_priority.snapshot())) << "the check cannot tell the orders";
      }
      // What is left below the target is queued by its errors: a smaller target from here.
      refiner finer(v, h, ranges, w);
      finer.refine_to_error(eps / 4);
      EXPECT_TRUE(e.refine(refine_goal::error_in_any_order(eps / 4)));
      EXPECT_EQ(same_set(e.snapshot(), finer), 0u);
      EXPECT_TRUE(e.refine_until(eps / 16));
      refiner finest(v, h, ranges, w);
      finest.refine_to_error(eps / 16);
      EXPECT_EQ(same_set(e.snapshot(), finest), 0u);
      EXPECT_TRUE(e.refine_full());
      EXPECT_EQ(same_set(e.snapshot(), all), 0u);
    }
    // Stopped part way (a stop request from the progress callback), then the same target
    // again, in any order and by priority: the target's set, nothing lost or split twice. Or a
    // larger target by priority: the stopped cut's set plus the larger target's, no more (what
    // the stopped run left is keyed again by its errors, not taken first by placeholder).
    const double eps = 0.01;
    std::vector<std::unique_ptr<refiner>> targets;
    for (const double t : {eps, 2 * eps, 8 * eps}) {
      targets.push_back(std::make_unique<refiner>(v, h, ranges, w));
      targets.back()->refine_to_error(t);
    }
    const refiner& r = *targets[0];
    for (const int again : {0, 1, 2, 3}) {
      for (const std::uint64_t sixteenths : {3u, 8u, 13u}) {
        SCOPED_TRACE(std::to_string(again) + " " + std::to_string(sixteenths));
        std::atomic<bool> armed{true};
        engine* self = nullptr;
        engine_options o = with_threads(n);
        o.progress_interval = 1;
        o.progress = [&](const engine_progress& p) {
          if (armed && p.splits >= r.statistics().splits * sixteenths / 16) self->cancel();
        };
        engine e(v, w, o);
        self = &e;
        EXPECT_FALSE(e.refine(refine_goal::error_in_any_order(eps)));
        const surface_snapshot stopped = e.snapshot();
        EXPECT_LT(stopped.split_count(), r.statistics().splits);
        EXPECT_TRUE(test::check_valid_cut(stopped.mesh(), box[0], box[1]));
        EXPECT_TRUE(test::same_surface(stopped.mesh(), replay(e, stopped)));
        armed = false;
        if (again >= 2) {
          const refiner& coarser = *targets[static_cast<std::size_t>(again - 1)];
          std::vector<bool> before(h.vertex_count(), false);
          stopped.for_each_split([&](std::uint64_t d) { before[d] = true; });
          EXPECT_TRUE(e.refine_until(again == 2 ? 2 * eps : 8 * eps));
          const surface_snapshot s = e.snapshot();
          std::uint64_t differ = 0;
          for (std::uint64_t d = 0; d < h.vertex_count(); ++d) {
            differ += ((before[d] || coarser.is_split(h.point(d))) != s.is_split(d)) ? 1U : 0U;
          }
          EXPECT_EQ(differ, 0u);
          continue;
        }
        EXPECT_TRUE(
            e.refine(again == 0 ? refine_goal::error_in_any_order(eps) : refine_goal::error(eps)));
        const surface_snapshot s = e.snapshot();
        EXPECT_EQ(s.split_count(), r.statistics().splits);
        EXPECT_EQ(same_set(s, r), 0u);
      }
    }
  }
}

TEST(Engine, triangle_budget_is_respected) {
  const volume v = make_gaussian_blobs({33, 33, 33}, 8, 3u);
  const auto box = test::data_box(v);
  for (const std::uint64_t k : {50u, 400u, 3000u}) {
    engine e(v, 0.4, with_threads(2));
    EXPECT_TRUE(e.refine(refine_goal::triangles(k)));
    const surface_snapshot s = e.snapshot();
    EXPECT_LE(s.triangle_count(), k);
    EXPECT_GT(s.split_count(), 0u);
    EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
  }
}

TEST(Engine, time_critical_gives_a_surface_by_the_deadline_then_improves_it) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine e(v, 0.5, with_threads(2));
  // τ1: a surface within 2 ms; τ2: more refinement on top of it.
  // (Under sanitizers on a loaded machine 2 ms may end before the first split is published:
  // the root surface is then the surface by the deadline, still a valid one.)
  EXPECT_FALSE(e.refine_for(2ms)) << "65³ does not refine fully in 2 ms";
  const surface_snapshot first = e.snapshot();
  const std::uint64_t first_splits = first.split_count();
  EXPECT_TRUE(test::same_surface(first.mesh(), replay(e, first)));
  // τ2 improves on it (a few budgets at most where a sanitizer slows everything down).
  for (int k = 0; k < 50 && e.snapshot().split_count() == first_splits; ++k) e.refine_for(20ms);
  const surface_snapshot second = e.snapshot();
  EXPECT_GT(second.split_count(), first_splits);
  EXPECT_TRUE(test::same_surface(second.mesh(), replay(e, second)));
  // Nothing was lost: the work interrupted by deadlines still reaches the full surface.
  e.refine_full();
  EXPECT_TRUE(
      test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.5).mesh));
}

// The one-shot deadline runs (the command's --time-ms) on both entries: by default the ladder of
// uniform cuts (a distant deadline reaches the finest cut, a spent one the coarsest, each a
// valid surface: the hierarchy's uniform cut here, 64 cells a side), and refinement by priority
// when asked (deadline_ladder = false), which publishes the engine's cut and reports splits.
TEST(Engine, one_shot_deadline_runs_climb_uniform_cuts_or_refine_by_priority_when_asked) {
  const volume v = make_marschner_lobb({65, 65, 65});
  const auto box = test::data_box(v);
  const test::reference_surface full = test::reference_marching_tetrahedra(v, 0.5);
  extract_options o;
  const auto both = [&v](const extract_options& opt, unsigned threads) {
    return threads == 0 ? extract_isosurface(v, 0.5, opt)
                        : extract_isosurface_parallel(v, 0.5, opt, threads);
  };
  for (const unsigned threads : {0u, 1u, 2u}) {
    SCOPED_TRACE(threads);
    o.deadline_ladder = true;
    o.goal = refine_goal::within(std::chrono::hours(1));
    // Progress names each cut's stride, coarse to fine (calls never overlap: see
    // finest_progress).
    std::vector<std::int32_t> strides;
    o.progress = [&strides](const extract_progress& p) {
      if (strides.empty() || strides.back() != p.stride) strides.push_back(p.stride);
    };
    const extract_result far = both(o, threads);
    o.progress = {};
    EXPECT_EQ(strides, (std::vector<std::int32_t>{8, 4, 2, 1}));
    EXPECT_EQ(far.ladder_stride, 1);
    EXPECT_EQ(far.stats.splits, 0u);
    EXPECT_TRUE(test::same_surface(far.mesh, full.mesh));
    o.goal = refine_goal::within(std::chrono::duration<double>(0.0));
    const extract_result spent = both(o, threads);
    EXPECT_EQ(spent.ladder_stride, 8);
    EXPECT_TRUE(test::same_surface(spent.mesh, uniform_surface(v, 0.5, 8)));
    EXPECT_TRUE(test::check_valid_cut(spent.mesh, box[0], box[1]));
    EXPECT_LE(spent.first_surface_seconds, spent.pipeline_seconds);
    o.deadline_ladder = false;
    o.goal = refine_goal::within(std::chrono::milliseconds(200));
    const extract_result priority = both(o, threads);
    EXPECT_EQ(priority.ladder_stride, 0);
    EXPECT_GT(priority.stats.splits, 0u);
    EXPECT_TRUE(test::check_valid_cut(priority.mesh, box[0], box[1]));
  }
}

// A deadline run does not wait for the range data: while its min/max pass is incomplete it
// refines without culling (coarse first) between pieces of the pass, and it never waits for the
// error pass (it orders by the bounds hi − lo). Its cuts are valid, by error too (placeholders
// and bounds keep every cut by error parent-closed), and equal the sequential path's replay of
// their straddling splits; the next full run makes the exact errors, re-keys the queue and ends
// at marching tetrahedra.
TEST(Engine, a_deadline_run_refines_before_the_range_data_is_complete_and_stays_valid) {
  const volume v = make_marschner_lobb({193, 193, 193});
  const auto box = test::data_box(v);
  for (const unsigned n : {1u, 2u}) {
    // One deadline run on a fresh engine, the deadline growing by half from 0.5 ms, three fresh
    // engines for each, until a run publishes splits and ends before the ranges are complete
    // (how long that takes depends on the machine, the build and the load: a short deadline may
    // split nothing, a long one finish the pass, and on a busy machine the window between the
    // two is narrow and moves from run to run).
    std::unique_ptr<engine> made;
    for (auto d = std::chrono::microseconds(500); d <= 2s && !made; d = d * 3 / 2) {
      for (int tries = 0; tries < 3 && !made; ++tries) {
        auto e = std::make_unique<engine>(v, 0.5, with_threads(n));
        (void)e->refine_for(d);
        if (e->snapshot().split_count() > 0 && !e->ranges_built()) made = std::move(e);
      }
    }
    ASSERT_TRUE(made) << n << " threads: no deadline run split before the ranges were complete";
    engine& e = *made;
    // Longer deadline runs until one has time for the rest of the pass (under a sanitizer a
    // step of the build can take longer than half of a short deadline: it is then skipped).
    for (auto d = std::chrono::microseconds(2000); d <= 20s && !e.ranges_built(); d *= 2) {
      (void)e.refine_for(d);
    }
    ASSERT_TRUE(e.ranges_built()) << n;
    (void)e.refine_for(5ms);  // culled, ordered by error bounds
    EXPECT_FALSE(e.errors_built()) << n << " threads: a deadline run made the error pass";
    const surface_snapshot s = e.snapshot();
    EXPECT_TRUE(s.check_integrity());
    EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1])) << n;
    for (const double eps : {1e300, 0.5, 0.05}) {
      EXPECT_TRUE(test::check_valid_cut(s.mesh_cut(eps), box[0], box[1])) << n << " " << eps;
    }
    EXPECT_TRUE(test::same_surface(s.mesh(), replay(e, s))) << n;  // replay makes the errors
    EXPECT_TRUE(e.errors_built());
    EXPECT_TRUE(e.refine_full());
    EXPECT_TRUE(
        test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.5).mesh))
        << n;
  }
}

// A cancel() while a deadline run builds the range data returns within one step of the build,
// not at its end: the data is still incomplete afterwards.
TEST(Engine, cancel_during_a_deadline_runs_range_build_stops_the_build) {
  const volume v = make_marschner_lobb({193, 193, 193});
  engine e(v, 0.5, with_threads(1));
  e.start(refine_goal::until(std::chrono::steady_clock::now() + 60s));
  std::this_thread::sleep_for(1ms);
  e.cancel();
  EXPECT_FALSE(e.running());
  EXPECT_FALSE(e.ranges_built()) << "the build ran on after cancel()";
  EXPECT_GE(e.statistics().cancelled_runs, 1u);
}

TEST(Engine, a_full_run_stopped_mid_sweep_hands_every_ready_diamond_back) {
  // A full goal's ready diamonds are taken by grid plane (plane_lists), not from the queue: by
  // the one-thread loop (sweep_on_one_thread) and by each task on more threads; stopped, they are
  // handed back to the queue, keyed as a full run keys them. A run to ε from there must split
  // exactly the straddling diamonds of error > ε not yet split (their ancestors straddle with
  // larger errors: nested ranges), so the final split set is the stopped cut's plus those: a
  // ready diamond lost or kept twice in the handover changes it.
  const volume v = make_marschner_lobb({65, 65, 65});
  for (const unsigned threads : {1u, 2u, 3u}) {
    SCOPED_TRACE(threads);
    std::atomic<bool> armed{true};  // the callback runs on the driver or on a task
    engine_options o = with_threads(threads);
    o.progress_interval = 1;
    engine* self = nullptr;
    o.progress = [&](const engine_progress& p) {
      if (armed && p.splits >= 3000) self->cancel();  // from the callback: a stop request
    };
    engine e(v, 0.5, o);
    self = &e;
    EXPECT_FALSE(e.refine_full()) << "the callback's stop did not stop the run";
    const surface_snapshot stopped = e.snapshot();
    std::unordered_set<std::uint64_t> before;
    stopped.for_each_split([&](std::uint64_t d) { before.insert(d); });
    ASSERT_GE(before.size(), 3000u);
    EXPECT_FALSE(e.done());
    EXPECT_TRUE(test::same_surface(stopped.mesh(), replay(e, stopped)));
    armed = false;
    const double eps = 0.02;
    EXPECT_TRUE(e.refine_until(eps));
    std::unordered_set<std::uint64_t> expected = before;
    const hierarchy& h = e.hierarchy_of();
    const range_data& rd = e.ranges();
    std::size_t added = 0;
    for (std::uint64_t i = 0; i < h.vertex_count(); ++i) {
      const ipoint c = h.point(i);
      if (!h.is_diamond(c)) continue;
      const diamond_range dr = rd.get(c);
      if (dr.straddles(0.5) && dr.error > eps && expected.insert(i).second) ++added;
    }
    ASSERT_GT(added, 0u) << "choose a smaller eps: the stopped cut already holds every such split";
    std::unordered_set<std::uint64_t> after;
    e.snapshot().for_each_split([&](std::uint64_t d) { after.insert(d); });
    EXPECT_EQ(after.size(), expected.size());
    EXPECT_TRUE(after == expected) << "the run to eps split a different set";
  }
}

TEST(Engine, cancel_from_another_thread_stops_every_worker_and_keeps_what_was_published) {
  const volume v = make_marschner_lobb({97, 97, 97});
  // One thread (the serial loop), two and three (full refinement in tasks).
  for (const unsigned n : {1u, 2u, 3u}) {
    SCOPED_TRACE(n);
    engine e(v, 0.5, with_threads(n));
    e.start(refine_goal::full());
    EXPECT_TRUE(e.running() || e.done());
    std::thread canceller([&] {
      std::this_thread::sleep_for(5ms);
      e.cancel();
    });
    canceller.join();
    EXPECT_FALSE(e.running());
    const engine_statistics a = e.statistics();
    ASSERT_FALSE(e.done()) << "97³ refines fully in 5 ms? make the volume larger";
    std::this_thread::sleep_for(10ms);
    const engine_statistics b = e.statistics();
    EXPECT_EQ(a.published, b.published) << "a worker published after cancel() returned";
    EXPECT_EQ(a.batches, b.batches) << "a task ran after cancel() returned";
    EXPECT_GE(b.cancelled_runs, 1u);
    const surface_snapshot s = e.snapshot();
    EXPECT_EQ(s.split_count() + 1, b.published);
    EXPECT_TRUE(test::same_surface(s.mesh(), replay(e, s)));
    // Restarting continues from the published cut and reaches the full surface.
    e.start(refine_goal::full());
    e.wait();
    EXPECT_TRUE(e.done());
    EXPECT_TRUE(
        test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.5).mesh));
    EXPECT_TRUE(e.done());
  }
}

TEST(Engine, isovalue_change_publishes_the_new_root_at_once_and_resumes_refining) {
  const volume v = make_marschner_lobb({65, 65, 65});
  std::mutex m;
  std::multiset<std::uint64_t> reclaimed;
  {
    engine_options o = with_threads(2);
    o.poison_retired = true;
    o.on_reclaim = [&](std::uint64_t g) {
      const std::lock_guard lock(m);
      reclaimed.insert(g);
    };
    engine e(v, 0.5, o);
    e.start(refine_goal::full());
    std::this_thread::sleep_for(2ms);
    e.set_isovalue(0.3);
    {
      const surface_snapshot s = e.snapshot();
      EXPECT_EQ(s.isovalue(), 0.3);
      EXPECT_EQ(s.generation(), 1u);
      EXPECT_TRUE(s.check_integrity());
    }
    e.wait();
    EXPECT_TRUE(e.done()) << "the interrupted full goal resumes at the new isovalue";
    const surface_snapshot s = e.snapshot();
    EXPECT_TRUE(test::same_surface(s.mesh(), test::reference_marching_tetrahedra(v, 0.3).mesh));
    EXPECT_EQ(e.statistics().reclamation.retired, 1u);
    EXPECT_THROW(e.set_isovalue(std::numeric_limits<double>::infinity()), error);
  }
  EXPECT_EQ(reclaimed, (std::multiset<std::uint64_t>{0, 1})) << "each root reclaimed exactly once";
}

TEST(Engine, an_isovalue_change_publishes_the_new_surface_before_the_old_run_has_stopped) {
  // Once the engine holds a reclaimed root's memory, set_isovalue() publishes the new root
  // before it stops the run on the old one (swap_root). The old run is held in its progress
  // callback until a reader sees the new isovalue, or 5 s pass; set_isovalue() cannot return
  // before that run has stopped, so the reader sees the new surface only if it was published
  // first. Also: the published time lies within the call, and the resumed goal completes.
  using clock = std::chrono::steady_clock;
  const volume v = make_marschner_lobb({65, 65, 65});
  for (const unsigned threads : {1u, 2u}) {
    SCOPED_TRACE(testing::Message() << threads << " threads");
    std::atomic<int> phase{0};  // 1 armed, 2 the run is held, 3 the reader saw the new surface
    std::atomic<int> reclaimed{0};
    engine_options o = with_threads(threads);
    o.progress_interval = 1;
    o.progress = [&](const engine_progress&) {
      int armed = 1;
      // acq_rel: pairs with the test thread's release-store of 1 and its acquire-loads of 2.
      if (!phase.compare_exchange_strong(armed, 2, std::memory_order_acq_rel)) return;
      const auto until = clock::now() + 5s;
      // acquire: pairs with the reader's release-store of 3.
      while (phase.load(std::memory_order_acquire) != 3 && clock::now() < until) {
        std::this_thread::sleep_for(100us);
      }
    };
    // relaxed: a count polled by this thread; the reclaimer's own mutex orders its spare.
    o.on_reclaim = [&](std::uint64_t) { reclaimed.fetch_add(1, std::memory_order_relaxed); };
    engine e(v, 0.5, o);
    e.set_isovalue(0.4);  // nothing reclaimed yet: this change maps the new root's memory
    const auto give_up = clock::now() + 5s;
    // relaxed: see on_reclaim.
    while (reclaimed.load(std::memory_order_relaxed) == 0 && clock::now() < give_up) {
      std::this_thread::sleep_for(1ms);
    }
    ASSERT_EQ(reclaimed.load(std::memory_order_relaxed), 1) << "the first root was not reclaimed";
    phase.store(1, std::memory_order_release);  // release: pairs with the callback's acq_rel
    e.start(refine_goal::full());
    // acquire: pairs with the callback's acq_rel.
    while (phase.load(std::memory_order_acquire) != 2 && clock::now() < give_up) {
      std::this_thread::sleep_for(100us);
    }
    ASSERT_EQ(phase.load(std::memory_order_acquire), 2) << "the run never called back";
    const auto t0 = clock::now();
    std::thread changer([&] { e.set_isovalue(0.3); });
    bool seen = false;
    for (const auto until = clock::now() + 5s; clock::now() < until;) {
      if (e.isovalue() == 0.3) {
        seen = true;
        break;
      }
      std::this_thread::sleep_for(50us);
    }
    phase.store(3, std::memory_order_release);  // release: pairs with the callback's acquire
    changer.join();
    const auto t1 = clock::now();
    EXPECT_TRUE(seen) << "the new surface was not published while the old run was held";
    const engine_statistics st = e.statistics();
    EXPECT_GE(st.surface_published_at, t0);
    EXPECT_LE(st.surface_published_at, t1);
    EXPECT_EQ(st.generation, 2u);
    e.wait();
    EXPECT_TRUE(e.done()) << "the interrupted full goal resumes at the new isovalue";
    EXPECT_TRUE(
        test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.3).mesh));
  }
}

TEST(Engine, a_root_on_a_reclaimed_roots_cleared_arrays_refines_exactly_as_a_fresh_engine) {
  // Each isovalue change hands the old root's per-vertex arrays, cleared on a thread of their
  // own, to a later root: entry by entry after a small cut, whole after a large one. A missed entry
  // would make a child ready too early or never, or put a stale record index in a reader's lookup:
  // the surfaces would differ from a fresh engine's. A sphere in 97³ (912 673 vertices: entry by
  // entry below ~14 K records): radii 5.5–12.7 leave 5–17 K records, 30.2 and 41.1 leave 39–125 K;
  // eps < 0 is the full goal.
  const volume v = make_sphere_field({97, 97, 97}, {48.3, 47.6, 48.9});
  engine e(v, 5.5, with_threads(2));
  const std::vector<std::pair<double, double>> steps = {
      {5.5, -1.0}, {30.2, -1.0}, {9.3, 0.1}, {41.1, 0.5}, {12.7, 0.5}, {9.3, -1.0}, {30.2, 0.5}};
  for (const auto& [w, eps] : steps) {
    SCOPED_TRACE(testing::Message() << "w " << w << " eps " << eps);
    std::this_thread::sleep_for(20ms);  // time for the cleaner; the surfaces hold either way
    e.set_isovalue(w);
    engine fresh(v, w, with_threads(2));
    if (eps < 0) {
      EXPECT_TRUE(e.refine_full());
      EXPECT_TRUE(fresh.refine_full());
    } else {
      EXPECT_TRUE(e.refine_until(eps));
      EXPECT_TRUE(fresh.refine_until(eps));
    }
    const surface_snapshot s = e.snapshot();
    const surface_snapshot f = fresh.snapshot();
    EXPECT_EQ(s.split_count(), f.split_count());
    EXPECT_TRUE(s.check_integrity());
    const triangle_mesh m = s.mesh();
    const triangle_mesh mf = f.mesh();
    EXPECT_EQ(m.vertices, mf.vertices);
    EXPECT_EQ(m.triangles, mf.triangles);
  }
  EXPECT_GE(e.statistics().recycled_roots, 1u) << "no root took a reclaimed root's arrays";
  EXPECT_LT(e.statistics().recycled_roots, steps.size());
}

TEST(Engine, a_held_snapshot_keeps_its_root_readable_across_isovalue_changes) {
  const volume v = make_sphere_field({33, 33, 33}, {16.2, 15.7, 16.4});
  engine_options o = with_threads(2);
  o.poison_retired = true;
  o.reclamation.reclaim_threshold = 2;
  o.reclamation.era_frequency = 1;
  engine e(v, 10.0, o);
  e.refine_until(0.5);
  const surface_snapshot held = e.snapshot();
  const triangle_mesh before = held.mesh();
  for (int i = 0; i < 30; ++i) {
    e.set_isovalue(8.0 + 0.1 * i);
    e.refine_until(0.5);
  }
  // The stalled reader pins only its own root: the others were reclaimed.
  const epoch_statistics st = e.statistics().reclamation;
  EXPECT_EQ(st.retired, 30u);
  EXPECT_LE(st.pending, 1u + o.reclamation.reclaim_threshold);
  EXPECT_TRUE(held.check_integrity());
  EXPECT_EQ(held.isovalue(), 10.0);
  const triangle_mesh after = held.mesh();
  EXPECT_EQ(after.vertices, before.vertices);
  EXPECT_EQ(after.triangles, before.triangles);
}

TEST(Engine, snapshots_taken_while_refining_are_valid_cuts_of_one_isovalue) {
  const volume v = make_gaussian_blobs({49, 49, 49}, 9, 7u);
  const auto box = test::data_box(v);
  engine e(v, 0.4, with_threads(2));
  const auto check = [&](const surface_snapshot& s) {
    const triangle_mesh m = s.mesh();
    EXPECT_TRUE(test::check_valid_cut(m, box[0], box[1]));
    EXPECT_TRUE(test::same_surface(m, replay(e, s)));
  };
  std::vector<std::uint64_t> seen{e.snapshot().split_count()};
  e.start(refine_goal::full());
  // How many snapshots land inside the refinement depends on the scheduler (on a loaded
  // machine the refinement may finish before this thread runs again), so none is required;
  // every one taken must be a valid cut, and their split counts must never decrease.
  while (e.running()) {
    const surface_snapshot s = e.snapshot();
    seen.push_back(s.split_count());
    if (seen.size() % 4 == 2) check(s);
  }
  e.wait();
  const surface_snapshot last = e.snapshot();
  seen.push_back(last.split_count());
  check(last);
  EXPECT_EQ(seen.front(), 0u) << "before start: the root cut";
  EXPECT_GT(seen.back(), 0u);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end())) << "published cuts only grow";
}

// A snapshot's triangle count is the cut's, in every cut a reader sees while tasks publish (each
// publication adds its splits' triangles to the count in one step and numbers its records from
// it): a 65³ field on 2 and 3 threads, nothing clipped, so the mesh has exactly those triangles.
TEST(Engine, every_cut_seen_while_tasks_publish_counts_its_own_triangles) {
  const volume v = make_marschner_lobb({65, 65, 65});
  for (const unsigned n : {2u, 3u}) {
    SCOPED_TRACE(n);
    engine e(v, 0.5, with_threads(n));
    e.start(refine_goal::full());
    // None required mid-run: on a loaded machine the run may finish before this thread looks.
    while (e.running()) {
      const surface_snapshot s = e.snapshot();
      if (s.split_count() == 0) continue;
      EXPECT_EQ(s.mesh().triangles.size(), s.triangle_count()) << s.split_count() << " splits";
    }
    e.wait();
    const surface_snapshot last = e.snapshot();
    EXPECT_EQ(last.mesh().triangles.size(), last.triangle_count());
    EXPECT_EQ(last.triangle_count(), e.statistics().refine.triangles);
    EXPECT_TRUE(e.done());
  }
}

// A reader's cut by error while a full run refines (records carry no error: mesh_cut takes the
// range data's exact errors, built by the first mesh_cut while the run goes on): every such
// cut is valid, and at the end it equals the sequential refiner's cut by the same error.
TEST(Engine, cuts_by_error_taken_while_a_full_run_refines_are_valid) {
  const volume v = make_gaussian_blobs({49, 49, 49}, 9, 7u);
  const auto box = test::data_box(v);
  const double eps = 0.02;
  for (const unsigned n : {1u, 2u}) {
    engine e(v, 0.4, with_threads(n));
    e.start(refine_goal::full());
    int taken = 0;
    while (e.running() && taken < 6) {
      const surface_snapshot s = e.snapshot();
      EXPECT_TRUE(test::check_valid_cut(s.mesh_cut(eps), box[0], box[1])) << n;
      ++taken;
    }
    e.wait();
    const hierarchy h(v.dims());
    const range_data ranges(v, h);
    refiner r(v, h, ranges, 0.4);
    r.refine_full();
    const surface_snapshot s = e.snapshot();
    EXPECT_TRUE(test::same_surface(s.mesh_cut(eps), r.extract_cut(eps))) << n;
    EXPECT_TRUE(test::same_surface(s.mesh_cut(1e300), r.extract_cut(1e300))) << n;
    EXPECT_TRUE(e.errors_built()) << "mesh_cut makes the exact errors";
  }
}

TEST(Engine, statistics_count_cases_and_primitives_like_the_sequential_refiner) {
  const volume v = make_marschner_lobb({33, 33, 33});
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  refiner r(v, h, ranges, 0.5);
  r.refine_full();
  // One thread (the serial loop), two and three (full refinement in tasks).
  for (const unsigned n : {1u, 2u, 3u}) {
    SCOPED_TRACE(n);
    engine e(v, 0.5, with_threads(n));
    e.refine_full();
    const refine_statistics a = r.statistics();
    const refine_statistics b = e.statistics().refine;
    EXPECT_EQ(a.splits, b.splits);
    EXPECT_EQ(a.visited, b.visited);
    EXPECT_EQ(a.culled, b.culled);
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_EQ(a.record_triangles, b.record_triangles);
    EXPECT_EQ(a.cases, b.cases);
    EXPECT_EQ(a.primitives, b.primitives);
    EXPECT_EQ(a.configurations, b.configurations);
    EXPECT_TRUE(e.done());
  }
}

// Every record follows the records of its parents, in every cut a reader can see: the rule that
// makes each published prefix a valid cut, whoever publishes (the one-thread loop, full
// refinement in tasks, the graph's commit step for priority goals).
TEST(Engine, records_follow_their_parents_records_on_every_path) {
  const volume v = make_gaussian_blobs({65, 61, 63}, 9, 13u);
  const auto parents_first = [](const engine& e, const surface_snapshot& s) {
    const hierarchy& h = e.hierarchy_of();
    std::unordered_set<std::uint64_t> before;
    std::size_t orphans = 0;
    s.for_each_split([&](std::uint64_t d) {
      std::array<ipoint, 4> ps{};
      const int n = h.parents(h.make_diamond(h.point(d)), ps);
      for (int i = 0; i < n; ++i) {
        if (before.count(h.index(ps[static_cast<std::size_t>(i)])) == 0) ++orphans;
      }
      before.insert(d);
    });
    return orphans;
  };
  for (const unsigned n : {1u, 2u, 3u}) {
    for (const bool full : {true, false}) {
      SCOPED_TRACE(testing::Message() << n << " threads, " << (full ? "full" : "error"));
      engine e(v, 0.4, with_threads(n));
      e.start(full ? refine_goal::full() : refine_goal::error(0.001));
      std::size_t taken = 0;
      while (e.running()) {
        const surface_snapshot s = e.snapshot();
        EXPECT_EQ(parents_first(e, s), 0u) << "a record before one of its parents'";
        ++taken;
      }
      e.wait();
      const surface_snapshot s = e.snapshot();
      EXPECT_GT(s.split_count(), 1000u);
      EXPECT_EQ(parents_first(e, s), 0u);
      RecordProperty("snapshots_during_the_run", static_cast<int>(taken));
    }
  }
}

// With one thread the engine runs its goals in a loop of its own (no graph): the same split
// sets as the sequential refiner where the order fixes them (full, error), the budget held and
// a valid cut otherwise.
TEST(Engine, one_thread_reaches_every_goal_like_the_sequential_refiner) {
  const volume v = make_marschner_lobb({41, 41, 41});
  const auto box = test::data_box(v);
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  for (const double eps : {0.1, 0.01}) {
    refiner r(v, h, ranges, 0.5);
    r.refine_to_error(eps);
    engine e(v, 0.5, with_threads(1));
    EXPECT_TRUE(e.refine_until(eps));
    EXPECT_EQ(e.snapshot().split_count(), r.statistics().splits) << eps;
    EXPECT_TRUE(test::same_surface(e.snapshot().mesh(), r.extract())) << eps;
  }
  for (const std::uint64_t k : {400u, 3000u}) {  // the root cut has 200
    engine e(v, 0.5, with_threads(1));
    EXPECT_TRUE(e.refine(refine_goal::triangles(k)));
    const surface_snapshot s = e.snapshot();
    EXPECT_LE(s.triangle_count(), k);
    EXPECT_GT(s.split_count(), 0u);
    EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
  }
  engine e(v, 0.5, with_threads(1));
  e.refine(refine_goal::until(std::chrono::steady_clock::now() + 2ms));
  const surface_snapshot s = e.snapshot();
  EXPECT_TRUE(test::check_valid_cut(s.mesh(), box[0], box[1]));
  EXPECT_TRUE(test::same_surface(s.mesh(), replay(e, s)));
  // and a full run continues the deadline's cut to the finest surface
  EXPECT_TRUE(e.refine_full());
  EXPECT_TRUE(
      test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.5).mesh));
}

TEST(Engine, parallel_extraction_matches_the_sequential_one_in_every_mode) {
  const volume v = make_marschner_lobb({41, 41, 41});
  extract_options full;
  const extract_result seq = extract_isosurface(v, 0.5, full);
  const extract_result par = extract_isosurface_parallel(v, 0.5, full, 2);
  // Both take the direct path: the same mesh, numbered alike.
  EXPECT_TRUE(seq.finest_direct);
  EXPECT_TRUE(par.finest_direct);
  EXPECT_EQ(seq.mesh.vertices, par.mesh.vertices);
  EXPECT_EQ(seq.mesh.triangles, par.mesh.triangles);
  const detail::path_choice hierarchy_path{false};  // the same splits on both
  const extract_result seq_refined = detail::extract_isosurface(v, 0.5, full, hierarchy_path);
  const extract_result refined =
      detail::extract_isosurface_parallel(v, 0.5, full, 2, hierarchy_path);
  EXPECT_FALSE(seq_refined.finest_direct);
  EXPECT_TRUE(test::same_surface(seq.mesh, seq_refined.mesh));
  EXPECT_TRUE(test::same_surface(seq.mesh, refined.mesh));
  EXPECT_GT(refined.stats.splits, 0U);
  EXPECT_EQ(seq_refined.stats.splits, refined.stats.splits);
  extract_options err;
  err.goal = refine_goal::error(0.05);
  EXPECT_TRUE(test::same_surface(extract_isosurface(v, 0.5, err).mesh,
                                 extract_isosurface_parallel(v, 0.5, err, 2).mesh));
  extract_options bad;
  bad.goal = refine_goal::error(-1.0);
  EXPECT_THROW((void)extract_isosurface_parallel(v, 0.5, bad, 2), error);
}

TEST(Engine, full_pipeline_reports_the_rows_of_its_two_passes_one_call_at_a_time) {
  const volume v = make_marschner_lobb({41, 37, 33});
  for (const unsigned threads : {1U, 2U, 4U}) {
    SCOPED_TRACE(threads);
    std::atomic<bool> inside{false};
    std::atomic<int> overlaps{0};
    std::vector<extract_progress> seen;  // one call at a time
    extract_options o;
    o.progress = [&](const extract_progress& p) {
      // seq_cst: the exchange pairs with another call's store of false below; a call that
      // finds true overlaps one still running.
      if (inside.exchange(true)) ++overlaps;
      seen.push_back(p);
      std::this_thread::yield();
      inside.store(false);  // seq_cst: pairs with the next call's exchange
    };
    const extract_result r = extract_isosurface_parallel(v, 0.5, o, threads);
    ASSERT_TRUE(r.finest_direct);
    EXPECT_EQ(overlaps.load(), 0);  // seq_cst: after the run's threads are joined
    ASSERT_FALSE(seen.empty());
    for (std::size_t i = 0; i < seen.size(); ++i) {
      EXPECT_EQ(seen[i].rows_total, 2U * 37U * 33U);
      EXPECT_EQ(seen[i].depth, seen[i].max_depth);
      EXPECT_GT(seen[i].max_depth, 0);
      if (i > 0) {
        EXPECT_GE(seen[i].rows_done, seen[i - 1].rows_done);
      }
    }
    EXPECT_EQ(seen.back().rows_done, seen.back().rows_total);
  }
}

TEST(Engine, root_surface_is_published_before_any_pass_over_the_volume) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine e(v, 0.5, with_threads(0));  // all cores, by records
  // Constructed: the root surface is there, and the range data is not built yet.
  EXPECT_EQ(e.range_build_seconds(), 0.0);
  const surface_snapshot first = e.snapshot();
  EXPECT_GT(first.triangle_count(), 0u);
  EXPECT_FALSE(e.done());  // the roots are not yet known to be culled
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(first.mesh(), box[0], box[1]));
  EXPECT_EQ(e.range_build_seconds(), 0.0);
  // The first run builds it, then refines.
  ASSERT_TRUE(e.refine_full());
  EXPECT_GT(e.range_build_seconds(), 0.0);
  EXPECT_TRUE(e.done());
  EXPECT_TRUE(
      test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.5).mesh));
  // A new isovalue: its root surface at once, its roots queued by the next run.
  e.set_isovalue(0.3);
  EXPECT_FALSE(e.done());
  ASSERT_TRUE(e.refine_full());
  EXPECT_TRUE(
      test::same_surface(e.snapshot().mesh(), test::reference_marching_tetrahedra(v, 0.3).mesh));
}

TEST(Engine, pipeline_reports_the_first_surface_before_the_range_data) {
  const volume v = make_marschner_lobb({65, 65, 65});
  const extract_result r =
      detail::extract_isosurface_parallel(v, 0.5, extract_options{}, 2, detail::path_choice{false});
  EXPECT_FALSE(r.finest_direct);
  EXPECT_GT(r.range_build_seconds, 0.0);
  EXPECT_LE(r.first_surface_seconds + r.range_build_seconds + r.refine_seconds + r.extract_seconds,
            r.pipeline_seconds + 1e-9);
  EXPECT_GT(r.range_bytes, 0u);
  EXPECT_TRUE(test::same_surface(r.mesh, test::reference_marching_tetrahedra(v, 0.5).mesh));
}

TEST(Engine, full_pipeline_gives_the_finest_surface_by_two_passes_the_same_for_every_count) {
  // A full run's result is the finest cut: by finest_surface(), after the root surface, with no
  // range data and no splits; the surface the hierarchy's path ends at, byte for byte the same
  // for 1, 2 and 3 threads.
  const volume v = make_marschner_lobb({57, 49, 41});
  const extract_result one = extract_isosurface_parallel(v, 0.5, extract_options{}, 1);
  EXPECT_TRUE(one.finest_direct);
  EXPECT_GT(one.first_surface_seconds, 0.0);
  EXPECT_EQ(one.range_build_seconds, 0.0);
  EXPECT_EQ(one.stats.splits, 0u);
  EXPECT_EQ(one.stats.triangles, one.mesh.triangles.size());
  EXPECT_LE(one.first_surface_seconds + one.extract_seconds, one.pipeline_seconds + 1e-9);
  for (const unsigned threads : {2u, 3u}) {
    const extract_result r = extract_isosurface_parallel(v, 0.5, extract_options{}, threads);
    EXPECT_EQ(r.mesh.vertices, one.mesh.vertices) << threads;
    EXPECT_EQ(r.mesh.triangles, one.mesh.triangles) << threads;
  }
  const extract_result by_splits =
      detail::extract_isosurface_parallel(v, 0.5, extract_options{}, 2, detail::path_choice{false});
  EXPECT_GT(by_splits.stats.splits, 0u);
  EXPECT_EQ(by_splits.mesh.vertices.size(), one.mesh.vertices.size());
  EXPECT_TRUE(test::same_surface(by_splits.mesh, one.mesh));
  // Normals on the direct path: those of the same positions on the hierarchy's path.
  extract_options normals;
  normals.normals = true;
  const extract_result shaded = extract_isosurface_parallel(v, 0.5, normals, 2);
  const extract_result shaded_refined =
      detail::extract_isosurface_parallel(v, 0.5, normals, 2, detail::path_choice{false});
  std::map<vec3, vec3> by_position;
  for (std::size_t i = 0; i < shaded_refined.mesh.vertices.size(); ++i) {
    by_position[shaded_refined.mesh.vertices[i]] = shaded_refined.mesh.normals[i];
  }
  ASSERT_EQ(shaded.mesh.normals.size(), shaded.mesh.vertices.size());
  for (std::size_t i = 0; i < shaded.mesh.vertices.size(); ++i) {
    EXPECT_EQ(shaded.mesh.normals[i], by_position.at(shaded.mesh.vertices[i])) << i;
  }
}

}  // namespace
}  // namespace progiso
