// progiso/core/hierarchy/hierarchy.hpp — the implicit 3D longest-edge-bisection (diamond)
// hierarchy.
//
// The grid of a volume is embedded in a forest of root cubes of side N = 2^L (paper §4;
// docs/ARCHITECTURE.md, "The hierarchy"). Every grid vertex that is not a root-cube corner is the
// centre of exactly one diamond: the tetrahedra that share the diamond's spine and are bisected
// together. Everything about a diamond follows from its centre c by integer arithmetic, nothing is
// stored:
//
//  * scale h = 2^min(tz(c_q)) with tz capped at L; odd axes are those where c_q / h is odd;
//    type = 3 - #odd axes (0: cube centre, 1: face centre, 2: edge midpoint).
//  * spine = c ± h s with s_q = 0 on even axes and, on odd axes, +1 if (c_q + h) mod 4h = 0,
//    else -1. Ring vertices surround the spine in cyclic order (6, 4 or 8 of them); tetrahedron
//    m of the diamond is (spine0, spine1, ring[m], ring[m+1]) when both ring vertices exist.
//  * parents are the ring vertices one level coarser; children are c ± h e_q (type 0, all
//    axes; type 1, odd axes) or c + (h/2)(±1, ±1, ±1) (type 2, h ≥ 2).
//
// With several root cubes the hierarchy is the restriction of one infinite hierarchy whose root
// cubes alternate by reflection, so the forest is conforming across cube faces and its finest
// level is still the reflected-Kuhn mesh: every unit cube cut into 6 tetrahedra around the
// diagonal from its all-even to its all-odd corner. The tests check all of this against a
// brute-force bisection.
//
// Choice of N: the largest power of two ≤ min(dims) - 1 whose padded grid (the data box rounded
// up to whole root cubes) has at most 1.25 times the vertices of the tightest padded grid with
// roots of side 8 or more. Padding vertices take the value of the nearest data vertex. For
// 2^L + 1 samples per axis this is N = 2^L with no padding; for 68³ samples it is N = 8 (a 72³
// grid) rather than N = 64 (a 128³ grid: several times the vertices, all of them refinement state
// and boundary diamonds). Roots below 8 are not chosen (unless the volume is smaller): the
// coarsest cut would then be nearly the finest.
#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <utility>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {

/// The code of an offset o in {-2..2}³, (o0 + 2) + 5 (o1 + 2) + 25 (o2 + 2), in [0, 125): a
/// doubled point 2c + h·o of a diamond (an edge key's, split_record.hpp's packed groups) or the
/// point c + (h/2)·o (hierarchy::half_offset_index).
[[nodiscard]] constexpr unsigned half_offset_code(int o0, int o1, int o2) noexcept {
  return static_cast<unsigned>((o0 + 2) + 5 * (o1 + 2) + 25 * (o2 + 2));
}
/// The offset of a half_offset_code().
[[nodiscard]] constexpr std::array<int, 3> half_offset_of(unsigned code) noexcept {
  return {static_cast<int>(code % 5) - 2, static_cast<int>(code / 5 % 5) - 2,
          static_cast<int>(code / 25) - 2};
}

/// The six tetrahedra of the cube with lowest corner `lowest` and edge `size` (each coordinate
/// of `lowest` a multiple of `size`), as longest-edge bisection leaves them: around the diagonal
/// from the cube's corner whose coordinates are even multiples of `size` to the opposite
/// corner, each tetrahedron that corner and one step of `size` towards the other along each
/// axis in turn, the six orders of the axes (x y z, x z y, y x z, y z x, z x y, z y x) giving
/// the six. Neighbouring cubes reflect the pattern, so their faces' diagonals agree. The root
/// cubes of a hierarchy (size N) and the unit cubes of the finest mesh (size 1).
[[nodiscard]] constexpr std::array<std::array<ipoint, 4>, 6> cube_tetrahedra(
    const ipoint& lowest, std::int32_t size) noexcept {
  constexpr int orders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  ipoint from{};
  ipoint step{};
  for (std::size_t a = 0; a < 3; ++a) {
    const bool even = ((lowest[a] / size) & 1) == 0;
    from[a] = even ? lowest[a] : lowest[a] + size;
    step[a] = even ? size : -size;
  }
  std::array<std::array<ipoint, 4>, 6> out{};
  for (std::size_t t = 0; t < 6; ++t) {
    ipoint p = from;
    out[t][0] = p;
    for (std::size_t k = 0; k < 3; ++k) {
      const auto a = static_cast<std::size_t>(orders[t][k]);
      p[a] += step[a];
      out[t][k + 1] = p;
    }
  }
  return out;
}

/// What the centre of a diamond determines.
struct diamond {
  ipoint centre{};
  std::int32_t scale = 0;         ///< h
  int type = 0;                   ///< 0 cube centre, 1 face centre, 2 edge midpoint
  int depth = 0;                  ///< 0 for roots; parents have depth - 1
  std::array<ipoint, 2> spine{};  ///< c - h s, c + h s
  int ring_size = 0;              ///< 6, 4 or 8 (before clipping to the grid)
  std::array<ipoint, 8> ring;     ///< cyclic; entries past ring_size are unspecified
  std::uint8_t ring_in_grid = 0;  ///< bit m set when ring[m] is a grid vertex
};

