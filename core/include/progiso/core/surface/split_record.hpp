// progiso/core/surface/split_record.hpp — what splitting one diamond does to the surface (paper
// §4).
//
// Splitting diamond D bisects its spine (c, d) at its centre e and replaces each of its k
// tetrahedra (c, d, a, b) by (c, e, a, b) and (e, d, a, b). The surface changes only inside D:
// the pieces in D's tetrahedra are replaced by the pieces in the 2k children tetrahedra, each of
// which belongs to one child diamond (the diamond centred at the midpoint of its longest edge)
// or to none at the finest level. A split record lists those new pieces, each tagged with the
// owning child, and classifies the split:
//
//  * per tetrahedron, the paper's case (Figure 7–9): 1 when c and d differ in colour and a, b
//    agree; 2 when c, d differ and a, b differ; 3/4/5 when c and d agree and a, b both share
//    their colour / both oppose it / differ; suffix b when e has c's colour (1: e has a's
//    colour), c otherwise. Cases 2b and 2c differ by whether e takes c's colour (2b) or d's.
//  * the primitives it amounts to (§4.2), counted per diamond with these rules:
//    - c ≠ d: one VertexMove (the spine's surface vertex moves to c-e or e-d);
//    - c ≠ d, or c = d = e: one VertexSplit per ring vertex a whose new edge a-e is crossed,
//      or VertexOpen when facet (a, c, d) is on the grid boundary (one triangle, not two);
//    - c = d ≠ e: all tetrahedra 3a → NewLoop (closed ring) or NewSurf (open ring); all 4a →
//      CylinderFlip; otherwise per component {5a 4a^h 5'a 3a^l} one VertexSplit for the new
//      spine vertex pair, one VertexSplit/VertexOpen per crossed edge a-e and one EdgeFlip per
//      4a tetrahedron, plus one ConnectivityChange per component beyond the first.
//
// compute_split() is a pure function of (diamond, field, isovalue): records can be computed in
// any order and in parallel; only their publication must follow parent-before-child order.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {

/// The paper's per-tetrahedron cases, after the split.
enum class tet_case : std::uint8_t { c1b, c1c, c2b, c2c, c3b, c3c, c4b, c4c, c5b, c5c };
inline constexpr std::size_t tet_case_count = 10;
[[nodiscard]] std::string_view to_string(tet_case c) noexcept;

/// The paper's refinement primitives (§4.2).
enum class primitive : std::uint8_t {
  vertex_move,
  vertex_split,
  vertex_open,
  edge_flip,
  new_loop,
  new_surf,
  cylinder_flip,
  connectivity_change
};
inline constexpr std::size_t primitive_count = 8;
[[nodiscard]] std::string_view to_string(primitive p) noexcept;

/// The global configuration of a split around its spine (paper §4.3–4.5).
enum class split_configuration : std::uint8_t {
  spine_crossed,       ///< c ≠ d (§4.3)
  no_new_crossing,     ///< c = d = e (§4.4)
  empty_region,        ///< c = d ≠ e, all 3a
  cylinder,            ///< c = d ≠ e, all 4a
  single_component,    ///< c = d ≠ e, one {5a 4a^h 5'a 3a^l}
  multiple_components  ///< c = d ≠ e, several
};
inline constexpr std::size_t split_configuration_count = 6;
[[nodiscard]] std::string_view to_string(split_configuration c) noexcept;

/// Owner value of a triangle in a finest tetrahedron (no diamond ever splits it).
inline constexpr std::uint64_t no_owner = ~std::uint64_t{0};

/// A surface triangle (three edge keys, oriented) in a tetrahedron owned by diamond `owner`
/// (grid index of its centre). It is part of every cut in which the owner is not split.
/// Trivial on purpose: the refiner allocates record storage in large chunks without
/// initialising it.
struct owned_triangle {
  std::uint64_t owner;
  std::array<std::uint64_t, 3> keys;
};

