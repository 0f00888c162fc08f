// The refiner's modes, statistics, output sensitivity and determinism.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/detail/path_choice.hpp>
#include <progiso/core/refine/detail/ready_queue.hpp>
#include <progiso/core/refine/refiner.hpp>

#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"

namespace progiso {
namespace {

struct fixture {
  volume v;
  hierarchy h;
  range_data ranges;
  explicit fixture(volume vol) : v(std::move(vol)), h(v.dims()), ranges(v, h) {}
};

TEST(Refiner, first_surface_needs_no_split_and_is_the_root_tetrahedra_surface) {
  fixture f(make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}));
  refiner r(f.v, f.h, f.ranges, 11.0);
  EXPECT_EQ(r.statistics().splits, 0u);
  const auto box = test::data_box(f.v);
  // The root tetrahedra's corners all lie outside the sphere: the first surface is empty, and
  // the first split (the root's centre is inside) creates a closed component.
  EXPECT_EQ(r.triangle_count(), 0u);
  EXPECT_TRUE(r.extract().empty());
  ASSERT_TRUE(r.split_next());
  EXPECT_GT(r.triangle_count(), 0u);
  EXPECT_EQ(
      r.statistics().configurations[static_cast<std::size_t>(split_configuration::empty_region)],
      1u);
  EXPECT_EQ(r.statistics().primitives[static_cast<std::size_t>(primitive::new_loop)], 1u);
  EXPECT_TRUE(test::check_valid_cut(r.extract(), box[0], box[1]));
  EXPECT_TRUE(test::watertight(r.extract()));
}

TEST(Refiner, quality_driven_refinement_leaves_no_error_above_the_threshold) {
  fixture f(make_marschner_lobb({33, 33, 33}));
  std::uint64_t previous = 0;
  for (const double eps : {0.2, 0.05, 0.01, 0.0}) {
    refiner r(f.v, f.h, f.ranges, 0.5);
    r.refine_to_error(eps);
    EXPECT_LE(r.next_error(), eps);
    EXPECT_GE(r.triangle_count(), previous) << "smaller error, fewer triangles at " << eps;
    previous = r.triangle_count();
  }
  refiner full(f.v, f.h, f.ranges, 0.5);
  full.refine_full();
  EXPECT_EQ(previous, full.triangle_count()) << "error 0 must reach full resolution";
}

// Breadth- and depth-first refinement skip the error of a ready diamond whose range need not
// be read (a piece of surface in one of its tetrahedra proves it straddles w); it is computed
// when asked for.
TEST(Refiner, errors_left_out_by_breadth_and_depth_first_order_are_computed_when_asked) {
  fixture f(make_gaussian_blobs({33, 29, 31}, 8, 5u));
  const double w = 0.3;
  refiner by_error(f.v, f.h, f.ranges, w, refine_order::largest_error_first);
  by_error.refine_full();
  for (const refine_order order : {refine_order::breadth_first, refine_order::depth_first}) {
    refiner r(f.v, f.h, f.ranges, w, order);
    // next_error() is the top diamond's nested error: finite, and no larger than the largest
    // error of the volume (the roots').
    double largest = 0.0;
    for (std::uint64_t i = 0; i < f.h.vertex_count(); ++i) {
      const ipoint c = f.h.point(i);
      if (f.h.is_diamond(c) && f.h.make_diamond(c).depth == 0) {
        largest = std::max(largest, f.ranges.get(c).error);
      }
    }
    for (int k = 0; k < 3000 && !r.done(); ++k) {
      const double e = r.next_error();
      ASSERT_TRUE(std::isfinite(e)) << "split " << k;
      ASSERT_GE(e, 0.0);
      ASSERT_LE(e, largest);
      r.split_next();
    }
    r.refine_full();
    EXPECT_EQ(r.statistics().splits, by_error.statistics().splits);
    // Records keep unknown errors; cuts by error read them from the range data, so they are
    // the same as after a refinement that computed every error.
    for (const double eps : {0.0, 0.002, 0.01, 0.05, 0.2}) {
      EXPECT_TRUE(test::same_surface(r.extract_cut(eps), by_error.extract_cut(eps))) << eps;
    }
    // The cuts differ from each other, so the errors decide them.
    EXPECT_LT(r.extract_cut(0.05).triangles.size(), r.extract_cut(0.002).triangles.size());
    EXPECT_LT(r.extract_cut(0.002).triangles.size(), r.extract().triangles.size());
  }
}

