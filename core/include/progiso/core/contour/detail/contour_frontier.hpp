// progiso/core/contour/detail/contour_frontier.hpp — what the sequential contour refiner
// (contour_refiner.hpp) and the contour engine (progiso/scheduler/contour_engine.hpp) share, so
// that both make the same records in the same way: the root contour, the per-vertex state that
// makes a diamond ready once all its parents are split, the readiness rule, the placement of
// contour vertices and the assembly of a cut's live segments into polylines.
//
// Not a public API: its layout may change with the two users.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/base/zeroed_array.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/contour/contour_split.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/contour/range_data2d.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::detail {

/// Owner of a segment of a finest triangle, and the diamond of the root record.
inline constexpr std::uint64_t no_owner2 = ~std::uint64_t{0};

/// A recorded segment with its two end positions (pixel units), placed when the record that
/// creates it is made: extraction then needs neither the image nor the range data.
struct placed_segment {
  owned_segment seg;
  std::array<vec2, 2> pos;
};

/// A diamond whose parents are all split and whose range straddles the isovalue: its nested
/// error and centre, 16 bytes (the grid index is hierarchy2d::index(centre), a multiply-add,
/// where the centre from the index would be a 64-bit division on every split's critical path).
/// A full refinement's breadth-first queue holds a whole level of them.
struct contour_ready {
  double error;
  ipoint2 centre;
};

/// The contour vertex on the grid edge with this key (edge_key2), pixel units.
[[nodiscard]] vec2 place_contour_vertex(const hierarchy2d& hier, const volume& image,
                                        double isovalue, std::uint64_t key) noexcept;

/// compute_contour_split() with each new segment's vertices placed: appended to `out` with the
/// positions place_contour_vertex() gives their keys (interpolate2 of the crossed edge's ends in
/// canonical order), from the samples the split has read already. The summary's primitives
/// carry their kinds only (their keys are no_key): what the refiners count.
contour_split_summary compute_placed_contour_split(const hierarchy2d& hier, const volume& image,
                                                   double isovalue, const diamond2& d,
                                                   std::vector<placed_segment>& out);
/// The same, written to out[0 .. added_segments) (room for max_split_segments).
contour_split_summary compute_placed_contour_split(const hierarchy2d& hier, const volume& image,
                                                   double isovalue, const diamond2& d,
                                                   placed_segment* out);
/// The most segments a split adds: one per new triangle.
inline constexpr std::size_t max_split_segments = 4;

/// The root cut: appends the placed segments of the root triangles to `segments` and the
/// centres of the root diamonds (roots of size ≥ 2) to `roots`. Reads 4 samples per root
/// square: no pass over the image beyond them.
void root_contour(const hierarchy2d& hier, const volume& image, double isovalue,
                  std::vector<placed_segment>& segments, std::vector<ipoint2>& roots);

/// The readiness rule: the diamond centred at c (parents all split) is queued by its nested
/// error when its range straddles the isovalue, and culled (nothing) otherwise.
[[nodiscard]] inline std::optional<contour_ready> ready_contour_diamond(
    const range_data2d& ranges, double isovalue, const ipoint2& c, std::int32_t scale) noexcept {
  const diamond_range r = ranges.get(c, scale);
  if (!r.straddles(isovalue)) return std::nullopt;
  return contour_ready{r.error, c};
}

/// Per grid vertex: whether the diamond is split and how many of its parents are.
class contour_frontier {
 public:
  explicit contour_frontier(const hierarchy2d& hier) : hier_(&hier), state_(hier.vertex_count()) {}

