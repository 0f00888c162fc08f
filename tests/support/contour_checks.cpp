#include <support/contour_checks.hpp>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <iterator>
#include <map>
#include <sstream>
#include <unordered_map>
#include <utility>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>

namespace progiso::test {
namespace {

using kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

std::string format(const vec2& p) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << p[0] << ", " << p[1] << ")";
  return s.str();
}

contour_check fail(std::string message) { return {false, std::move(message)}; }

// The segments of a polyline as (from, to) vertex indices: consecutive pairs, plus the closing
// one of a closed polyline (as contour_set::segment_count() counts them).
template <class F>
void for_each_segment(const polyline& line, F&& f) {
  const std::size_t n = line.vertices.size();
  if (n < 2) return;
  for (std::size_t k = 0; k + 1 < n; ++k) f(line.vertices[k], line.vertices[k + 1]);
  if (line.closed) f(line.vertices[n - 1], line.vertices[0]);
}

// Polylines grouped by isovalue (by bit pattern, so that NaN groups too), in order.
std::map<std::uint64_t, std::vector<std::size_t>> by_isovalue(const contour_set& contours) {
  std::map<std::uint64_t, std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    groups[std::bit_cast<std::uint64_t>(contours.polylines[i].isovalue)].push_back(i);
  }
  return groups;
}

// The first vertex index out of range, as a failed check; ok when there is none.
contour_check indices_in_range(const contour_set& contours) {
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    for (const std::uint32_t v : contours.polylines[i].vertices) {
      if (v >= contours.vertices.size()) {
        return fail("polyline " + std::to_string(i) + " uses vertex " + std::to_string(v) + " of " +
                    std::to_string(contours.vertices.size()));
      }
    }
  }
  return {};
}

bool on_border(const vec2& p, const box2& box) {
  return p[0] == box.min[0] || p[0] == box.max[0] || p[1] == box.min[1] || p[1] == box.max[1];
}

}  // namespace

box2 image_box(const volume& image) {
  box2 box;
  for (std::size_t q = 0; q < 2; ++q) {
    box.min[q] = image.origin()[q];
    box.max[q] = image.origin()[q] + static_cast<double>(image.dims()[q] - 1) * image.spacing()[q];
  }
  return box;
}

contour_check vertices_used_at_most_twice(const contour_set& contours) {
  if (contour_check r = indices_in_range(contours); !r) return r;
  for (const auto& [iso, lines] : by_isovalue(contours)) {
    std::unordered_map<std::uint32_t, int> uses;
    for (const std::size_t i : lines) {
      contour_check r;
      for_each_segment(contours.polylines[i], [&](std::uint32_t u, std::uint32_t v) {
        for (const std::uint32_t x : {u, v}) {
          if (++uses[x] > 2 && r) {
            r = fail("vertex " + std::to_string(x) + " " + format(contours.vertices[x]) +
                     " used by more than two segments (third in polyline " + std::to_string(i) +
                     ", isovalue " + std::to_string(contours.polylines[i].isovalue) + ")");
          }
        }
      });
      if (!r) return r;
    }
  }
  return {};
}

contour_check no_zero_length_segments(const contour_set& contours) {
  if (contour_check r = indices_in_range(contours); !r) return r;
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    contour_check r;
    for_each_segment(contours.polylines[i], [&](std::uint32_t u, std::uint32_t v) {
      if (r && contours.vertices[u] == contours.vertices[v]) {
        r = fail("polyline " + std::to_string(i) + ": zero-length segment " + std::to_string(u) +
                 " -> " + std::to_string(v) + " at " + format(contours.vertices[u]));
      }
    });
    if (!r) return r;
  }
  return {};
}

contour_check no_repeated_vertices(const contour_set& contours) {
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    std::vector<std::uint32_t> v = contours.polylines[i].vertices;
    std::sort(v.begin(), v.end());
    if (const auto it = std::adjacent_find(v.begin(), v.end()); it != v.end()) {
      return fail("polyline " + std::to_string(i) + " visits vertex " + std::to_string(*it) +
                  " twice");
    }
  }
  return {};
}

