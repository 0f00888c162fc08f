// progiso/core/contour/hierarchy2d.hpp — the implicit 2D longest-edge-bisection hierarchy over
// images.
//
// The 2D counterpart of hierarchy.hpp (paper §3; docs/ARCHITECTURE.md, "The hierarchy", with d =
// 2): the image grid is embedded in a forest of root squares of side N = 2^L (the largest power of
// two ≤ min(w, h) − 1), each cut by the diagonal from its corner at even multiples of N to its
// corner at odd multiples. Every grid vertex that is not a root-square corner is the centre of one
// diamond: the (one or) two triangles sharing its spine, bisected together. From the centre c
// alone:
//
//  * scale h = 2^min(tz(c_x), tz(c_y)) (tz capped at L); odd axes: c_q / h odd;
//    type = 2 − #odd axes (0: square centre, spine a square diagonal; 1: edge midpoint, spine an
//    axis edge).
//  * spine = c ± h s, s_q = 0 on even axes, on odd axes +1 if (c_q + h) mod 4h = 0 else −1.
//  * ring: the apex of each triangle — type 0: the square's other two corners; type 1: c ± h
//    along the even axis. Triangle m is (spine0, spine1, ring[m]) when ring[m] is in the grid.
//  * depth = 2 (L − 1 − log2 h) + type; parents are the ring vertices of depth − 1 (2 for
//    interior diamonds); children are c ± h e_q (type 0) or c + (h/2)(±1, ±1) (type 1, h ≥ 2),
//    4 for interior diamonds.
//
// The finest level cuts every unit square by the diagonal from its all-even to its all-odd
// corner. tests/core/hierarchy2d_test.cpp checks all of this against brute-force bisection.
#pragma once

#include <array>
#include <bit>
#include <cstdint>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso {

/// Integer coordinates of a vertex of the 2D hierarchy grid: x = column, y = row.
using ipoint2 = std::array<std::int32_t, 2>;

/// Key of grid edge (a, b): its doubled midpoint packed x | y << 32. Unique among all edges of
/// all bisection meshes (as in 3D: coarse edges are spines, finest edges have half-integer
/// midpoints and one diagonal per unit square).
[[nodiscard]] constexpr std::uint64_t edge_key2(const ipoint2& a, const ipoint2& b) noexcept {
  return static_cast<std::uint64_t>(static_cast<std::uint32_t>(a[0] + b[0])) |
         (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a[1] + b[1])) << 32);
}
/// The doubled midpoint encoded in an edge key.
[[nodiscard]] constexpr ipoint2 edge_key2_point(std::uint64_t key) noexcept {
  return {static_cast<std::int32_t>(key & 0xFFFFFFFFu), static_cast<std::int32_t>(key >> 32)};
}
/// Canonical vertex order: row first, then column.
[[nodiscard]] constexpr bool vertex_less2(const ipoint2& a, const ipoint2& b) noexcept {
  return a[1] != b[1] ? a[1] < b[1] : a[0] < b[0];
}

/// What the centre of a 2D diamond determines.
struct diamond2 {
  ipoint2 centre{};
  std::int32_t scale = 0;
  int type = 0;  ///< 0 square centre, 1 edge midpoint
  int depth = 0;
  std::array<ipoint2, 2> spine{};  ///< c − h s, c + h s
  std::array<ipoint2, 2> ring{};   ///< apex of each triangle
  std::uint8_t ring_in_grid = 0;   ///< bit m set when ring[m] is a grid vertex
};

/// The forest of root squares covering an image, and diamond arithmetic on it.
class hierarchy2d {
 public:
  /// Hierarchy for an image of width × height samples (each ≥ 2, ≤ 2^20 + 1).
  hierarchy2d(std::int64_t width, std::int64_t height);

  [[nodiscard]] int levels() const noexcept { return levels_; }
  [[nodiscard]] std::int32_t root_size() const noexcept { return root_; }
  [[nodiscard]] const ipoint2& squares() const noexcept { return squares_; }
  [[nodiscard]] const ipoint2& grid_max() const noexcept { return grid_max_; }
  [[nodiscard]] const ipoint2& data_max() const noexcept { return data_max_; }
  [[nodiscard]] std::uint64_t vertex_count() const noexcept { return vertex_count_; }
  [[nodiscard]] int max_depth() const noexcept { return 2 * (levels_ - 1) + 1; }