TEST(Refiner, triangle_budget_is_respected_and_splits_largest_error_first) {
  fixture f(make_gaussian_blobs({33, 33, 33}, 8, 3u));
  refiner r(f.v, f.h, f.ranges, 0.3);
  r.refine_to_triangles(2000);
  EXPECT_LE(r.triangle_count(), 2000u);
  EXPECT_EQ(r.extract().triangles.size(), r.triangle_count());
  // Largest error first, by bands at most error_bucket_widest wide: when the budget stops the run
  // inside the band of next_error(), every diamond of a larger band is split and none of a smaller
  // one, so the budgeted cut lies between the cuts by error at the band's bounds.
  const auto [lo, hi] = detail::error_bucket_bounds(detail::error_bucket(r.next_error()));
  ASSERT_LE(lo, r.next_error());
  ASSERT_LT(r.next_error(), hi);
  ASSERT_LE(hi / lo, detail::error_bucket_widest + 1e-12);
  ASSERT_GE(hi / lo, detail::error_bucket_narrowest - 1e-12);
  refiner above(f.v, f.h, f.ranges, 0.3);
  above.refine_to_error(std::nextafter(hi, 0.0));  // every error ≥ hi
  refiner at(f.v, f.h, f.ranges, 0.3);
  at.refine_to_error(std::nextafter(lo, -1.0));  // every error ≥ lo
  std::uint64_t in_above = 0;
  std::uint64_t in_r = 0;
  for (std::uint64_t i = 0; i < f.h.vertex_count(); ++i) {
    const ipoint c = f.h.point(i);
    if (!f.h.is_diamond(c)) continue;
    if (above.is_split(c)) {
      ++in_above;
      EXPECT_TRUE(r.is_split(c)) << "a diamond of a larger band left unsplit";
    }
    if (r.is_split(c)) {
      ++in_r;
      EXPECT_TRUE(at.is_split(c)) << "a diamond of a smaller band split";
    }
  }
  EXPECT_EQ(in_r, r.statistics().splits);
  EXPECT_GT(in_above, 0u);
  EXPECT_LT(in_above, at.statistics().splits);
}

// An error target is exact although the queue orders by bands: the split set of
// refine_to_error(ε) is every straddling diamond of error > ε, for targets inside a band and on
// its bounds, and moving the target between runs re-ranks what is queued.
TEST(Refiner, error_targets_are_exact_inside_a_band) {
  fixture f(make_gyroid_field({29, 33, 31}, 9.0));
  const double w = 0.15;
  refiner full(f.v, f.h, f.ranges, w);
  full.refine_full();
  std::vector<std::uint64_t> by_error;  // straddling, split by a full refinement
  for (std::uint64_t i = 0; i < f.h.vertex_count(); ++i) {
    if (f.h.is_diamond(f.h.point(i)) && full.is_split(f.h.point(i))) by_error.push_back(i);
  }
  const auto [lo, hi] = detail::error_bucket_bounds(detail::error_bucket(0.05));
  refiner moving(f.v, f.h, f.ranges, w);
  for (const double eps : {hi, std::nextafter(hi, 0.0), 0.5 * (lo + hi), lo, 0.3 * lo}) {
    SCOPED_TRACE(eps);
    refiner r(f.v, f.h, f.ranges, w);
    r.refine_to_error(eps);
    moving.refine_to_error(eps);  // targets descend: each run continues the last
    std::uint64_t expected = 0;
    for (const std::uint64_t i : by_error) {
      const ipoint c = f.h.point(i);
      const bool above = f.ranges.get(c).error > eps;
      expected += above ? 1 : 0;
      ASSERT_EQ(r.is_split(c), above);
      ASSERT_EQ(moving.is_split(c), above);
    }
    EXPECT_EQ(r.statistics().splits, expected);
    EXPECT_LE(r.next_error(), eps);
  }
}

TEST(Refiner, zero_time_budget_returns_the_root_surface) {
  fixture f(make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}));
  refiner r(f.v, f.h, f.ranges, 11.0);
  r.refine_until(std::chrono::steady_clock::now());
  EXPECT_EQ(r.statistics().splits, 0u);
  r.refine_until(std::chrono::steady_clock::now() + std::chrono::seconds(60));
  EXPECT_TRUE(r.done());
}

TEST(Refiner, same_split_set_gives_the_same_surface_whatever_the_order) {
  fixture f(make_gyroid_field({29, 33, 31}, 9.0));
  refiner a(f.v, f.h, f.ranges, 0.15, refine_order::breadth_first);
  refiner b(f.v, f.h, f.ranges, 0.15, refine_order::largest_error_first);
  refiner c(f.v, f.h, f.ranges, 0.15, refine_order::depth_first);
  a.refine_full();
  b.refine_full();
  c.refine_full();
  EXPECT_EQ(a.statistics().splits, b.statistics().splits);
  EXPECT_EQ(a.statistics().splits, c.statistics().splits);
  EXPECT_TRUE(test::same_surface(a.extract(), b.extract()));
  EXPECT_TRUE(test::same_surface(a.extract(), c.extract()));
}