contour_check open_chains_end_on_border(const contour_set& contours, const box2& box) {
  if (contour_check r = indices_in_range(contours); !r) return r;
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    const polyline& line = contours.polylines[i];
    if (line.closed) continue;
    if (line.vertices.size() < 2) {
      return fail("open polyline " + std::to_string(i) + " has " +
                  std::to_string(line.vertices.size()) + " vertices");
    }
    for (const std::uint32_t end : {line.vertices.front(), line.vertices.back()}) {
      if (!on_border(contours.vertices[end], box)) {
        return fail("open polyline " + std::to_string(i) + " ends at vertex " +
                    std::to_string(end) + " " + format(contours.vertices[end]) +
                    ", not on the border of " + format(box.min) + " - " + format(box.max));
      }
    }
  }
  return {};
}

contour_check closed_loops_have_three_vertices(const contour_set& contours) {
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    const polyline& line = contours.polylines[i];
    if (line.closed && line.vertices.size() < 3) {
      return fail("closed polyline " + std::to_string(i) + " has " +
                  std::to_string(line.vertices.size()) + " vertices");
    }
  }
  return {};
}

contour_check no_crossings(const contour_set& contours) {
  if (contour_check r = indices_in_range(contours); !r) return r;
  using box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::size_t>;
  struct ref {
    std::uint32_t u;
    std::uint32_t v;
    std::size_t line;
  };
  const auto point = [&](std::uint32_t i) {
    return kernel::Point_2(contours.vertices[i][0], contours.vertices[i][1]);
  };
  constexpr std::size_t limit = 1000;
  std::size_t pairs = 0;
  std::string first;
  for (const auto& [iso, lines] : by_isovalue(contours)) {
    std::vector<ref> segments;
    std::vector<box> boxes;
    for (const std::size_t i : lines) {
      for_each_segment(contours.polylines[i], [&](std::uint32_t u, std::uint32_t v) {
        const vec2& a = contours.vertices[u];
        const vec2& b = contours.vertices[v];
        if (a == b) return;
        const CGAL::Bbox_2 bb(std::min(a[0], b[0]), std::min(a[1], b[1]), std::max(a[0], b[0]),
                              std::max(a[1], b[1]));
        boxes.emplace_back(bb, segments.size());
        segments.push_back({u, v, i});
      });
    }
    const auto describe = [&](const ref& s) {
      return "segment " + std::to_string(s.u) + " " + format(contours.vertices[s.u]) + " -> " +
             std::to_string(s.v) + " " + format(contours.vertices[s.v]) + " of polyline " +
             std::to_string(s.line);
    };
    const auto report = [&](const ref& s, const ref& t, const char* what) {
      if (pairs++ == 0) {
        first = describe(s) + " " + what + " " + describe(t);
      }
    };
    const auto check_pair = [&](const box& a, const box& b) {
      if (pairs >= limit) return;
      const ref& s = segments[a.info()];
      const ref& t = segments[b.info()];
      const int shared = (s.u == t.u || s.u == t.v ? 1 : 0) + (s.v == t.u || s.v == t.v ? 1 : 0);
      if (shared == 2) {
        report(s, t, "repeats");
      } else if (shared == 1) {
        // Meeting at the shared vertex is fine; overlapping along a common line is not.
        const std::uint32_t common = s.u == t.u || s.u == t.v ? s.u : s.v;
        const kernel::Point_2 c = point(common);
        const kernel::Point_2 p = point(s.u == common ? s.v : s.u);
        const kernel::Point_2 q = point(t.u == common ? t.v : t.u);
        if (CGAL::collinear(c, p, q) && (CGAL::collinear_are_ordered_along_line(c, p, q) ||
                                         CGAL::collinear_are_ordered_along_line(c, q, p))) {
          report(s, t, "overlaps");
        }
      } else if (CGAL::do_intersect(kernel::Segment_2(point(s.u), point(s.v)),
                                    kernel::Segment_2(point(t.u), point(t.v)))) {
        report(s, t, "intersects");
      }
    };
    CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), check_pair, std::ptrdiff_t{10},
                                  CGAL::Box_intersection_d::CLOSED);
  }
  if (pairs == 0) return {};
  return fail(std::to_string(pairs) + (pairs >= limit ? "+" : "") +
              " intersecting segment pairs; first: " + first);
}

