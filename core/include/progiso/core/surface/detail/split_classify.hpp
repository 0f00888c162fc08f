// progiso/core/surface/detail/split_classify.hpp — the part of a split summary that the colours of
// the diamond's points decide (paper §4; the rules are in split_record.hpp): tetrahedra, removed
// triangles, the case of every tetrahedron, the configuration and the primitives.
//
// Ring quantities are bit sets over ring positions (bit m: ring[m]), so the rules become a few
// popcounts instead of a loop with a data-dependent branch per tetrahedron. Shared by both split
// paths of split_record.cpp.
#pragma once

#include <progiso/core/surface/split_record.hpp>

namespace progiso::detail {

/// Colours (value > isovalue) of a diamond's points.
struct split_colours {
  bool c = false;             ///< spine end c (diamond::spine[0])
  bool d = false;             ///< spine end d (diamond::spine[1])
  bool e = false;             ///< the centre
  unsigned ring = 0;          ///< bit m: ring[m] (only bits of ring_in_grid count)
  unsigned ring_in_grid = 0;  ///< bit m: ring[m] is a grid vertex
  int n = 0;                  ///< ring size (4, 6 or 8)

  /// Tetrahedron (c, d, ring[m], ring[m + 1]) lies in the grid.
  [[nodiscard]] bool tet_exists(int m) const noexcept {
    const int m1 = (m + 1 == n ? 0 : m + 1);
    return ((ring_in_grid >> m) & 1u) && ((ring_in_grid >> m1) & 1u);
  }
};

/// Fills tets, removed_triangles, cases, configuration and primitives of s (added_triangles is
/// left alone: it needs the children's surface).
void classify(const split_colours& k, split_summary& s) noexcept;

}  // namespace progiso::detail