// extract_isosurface() in full mode takes the direct path (finest_surface()): the surface full
// refinement gives, with no split, and its progress told in rows; asked not to, it refines.
TEST(Refiner, one_shot_full_extraction_gives_the_refined_surface_in_two_passes) {
  const volume v = make_marschner_lobb({49, 45, 47});
  extract_options o;
  std::vector<extract_progress> direct_reports;
  o.progress = [&](const extract_progress& p) { direct_reports.push_back(p); };
  const extract_result direct = extract_isosurface(v, 0.5, o);
  EXPECT_TRUE(direct.finest_direct);
  EXPECT_EQ(direct.stats.splits, 0U);
  EXPECT_EQ(direct.range_build_seconds, 0.0);
  EXPECT_EQ(direct.stats.triangles, direct.mesh.triangles.size());
  EXPECT_GT(direct.first_surface_seconds, 0.0);
  EXPECT_EQ(direct.first_surface_seconds, direct.pipeline_seconds);
  ASSERT_FALSE(direct_reports.empty());
  EXPECT_EQ(direct_reports.back().rows_done, 2U * 45U * 47U);
  EXPECT_EQ(direct_reports.back().rows_total, 2U * 45U * 47U);
  EXPECT_EQ(direct_reports.back().depth, hierarchy(v.dims()).max_depth());

  std::uint64_t refined_reports = 0;
  o.progress = [&](const extract_progress& p) {
    ++refined_reports;
    EXPECT_EQ(p.rows_total, 0U);  // splits and depths on the hierarchy's path
  };
  const extract_result refined = detail::extract_isosurface(v, 0.5, o, detail::path_choice{false});
  EXPECT_FALSE(refined.finest_direct);
  EXPECT_GT(refined.stats.splits, 0U);
  EXPECT_GT(refined_reports, 0U);
  EXPECT_EQ(direct.mesh.triangles.size(), refined.mesh.triangles.size());
  EXPECT_TRUE(test::same_surface(direct.mesh, refined.mesh));
  EXPECT_TRUE(test::same_surface(direct.mesh, test::reference_marching_tetrahedra(v, 0.5).mesh));
}

TEST(Refiner, isovalue_outside_the_data_range_gives_an_empty_surface) {
  const volume v = make_sphere_field({17, 17, 17}, {8, 8, 8});
  extract_options o;
  const extract_result res = extract_isosurface(v, 1000.0, o);
  EXPECT_TRUE(res.mesh.empty());
  EXPECT_TRUE(res.isovalue_outside_data);
  EXPECT_EQ(res.stats.splits, 0u);
}

TEST(Refiner, non_finite_isovalue_is_rejected) {
  const volume v = make_sphere_field({17, 17, 17}, {8, 8, 8});
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  EXPECT_THROW(refiner(v, h, ranges, std::nan("")), error);
  extract_options o;
  EXPECT_THROW((void)extract_isosurface(v, std::numeric_limits<double>::infinity(), o), error);
}

TEST(Refiner, statistics_account_for_every_split) {
  fixture f(make_gaussian_blobs({41, 35, 38}, 10, 9u));
  refiner r(f.v, f.h, f.ranges, 0.3);
  r.refine_full();
  const refine_statistics& s = r.statistics();
  const std::uint64_t configs =
      std::accumulate(s.configurations.begin(), s.configurations.end(), std::uint64_t{0});
  EXPECT_EQ(configs, s.splits);
  // One VertexMove exactly for the splits whose spine is crossed.
  EXPECT_EQ(s.primitives[static_cast<std::size_t>(primitive::vertex_move)],
            s.configurations[static_cast<std::size_t>(split_configuration::spine_crossed)]);
  // Cases 1 and 2 occur exactly in spine-crossed splits; every configuration occurred.
  EXPECT_GT(s.cases[static_cast<std::size_t>(tet_case::c1b)] +
                s.cases[static_cast<std::size_t>(tet_case::c2b)],
            0u);
  for (std::size_t i = 0; i < split_configuration_count; ++i) {
    EXPECT_GT(s.configurations[i], 0u) << to_string(static_cast<split_configuration>(i));
  }
  EXPECT_EQ(s.visited, s.splits + s.culled);
  // The final count equals the reference's triangle count (no clipping at 2^L + 1... here the
  // dims are not, so compare with the extracted mesh instead).
  EXPECT_EQ(r.extract().triangles.size(),
            test::reference_marching_tetrahedra(f.v, 0.3).mesh.triangles.size());
}

// Output sensitivity: a sphere of radius 6 in a 257^3 field. The finest surface has about
// 4000 triangles; everything far from it is culled by the range data at coarse levels.
// Bound asserted: diamonds visited < voxels / 1000, i.e. < 17 thousand of 17 million
// (measured: 3075 visited, 2784 split).
TEST(Refiner, small_sphere_in_257_cubed_visits_far_fewer_diamonds_than_voxels) {
  fixture f(make_sphere_field({257, 257, 257}, {100.3, 140.2, 90.7}));
  refiner r(f.v, f.h, f.ranges, 6.0, refine_order::breadth_first);
  r.refine_full();
  const std::uint64_t voxels = f.v.voxel_count();
  EXPECT_LT(r.statistics().visited * 1000, voxels) << "visited " << r.statistics().visited;
  EXPECT_GT(r.triangle_count(), 400u);
}

}  // namespace
}  // namespace progiso