contour_check consistently_oriented(const contour_set& contours) {
  if (contour_check r = indices_in_range(contours); !r) return r;
  for (const auto& [iso, lines] : by_isovalue(contours)) {
    std::unordered_map<std::uint32_t, std::pair<int, int>> use;  // starts, ends
    for (const std::size_t i : lines) {
      contour_check r;
      for_each_segment(contours.polylines[i], [&](std::uint32_t u, std::uint32_t v) {
        if (!r) return;
        if (++use[u].first > 1) {
          r = fail("vertex " + std::to_string(u) + " " + format(contours.vertices[u]) +
                   " starts two segments (second in polyline " + std::to_string(i) + ")");
        } else if (++use[v].second > 1) {
          r = fail("vertex " + std::to_string(v) + " " + format(contours.vertices[v]) +
                   " ends two segments (second in polyline " + std::to_string(i) + ")");
        }
      });
      if (!r) return r;
    }
  }
  return {};
}

double signed_area(const contour_set& contours, const polyline& line) {
  double twice = 0.0;
  const std::size_t n = line.vertices.size();
  for (std::size_t k = 0; k < n; ++k) {
    const vec2& a = contours.vertices[line.vertices[k]];
    const vec2& b = contours.vertices[line.vertices[(k + 1) % n]];
    twice += a[0] * b[1] - b[0] * a[1];
  }
  return 0.5 * twice;
}

std::vector<position_segment> directed_segments(const contour_set& contours) {
  std::vector<position_segment> out;
  out.reserve(contours.segment_count());
  for (const polyline& line : contours.polylines) {
    for_each_segment(line, [&](std::uint32_t u, std::uint32_t v) {
      out.push_back({contours.vertices.at(u), contours.vertices.at(v)});
    });
  }
  std::sort(out.begin(), out.end());
  return out;
}

::testing::AssertionResult same_segments(const contour_set& a, const contour_set& b) {
  const std::vector<position_segment> sa = directed_segments(a);
  const std::vector<position_segment> sb = directed_segments(b);
  if (sa == sb) return ::testing::AssertionSuccess();
  std::vector<position_segment> only_a;
  std::vector<position_segment> only_b;
  std::set_difference(sa.begin(), sa.end(), sb.begin(), sb.end(), std::back_inserter(only_a));
  std::set_difference(sb.begin(), sb.end(), sa.begin(), sa.end(), std::back_inserter(only_b));
  auto r = ::testing::AssertionFailure();
  r << "segments: " << sa.size() << " vs " << sb.size() << "; only in the first: " << only_a.size()
    << ", only in the second: " << only_b.size();
  if (!only_a.empty()) {
    r << "; first only in the first: " << format(only_a.front()[0]) << " -> "
      << format(only_a.front()[1]);
  }
  if (!only_b.empty()) {
    r << "; first only in the second: " << format(only_b.front()[0]) << " -> "
      << format(only_b.front()[1]);
  }
  return r;
}

::testing::AssertionResult check_valid_contour(const contour_set& contours, const box2& box) {
  const std::array<std::pair<const char*, contour_check>, 7> checks{{
      {"vertex degree", vertices_used_at_most_twice(contours)},
      {"zero-length segments", no_zero_length_segments(contours)},
      {"repeated vertices", no_repeated_vertices(contours)},
      {"open chains", open_chains_end_on_border(contours, box)},
      {"closed loops", closed_loops_have_three_vertices(contours)},
      {"crossings", no_crossings(contours)},
      {"orientation", consistently_oriented(contours)},
  }};
  std::string failures;
  for (const auto& [name, result] : checks) {
    if (!result) failures += std::string(name) + ": " + result.message + "\n";
  }
  if (failures.empty()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << contours.polylines.size() << " polylines, "
                                       << contours.segment_count() << " segments:\n"
                                       << failures;
}

}  // namespace progiso::test