  [[nodiscard]] bool is_split(std::uint64_t index) const noexcept {
    return (state_.get()[index] & split_bit) != 0;
  }
  /// Marks diamond d (grid index `index`) split and calls ready(child centre, child scale) for
  /// each child whose parents are now all split, in hierarchy2d::children()'s order.
  /// Returns d's child count. The children's scales and parent counts follow from d's type (as
  /// hierarchy2d::parent_count() gives them): a square centre's children are the edge midpoints
  /// of its sides, of its scale, whose parents are the square centres on either side that lie in
  /// the grid; an edge midpoint's are square centres of half its scale, with two parents each.
  template <class Ready>
  int split(const diamond2& d, std::uint64_t index, Ready&& ready) {
    std::uint8_t* state = state_.get();
    state[index] = static_cast<std::uint8_t>(state[index] | split_bit);
    const ipoint2& c = d.centre;
    const std::int32_t h = d.scale;
    const ipoint2& gmax = hier_->grid_max();
    int n = 0;
    const auto visit = [&](const ipoint2& child, std::int32_t scale, int parents) {
      const std::uint64_t ci = hier_->index(child);
      // The count is the low bits and never exceeds the parent count: the add carries into
      // nothing else. One read-modify-write, so a fresh page is first touched by a write.
      const auto count =
          static_cast<std::uint8_t>(add_in_place(state[ci], std::uint8_t{1}) & parent_count_mask);
      ++n;
      PROGISO_ASSERT(scale == hier_->scale_of(child) && parents == hier_->parent_count(child));
      if (count == parents) ready(child, scale);
    };
    if (d.type == 0) {
      // Along axis q the child's parents lie at ± h along q.
      const auto side = [&](const ipoint2& child, std::size_t q) {
        if (!hier_->in_grid(child)) return;
        visit(child, h, (child[q] - h >= 0 ? 1 : 0) + (child[q] + h <= gmax[q] ? 1 : 0));
      };
      side({c[0] + h, c[1]}, 0);
      side({c[0] - h, c[1]}, 0);
      side({c[0], c[1] + h}, 1);
      side({c[0], c[1] - h}, 1);
    } else if (h >= 2) {
      const std::int32_t g = h / 2;
      for (const ipoint2 child : {ipoint2{c[0] + g, c[1] + g}, ipoint2{c[0] - g, c[1] + g},
                                  ipoint2{c[0] + g, c[1] - g}, ipoint2{c[0] - g, c[1] - g}}) {
        if (hier_->in_grid(child)) visit(child, g, 2);
      }
    }
    return n;
  }

 private:
  static constexpr std::uint8_t split_bit = 0x80;
  static constexpr std::uint8_t parent_count_mask = 0x07;
  const hierarchy2d* hier_;
  zeroed_array<std::uint8_t> state_;
};

/// Turns the live segments of a cut into polylines: clips them to the data box (the padded
/// grid reaches beyond it), shares vertices by edge key, chains segments (every vertex has at
/// most one outgoing and one incoming segment) and maps positions to physical coordinates.
class contour_assembler {
 public:
  /// `expected` segments size the key table (a hint).
  contour_assembler(const hierarchy2d& hier, double isovalue, std::size_t expected);
  /// Starts the live segments of the record of diamond `diamond` (its grid index; no_owner2 for
  /// the root record). A vertex on a unit edge (a finest triangle's leg) belongs to one split's
  /// record in every cut: the split of the finest edge midpoint at one of the edge's ends makes
  /// the only four triangles that hold the edge, and nothing splits them again. add() names such
  /// vertices within the record, without the key table; only the vertices on the diagonals,
  /// which neighbouring splits share, go through it.
  void begin_record(std::uint64_t diamond);
  /// Adds one live segment of the cut (of the record begun last, if any).
  void add(const placed_segment& s);
  /// The polylines, with positions origin + p × spacing. Once.
  [[nodiscard]] contour_set finish(const std::array<double, 2>& origin,
                                   const std::array<double, 2>& spacing);

 private:
  std::uint32_t key_id(std::uint64_t key, const vec2& p);
  // key_id(), or the record's own id for a key on a unit edge (see begin_record()).
  std::uint32_t end_id(std::uint64_t key, const vec2& p);
  std::uint32_t point_id(const vec2& p);

  // Vertex ids by key. Keys whose doubled coordinates fit in 16 bits each (images up to 32768
  // samples a side) live in a table of 8-byte slots (key << 32 | id; half the bytes of
  // flat_map's, so twice the slots stay in cache), others in flat_map.
  std::uint32_t compact_id(std::uint32_t key, const vec2& p);
  void grow_compact();

  // The record begun last: whether it is a split's (not the root record's), and the ids given
  // to its unit edges' vertices so far (a finest edge midpoint's split has four unit edges).
  bool local_ = false;
  std::array<std::uint64_t, 4> local_keys_{};
  std::array<std::uint32_t, 4> local_ids_{};
  std::uint32_t local_count_ = 0;
  double bx_;
  double by_;
  double isovalue_;
  contour_set out_;
  bool compact_keys_;
  std::vector<std::uint64_t> compact_;
  std::uint32_t compact_size_ = 0;
  int compact_shift_ = 32;
  flat_map ids_;
  std::map<vec2, std::uint32_t> clipped_;  // clipped ends, by exact position
  std::vector<std::array<std::uint32_t, 2>> segs_;
};

}  // namespace progiso::detail
