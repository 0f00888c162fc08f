// tests/support/contour_checks.hpp — validity checks of extracted 2D contours (invariant 2,
// docs/ARCHITECTURE.md).
//
// Each check takes a contour_set and returns a contour_check: whether the property holds and,
// when it does not, a one-line description of the first violation (polyline, vertex indices and
// positions), so that a failing gtest assertion says what is wrong and where. Properties that
// concern one contour (vertex degree, orientation, crossings) are checked per isovalue: the
// polylines of one isovalue form one contour, and contours of different isovalues may meet
// (their vertices are clamped into the same edge interiors). The checks are exact: topology by
// vertex index, the border by exact coordinate equality (extraction computes every vertex
// bit-identically, so no tolerance is needed), crossings with CGAL's exact predicates
// (Exact_predicates_inexact_constructions_kernel).
//
// check_valid_contour() bundles what every contour a reader can obtain must satisfy. The
// absolute side (f > w on the left) is not checked here: a coarse cut's segments need not agree
// with the finest mesh's field, so it is left to the equality tests against the reference
// extractor (same_segments()), which compare directed segments.
//
// Cost: O(S log S) for S segments; crossings use CGAL's box intersection (a sweep, about
// O(S log S + pairs of overlapping bounding boxes): well under a second for 10^5 segments).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/contour/contour.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::test {

/// The outcome of one contour check: ok, or the first violation found.
struct contour_check {
  bool ok = true;
  /// Empty when ok; otherwise a description of the first violation.
  std::string message;

  explicit operator bool() const noexcept { return ok; }
};

/// An axis-aligned box of the plane, min and max corners included.
struct box2 {
  vec2 min{};
  vec2 max{};
};

/// The data box of an image: origin and origin + (dims − 1) · spacing on its first two axes,
/// computed the way extraction computes positions, so border vertices lie exactly on its sides.
[[nodiscard]] box2 image_box(const volume& image);

/// Every vertex index is in range, and within the polylines of one isovalue every vertex is
/// used by at most two segments.
[[nodiscard]] contour_check vertices_used_at_most_twice(const contour_set& contours);

/// No segment joins two equal positions (exact comparison).
[[nodiscard]] contour_check no_zero_length_segments(const contour_set& contours);

/// No polyline visits a vertex index twice.
[[nodiscard]] contour_check no_repeated_vertices(const contour_set& contours);

/// Every open polyline has at least 2 vertices and both its end vertices on the border of
/// `box` (x == min.x, x == max.x, y == min.y or y == max.y exactly).
[[nodiscard]] contour_check open_chains_end_on_border(const contour_set& contours, const box2& box);

/// Every closed polyline has at least 3 vertices.
[[nodiscard]] contour_check closed_loops_have_three_vertices(const contour_set& contours);

/// No two segments of one isovalue intersect, except two segments that share an end vertex
/// index, which may only meet there (they are checked for collinear overlap). Segments whose
/// ends are equal positions under different indices do intersect. Exact predicates; zero-length
/// segments are skipped (no_zero_length_segments() reports them). The message counts
/// intersecting pairs (at most 1000) and describes the first.
[[nodiscard]] contour_check no_crossings(const contour_set& contours);

/// Polylines are consistently directed: within one isovalue, no vertex starts two segments or
/// ends two segments, so a vertex used by two segments ends one and starts the other.
[[nodiscard]] contour_check consistently_oriented(const contour_set& contours);

/// Signed area enclosed by a closed polyline (shoelace formula): positive when it runs
/// counterclockwise in the (x, y) frame, i.e. with its inside on its left.
[[nodiscard]] double signed_area(const contour_set& contours, const polyline& line);

/// An oriented segment by its end positions.
using position_segment = std::array<vec2, 2>;

/// All directed segments of the set, as position pairs, sorted.
[[nodiscard]] std::vector<position_segment> directed_segments(const contour_set& contours);

/// Success when directed_segments(a) == directed_segments(b) (exact doubles); otherwise a
/// failure with both segment counts, how many segments of each are missing from the other, and
/// the first of them.
[[nodiscard]] ::testing::AssertionResult same_segments(const contour_set& a, const contour_set& b);

/// Success when every check above holds for `contours` within `box`; otherwise a failure with
/// the message of every failed check, one per line. Use as
/// EXPECT_TRUE(check_valid_contour(contours, image_box(image))).
[[nodiscard]] ::testing::AssertionResult check_valid_contour(const contour_set& contours,
                                                             const box2& box);

}  // namespace progiso::test
