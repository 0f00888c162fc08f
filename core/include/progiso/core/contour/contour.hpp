// progiso/core/contour/contour.hpp — isocontours of 2D images as polylines.
//
// A contour set holds the polylines of one or several isovalues over one image: closed loops,
// and open chains whose two ends lie on the image border. Vertices are shared by index; each
// vertex is used by at most two segments of its polyline set. Coordinates are pixel units:
// x = column, y = row (origin + index × spacing, as for volumes, with the image's first two
// spacings and origins).
//
// Orientation: every polyline runs with the region f > isovalue on its left in the (x, y)
// frame, i.e. for a segment p → q and any point b with f(b) > w next to it,
// (q − p) × (b − p) > 0. (Drawn with y pointing down, as images are, that region appears on the
// right.)
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

using vec2 = std::array<double, 2>;

/// One polyline: indices into contour_set::vertices, in order. A closed polyline does not
/// repeat its first vertex at the end.
struct polyline {
  std::vector<std::uint32_t> vertices;
  bool closed = false;
  double isovalue = 0.0;
};

/// The polylines of one or several isovalues over one image.
struct contour_set {
  std::vector<vec2> vertices;
  std::vector<polyline> polylines;

  [[nodiscard]] bool empty() const noexcept { return polylines.empty(); }
  [[nodiscard]] std::size_t segment_count() const noexcept {
    std::size_t n = 0;
    for (const auto& p : polylines) {
      if (p.vertices.size() >= 2) n += p.vertices.size() - (p.closed ? 0 : 1);
    }
    return n;
  }
};

}  // namespace progiso
