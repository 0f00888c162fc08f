// The contour engine: the 2D engine's four scenarios and its guarantees. Full refinement equals
// marching triangles on the finest mesh and the sequential contour refiner; error and budget
// goals split what the refiner splits; deadlines and cancels stop a run and leave a valid cut;
// snapshots are immutable while the run goes on; an isovalue change publishes the new root
// contour at once, keeps old snapshots readable and resumes the goal; the progress callback's
// exceptions come back to the caller.
#include <progiso/scheduler/contour_engine.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/contour/contour_refiner.hpp>

#include "support/contour_checks.hpp"
#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

using namespace std::chrono_literals;

volume make_image(std::int64_t w, std::int64_t h, double (*f)(double, double)) {
  return test::make_test_image(w, h, f);
}

double corner_circle(double x, double y) { return std::hypot(x - 20.3, y - 17.6); }
double waves(double x, double y) {
  return std::sin(x * 0.21) * std::cos(y * 0.17) + 0.4 * std::sin((x + 2 * y) * 0.05);
}
double edge_cut(double x, double y) { return std::hypot(x - 44.0, y + 3.0); }

// Exactly equal contour sets: same vertices (bit for bit), same polylines in the same order.
::testing::AssertionResult identical(const contour_set& a, const contour_set& b) {
  if (a.vertices != b.vertices) {
    return ::testing::AssertionFailure()
           << "vertices differ: " << a.vertices.size() << " vs " << b.vertices.size();
  }
  if (a.polylines.size() != b.polylines.size()) {
    return ::testing::AssertionFailure()
           << "polyline counts differ: " << a.polylines.size() << " vs " << b.polylines.size();
  }
  for (std::size_t i = 0; i < a.polylines.size(); ++i) {
    if (a.polylines[i].vertices != b.polylines[i].vertices ||
        a.polylines[i].closed != b.polylines[i].closed ||
        a.polylines[i].isovalue != b.polylines[i].isovalue) {
      return ::testing::AssertionFailure() << "polyline " << i << " differs";
    }
  }
  return ::testing::AssertionSuccess();
}

// The sequential refiner on the same image, for comparisons.
struct sequential {
  hierarchy2d h;
  range_data2d ranges;
  contour_refiner r;
  sequential(const volume& img, double w)
      : h(img.dims()[0], img.dims()[1]), ranges(img, h), r(img, h, ranges, w) {}
};

// Every grid point is a diamond centre (or not one, then neither splits it).
void expect_same_split_set(const contour_snapshot& s, const contour_refiner& r,
                           const hierarchy2d& h) {
  std::uint64_t differ = 0;
  for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
      if (s.is_split({x, y}) != r.is_split({x, y})) ++differ;
    }
  }
  EXPECT_EQ(differ, 0U);
  EXPECT_EQ(s.split_count(), r.statistics().splits);
  EXPECT_EQ(s.segment_count(), r.segment_count());
}

// A busy field large enough that a full run takes tens of milliseconds on one thread.
const volume& busy_image() {
  static const volume img = make_image(1500, 1200, waves);
  return img;
}

TEST(ContourEngine, root_contour_is_published_at_construction_without_range_data) {
  const volume img = make_image(70, 45, waves);
  contour_engine eng(img, 0.1);
  const contour_snapshot s = eng.snapshot();
  ASSERT_TRUE(s.valid());
  EXPECT_EQ(s.split_count(), 0U);
  EXPECT_EQ(s.isovalue(), 0.1);
  EXPECT_EQ(s.generation(), 0U);
  EXPECT_EQ(eng.range_build_seconds(), 0.0);  // no pass over the image yet
  sequential seq(img, 0.1);
  EXPECT_TRUE(identical(s.extract(), seq.r.extract()));
  EXPECT_EQ(s.segment_count(), seq.r.segment_count());
  EXPECT_TRUE(s.check_integrity());
}

TEST(ContourEngine, full_refinement_equals_marching_triangles_and_the_refiner) {
  std::vector<std::pair<volume, double>> cases;
  cases.emplace_back(make_image(70, 45, waves), 0.1);
  cases.emplace_back(make_image(50, 29, edge_cut), 20.0);  // open chains, padding
  if (const auto dir = test::shared_data_dir()) {
    for (const auto& info : test::shared_images()) {
      cases.emplace_back(test::load_pgm(*dir / info.file), info.isovalues.front());
    }
  }
  for (const auto& [img, w] : cases) {
    SCOPED_TRACE(std::to_string(img.dims()[0]) + "x" + std::to_string(img.dims()[1]));
    contour_engine eng(img, w);
    EXPECT_TRUE(eng.refine_full());
    EXPECT_TRUE(eng.done());
    const contour_snapshot s = eng.snapshot();
    const contour_set mine = s.extract();
    EXPECT_TRUE(test::same_segments(mine, test::reference_contours(img, w)));
    EXPECT_TRUE(test::check_valid_contour(mine, test::image_box(img)));
    sequential seq(img, w);
    seq.r.refine_full();
    EXPECT_TRUE(test::same_segments(mine, seq.r.extract()));
    expect_same_split_set(s, seq.r, seq.h);
    EXPECT_TRUE(s.check_integrity());
    EXPECT_GT(eng.range_build_seconds(), 0.0);
  }
}

