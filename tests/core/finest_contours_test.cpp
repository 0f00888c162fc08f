// finest_contours() (core/contour/finest_contours.hpp): the finest cut's contours by two passes
// over the pixels. They must be full 2D refinement's: the independent reference (plain marching
// triangles, tests/support) segment for segment, and the refiner's extraction polyline for
// polyline (the same chains, closed or open, each open one from the same end; a closed one may
// start elsewhere on its loop, since vertices are numbered in another order) — on analytic
// images of every small size and parity, ties at the isovalue, physical coordinates and every
// shared image; and extract_contours()'s full mode gives them unless asked for the hierarchy.
#include <progiso/core/contour/finest_contours.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/contour/range_data2d.hpp>
#include <progiso/core/refine/detail/path_choice.hpp>

#include "support/contour_checks.hpp"
#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

double circle(double x, double y) { return std::hypot(x - 20.3, y - 17.6); }
double waves(double x, double y) {
  return std::sin(x * 0.21) * std::cos(y * 0.17) + 0.4 * std::sin((x + 2 * y) * 0.05);
}
double edge_cut(double x, double y) { return std::hypot(x - 44.0, y + 3.0); }

/// Each polyline as its positions (a closed one rotated to start at its smallest), with its
/// closed flag; sorted.
std::vector<std::pair<bool, std::vector<vec2>>> chains(const contour_set& c) {
  std::vector<std::pair<bool, std::vector<vec2>>> out;
  for (const polyline& p : c.polylines) {
    std::vector<vec2> pos;
    for (const std::uint32_t v : p.vertices) pos.push_back(c.vertices[v]);
    if (p.closed) std::rotate(pos.begin(), std::min_element(pos.begin(), pos.end()), pos.end());
    out.emplace_back(p.closed, std::move(pos));
  }
  std::sort(out.begin(), out.end());
  return out;
}

void expect_finest_equals_full_refinement(const volume& img, double w) {
  const contour_set mine = finest_contours(img, w);
  EXPECT_TRUE(test::same_segments(mine, test::reference_contours(img, w)));
  EXPECT_TRUE(test::check_valid_contour(mine, test::image_box(img)));
  const hierarchy2d h(img.dims()[0], img.dims()[1]);
  const range_data2d ranges(img, h);
  contour_refiner r(img, h, ranges, w, contour_order::breadth_first);
  r.refine_full();
  const contour_set full = r.extract();
  EXPECT_EQ(mine.vertices.size(), full.vertices.size());
  EXPECT_EQ(mine.polylines.size(), full.polylines.size());
  EXPECT_TRUE(chains(mine) == chains(full));
  for (const polyline& p : mine.polylines) EXPECT_EQ(p.isovalue, w);
}

TEST(FinestContours, equal_full_refinement_on_analytic_images_of_every_small_size) {
  expect_finest_equals_full_refinement(test::make_test_image(41, 36, circle), 9.5);
  expect_finest_equals_full_refinement(test::make_test_image(33, 33, circle), 12.25);
  expect_finest_equals_full_refinement(test::make_test_image(70, 45, waves), 0.1);
  expect_finest_equals_full_refinement(test::make_test_image(50, 29, edge_cut), 20.0);
  for (std::int64_t w = 2; w <= 11; ++w) {
    for (std::int64_t h = 2; h <= 11; ++h) {
      SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
      expect_finest_equals_full_refinement(test::make_test_image(w, h, waves), 0.1);
      expect_finest_equals_full_refinement(test::make_test_image(w, h, circle), 18.0);
    }
  }
}

TEST(FinestContours, ties_physical_coordinates_and_every_shared_image) {
  // Integer pixels 0..3 with the isovalue on a value: ties are white.
  std::vector<std::byte> bytes(37 * 29);
  std::uint32_t state = 99;
  for (std::byte& b : bytes) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<std::byte>((state >> 24) & 3u);
  }
  const volume ties({37, 29, 1}, sample_type::u8, bytes, {2.0, 0.5, 1.0}, {10.0, -3.0, 0.0});
  expect_finest_equals_full_refinement(ties, 1.0);
  expect_finest_equals_full_refinement(ties, 2.0);
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const auto& info : test::shared_images()) {
    const volume img = test::load_pgm(*dir / info.file);
    for (const double w : info.isovalues) {
      SCOPED_TRACE(std::string(info.name) + " at " + std::to_string(w));
      expect_finest_equals_full_refinement(img, w);
    }
  }
}

TEST(FinestContours, extract_contours_full_takes_the_direct_path_unless_told_otherwise) {
  const volume img = test::make_test_image(70, 45, waves);
  contour_options full;
  const contour_result direct = extract_contours(img, {0.1, -0.3}, full);
  EXPECT_TRUE(direct.finest_direct);
  EXPECT_EQ(direct.range_build_seconds, 0.0);
  ASSERT_EQ(direct.stats.size(), 2u);
  EXPECT_EQ(direct.stats[0].splits, 0u);
  EXPECT_EQ(direct.stats[0].segments + direct.stats[1].segments, direct.contours.segment_count());
  const contour_result refined =
      detail::extract_contours(img, {0.1, -0.3}, full, detail::path_choice{false});
  EXPECT_FALSE(refined.finest_direct);
  EXPECT_GT(refined.stats[0].splits, 0u);
  EXPECT_TRUE(chains(direct.contours) == chains(refined.contours));
  // Frames need the refinement's stages: the hierarchy's path.
  contour_options framed;
  int frames = 0;
  framed.frame = [&frames](const contour_set&, int) { ++frames; };
  const contour_result staged = extract_contours(img, {0.1}, framed);
  EXPECT_FALSE(staged.finest_direct);
  EXPECT_GT(frames, 1);
  // A sink gets each isovalue's finest contours.
  contour_options sunk;
  std::vector<std::size_t> seen;
  sunk.sink = [&](const contour_set& c, std::size_t k) {
    seen.push_back(k);
    EXPECT_TRUE(chains(c) == chains(finest_contours(img, k == 0 ? 0.1 : -0.3)));
  };
  const contour_result sunk_result = extract_contours(img, {0.1, -0.3}, sunk);
  EXPECT_TRUE(sunk_result.contours.empty());
  EXPECT_EQ(seen, (std::vector<std::size_t>{0, 1}));
}

TEST(FinestContours, refuses_a_volume_and_a_non_finite_isovalue) {
  const volume img = test::make_test_image(9, 9, circle);
  EXPECT_THROW((void)finest_contours(img, std::nan("")), error);
  std::vector<std::byte> bytes(8);
  const volume v({2, 2, 2}, sample_type::u8, bytes);
  EXPECT_THROW((void)finest_contours(v, 0.5), error);
}

}  // namespace
}  // namespace progiso
