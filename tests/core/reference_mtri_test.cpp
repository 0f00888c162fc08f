// The 2D reference extractor on fields whose contours are known: closed loops with the stated
// orientation, open chains ending on the border, vertices on their edges, no degenerate
// segments when samples equal the isovalue, and valid contours on the shared images.
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>

#include <cmath>
#include <cstring>
#include <iostream>
#include <numbers>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "support/contour_checks.hpp"
#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso::test {
namespace {

template <class F>
volume f64_image(std::int64_t w, std::int64_t h, F&& f) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(w * h) * sizeof(double));
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      const double v = f(static_cast<double>(x), static_cast<double>(y));
      std::memcpy(&bytes[static_cast<std::size_t>(x + w * y) * sizeof(double)], &v, sizeof v);
    }
  }
  return volume({w, h, 1}, sample_type::f64, std::move(bytes));
}

template <class F>
volume u8_image(std::int64_t w, std::int64_t h, F&& f) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(w * h));
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      bytes[static_cast<std::size_t>(x + w * y)] = static_cast<std::byte>(f(x, y));
    }
  }
  return volume({w, h, 1}, sample_type::u8, std::move(bytes));
}

using point = std::array<std::int64_t, 2>;

// The ends of the finest-mesh edge with this key (doubled midpoint x | y << 32): an axis edge
// when one coordinate is odd, else the diagonal of its unit square from the all-even corner to
// the all-odd corner.
std::array<point, 2> finest_edge(std::uint64_t key) {
  const auto mx = static_cast<std::int64_t>(key & 0xFFFFFFFFu);
  const auto my = static_cast<std::int64_t>(key >> 32);
  if (mx % 2 == 1 && my % 2 == 1) {
    const point b{(mx - 1) / 2, (my - 1) / 2};
    const point e{b[0] % 2 == 0 ? b[0] : b[0] + 1, b[1] % 2 == 0 ? b[1] : b[1] + 1};
    return {e, point{2 * b[0] + 1 - e[0], 2 * b[1] + 1 - e[1]}};
  }
  if (mx % 2 == 1) return {point{(mx - 1) / 2, my / 2}, point{(mx + 1) / 2, my / 2}};
  return {point{mx / 2, (my - 1) / 2}, point{mx / 2, (my + 1) / 2}};
}