TEST(ContourEngine, error_goals_split_exactly_what_the_refiner_splits) {
  const volume img = make_image(97, 80, waves);
  contour_engine eng(img, 0.05);
  sequential seq(img, 0.05);
  // Coarse to fine, then a coarser goal (nothing to do), and cuts of the result by error.
  for (const double eps : {0.3, 0.1, 0.02, 0.005, 0.05}) {
    SCOPED_TRACE(eps);
    EXPECT_TRUE(eng.refine_until(eps));
    seq.r.refine_to_error(eps);
    const contour_snapshot s = eng.snapshot();
    expect_same_split_set(s, seq.r, seq.h);
    EXPECT_TRUE(test::same_segments(s.extract(), seq.r.extract()));
    for (const double cut : {0.2, 0.04, 0.0}) {
      EXPECT_TRUE(test::same_segments(s.extract_cut(cut), seq.r.extract_cut(cut)));
      EXPECT_TRUE(test::check_valid_contour(s.extract_cut(cut), test::image_box(img)));
    }
  }
}

TEST(ContourEngine, segment_budgets_are_respected_and_match_the_refiner) {
  const volume img = make_image(97, 80, waves);
  for (const std::uint64_t budget : {20U, 150U, 600U}) {
    SCOPED_TRACE(budget);
    contour_engine eng(img, 0.05);
    EXPECT_TRUE(eng.refine(refine_goal::triangles(budget)));
    const contour_snapshot s = eng.snapshot();
    EXPECT_LE(s.segment_count(), budget);
    sequential seq(img, 0.05);
    while (seq.r.split_next(budget)) {
    }
    expect_same_split_set(s, seq.r, seq.h);
    EXPECT_TRUE(test::check_valid_contour(s.extract(), test::image_box(img)));
  }
}

TEST(ContourEngine, the_same_split_set_gives_identical_contours_whatever_the_order) {
  const volume img = make_image(97, 80, waves);
  contour_engine full(img, 0.05);  // last in first out
  EXPECT_TRUE(full.refine_full());
  contour_engine by_error(img, 0.05);  // largest error first, in steps
  for (const double eps : {0.2, 0.01, -1.0}) EXPECT_TRUE(by_error.refine_until(eps));
  const contour_snapshot a = full.snapshot();
  const contour_snapshot b = by_error.snapshot();
  ASSERT_EQ(a.split_count(), b.split_count());
  EXPECT_TRUE(identical(a.extract(), b.extract()));
  EXPECT_TRUE(identical(a.extract_cut(0.03), b.extract_cut(0.03)));
  // A sparse cut (below a split per 4096 grid vertices: its records sorted) against the same
  // cut taken from a finer run's records, on a large image with a small contour.
  const volume large = make_image(1200, 900, corner_circle);
  contour_engine fine(large, 8.0);
  EXPECT_TRUE(fine.refine_full());
  contour_engine coarse(large, 8.0);
  EXPECT_TRUE(coarse.refine_until(0.1));
  const contour_snapshot c = coarse.snapshot();
  ASSERT_GT(c.split_count(), 10U);
  ASSERT_LT(c.split_count(), coarse.hierarchy_of().vertex_count() / 4096);
  EXPECT_TRUE(identical(c.extract(), fine.snapshot().extract_cut(0.1)));
  EXPECT_TRUE(test::check_valid_contour(c.extract(), test::image_box(large)));
  sequential seq(large, 8.0);
  seq.r.refine_to_error(0.1);
  EXPECT_TRUE(test::same_segments(c.extract(), seq.r.extract()));
  // A dense cut (read through a bitmap) against the same cut of the full run.
  contour_engine dense(img, 0.05);
  EXPECT_TRUE(dense.refine_until(0.3));
  const contour_snapshot d = dense.snapshot();
  ASSERT_GT(d.split_count(), dense.hierarchy_of().vertex_count() / 4096);
  EXPECT_TRUE(identical(d.extract(), a.extract_cut(0.3)));
}