/// The surface pieces of one child tetrahedron in compact form, for stores that keep millions of
/// records (the sequential refiner and the engine). Every point of a diamond with centre c and
/// scale h lies in c + h·{-1, 0, 1}³, so the doubled midpoint of any edge between two of them (its
/// edge key) is 2c + h·o with o in {-2..2}³: one byte, (o0 + 2) + 5 (o1 + 2) + 25 (o2 + 2). The
/// owner (as in owned_triangle) is the diamond centred at the midpoint of the child's longest
/// edge, c + (h/2)·o: the same code, in the top byte, or no_owner_code for a finest child (and
/// for an owner beyond the grid). One word for one or two triangles, against 32 bytes per
/// owned_triangle; unpack() gives back the edge keys and group_owner() the owner's grid index (h
/// is a power of two, so packing needs no division).
///
/// One word, written whole: a group is copied right after it is made, and a copy that reads what
/// narrower stores just wrote waits for them to retire (failed store-to-load forwarding).
struct packed_group {
  std::uint64_t bits;  ///< byte 0: triangles (1 or 2); byte 1 + 3k + v: edge code of vertex v
                       ///< of triangle k; byte 7: the owner's code
  static constexpr unsigned no_owner_code = 0xFFu;

  [[nodiscard]] std::size_t count() const noexcept { return bits & 0xFFu; }
  [[nodiscard]] unsigned edge(std::size_t k, std::size_t v) const noexcept {
    return static_cast<unsigned>(bits >> (8 * (1 + 3 * k + v))) & 0xFFu;
  }
  [[nodiscard]] unsigned owner_code() const noexcept { return static_cast<unsigned>(bits >> 56); }
};

/// The grid index of g's owner (no_owner for none); g was made by the split of the diamond
/// whose centre has grid index `diamond`, with scale `scale`.
[[nodiscard]] inline std::uint64_t group_owner(const hierarchy& hier, std::uint64_t diamond,
                                               std::int32_t scale, const packed_group& g) noexcept {
  const unsigned code = g.owner_code();
  if (code == packed_group::no_owner_code) return no_owner;
  return hier.half_offset_index(diamond, scale, code);
}

/// Edge keys of triangle k of g, made by the split of the diamond whose doubled centre has the
/// edge key `centre_key` (edge_key(c, c)), with this scale.
[[nodiscard]] inline std::array<std::uint64_t, 3> unpack_at(std::uint64_t centre_key,
                                                            std::int32_t scale,
                                                            const packed_group& g,
                                                            std::size_t k) noexcept {
  // A key packs the doubled midpoint 2c + h·o field by field, and no field leaves its range, so
  // the key is the number key(2c) + h · Σ o_q 2^(21 q): one table entry per code, o in {-2..2}³.
  static constexpr auto deltas = [] {
    std::array<std::int64_t, 125> t{};
    for (unsigned e = 0; e < 125; ++e) {
      const std::array<int, 3> o = half_offset_of(e);
      std::int64_t d = 0;
      for (std::size_t q = 0; q < 3; ++q) d += o[q] * (std::int64_t{1} << (q * edge_key_bits));
      t[e] = d;
    }
    return t;
  }();
  std::array<std::uint64_t, 3> keys{};
  for (std::size_t v = 0; v < 3; ++v) {
    keys[v] = centre_key + static_cast<std::uint64_t>(scale * deltas[g.edge(k, v)]);
  }
  return keys;
}

/// The same for the diamond with this centre.
[[nodiscard]] inline std::array<std::uint64_t, 3> unpack(const ipoint& centre, std::int32_t scale,
                                                         const packed_group& g,
                                                         std::size_t k) noexcept {
  return unpack_at(edge_key(centre, centre), scale, g, k);
}

/// Calls f(owner, edge keys) for every triangle of groups[first, first + count) whose owner
/// passes take(owner); the groups were made by the split of the diamond centred at grid vertex
/// `diamond` (an index), with scale `scale`. The centre is computed only when some group is
/// taken.
template <class Groups, class Take, class F>
void for_each_unpacked(const hierarchy& hier, std::uint64_t diamond, std::int32_t scale,
                       const Groups& groups, std::uint64_t first, std::uint64_t count, Take&& take,
                       F&& f) {
  std::uint64_t centre_key = 0;
  bool have_centre = false;
  for (std::uint64_t i = first; i < first + count; ++i) {
    const packed_group& g = groups[i];
    const std::uint64_t owner = group_owner(hier, diamond, scale, g);
    if (!take(owner)) continue;
    if (!have_centre) {
      const ipoint c = hier.point(diamond);
      centre_key = edge_key(c, c);
      have_centre = true;
    }
    for (std::size_t t = 0; t < g.count(); ++t) f(owner, unpack_at(centre_key, scale, g, t));
  }
}

