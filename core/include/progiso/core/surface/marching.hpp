// progiso/core/surface/marching.hpp — marching tetrahedra on one tetrahedron, with canonical
// vertices.
//
// Every surface piece progiso produces, at any resolution, is the marching-tetrahedra surface of
// one tetrahedron of the current bisection mesh. This header fixes the rules that make pieces
// of neighbouring tetrahedra fit exactly, whatever tetrahedra they come from:
//
//  * Colours (paper §3.1): a vertex is black when f > w and white when f <= w. An edge is
//    crossed when its ends differ in colour.
//  * A surface vertex is named by its grid edge: edge_key() packs the doubled midpoint a + b,
//    which identifies the edge uniquely among all edges of all bisection meshes (a coarse edge
//    is the spine of the diamond centred at its midpoint; a finest edge has a half-integer
//    midpoint and the finest mesh has one diagonal per unit square and cube).
//  * Its position is interpolated from the canonically ordered ends (lower (z, y, x) first):
//    t = (w - fa) / (fb - fa), clamped into [interpolation_margin, 1 - interpolation_margin],
//    p = a + t (b - a). The clamp keeps every surface vertex strictly inside its edge, so no
//    triangle is degenerate even when samples equal the isovalue exactly (common with integer
//    data). Every tetrahedron touching an edge computes a bit-identical point.
//  * A two-two split gives a quad on edges (b1w1, b1w2, b2w2, b2w1); it is cut along the
//    diagonal that contains the quad vertex with the smallest edge key.
//  * Each triangle is oriented so that its right-hand normal points from black to white
//    (toward decreasing values). The test is exact: it uses the doubled midpoints (the keys'
//    integer coordinates), whose triangle lies in the plane that separates black from white.
//
// Cost: a few dozen integer operations per crossed tetrahedron; no allocation.
#pragma once

#include <array>
#include <cstdint>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso {

/// Integer coordinates of a vertex of the hierarchy grid.
using ipoint = std::array<std::int32_t, 3>;

/// Surface vertices are kept at least this fraction of an edge away from its ends.
inline constexpr double interpolation_margin = 1.0 / 4096.0;

/// Where isovalue w crosses the edge from the value fp to fq: t = (w − fp) / (fq − fp), clamped
/// into [interpolation_margin, 1 − interpolation_margin] (a NaN t takes the lower bound). Both
/// interpolate() and the 2D interpolate2() call it with the edge's ends in canonical order.
[[nodiscard]] inline double crossing_parameter(double fp, double fq, double w) noexcept {
  double t = (w - fp) / (fq - fp);
  if (!(t >= interpolation_margin)) t = interpolation_margin;
  if (t > 1.0 - interpolation_margin) t = 1.0 - interpolation_margin;
  return t;
}

/// Bits per axis in an edge key: doubled coordinates below 2^21.
inline constexpr int edge_key_bits = 21;

/// The key of grid edge (a, b): its doubled midpoint, packed x | y << 21 | z << 42.
[[nodiscard]] constexpr std::uint64_t edge_key(const ipoint& a, const ipoint& b) noexcept {
  return static_cast<std::uint64_t>(a[0] + b[0]) |
         (static_cast<std::uint64_t>(a[1] + b[1]) << edge_key_bits) |
         (static_cast<std::uint64_t>(a[2] + b[2]) << (2 * edge_key_bits));
}

/// The doubled midpoint encoded in an edge key.
[[nodiscard]] constexpr ipoint edge_key_point(std::uint64_t key) noexcept {
  constexpr std::uint64_t mask = (std::uint64_t{1} << edge_key_bits) - 1;
  return {static_cast<std::int32_t>(key & mask),
          static_cast<std::int32_t>((key >> edge_key_bits) & mask),
          static_cast<std::int32_t>(key >> (2 * edge_key_bits))};
}

/// True when a precedes b in the canonical vertex order (z, then y, then x).
[[nodiscard]] constexpr bool vertex_less(const ipoint& a, const ipoint& b) noexcept {
  if (a[2] != b[2]) return a[2] < b[2];
  if (a[1] != b[1]) return a[1] < b[1];
  return a[0] < b[0];
}

/// The surface vertex on crossed edge (a, b), in grid units, by the canonical rule above.
/// Inline: every extraction places its vertices through it, the finest surface's per vertex.
[[nodiscard]] inline vec3 interpolate(const ipoint& a, double fa, const ipoint& b, double fb,
                                      double isovalue) noexcept {
  const bool swap = vertex_less(b, a);
  const ipoint& p = swap ? b : a;
  const ipoint& q = swap ? a : b;
  const double t = crossing_parameter(swap ? fb : fa, swap ? fa : fb, isovalue);
  vec3 r{};
  for (std::size_t k = 0; k < 3; ++k) {
    r[k] = static_cast<double>(p[k]) + t * static_cast<double>(q[k] - p[k]);
  }
  return r;
}

/// At most two oriented triangles, each three edge keys.
struct tet_surface {
  std::array<std::array<std::uint64_t, 3>, 2> triangles{};
  int count = 0;
};

/// Marching tetrahedra on tetrahedron p[0..3] with values f[0..3] at isovalue w.
[[nodiscard]] tet_surface march_tet(const std::array<ipoint, 4>& p, const std::array<double, 4>& f,
                                    double isovalue) noexcept;

/// Number of triangles march_tet() would produce, from the colours alone.
[[nodiscard]] inline int tet_triangle_count(unsigned black_mask) noexcept {
  // Indexed by the mask of black vertices: 0 or 4 black → 0, 2 black → 2, else 1.
  static constexpr int count[16] = {0, 1, 1, 2, 1, 2, 2, 1, 1, 2, 2, 1, 2, 1, 1, 0};
  return count[black_mask & 0xFu];
}

}  // namespace progiso