  [[nodiscard]] bool in_grid(const ipoint2& p) const noexcept {
    return p[0] >= 0 && p[1] >= 0 && p[0] <= grid_max_[0] && p[1] <= grid_max_[1];
  }
  [[nodiscard]] std::uint64_t index(const ipoint2& p) const noexcept {
    return static_cast<std::uint64_t>(p[0]) + stride_ * static_cast<std::uint64_t>(p[1]);
  }
  /// The grid vertex of a linear index (the inverse of index()).
  [[nodiscard]] ipoint2 point(std::uint64_t index) const noexcept {
    const std::uint64_t y = index / stride_;
    return {static_cast<std::int32_t>(index - y * stride_), static_cast<std::int32_t>(y)};
  }
  [[nodiscard]] bool is_diamond(const ipoint2& p) const noexcept;
  [[nodiscard]] std::int32_t scale_of(const ipoint2& p) const noexcept;
  [[nodiscard]] int depth_of(const ipoint2& p) const noexcept;
  /// Precondition: is_diamond(c).
  [[nodiscard]] diamond2 make_diamond(const ipoint2& c) const noexcept;
  int parents(const diamond2& d, std::array<ipoint2, 2>& out) const noexcept;
  [[nodiscard]] int parent_count(const ipoint2& c) const noexcept;
  int children(const diamond2& d, std::array<ipoint2, 4>& out) const noexcept;

  [[nodiscard]] std::uint64_t root_count() const noexcept {
    return static_cast<std::uint64_t>(squares_[0]) * static_cast<std::uint64_t>(squares_[1]);
  }
  /// The two triangles of root square r (row-major), each (spine0, spine1, apex).
  void root_triangles(std::uint64_t r, std::array<std::array<ipoint2, 3>, 2>& out) const noexcept;
  /// Centre of root square r.
  [[nodiscard]] ipoint2 root_centre(std::uint64_t r) const noexcept;

  /// The two ends of the grid edge with this key, canonical order.
  [[nodiscard]] std::array<ipoint2, 2> edge_ends(std::uint64_t key) const noexcept;

  /// True when the diamond's region lies wholly beyond the data box.
  [[nodiscard]] bool outside_data(const ipoint2& c, std::int32_t h) const noexcept {
    return c[0] - h >= data_max_[0] || c[1] - h >= data_max_[1];
  }

 private:
  int levels_ = 0;
  std::int32_t root_ = 1;
  ipoint2 squares_{};
  ipoint2 grid_max_{};
  ipoint2 data_max_{};
  std::uint64_t stride_ = 0;
  std::uint64_t vertex_count_ = 0;
};

// Inline: the refiners make a diamond per split.
inline std::int32_t hierarchy2d::scale_of(const ipoint2& p) const noexcept {
  // min(tz(x), tz(y)) = tz(x | y); 0 (both zero) has 32 trailing zeros, capped like the others.
  return std::int32_t{1} << std::min(
             std::countr_zero(static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1])),
             levels_);
}

inline bool hierarchy2d::is_diamond(const ipoint2& p) const noexcept {
  return in_grid(p) && scale_of(p) < root_;
}

inline diamond2 hierarchy2d::make_diamond(const ipoint2& c) const noexcept {
  PROGISO_ASSERT(is_diamond(c));
  diamond2 d;
  d.centre = c;
  const int lg = std::countr_zero(static_cast<std::uint32_t>(scale_of(c)));
  const std::int32_t h = std::int32_t{1} << lg;
  d.scale = h;
  // On an odd axis (c_q / h odd) the spine steps +1 when (c_q + h) mod 4h = 0, else −1.
  const bool odd_x = ((c[0] >> lg) & 1) != 0;
  const bool odd_y = ((c[1] >> lg) & 1) != 0;
  const std::int32_t sx = odd_x ? (((c[0] + h) & (4 * h - 1)) == 0 ? 1 : -1) : 0;
  const std::int32_t sy = odd_y ? (((c[1] + h) & (4 * h - 1)) == 0 ? 1 : -1) : 0;
  d.type = 2 - (odd_x ? 1 : 0) - (odd_y ? 1 : 0);
  d.depth = 2 * (levels_ - 1 - lg) + d.type;
  d.spine[0] = {c[0] - h * sx, c[1] - h * sy};
  d.spine[1] = {c[0] + h * sx, c[1] + h * sy};
  if (d.type == 0) {
    // The square's other two corners.
    d.ring[0] = {c[0] + h * sx, c[1] - h * sy};
    d.ring[1] = {c[0] - h * sx, c[1] + h * sy};
  } else if (odd_x) {
    // Across the axis edge: the centres of the two squares that share it.
    d.ring[0] = {c[0], c[1] + h};
    d.ring[1] = {c[0], c[1] - h};
  } else {
    d.ring[0] = {c[0] + h, c[1]};
    d.ring[1] = {c[0] - h, c[1]};
  }
  d.ring_in_grid =
      static_cast<std::uint8_t>((in_grid(d.ring[0]) ? 1u : 0u) | (in_grid(d.ring[1]) ? 2u : 0u));
  return d;
}

}  // namespace progiso
