// The contour checks themselves: each one passes on a good hand-made contour and fails, with a
// message naming the culprit, on a contour broken in exactly the way it looks for.
#include <chrono>
#include <iostream>
#include <string>

#include <gtest/gtest.h>

#include "support/contour_checks.hpp"
#include "support/reference_mtri.hpp"

namespace progiso::test {
namespace {

const box2 box10{{0.0, 0.0}, {10.0, 10.0}};

// A closed square loop (counterclockwise) and an open chain from the left to the bottom border.
contour_set good_contour() {
  contour_set c;
  c.vertices = {{4, 4}, {6, 4}, {6, 6}, {4, 6}, {0, 2}, {1, 1.5}, {2, 0}};
  c.polylines.push_back({{0, 1, 2, 3}, true, 5.0});
  c.polylines.push_back({{4, 5, 6}, false, 5.0});
  return c;
}

bool mentions(const contour_check& r, const std::string& what) {
  return r.message.find(what) != std::string::npos;
}

TEST(ContourChecks, good_contour_passes_every_check) {
  const contour_set c = good_contour();
  EXPECT_TRUE(vertices_used_at_most_twice(c)) << vertices_used_at_most_twice(c).message;
  EXPECT_TRUE(no_zero_length_segments(c));
  EXPECT_TRUE(no_repeated_vertices(c));
  EXPECT_TRUE(open_chains_end_on_border(c, box10));
  EXPECT_TRUE(closed_loops_have_three_vertices(c));
  EXPECT_TRUE(no_crossings(c)) << no_crossings(c).message;
  EXPECT_TRUE(consistently_oriented(c));
  EXPECT_TRUE(check_valid_contour(c, box10));
  EXPECT_TRUE(check_valid_contour(contour_set{}, box10));
}

TEST(ContourChecks, vertex_of_three_segments_fails_within_one_isovalue_only) {
  contour_set c = good_contour();
  c.vertices.push_back({0, 4});
  c.polylines.push_back({{7, 0}, false, 5.0});  // a third segment at vertex 0
  const contour_check r = vertices_used_at_most_twice(c);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "vertex 0")) << r.message;
  EXPECT_FALSE(check_valid_contour(c, box10));
  c.polylines.back().isovalue = 6.0;  // another isovalue's contour may touch this one
  EXPECT_TRUE(vertices_used_at_most_twice(c)) << vertices_used_at_most_twice(c).message;
}

TEST(ContourChecks, vertex_index_out_of_range_fails) {
  contour_set c = good_contour();
  c.polylines[0].vertices.push_back(99);
  EXPECT_FALSE(vertices_used_at_most_twice(c));
  EXPECT_FALSE(no_crossings(c));
  EXPECT_FALSE(check_valid_contour(c, box10));
}

TEST(ContourChecks, zero_length_segment_fails) {
  contour_set c = good_contour();
  c.vertices.push_back({6, 4});  // same position as vertex 1
  c.polylines[0].vertices = {0, 1, 7, 2, 3};
  const contour_check r = no_zero_length_segments(c);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "1 -> 7")) << r.message;
  EXPECT_FALSE(check_valid_contour(c, box10));
}

TEST(ContourChecks, repeated_vertex_in_a_polyline_fails) {
  contour_set c = good_contour();
  c.polylines[0].vertices = {0, 1, 2, 1, 3};
  EXPECT_FALSE(no_repeated_vertices(c));
  EXPECT_TRUE(mentions(no_repeated_vertices(c), "vertex 1"));
}

TEST(ContourChecks, open_chain_ending_inside_the_box_fails) {
  contour_set c = good_contour();
  c.polylines[1].vertices = {4, 5};
  const contour_check r = open_chains_end_on_border(c, box10);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "vertex 5")) << r.message;
  c.polylines[1].vertices = {4};
  EXPECT_FALSE(open_chains_end_on_border(c, box10));
  // Exactly on the border only: a hair inside is not on it.
  c.vertices[6] = {2, 1e-300};
  c.polylines[1].vertices = {4, 5, 6};
  EXPECT_FALSE(open_chains_end_on_border(c, box10));
  c.vertices[6] = {10, 3};
  EXPECT_TRUE(open_chains_end_on_border(c, box10));
}

TEST(ContourChecks, closed_loop_of_two_vertices_fails) {
  contour_set c = good_contour();
  c.polylines[0].vertices = {0, 1};
  EXPECT_FALSE(closed_loops_have_three_vertices(c));
  EXPECT_FALSE(check_valid_contour(c, box10));
}

TEST(ContourChecks, crossing_segments_fail) {
  contour_set c = good_contour();
  // A chain through the square loop.
  c.vertices.push_back({5, 0});
  c.vertices.push_back({5, 10});
  c.polylines.push_back({{7, 8}, false, 5.0});
  const contour_check r = no_crossings(c);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "2 intersecting")) << r.message;
  // Contours of different isovalues may cross.
  c.polylines.back().isovalue = 7.0;
  EXPECT_TRUE(no_crossings(c)) << no_crossings(c).message;
}