/// The children of one diamond, with what a refinement needs to know about each.
struct child_list {
  int count = 0;
  std::int32_t scale = 0;               ///< the children's h (the same for all of them)
  int type = 0;                         ///< the children's type (the same for all of them)
  std::array<ipoint, 8> centre;         ///< first `count` entries
  std::array<std::uint8_t, 8> parents;  ///< parent_count(centre[i])
};

/// The forest of root cubes covering a volume's grid, and diamond arithmetic on it.
class hierarchy {
 public:
  /// Hierarchy for a volume with the given dims (each ≥ 2).
  explicit hierarchy(const index3& data_dims);

  [[nodiscard]] int levels() const noexcept { return levels_; }            ///< L
  [[nodiscard]] std::int32_t root_size() const noexcept { return root_; }  ///< N = 2^L
  [[nodiscard]] const ipoint& cubes() const noexcept { return cubes_; }    ///< root cubes per axis
  [[nodiscard]] const ipoint& grid_max() const noexcept { return grid_max_; }  ///< cubes * N
  [[nodiscard]] const ipoint& data_max() const noexcept { return data_max_; }  ///< dims - 1
  [[nodiscard]] std::uint64_t vertex_count() const noexcept { return vertex_count_; }
  /// Deepest depth a diamond can have (type 2 at h = 1), or -1 when N = 1.
  [[nodiscard]] int max_depth() const noexcept { return 3 * (levels_ - 1) + 2; }

  [[nodiscard]] bool in_grid(const ipoint& p) const noexcept {
    return p[0] >= 0 && p[1] >= 0 && p[2] >= 0 && p[0] <= grid_max_[0] && p[1] <= grid_max_[1] &&
           p[2] <= grid_max_[2];
  }
  /// Linear index of a grid vertex, x fastest.
  [[nodiscard]] std::uint64_t index(const ipoint& p) const noexcept {
    return static_cast<std::uint64_t>(p[0]) + stride_y_ * static_cast<std::uint64_t>(p[1]) +
           stride_z_ * static_cast<std::uint64_t>(p[2]);
  }
  /// The grid index of c + (h/2)·o from c's grid index, for o of half_offset_code `code` (a
  /// packed group's owner, split_record.hpp). Precondition: the point is a grid vertex (h·o
  /// even on every axis).
  [[nodiscard]] std::uint64_t half_offset_index(std::uint64_t index, std::int32_t h,
                                                unsigned code) const noexcept {
    return index + static_cast<std::uint64_t>(std::int64_t{h} * doubled_offset_[code] / 2);
  }
  /// The grid vertex of a linear index (the inverse of index()): two divisions by reciprocal
  /// multiplication, corrected to the exact quotient (a hot path of the refiners, inlined always:
  /// out of line, its call costs as much as its work).
  [[nodiscard]] [[gnu::always_inline]] inline ipoint point(std::uint64_t index) const noexcept {
    const std::uint64_t z = divide(index, stride_z_, inverse_z_);
    const std::uint64_t r = index - z * stride_z_;
    const std::uint64_t y = divide(r, stride_y_, inverse_y_);
    return {static_cast<std::int32_t>(r - y * stride_y_), static_cast<std::int32_t>(y),
            static_cast<std::int32_t>(z)};
  }

