// Refinement where it is wanted (refine_goal::focus): the engine refines inside a box, or around
// a point, first; the cut stays a valid cut across the box's boundary; inside the box an error
// target behaves as without a focus.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/scheduler/engine.hpp>

#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"

namespace progiso {
namespace {

engine_options with_threads(unsigned n) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = n;
  return o;
}

using box3 = std::array<double, 3>;

// The triangles lying wholly inside [lo, hi] (positions are grid coordinates: spacing 1).
std::vector<test::position_triangle> inside(const triangle_mesh& m, const box3& lo,
                                            const box3& hi) {
  std::vector<test::position_triangle> out;
  for (const test::position_triangle& t : test::canonical_triangles(m)) {
    bool in = true;
    for (const vec3& p : t) {
      for (std::size_t q = 0; q < 3; ++q) in = in && p[q] >= lo[q] && p[q] <= hi[q];
    }
    if (in) out.push_back(t);
  }
  return out;
}

// The triangles with some corner where a·x + b·y + c·z + d ≥ 0.
std::size_t touching(const triangle_mesh& m, const std::array<double, 4>& plane) {
  std::size_t n = 0;
  for (const test::position_triangle& t : test::canonical_triangles(m)) {
    bool any = false;
    for (const vec3& p : t) {
      any = any || plane[0] * p[0] + plane[1] * p[1] + plane[2] * p[2] + plane[3] >= 0.0;
    }
    n += any ? 1 : 0;
  }
  return n;
}

// A box of half-side r around a vertex of the mesh (a third of the way through its vertices).
std::pair<box3, box3> box_around(const triangle_mesh& m, double r) {
  const vec3 p = m.vertices.at(m.vertices.size() / 3);
  return {box3{p[0] - r, p[1] - r, p[2] - r}, box3{p[0] + r, p[1] + r, p[2] + r}};
}

TEST(Focus, EachDiamondsReachLiesInEachParentsReach) {
  for (const index3 dims : {index3{33, 33, 33}, index3{20, 37, 26}}) {
    const hierarchy h(dims);
    std::size_t pairs = 0;
    for (std::uint64_t i = 0; i < h.vertex_count(); ++i) {
      const ipoint c = h.point(i);
      if (!h.is_diamond(c)) continue;
      const diamond d = h.make_diamond(c);
      const double rc = focus_reach(d.scale, d.type);
      ASSERT_GE(rc, d.scale);  // the diamond's own region, c ± h, is inside its reach
      std::array<ipoint, 4> parents{};
      const int n = h.parents(d, parents);
      for (int k = 0; k < n; ++k) {
        const diamond p = h.make_diamond(parents[static_cast<std::size_t>(k)]);
        const double rp = focus_reach(p.scale, p.type);
        for (std::size_t q = 0; q < 3; ++q) {
          ASSERT_GE(c[q] - rc, p.centre[q] - rp) << "child " << i;
          ASSERT_LE(c[q] + rc, p.centre[q] + rp) << "child " << i;
        }
        ++pairs;
      }
    }
    EXPECT_GT(pairs, 1000u);
  }
}

TEST(Focus, AViewsWeightsNeverGrowFromAParentToItsChildren) {
  // The keys of a view stay nested: distance and frustum alike (the cut stays parent-closed).
  const hierarchy h(index3{33, 29, 37});
  const std::array<std::array<double, 4>, 4> frustum{{{1.0, 0.2, 0.0, -12.0},
                                                      {-0.3, 1.0, 0.1, -4.0},
                                                      {0.0, -0.5, 1.0, -9.0},
                                                      {-1.0, 0.0, 0.3, 30.0}}};
  const refine_goal g = refine_goal::error(0.0).viewed({40.0, 2.0, 18.0}, 1.5, frustum, 0.25);
  std::size_t pairs = 0;
  std::size_t out_of_view = 0;
  for (std::uint64_t i = 0; i < h.vertex_count(); ++i) {
    const ipoint c = h.point(i);
    if (!h.is_diamond(c)) continue;
    const diamond d = h.make_diamond(c);
    const double wc = focus_weight(*g.focus, c, d.scale, d.type);
    ASSERT_GT(wc, 0.0);
    ASSERT_LE(wc, 1.0);
    std::array<ipoint, 4> parents{};
    const int n = h.parents(d, parents);
    for (int k = 0; k < n; ++k) {
      const diamond p = h.make_diamond(parents[static_cast<std::size_t>(k)]);
      const double wp = focus_weight(*g.focus, p.centre, p.scale, p.type);
      ASSERT_LE(wc, wp) << "child " << i;
      ++pairs;
      // The frustum culls (a quarter of the distance weight) where a parent is in view.
      refine_focus seen = *g.focus;
      seen.plane_count = 0;
      if (wc < focus_weight(seen, c, d.scale, d.type) &&
          wp == focus_weight(seen, p.centre, p.scale, p.type))
        ++out_of_view;
    }
  }
  EXPECT_GT(pairs, 1000u);
  EXPECT_GT(out_of_view, 10u);
}

TEST(Focus, AViewSplitsWhatItSeesAsWithoutAFocusAndLessOutOfView) {
  const volume v = make_gaussian_blobs({48, 44, 40}, 9, 5u);
  const double w = 0.35;
  const double eps = 0.002;
  engine plain(v, w, with_threads(2));
  plain.refine_until(eps);
  // Everything at x ≥ 30 in view, weight 1 there (the box is the whole grid); nothing else.
  const std::array<double, 4> plane{1.0, 0.0, 0.0, -30.0};
  const std::array<double, 4> far_side{-1.0, 0.0, 0.0, 18.0};  // x ≤ 18
  refine_goal g = refine_goal::error(eps).focused({0, 0, 0}, {47, 43, 39});
  g.focus->planes[0] = plane;
  g.focus->plane_count = 1;
  g.focus->outside = 0.0;
  engine viewed(v, w, with_threads(2));
  ASSERT_TRUE(viewed.refine(g));
  const triangle_mesh a = plain.snapshot().mesh();
  const triangle_mesh b = viewed.snapshot().mesh();
  const auto want = inside(a, {30, 0, 0}, {47, 43, 39});
  ASSERT_GT(want.size(), 200u);
  EXPECT_TRUE(want == inside(b, {30, 0, 0}, {47, 43, 39}));
  // Out of view (reach cubes below x = 30: no finest diamond centred below x = 22) the cut
  // stays coarser.
  EXPECT_LT(touching(b, far_side), touching(a, far_side) / 2);
  EXPECT_GT(touching(a, far_side), 100u);
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(b, box[0], box[1]));
  // From an eye: the budget goes to what the frustum holds and is near.
  const std::array<std::array<double, 4>, 1> half{{plane}};
  engine budget_plain(v, w, with_threads(2));
  budget_plain.refine(refine_goal::triangles(a.triangles.size() / 6));
  engine budget_viewed(v, w, with_threads(2));
  budget_viewed.refine(
      refine_goal::triangles(a.triangles.size() / 6).viewed({60.0, 22.0, 20.0}, 2.0, half, 0.1));
  const triangle_mesh c = budget_plain.snapshot().mesh();
  const triangle_mesh d = budget_viewed.snapshot().mesh();
  EXPECT_GT(inside(d, {30, 0, 0}, {47, 43, 39}).size(),
            2 * inside(c, {30, 0, 0}, {47, 43, 39}).size());
  EXPECT_TRUE(test::check_valid_cut(d, box[0], box[1]));
}

