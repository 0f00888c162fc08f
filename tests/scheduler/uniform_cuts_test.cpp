// The engine's uniform cuts (engine_options::uniform_cuts): full and deadline runs from an
// unrefined root publish cuts made by streaming passes, each a cut of the hierarchy; what runs
// by records after them never shows a coarser surface; changes and buffers follow them.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/finest_surface.hpp>
#include <progiso/core/surface/surface_change.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/hierarchy_export.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/render_checks.hpp"

namespace progiso {
namespace {

using test::same_bytes;

// A grid no stride divides (the cuts are clipped to the box), with a surface the box cuts open.
volume test_volume() { return make_marschner_lobb({46, 39, 52}); }
constexpr double test_w = 0.5;

engine_options with_threads(unsigned n) {
  engine_options o;
  o.threads = n;
  return o;
}

TEST(UniformCuts, a_full_run_publishes_the_finest_surface_of_the_passes_for_every_thread_count) {
  const volume v = test_volume();
  const triangle_mesh finest = finest_surface(v, test_w);
  for (const unsigned n : {1u, 2u}) {
    engine e(v, test_w, with_threads(n));
    EXPECT_FALSE(e.done());
    EXPECT_TRUE(e.refine_full());
    EXPECT_TRUE(e.done());
    const surface_snapshot s = e.snapshot();
    EXPECT_EQ(s.uniform_stride(), 1);
    EXPECT_EQ(s.split_count(), 0u);
    EXPECT_EQ(s.triangle_count(), finest.triangles.size());
    EXPECT_TRUE(same_bytes(s.mesh(), finest)) << n;
    render_buffers b;
    s.mesh_into(b);
    EXPECT_EQ(b.triangle_count(), finest.triangles.size());
    EXPECT_EQ(b.vertex_count(), finest.vertices.size());
    // The same surface as full refinement by records, as a set of triangles.
    engine_options records = with_threads(n);
    records.uniform_cuts = false;
    engine r(v, test_w, records);
    r.refine_full();
    const surface_snapshot rs = r.snapshot();
    EXPECT_EQ(rs.uniform_stride(), 0);
    EXPECT_GT(rs.split_count(), 0u);
    EXPECT_TRUE(test::same_surface(rs.mesh(), finest));
    EXPECT_EQ(e.statistics().roots, 2u);  // the root surface, then the finest cut
    e.cancel();  // joins the run's driver, which retires what it replaced after the run
    EXPECT_EQ(e.statistics().reclamation.retired, 1u);
  }
}

TEST(UniformCuts, a_deadline_run_publishes_hierarchy_cuts_coarse_to_fine_as_they_are_made) {
  const volume v = make_marschner_lobb({97, 97, 97});
  const auto box = test::data_box(v);
  for (const unsigned n : {1u, 2u}) {
    engine e(v, test_w, with_threads(n));
    std::vector<std::int32_t> seen;  // strides, in the order a reader saw them
    std::atomic<bool> stop{false};
    std::mutex m;
    std::map<std::int32_t, triangle_mesh> meshes;
    std::thread reader([&] {
      // relaxed: a flag; the thread's join orders what it wrote.
      while (!stop.load(std::memory_order_relaxed)) {
        const surface_snapshot s = e.snapshot();
        const std::int32_t st = s.uniform_stride();
        if (seen.empty() || seen.back() != st) {
          seen.push_back(st);
          const std::lock_guard lock(m);
          meshes.emplace(st, s.mesh());
        }
      }
    });
    EXPECT_TRUE(e.refine_for(std::chrono::seconds(60)));
    stop.store(true, std::memory_order_relaxed);
    reader.join();
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(e.snapshot().uniform_stride(), 1);
    EXPECT_TRUE(e.done());
    // Coarse to fine, each one the uniform cut of its stride (the root surface shows first).
    for (std::size_t k = 1; k < seen.size(); ++k) {
      EXPECT_GT(seen[k], 0);
      if (seen[k - 1] > 0) {
        EXPECT_LT(seen[k], seen[k - 1]);
      }
    }
    for (const auto& [stride, mesh] : meshes) {
      SCOPED_TRACE(stride);
      EXPECT_TRUE(test::check_valid_cut(mesh, box[0], box[1]));
      if (stride > 0) {
        EXPECT_TRUE(same_bytes(mesh, uniform_cut(v, test_w, stride)));
      }
    }
  }
}

TEST(UniformCuts, a_short_deadline_stops_the_ladder_and_a_later_one_goes_on_below_it) {
  const volume v = make_marschner_lobb({129, 129, 129});
  engine e(v, test_w, with_threads(2));
  // A deadline already past makes nothing: the root surface stays.
  EXPECT_FALSE(e.refine_for(std::chrono::steady_clock::duration::zero()));
  EXPECT_EQ(e.snapshot().uniform_stride(), 0);
  std::int32_t last = 1 << 20;
  for (int k = 0; k < 200 && !e.done(); ++k) {
    e.refine_for(std::chrono::microseconds(300));
    const std::int32_t st = e.snapshot().uniform_stride();
    if (st > 0) {
      EXPECT_LE(st, last);
      last = st;
    }
  }
  e.refine_for(std::chrono::seconds(60));
  EXPECT_EQ(e.snapshot().uniform_stride(), 1);
  EXPECT_TRUE(same_bytes(e.snapshot().mesh(), finest_surface(v, test_w)));
}

TEST(UniformCuts, an_isovalue_change_shows_the_new_root_surface_then_its_own_uniform_cuts) {
  const volume v = test_volume();
  engine e(v, test_w, with_threads(2));
  e.refine_full();
  e.set_isovalue(0.3);
  const surface_snapshot first = e.snapshot();
  EXPECT_EQ(first.uniform_stride(), 0);
  EXPECT_EQ(first.isovalue(), 0.3);
  e.refine_for(std::chrono::seconds(60));
  const surface_snapshot s = e.snapshot();
  EXPECT_EQ(s.uniform_stride(), 1);
  EXPECT_EQ(s.isovalue(), 0.3);
  EXPECT_TRUE(same_bytes(s.mesh(), finest_surface(v, 0.3)));
  // An isovalue change during a full run resumes it at the new isovalue. Whether the change
  // lands while the run still goes is a race (a loaded machine may finish the passes first, and
  // the change then only shows the new root surface), so it is tried on fresh roots until it
  // lands inside a run; each try ends with one of those two surfaces, never another.
  const triangle_mesh finest = finest_surface(v, 0.6);
  int resumed = 0;
  for (int attempt = 0; attempt < 20 && resumed == 0; ++attempt) {
    e.set_isovalue(0.45);  // a root surface: the full run below has its passes to make
    e.start(refine_goal::full());
    e.set_isovalue(0.6);
    e.wait();
    const surface_snapshot after = e.snapshot();
    EXPECT_EQ(after.isovalue(), 0.6);
    if (after.uniform_stride() == 1) {
      EXPECT_TRUE(same_bytes(after.mesh(), finest));
      ++resumed;
    } else {
      EXPECT_EQ(after.uniform_stride(), 0);  // the root surface: the run had ended
    }
  }
  EXPECT_EQ(resumed, 1) << "no isovalue change landed inside a full run in 20 tries";
}

TEST(UniformCuts, runs_by_records_from_a_uniform_cut_show_their_cut_only_once_it_is_reached) {
  const volume v = test_volume();
  engine_options o = with_threads(2);
  std::vector<std::int32_t> strides_seen_by_progress;
  engine* self = nullptr;
  o.progress = [&](const engine_progress&) {
    strides_seen_by_progress.push_back(self->snapshot().uniform_stride());
  };
  o.progress_interval = 64;
  engine e(v, test_w, o);
  self = &e;
  // The coarsest uniform cut: a ladder of at least one cut, then an error run.
  std::int32_t stride = 0;
  for (int k = 0; k < 100 && stride <= 1; ++k) {
    e.set_isovalue(k % 2 == 0 ? 0.45 : 0.5);
    e.refine_for(std::chrono::microseconds(200 + 50 * k));
    stride = e.snapshot().uniform_stride();
  }
  ASSERT_GT(stride, 1) << "no coarse uniform cut was made";
  const double w = e.isovalue();
  strides_seen_by_progress.clear();
  EXPECT_TRUE(e.refine_until(0.05));
  const surface_snapshot s = e.snapshot();
  EXPECT_EQ(s.uniform_stride(), 0);
  EXPECT_GT(s.split_count(), 0u);
  // While it refined, readers saw the uniform cut.
  ASSERT_FALSE(strides_seen_by_progress.empty());
  for (const std::int32_t st : strides_seen_by_progress) EXPECT_EQ(st, stride);
  // Its cut is the error cut of a fresh engine, vertex for vertex.
  engine_options records = with_threads(2);
  records.uniform_cuts = false;
  engine r(v, w, records);
  r.refine_until(0.05);
  EXPECT_TRUE(same_bytes(s.mesh(), r.snapshot().mesh()));
  // After the finest cut, error and budget goals ask for nothing more.
  e.refine_full();
  EXPECT_TRUE(e.refine_until(0.05));
  EXPECT_TRUE(e.refine(refine_goal::triangles(10)));
  EXPECT_EQ(e.snapshot().uniform_stride(), 1);
}

TEST(UniformCuts, a_cancelled_run_keeps_what_it_published) {
  const volume v = make_marschner_lobb({129, 129, 129});
  engine e(v, test_w, with_threads(2));
  e.start(refine_goal::full());
  e.cancel();
  const surface_snapshot s = e.snapshot();
  EXPECT_TRUE(s.uniform_stride() == 0 || s.uniform_stride() == 1);
  EXPECT_TRUE(s.check_integrity());
  e.start(refine_goal::until(std::chrono::steady_clock::now() + std::chrono::seconds(60)));
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  e.cancel();
  EXPECT_FALSE(e.running());
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(e.snapshot().mesh(), box[0], box[1]));
}

TEST(UniformCuts, changes_to_and_from_uniform_cuts_keep_slots_equal_to_mesh_into) {
  const volume v = test_volume();
  for (const bool normals : {false, true}) {
    engine e(v, test_w, with_threads(2));
    const vertex_normals nv = normals ? vertex_normals::gradient : vertex_normals::none;
    render_slots slots;
    surface_change change;
    cut_mark mark;
    const auto follow = [&] {
      const surface_snapshot s = e.snapshot();
      s.change_since(mark, change, nv);
      slots.apply(change);
      mark = s.mark();
      render_buffers b;
      s.mesh_into(b, nv);
      // The pool's triangles equal the buffers', as multisets of nine floats.
      EXPECT_EQ(test::slot_triangles(slots, normals), test::buffer_triangles(b, normals));
      return s.uniform_stride();
    };
    EXPECT_EQ(follow(), 0);
    e.refine_for(std::chrono::seconds(60));
    EXPECT_EQ(follow(), 1);
    EXPECT_TRUE(change.rebuilt);
    follow();  // the same cut again: no change
    EXPECT_FALSE(change.rebuilt);
    EXPECT_TRUE(change.added.empty());
    e.set_isovalue(0.4);
    EXPECT_EQ(follow(), 0);
    e.refine_until(0.1);  // records, shown once reached
    EXPECT_EQ(follow(), 0);
    e.refine_full();
    EXPECT_EQ(follow(), 1);
  }
}

TEST(UniformCuts, a_uniform_cut_answers_by_its_split_set_and_refuses_what_needs_records) {
  const volume v = test_volume();
  engine e(v, test_w, with_threads(1));
  e.refine_full();
  const surface_snapshot s = e.snapshot();
  ASSERT_EQ(s.uniform_stride(), 1);
  const hierarchy& h = e.hierarchy_of();
  // Every diamond is split in the finest cut; root corners are no diamonds.
  EXPECT_TRUE(s.is_split(h.index({1, 1, 1})));
  EXPECT_FALSE(s.is_split(h.index({0, 0, 0})));
  EXPECT_THROW(s.for_each_split([](std::uint64_t) {}), error);
  EXPECT_THROW(s.for_each_triangle([](const owned_triangle&) {}), error);
  EXPECT_THROW((void)s.mesh_cut(0.1), error);
  std::vector<std::byte> stream;
  hierarchy_exporter x(e, [&stream](std::span<const std::byte> b) {
    stream.insert(stream.end(), b.begin(), b.end());
  });
  EXPECT_THROW(x.write(s), error);
  EXPECT_TRUE(s.check_integrity());
  // The replay of its split set by the sequential refiner gives its surface.
  refiner r(v, h, e.ranges(), test_w, refine_order::breadth_first);
  r.refine_set([&s](std::uint64_t d) { return s.is_split(d); });
  EXPECT_TRUE(test::same_surface(r.extract(), s.mesh()));
}

TEST(UniformCuts, off_every_run_refines_by_records) {
  const volume v = test_volume();
  engine_options o = with_threads(2);
  o.uniform_cuts = false;
  engine e(v, test_w, o);
  e.refine_for(std::chrono::milliseconds(5));
  EXPECT_EQ(e.snapshot().uniform_stride(), 0);
  e.refine_full();
  EXPECT_EQ(e.snapshot().uniform_stride(), 0);
  EXPECT_GT(e.snapshot().split_count(), 0u);
}

}  // namespace
}  // namespace progiso