/// Classification of one split.
struct split_summary {
  int tets = 0;               ///< tetrahedra of the diamond inside the grid
  int removed_triangles = 0;  ///< surface triangles in those tetrahedra before the split
  int added_triangles = 0;    ///< in the 2 * tets children
  split_configuration configuration = split_configuration::no_new_crossing;
  std::array<std::uint8_t, tet_case_count> cases{};
  std::array<std::uint16_t, primitive_count> primitives{};
  /// ≥ 0 for a diamond wholly in the grid: the index of its classification (every field above
  /// but added_triangles) in interior_classification(); -1 otherwise.
  std::int16_t classification = -1;
  /// The new edges (centre, centre + h·o) whose ends differ in colour: bit
  /// edge_offset_code(o) each. Set by the packed compute_split() only (not part of the
  /// classification above).
  std::uint32_t crossed = 0;
};

/// Code of an offset o in {-1, 0, 1}³ (a point of a diamond relative to its centre, in units of
/// its scale): (o0 + 1) + 3 (o1 + 1) + 9 (o2 + 1), in [0, 27); 13 is the centre itself.
[[nodiscard]] constexpr unsigned edge_offset_code(const std::array<int, 3>& o) noexcept {
  return static_cast<unsigned>((o[0] + 1) + 3 * (o[1] + 1) + 9 * (o[2] + 1));
}
inline constexpr unsigned centre_offset_code = 13;

/// The two ends of every edge a packed group of one diamond can name: entry k (a group's edge
/// code, see packed_group) holds the edge_offset_code() of both ends, or {centre_offset_code,
/// centre_offset_code} for a code no edge of the diamond has. When one end is the centre it
/// comes first. The table depends only on the diamond's shape.
using group_edge_table = std::array<std::array<std::uint8_t, 2>, 125>;
/// The table for the diamond centred at c with scale h.
[[nodiscard]] const group_edge_table& group_edges(const ipoint& c, std::int32_t h) noexcept;

/// Number of classifications of diamonds wholly in the grid: one per ring size (4, 6, 8) and
/// colouring of the spine ends, centre and ring.
inline constexpr std::size_t interior_classification_count = (8u << 4) + (8u << 6) + (8u << 8);
/// Classification i (split_summary::classification); its added_triangles is 0.
[[nodiscard]] const split_summary& interior_classification(std::size_t i) noexcept;

/// Computes the split record of diamond d at isovalue w: appends the new triangles to `out`
/// and returns the classification. Pure: depends only on (d, the field, w).
split_summary compute_split(const hierarchy& hier, const volume& vol, double isovalue,
                            const diamond& d, std::vector<owned_triangle>& out);

/// compute_split() with the new pieces appended in compact form, one group per child
/// tetrahedron with surface; the same triangles in the same order. Table-driven: the surface of
/// each child for each colouring of its corners is looked up, not marched (see split_record.cpp).
split_summary compute_split(const hierarchy& hier, const volume& vol, double isovalue,
                            const diamond& d, std::vector<packed_group>& out);
/// The same for the diamond centred at `centre` (a diamond::centre), without the diamond.
split_summary compute_split(const hierarchy& hier, const volume& vol, double isovalue,
                            const ipoint& centre, std::vector<packed_group>& out);
/// The same when the diamond's scale is known (hierarchy::scale_of(centre)).
split_summary compute_split(const hierarchy& hier, const volume& vol, double isovalue,
                            const ipoint& centre, std::int32_t scale,
                            std::vector<packed_group>& out);

/// The surface in the six tetrahedra of root cube r (hierarchy::root_tets), appended to `out`,
/// each piece owned by the root diamond. Returns that diamond's centre, or nullopt when the
/// root cube is a single cell (root_size 1: no diamond, pieces owned by no_owner). Pure.
std::optional<ipoint> compute_root(const hierarchy& hier, const volume& vol, double isovalue,
                                   std::uint64_t r, std::vector<owned_triangle>& out);

}  // namespace progiso