TEST(Focus, ErrorTargetInsideTheBoxIsTheUnfocusedOne) {
  const volume v = make_gaussian_blobs({48, 44, 40}, 7, 3u);
  const double w = 0.35;
  const double eps = 0.002;
  engine plain(v, w, with_threads(2));
  plain.refine_until(eps);
  const auto [lo, hi] = box_around(plain.snapshot().mesh(), 9.0);
  engine focused(v, w, with_threads(2));
  ASSERT_TRUE(focused.refine(refine_goal::error(eps).focused(lo, hi)));
  const triangle_mesh a = plain.snapshot().mesh();
  const triangle_mesh b = focused.snapshot().mesh();
  EXPECT_LT(focused.snapshot().split_count(), plain.snapshot().split_count());
  const auto want = inside(a, lo, hi);
  ASSERT_GT(want.size(), 200u);
  EXPECT_TRUE(want == inside(b, lo, hi));
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(b, box[0], box[1]));
}

TEST(Focus, BudgetAndDeadlineRefineInsideFirst) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine full(v, 0.5, with_threads(2));
  full.refine_full();
  const std::uint64_t finest = full.snapshot().triangle_count();
  const triangle_mesh finest_mesh = full.snapshot().mesh();
  const auto [lo, hi] = box_around(finest_mesh, 10.0);
  const vec3 eye = finest_mesh.vertices[finest_mesh.vertices.size() / 5];
  const box3 near_lo{eye[0] - 8, eye[1] - 8, eye[2] - 8};
  const box3 near_hi{eye[0] + 8, eye[1] + 8, eye[2] + 8};
  const auto box = test::data_box(v);
  for (const unsigned threads : {1u, 2u}) {
    engine plain(v, 0.5, with_threads(threads));
    plain.refine(refine_goal::triangles(finest / 8));
    engine focused(v, 0.5, with_threads(threads));
    focused.refine(refine_goal::triangles(finest / 8).focused(lo, hi, 4.0));
    const triangle_mesh a = plain.snapshot().mesh();
    const triangle_mesh b = focused.snapshot().mesh();
    EXPECT_LE(b.triangles.size(), finest / 8 + 64);
    EXPECT_GT(inside(b, lo, hi).size(), 2 * inside(a, lo, hi).size()) << threads;
    EXPECT_TRUE(test::check_valid_cut(b, box[0], box[1]));
    // Around a point: more of the surface near it than without the focus.
    engine around(v, 0.5, with_threads(threads));
    around.refine(refine_goal::triangles(finest / 8).focused(eye, 2.0));
    const triangle_mesh c = around.snapshot().mesh();
    ASSERT_GT(inside(finest_mesh, near_lo, near_hi).size(), 100u);
    EXPECT_GT(inside(c, near_lo, near_hi).size(), 2 * inside(a, near_lo, near_hi).size());
    EXPECT_TRUE(test::check_valid_cut(c, box[0], box[1]));
  }
}