TEST(ContourChecks, touching_at_a_point_without_a_shared_index_fails) {
  contour_set c = good_contour();
  // An end on the interior of the loop's bottom edge, and a duplicate of vertex 0.
  c.vertices.push_back({5, 4});
  c.vertices.push_back({5, 0});
  c.polylines.push_back({{8, 7}, false, 5.0});
  EXPECT_FALSE(no_crossings(c));
  contour_set d = good_contour();
  d.vertices.push_back({4, 4});
  d.vertices.push_back({0, 8});
  d.polylines.push_back({{8, 7}, false, 5.0});
  const contour_check r = no_crossings(d);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "intersects")) << r.message;
}

TEST(ContourChecks, collinear_overlap_of_segments_sharing_a_vertex_fails) {
  contour_set c;
  c.vertices = {{0, 5}, {4, 5}, {2, 5}};
  c.polylines.push_back({{0, 1, 2}, false, 1.0});  // doubles back along itself
  const contour_check r = no_crossings(c);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "overlaps")) << r.message;
  // Collinear, but continuing straight on: fine.
  c.vertices[2] = {7, 5};
  EXPECT_TRUE(no_crossings(c)) << no_crossings(c).message;
  // The same segment twice.
  contour_set d;
  d.vertices = {{0, 5}, {4, 5}};
  d.polylines.push_back({{0, 1}, false, 1.0});
  d.polylines.push_back({{1, 0}, false, 1.0});
  EXPECT_TRUE(mentions(no_crossings(d), "repeats"));
}

TEST(ContourChecks, inconsistently_directed_polylines_fail) {
  contour_set c;
  c.vertices = {{0, 2}, {2, 2}, {2, 0}, {0, 0}};
  // A → B → C and then A → D → C: C ends two segments.
  c.vertices.push_back({1, 1});
  c.polylines.push_back({{0, 1, 2}, false, 1.0});
  c.polylines.push_back({{0, 3, 2}, false, 1.0});
  const contour_check r = consistently_oriented(c);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "vertex 2") || mentions(r, "vertex 0")) << r.message;
  // C → D → A continues the first chain: consistent.
  c.polylines[1].vertices = {2, 3, 0};
  EXPECT_TRUE(consistently_oriented(c)) << consistently_oriented(c).message;
}

TEST(ContourChecks, signed_area_is_positive_counterclockwise) {
  const contour_set c = good_contour();
  EXPECT_EQ(signed_area(c, c.polylines[0]), 4.0);
  polyline reversed = c.polylines[0];
  std::reverse(reversed.vertices.begin(), reversed.vertices.end());
  EXPECT_EQ(signed_area(c, reversed), -4.0);
}

TEST(ContourChecks, same_segments_ignores_numbering_but_not_direction) {
  const contour_set a = good_contour();
  // The same directed segments, renumbered and split into other polylines.
  contour_set b;
  b.vertices = {{6, 6}, {4, 6}, {4, 4}, {6, 4}, {2, 0}, {1, 1.5}, {0, 2}};
  b.polylines.push_back({{6, 5, 4}, false, 5.0});
  b.polylines.push_back({{2, 3, 0}, false, 5.0});
  b.polylines.push_back({{0, 1, 2}, false, 5.0});
  EXPECT_TRUE(same_segments(a, b));
  b.polylines[0].vertices = {4, 5, 6};
  const ::testing::AssertionResult r = same_segments(a, b);
  EXPECT_FALSE(r);
  EXPECT_NE(std::string(r.message()).find("only in the first: 2"), std::string::npos)
      << r.message();
  b.polylines.pop_back();
  EXPECT_FALSE(same_segments(a, b));
}

TEST(ContourChecks, image_box_follows_origin_and_spacing) {
  const volume v({5, 3, 1}, sample_type::u8, std::vector<std::byte>(15), {0.5, 2.0, 1.0},
                 {1.0, -1.0, 0.0});
  const box2 b = image_box(v);
  EXPECT_EQ(b.min, (vec2{1.0, -1.0}));
  EXPECT_EQ(b.max, (vec2{3.0, 3.0}));
}

TEST(ContourChecks, a_hundred_thousand_segments_check_in_seconds) {
  // Noise: a contour through about half the triangles of a 300 × 300 image.
  const std::int64_t n = 300;
  std::vector<std::byte> bytes(static_cast<std::size_t>(n * n));
  std::uint32_t s = 12345;
  for (std::byte& b : bytes) {
    s = s * 1664525u + 1013904223u;
    b = static_cast<std::byte>(s >> 24);
  }
  const volume v({n, n, 1}, sample_type::u8, std::move(bytes));
  const contour_set c = reference_contours(v, 127.5);
  EXPECT_GT(c.segment_count(), 80000u);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(check_valid_contour(c, image_box(v)));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << c.segment_count() << " segments checked in " << seconds << " s\n";
}

}  // namespace
}  // namespace progiso::test