double cross(const vec2& o, const vec2& a, const vec2& b) {
  return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

// Every segment lies in one finest triangle (the two edges of its keys share a corner), each
// end on its edge, with every black corner on the left and every white corner on the right.
void check_segments_against_their_triangles(const volume& v, double w) {
  const std::vector<segment> segments = reference_segments(v, w);
  for (const segment& s : segments) {
    const auto e0 = finest_edge(s.keys[0]);
    const auto e1 = finest_edge(s.keys[1]);
    std::set<point> corners{e0[0], e0[1], e1[0], e1[1]};
    ASSERT_EQ(corners.size(), 3u) << "the two edges of a segment share one corner";
    for (std::size_t k = 0; k < 2; ++k) {
      const auto& e = k == 0 ? e0 : e1;
      const vec2 a{static_cast<double>(e[0][0]), static_cast<double>(e[0][1])};
      const vec2 b{static_cast<double>(e[1][0]), static_cast<double>(e[1][1])};
      EXPECT_NEAR(cross(a, b, s.p[k]), 0.0, 1e-12);
      for (std::size_t q = 0; q < 2; ++q) {
        EXPECT_GT(s.p[k][q], std::min(a[q], b[q]) - 1e-12);
        EXPECT_LT(s.p[k][q], std::max(a[q], b[q]) + 1e-12);
      }
      // Strictly inside the edge.
      EXPECT_NE(s.p[k], a);
      EXPECT_NE(s.p[k], b);
      // Colours differ at the two ends.
      EXPECT_NE(v.value(e[0][0], e[0][1], 0) > w, v.value(e[1][0], e[1][1], 0) > w);
    }
    for (const point& c : corners) {
      const vec2 pc{static_cast<double>(c[0]), static_cast<double>(c[1])};
      const double side = cross(s.p[0], s.p[1], pc);
      if (v.value(c[0], c[1], 0) > w) {
        EXPECT_GT(side, 0.0) << "black corner " << c[0] << "," << c[1] << " not on the left";
      } else {
        EXPECT_LT(side, 0.0) << "white corner " << c[0] << "," << c[1] << " not on the right";
      }
    }
  }
}

TEST(ReferenceMtri, distance_field_gives_one_clockwise_loop_with_the_outside_black) {
  // f = distance from the centre: the disk inside is white (f <= w), the outside black. With
  // black on the left the loop runs clockwise in the (x, y) frame: negative signed area.
  const volume v =
      f64_image(41, 37, [](double x, double y) { return std::hypot(x - 20.3, y - 18.7); });
  const contour_set c = reference_contours(v, 10.5);
  ASSERT_EQ(c.polylines.size(), 1u);
  EXPECT_TRUE(c.polylines[0].closed);
  EXPECT_EQ(c.polylines[0].isovalue, 10.5);
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
  const double area = signed_area(c, c.polylines[0]);
  EXPECT_LT(area, 0.0);
  EXPECT_NEAR(-area, std::numbers::pi * 10.5 * 10.5, 0.02 * std::numbers::pi * 10.5 * 10.5);
  check_segments_against_their_triangles(v, 10.5);
}

TEST(ReferenceMtri, negated_distance_field_gives_a_counterclockwise_loop) {
  const volume v =
      f64_image(41, 37, [](double x, double y) { return -std::hypot(x - 20.3, y - 18.7); });
  const contour_set c = reference_contours(v, -10.5);
  ASSERT_EQ(c.polylines.size(), 1u);
  EXPECT_GT(signed_area(c, c.polylines[0]), 0.0);
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
}

TEST(ReferenceMtri, ramp_gives_one_open_chain_from_border_to_border) {
  // f = x, w = 3.5: the vertical line x = 3.5, black (x > 3.5) on the left, so it runs toward
  // decreasing y: from the last row to the first.
  const volume v = f64_image(9, 7, [](double x, double) { return x; });
  const contour_set c = reference_contours(v, 3.5);
  ASSERT_EQ(c.polylines.size(), 1u);
  const polyline& line = c.polylines[0];
  EXPECT_FALSE(line.closed);
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
  for (const std::uint32_t i : line.vertices) EXPECT_EQ(c.vertices[i][0], 3.5);
  EXPECT_EQ(c.vertices[line.vertices.front()][1], 6.0);
  EXPECT_EQ(c.vertices[line.vertices.back()][1], 0.0);
  EXPECT_EQ(c.segment_count(), 12u);  // two triangles per unit square of column 3
  check_segments_against_their_triangles(v, 3.5);
}

TEST(ReferenceMtri, saddle_gives_open_chains_on_the_border_and_a_valid_contour) {
  const volume v =
      f64_image(23, 19, [](double x, double y) { return (x - 11.2) * (y - 9.1) + 0.3 * x; });
  for (const double w : {-20.0, 0.0, 3.3, 40.0}) {
    const contour_set c = reference_contours(v, w);
    EXPECT_TRUE(check_valid_contour(c, image_box(v))) << "w = " << w;
    for (const polyline& line : c.polylines) EXPECT_FALSE(line.closed);
    check_segments_against_their_triangles(v, w);
  }
}

TEST(ReferenceMtri, samples_equal_to_the_isovalue_give_no_degenerate_segments) {
  // Small integers, many of them equal to w: vertices clamp 1/4096 inside their edges.
  const volume v = u8_image(31, 27, [](std::int64_t x, std::int64_t y) { return (x * y + x) % 3; });
  for (const double w : {0.0, 1.0}) {
    const contour_set c = reference_contours(v, w);
    EXPECT_GT(c.segment_count(), 100u);
    EXPECT_TRUE(check_valid_contour(c, image_box(v))) << "w = " << w;
    check_segments_against_their_triangles(v, w);
  }
  // At the maximum everything is white: no contour.
  EXPECT_TRUE(reference_segments(v, 2.0).empty());
  EXPECT_TRUE(reference_contours(v, 2.0).empty());
}

TEST(ReferenceMtri, contours_chain_exactly_the_segments) {
  const volume v = u8_image(40, 33, [](std::int64_t x, std::int64_t y) {
    return static_cast<int>(100.0 + 60.0 * std::sin(0.4 * static_cast<double>(x)) *
                                        std::cos(0.3 * static_cast<double>(y)));
  });
  const std::vector<segment> segments = reference_segments(v, 110.0);
  contour_set loose;
  for (const segment& s : segments) {
    const auto n = static_cast<std::uint32_t>(loose.vertices.size());
    loose.vertices.push_back(s.p[0]);
    loose.vertices.push_back(s.p[1]);
    loose.polylines.push_back({{n, n + 1}, false, 110.0});
  }
  const contour_set c = reference_contours(v, 110.0);
  EXPECT_TRUE(same_segments(c, loose));
  EXPECT_EQ(c.segment_count(), segments.size());
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
  // One vertex per distinct key.
  std::set<std::uint64_t> keys;
  for (const segment& s : segments) keys.insert(s.keys.begin(), s.keys.end());
  EXPECT_EQ(c.vertices.size(), keys.size());
  bool closed = false;
  bool open = false;
  for (const polyline& line : c.polylines) (line.closed ? closed : open) = true;
  EXPECT_TRUE(closed);
  EXPECT_TRUE(open);
}

TEST(ReferenceMtri, vertices_interpolate_from_the_lower_row_first_and_use_edge_key2) {
  // The unit square [1, 2] × [0, 1] is cut from (2, 0) (all even) to (1, 1) (all odd): the
  // canonical order puts (2, 0) first (lower row), although its column is the larger.
  const volume v = f64_image(3, 2, [](double x, double y) {
    return x == 2 && y == 0 ? 0.1 : (x == 1 && y == 1 ? 0.7 : (x == 1 ? 0.9 : 0.0));
  });
  const double w = 0.3;
  const double t = (w - 0.1) / (0.7 - 0.1);
  const vec2 expected{2.0 + t * -1.0, 0.0 + t * 1.0};
  bool found = false;
  for (const segment& s : reference_segments(v, w)) {
    for (std::size_t k = 0; k < 2; ++k) {
      const auto e = finest_edge(s.keys[k]);
      EXPECT_EQ(
          s.keys[k],
          edge_key2({static_cast<std::int32_t>(e[0][0]), static_cast<std::int32_t>(e[0][1])},
                    {static_cast<std::int32_t>(e[1][0]), static_cast<std::int32_t>(e[1][1])}));
      if (s.keys[k] == edge_key2({2, 0}, {1, 1})) {
        EXPECT_EQ(s.p[k], expected);  // bit for bit
        found = true;
      }
    }
  }
  EXPECT_TRUE(found);
}

TEST(ReferenceMtri, positions_follow_origin_and_spacing) {
  std::vector<std::byte> bytes(12);
  for (std::size_t i = 0; i < 12; ++i) bytes[i] = static_cast<std::byte>(i % 4 == 2 ? 10 : 0);
  const volume v({4, 3, 1}, sample_type::u8, std::move(bytes), {0.5, 2.0, 1.0}, {1.0, -3.0, 0.0});
  const contour_set c = reference_contours(v, 5.0);
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
  for (const vec2& p : c.vertices) {
    EXPECT_GT(p[0], 1.5);  // around column 2: x = 1 + 2 * 0.5
    EXPECT_LT(p[0], 2.5);
  }
}

TEST(ReferenceMtri, rejects_nan_isovalue_and_volumes) {
  const volume v = u8_image(4, 4, [](auto x, auto) { return x; });
  EXPECT_THROW((void)reference_segments(v, std::nan("")), error);
  const volume thick({4, 4, 2}, sample_type::u8, std::vector<std::byte>(32));
  EXPECT_THROW((void)reference_contours(thick, 1.0), error);
}

TEST(ReferenceMtri, shared_images_give_valid_contours) {
  const auto dir = shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const shared_image& info : shared_images()) {
    const volume v = load_pgm(*dir / info.file);
    for (const double w : info.isovalues) {
      const contour_set c = reference_contours(v, w);
      std::size_t closed = 0;
      for (const polyline& line : c.polylines) closed += line.closed ? 1 : 0;
      std::cout << info.name << " w=" << w << ": " << c.segment_count() << " segments, " << closed
                << " closed loops, " << c.polylines.size() - closed << " open chains\n";
      EXPECT_GT(c.segment_count(), 0u) << info.name << " w=" << w;
      EXPECT_TRUE(check_valid_contour(c, image_box(v))) << info.name << " w=" << w;
    }
  }
}

TEST(ReferenceMtri, pgm_reader_rejects_what_it_cannot_read) {
  EXPECT_THROW((void)load_pgm("no/such/file.pgm"), error);
}

}  // namespace
}  // namespace progiso::test