TEST(Focus, ALaterGoalWithoutFocusKeysTheQueueAgain) {
  const volume v = make_gaussian_blobs({40, 40, 40}, 5, 11u);
  const double eps = 0.004;
  engine e(v, 0.3, with_threads(2));
  e.refine(refine_goal::triangles(3000).focused({0, 0, 0}, {8, 8, 8}));
  ASSERT_TRUE(e.refine_until(eps));
  engine fresh(v, 0.3, with_threads(2));
  fresh.refine_until(eps);
  // Every diamond of error above eps is split: the cut by eps is the unfocused target's.
  const triangle_mesh got = e.snapshot().mesh_cut(eps);
  const triangle_mesh want = fresh.snapshot().mesh();
  EXPECT_TRUE(test::same_surface(got, want));
}

TEST(Focus, BadFocusIsRefused) {
  engine e(make_sphere_field({12, 12, 12}, {6, 6, 6}), 3.0, with_threads(1));
  EXPECT_THROW(e.refine(refine_goal::triangles(10).focused({5, 0, 0}, {4, 9, 9})), error);
  EXPECT_THROW(e.refine(refine_goal::triangles(10).focused({1, 1, 1}, -1.0)), error);
  EXPECT_THROW(e.refine(refine_goal::triangles(10).focused({1, 1, 1}, std::nan(""))), error);
  EXPECT_THROW(check_goal(refine_goal::error(1).focused({0, 0, 0}, {1, std::nan(""), 1})), error);
  const std::array<std::array<double, 4>, 1> good{{{1.0, 0.0, 0.0, -2.0}}};
  const std::array<std::array<double, 4>, 1> no_normal{{{0.0, 0.0, 0.0, 1.0}}};
  const std::array<std::array<double, 4>, 1> not_finite{{{1.0, std::nan(""), 0.0, 1.0}}};
  const std::array<std::array<double, 4>, 7> seven{};
  EXPECT_NO_THROW(check_goal(refine_goal::error(1).viewed({1, 1, 1}, 1.0, good, 0.5)));
  EXPECT_THROW(check_goal(refine_goal::error(1).viewed({1, 1, 1}, 1.0, good, 1.5)), error);
  EXPECT_THROW(check_goal(refine_goal::error(1).viewed({1, 1, 1}, 1.0, good, -0.1)), error);
  EXPECT_THROW(check_goal(refine_goal::error(1).viewed({1, 1, 1}, 1.0, no_normal, 0.5)), error);
  EXPECT_THROW(check_goal(refine_goal::error(1).viewed({1, 1, 1}, 1.0, not_finite, 0.5)), error);
  EXPECT_THROW((void)refine_goal::error(1).viewed({1, 1, 1}, 1.0, seven, 0.5), error);
  EXPECT_THROW(e.refine(refine_goal::triangles(10).viewed({1, 1, 1}, 1.0, good, 2.0)), error);
}

}  // namespace
}  // namespace progiso