TEST(ContourEngine, a_deadline_stops_the_run_and_leaves_a_valid_cut) {
  const volume& img = busy_image();
  contour_engine eng(img, 0.1);
  (void)eng.ranges();  // the range data is the first run's; built here, the deadline is refinement
  // A deadline already past: nothing is split, and the goal is not reached.
  EXPECT_FALSE(eng.refine(refine_goal::until(std::chrono::steady_clock::now())));
  EXPECT_EQ(eng.snapshot().split_count(), 0U);
  // A short deadline: some splits, not all, and the run ends soon after it. (On a loaded
  // machine the run's thread may start after a short deadline: then a longer one.)
  auto budget = std::chrono::steady_clock::duration(3ms);
  for (;;) {
    const auto t0 = std::chrono::steady_clock::now();
    const bool reached = eng.refine_for(budget);
    const auto took = std::chrono::steady_clock::now() - t0;
    EXPECT_FALSE(reached);
    EXPECT_LT(took, budget + 500ms);  // one split past the deadline at most; generous
    if (eng.snapshot().split_count() > 0 || budget > 200ms) break;
    budget *= 2;
  }
  const contour_snapshot s = eng.snapshot();
  EXPECT_GT(s.split_count(), 0U);
  EXPECT_FALSE(eng.done());
  EXPECT_TRUE(test::check_valid_contour(s.extract(), test::image_box(img)));
  // Later deadlines improve the same contour; a long one finishes it.
  EXPECT_TRUE(eng.refine_for(60s));
  EXPECT_TRUE(eng.done());
  EXPECT_GT(eng.snapshot().split_count(), s.split_count());
}

TEST(ContourEngine, cancel_stops_a_run_and_keeps_what_was_published) {
  const volume& img = busy_image();
  contour_engine_options opt;
  std::atomic<int> calls{0};
  contour_engine* self = nullptr;
  opt.progress_interval = 512;
  opt.progress = [&](const engine_progress& p) {
    EXPECT_GT(p.splits, 0U);
    // From the callback, cancel() only requests the stop.
    if (calls.fetch_add(1) == 2) self->cancel();
  };
  contour_engine eng(img, 0.1, std::move(opt));
  self = &eng;
  EXPECT_FALSE(eng.refine_full());
  EXPECT_FALSE(eng.running());
  EXPECT_FALSE(eng.done());
  const contour_snapshot s = eng.snapshot();
  EXPECT_GE(s.split_count(), 3U * 512U);
  EXPECT_EQ(eng.statistics().cancelled_runs, 1U);
  EXPECT_TRUE(test::check_valid_contour(s.extract(), test::image_box(img)));
  // cancel() from another thread, while running, returns once the run is quiet.
  eng.start(refine_goal::full());
  eng.cancel();
  EXPECT_FALSE(eng.running());
  const std::uint64_t kept = eng.snapshot().split_count();
  EXPECT_GE(kept, s.split_count());  // what was published stays
  // The goal resumes where it stopped, and ends where an uninterrupted run ends.
  calls = 100;
  EXPECT_TRUE(eng.refine_full());
  sequential seq(img, 0.1);
  seq.r.refine_full();
  const contour_snapshot f = eng.snapshot();
  EXPECT_EQ(f.split_count(), seq.r.statistics().splits);
  EXPECT_EQ(f.segment_count(), seq.r.segment_count());
  EXPECT_TRUE(test::same_segments(f.extract(), seq.r.extract()));
}

TEST(ContourEngine, is_split_answers_the_snapshot_cut_from_several_threads_at_once) {
  // The first is_split() call marks the cut's splits; concurrent first calls agree on one
  // marking (the others' are dropped), and a moved snapshot keeps it. The cut is a snapshot
  // taken mid-run: later splits are not in it.
  const volume img = make_image(97, 80, waves);
  contour_engine eng(img, 0.05);
  EXPECT_TRUE(eng.refine_until(0.1));
  contour_snapshot s = eng.snapshot();
  EXPECT_TRUE(eng.refine_full());
  sequential seq(img, 0.05);
  seq.r.refine_to_error(0.1);
  const hierarchy2d& h = seq.h;
  std::atomic<std::uint64_t> differ{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      std::uint64_t d = 0;
      for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
        for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
          if (s.is_split({x, y}) != seq.r.is_split({x, y})) ++d;
        }
      }
      differ.fetch_add(d, std::memory_order_relaxed);  // relaxed: read after the joins
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(differ.load(std::memory_order_relaxed), 0U);
  const contour_snapshot moved = std::move(s);
  EXPECT_EQ(moved.split_count(), seq.r.statistics().splits);
  expect_same_split_set(moved, seq.r, seq.h);
  EXPECT_FALSE(moved.is_split({-1, 0}));
}