  /// True when p is a grid vertex that is the centre of a diamond (not a root-cube corner).
  [[nodiscard]] bool is_diamond(const ipoint& p) const noexcept;
  /// Scale of a centre: 2^min(tz), tz capped at L (the cap as a set bit: the min of the
  /// coordinates' trailing zeros and L is the trailing zeros of their union with 2^L). Inline:
  /// the refiners ask it per split and per child.
  [[nodiscard]] std::int32_t scale_of(const ipoint& p) const noexcept {
    const std::uint32_t bits = static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) |
                               static_cast<std::uint32_t>(p[2]) | (std::uint32_t{1} << levels_);
    return std::int32_t{1} << std::countr_zero(bits);
  }
  /// Depth of a diamond centre (see diamond::depth). Inline: a full run on one thread asks it
  /// per split.
  [[nodiscard]] int depth_of(const ipoint& p) const noexcept {
    const int lg = std::countr_zero(static_cast<std::uint32_t>(scale_of(p)));
    const int odd = static_cast<int>(((p[0] >> lg) & 1) + ((p[1] >> lg) & 1) + ((p[2] >> lg) & 1));
    return 3 * (levels_ - 1 - lg) + (3 - odd);
  }
  /// Everything about the diamond centred at c. Precondition: is_diamond(c).
  [[nodiscard]] diamond make_diamond(const ipoint& c) const noexcept;

  /// Parents that are grid vertices; returns how many were written.
  int parents(const diamond& d, std::array<ipoint, 4>& out) const noexcept;
  /// Number of parents that are grid vertices, without building the diamond.
  [[nodiscard]] int parent_count(const ipoint& c) const noexcept;
  /// Children that are grid vertices; returns how many were written.
  int children(const diamond& d, std::array<ipoint, 8>& out) const noexcept;
  /// The same for the diamond centred at c (a diamond centre), without building the diamond.
  int children(const ipoint& c, std::array<ipoint, 8>& out) const noexcept;
  /// Children (same order as children()) and their parent counts, for the diamond centred at c
  /// whose scale is h and type is `type` (as scale_of and make_diamond give them): what
  /// children() and parent_count() give, in one pass, from facts known at the parent.
  [[nodiscard]] child_list children_of(const ipoint& c, std::int32_t h, int type) const noexcept;
  /// Type of the diamond centred at c, whose scale is h (diamond::type, without the diamond):
  /// 3 minus the number of axes odd at scale h.
  [[nodiscard]] static int type_of(const ipoint& c, std::int32_t h) noexcept {
    const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
    return 3 - static_cast<int>(((c[0] >> lg) & 1) + ((c[1] >> lg) & 1) + ((c[2] >> lg) & 1));
  }

  /// Root cubes' centres (the root diamonds when N ≥ 2), and their 6 tetrahedra each.
  [[nodiscard]] std::uint64_t root_count() const noexcept {
    return static_cast<std::uint64_t>(cubes_[0]) * static_cast<std::uint64_t>(cubes_[1]) *
           static_cast<std::uint64_t>(cubes_[2]);
  }
  /// Minimum corner of root cube r and its 6 tetrahedra (around the reflected diagonal).
  void root_tets(std::uint64_t r, std::array<std::array<ipoint, 4>, 6>& out) const noexcept;

  /// The two ends of the grid edge with the given edge key (canonical order: lower first).
  [[nodiscard]] std::array<ipoint, 2> edge_ends(std::uint64_t key) const noexcept {
    const ipoint d2 = edge_key_point(key);
    const int odd = (d2[0] & 1) + (d2[1] & 1) + (d2[2] & 1);
    if (odd == 0) return spine_ends(d2);  // the spine of the diamond centred at d2 / 2
    // A finest edge: along one axis, or the diagonal of a unit square or cube that joins the
    // corner even on the edge's axes to the corner odd on them.
    std::array<ipoint, 2> e{};
    for (std::size_t q = 0; q < 3; ++q) {
      const std::int32_t lo = d2[q] >> 1;
      const bool flip = (d2[q] & 1) != 0 && odd > 1 && (lo & 1) != 0;
      e[0][q] = lo + (flip ? 1 : 0);
      e[1][q] = lo + ((d2[q] & 1) != 0 && !flip ? 1 : 0);
    }
    if (vertex_less(e[1], e[0])) std::swap(e[0], e[1]);
    return e;
  }

  /// True when the region of the diamond lies wholly in the padding outside the data box
  /// (its pieces of surface would all be clipped away).
  [[nodiscard]] bool outside_data(const ipoint& c, std::int32_t h) const noexcept {
    return c[0] - h >= data_max_[0] || c[1] - h >= data_max_[1] || c[2] - h >= data_max_[2];
  }

 private:
  std::array<ipoint, 2> spine_ends(const ipoint& d2) const noexcept;
  static constexpr int min_root_levels = 3;          // roots of side 8 or more
  static constexpr double max_padding_ratio = 1.25;  // see "Choice of N" above
  static int choose_levels(const ipoint& data_max, std::int64_t min_extent) noexcept;
  int children_at(const ipoint& c, std::int32_t h, int type,
                  std::array<ipoint, 8>& out) const noexcept;

  int levels_ = 0;
  std::int32_t root_ = 1;
  ipoint cubes_{};
  ipoint grid_max_{};
  ipoint data_max_{};
  std::uint64_t stride_y_ = 0;
  std::uint64_t stride_z_ = 0;
  double inverse_y_ = 0.0;  // 1 / stride_y_
  double inverse_z_ = 0.0;  // 1 / stride_z_
  // Per code of half_offset_index(): o0 + o1 stride_y + o2 stride_z, twice the index offset of
  // (h/2)·o at h = 1.
  std::array<std::int64_t, 125> doubled_offset_{};
  std::uint64_t vertex_count_ = 0;

  // floor(i / d) from a product with inv ≈ 1/d: exact for i < 2^53 (the double quotient is
  // within 2^-20 of the true one for quotients below 2^32, so one step up or down corrects it).
  static std::uint64_t divide(std::uint64_t i, std::uint64_t d, double inv) noexcept {
    auto q = static_cast<std::uint64_t>(static_cast<double>(i) * inv);
    if (q * d > i) {
      --q;
    } else if ((q + 1) * d <= i) {
      ++q;
    }
    return q;
  }
};

}  // namespace progiso