TEST(ContourEngine, a_snapshot_is_immutable_while_the_run_goes_on) {
  const volume& img = busy_image();
  contour_engine eng(img, 0.1);
  eng.start(refine_goal::full());
  contour_snapshot s = eng.snapshot();
  while (s.split_count() == 0 && eng.running()) {
    std::this_thread::yield();
    s = eng.snapshot();
  }
  const std::uint64_t splits = s.split_count();
  const std::uint64_t segments = s.segment_count();
  const contour_set before = s.extract();
  eng.wait();
  EXPECT_EQ(s.split_count(), splits);
  EXPECT_EQ(s.segment_count(), segments);
  EXPECT_TRUE(identical(s.extract(), before));
  EXPECT_TRUE(test::check_valid_contour(before, test::image_box(img)));
  EXPECT_GT(eng.snapshot().split_count(), splits);
}

TEST(ContourEngine, an_isovalue_change_publishes_the_new_root_at_once_and_resumes_the_goal) {
  const volume& img = busy_image();
  contour_engine_options opt;
  std::vector<std::uint64_t> reclaimed;
  std::mutex m;
  opt.on_reclaim = [&](std::uint64_t g) {
    const std::lock_guard lock(m);
    reclaimed.push_back(g);
  };
  contour_engine eng(img, 0.1, std::move(opt));
  std::optional<contour_snapshot> old = eng.snapshot();
  const contour_set old_contour = old->extract();
  eng.start(refine_goal::full());
  eng.set_isovalue(-0.3);
  {
    const contour_snapshot s = eng.snapshot();
    EXPECT_EQ(s.isovalue(), -0.3);
    EXPECT_EQ(s.generation(), 1U);
    EXPECT_TRUE(s.check_integrity());
  }
  // The old snapshot still reads the old isovalue's cut: its root is pinned.
  EXPECT_EQ(old->isovalue(), 0.1);
  EXPECT_TRUE(identical(old->extract(), old_contour));
  {
    const std::lock_guard lock(m);
    EXPECT_TRUE(reclaimed.empty());
  }
  old.reset();
  eng.wait();  // the interrupted full goal resumed on the new isovalue
  EXPECT_TRUE(eng.done());
  sequential seq(img, -0.3);
  seq.r.refine_full();
  EXPECT_TRUE(test::same_segments(eng.snapshot().extract(), seq.r.extract()));
  eng.set_isovalue(0.2);  // retires generation 1; generation 0 is no longer pinned
  {
    const std::lock_guard lock(m);
    EXPECT_NE(std::find(reclaimed.begin(), reclaimed.end(), 0U), reclaimed.end());
  }
  EXPECT_FALSE(eng.running());  // no run was active: nothing resumes
  EXPECT_EQ(eng.snapshot().split_count(), 0U);
}

TEST(ContourEngine, progress_callback_errors_come_back_to_the_caller) {
  const volume img = make_image(300, 200, waves);
  {
    contour_engine_options opt;
    opt.progress_interval = 64;
    opt.progress = [](const engine_progress&) { throw std::runtime_error("from the callback"); };
    contour_engine eng(img, 0.1, std::move(opt));
    EXPECT_THROW((void)eng.refine_full(), std::runtime_error);
    EXPECT_FALSE(eng.running());
    EXPECT_TRUE(test::check_valid_contour(eng.snapshot().extract(), test::image_box(img)));
  }
  {
    contour_engine_options opt;
    contour_engine* self = nullptr;
    opt.progress_interval = 64;
    opt.progress = [&self](const engine_progress&) { self->wait(); };  // would deadlock
    contour_engine eng(img, 0.1, std::move(opt));
    self = &eng;
    EXPECT_THROW((void)eng.refine_full(), error);
  }
}

TEST(ContourEngine, rejects_bad_input_with_clear_errors) {
  const volume vol({4, 4, 4}, sample_type::u8, std::vector<std::byte>(64));
  EXPECT_THROW(contour_engine(vol, 1.0), error);
  const volume img = make_image(10, 10, waves);
  EXPECT_THROW(contour_engine(img, std::nan("")), error);
  EXPECT_THROW(contour_engine(std::shared_ptr<const volume>(), 0.0), error);
  contour_engine eng(img, 0.0);
  EXPECT_THROW(eng.set_isovalue(std::numeric_limits<double>::infinity()), error);
  EXPECT_THROW(eng.start(refine_goal::error(std::nan(""))), error);
  EXPECT_EQ(eng.isovalue(), 0.0);
}

}  // namespace
}  // namespace progiso
