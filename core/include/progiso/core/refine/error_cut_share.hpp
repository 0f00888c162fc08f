// progiso/core/refine/error_cut_share.hpp — one share of an error goal's cut, for processes (MPI
// ranks) that each make the splits whose centres lie in their own planes of the grid.
//
// An error goal's split set is fixed: a diamond splits exactly when its nested range straddles w
// and its nested error exceeds ε (refine_goal::error). Both tests are nested (a child's range lies
// in each parent's, its error is at most theirs), so the set is closed under parents, and a run
// takes the same set whatever its order or thread count. A share therefore needs no message to
// decide its splits, ancestors on other ranks included: it walks down from the roots depth by
// depth, testing only diamonds whose subtree can reach its planes (every descendant of a diamond of
// scale h has its centre within h of the diamond's on every axis), so the few coarse diamonds are
// tested by every share and each fine one by its owner and its neighbours near a boundary. It
// reads the complete range data (exact errors), the stencils of the diamonds it tests and the
// vertices of the splits it makes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/split_record.hpp>

namespace progiso::detail {

/// Planes [z_begin, z_end) of the hierarchy's grid, whose diamonds a share splits, and the range
/// data's pieces [piece_begin, piece_end) it builds. Shares partition both; a share's pieces read
/// the samples of its planes (the last plane's pieces also the grid's far padding).
struct cut_share {
  std::int32_t z_begin = 0;
  std::int32_t z_end = 0;
  std::size_t piece_begin = 0;
  std::size_t piece_end = 0;
};

/// Share k of `shares` of a grid whose range data has `pieces` pieces (range_data::piece_count():
/// piece p covers the grid planes [4p − 4, 4p)); shares may be empty when there are more shares
/// than pieces.
[[nodiscard]] cut_share error_cut_share(const hierarchy& hier, std::size_t pieces, std::size_t k,
                                        std::size_t shares) noexcept;

/// One split of the cut, with what a hierarchy stream record needs.
struct share_split {
  std::uint64_t diamond = 0;      ///< grid index of its centre
  std::uint64_t first_group = 0;  ///< its groups: share_splits::groups[first_group, + groups)
  std::uint32_t groups = 0;
  std::uint32_t crossed = 0;  ///< split_summary::crossed
  double value = 0.0;         ///< the field at its centre
  double error = 0.0;         ///< its nested error
  int depth = 0;              ///< hierarchy::depth_of(centre)
};

/// A share's splits, each after its parents.
struct share_splits {
  std::vector<share_split> splits;
  std::vector<packed_group> groups;
};

/// A share's splits by rounds of decreasing error thresholds (a deadline across ranks): the set
/// of a smaller threshold contains that of a larger one, so each round only adds splits, and
/// after a round the share's splits are those of refine_goal::error(threshold) in its planes.
/// Diamonds tested and kept but not split wait with their errors for a later round.
class error_cut_walk {
 public:
  /// Tests the root diamonds that can reach planes [z_begin, z_end): those that straddle wait
  /// for the first round. `ranges` is complete with exact errors; all four must outlive the walk.
  error_cut_walk(const hierarchy& hier, const volume& vol, const range_data& ranges,
                 double isovalue, std::int32_t z_begin, std::int32_t z_end);

  /// Splits, depth by depth, every diamond of the share's reach whose nested range straddles
  /// the isovalue and whose nested error exceeds `max_error` (at most the last round's), in
  /// pieces through `run`. `stop`, asked between pieces, ends the round early: then it returns
  /// false and the splits past round_end() are not a round's (the walk is not to be extended).
  bool extend(double max_error, const parallel_loop& run = {},
              const std::function<bool()>& stop = {});

  /// Every split made, in rounds (each after its parents), and the count after the last
  /// finished round.
  [[nodiscard]] const share_splits& splits() const noexcept { return out_; }
  [[nodiscard]] std::size_t round_end() const noexcept { return round_end_; }
  /// The largest error of a diamond kept but not split (0 when none): a smaller threshold than
  /// this adds splits, a larger one none.
  [[nodiscard]] double largest_waiting_error() const noexcept;

 private:
  struct waiting {
    std::uint64_t diamond;
    double error;
  };
  const hierarchy& hier_;
  const volume& vol_;
  const range_data& ranges_;
  double isovalue_;
  std::int32_t z_begin_, z_end_;
  share_splits out_;
  std::size_t round_end_ = 0;
  std::vector<std::vector<waiting>> waiting_;  // by depth, ascending grid index
  bool broken_ = false;
};

/// The splits of refine_goal::error(max_error)'s cut of `vol` at `isovalue` whose centres lie in
/// the grid planes [z_begin, z_end), by depth and then grid index (one round of error_cut_walk).
/// `ranges` is complete with exact errors, built from the same volume (at least the pieces that
/// meet the diamonds tested; see range_data::piece_bytes). Each depth's diamonds are tested in
/// pieces through `run`; the result does not depend on it.
[[nodiscard]] share_splits error_cut_splits(const hierarchy& hier, const volume& vol,
                                            const range_data& ranges, double isovalue,
                                            double max_error, std::int32_t z_begin,
                                            std::int32_t z_end, const parallel_loop& run = {});

/// Writes through `out` the hierarchy stream of a cut made in shares: the header and the root
/// chunk (from `vol`: the root corners' samples and the root tetrahedra's surface, a few samples
/// in all), every share's splits ordered by depth and grid index (parents first), and the end
/// mark. Its cut of all records is the one process's cut of the same goal, vertex for vertex.
/// `shares` may be any partition of the cut's splits (by rank, by rank and round), in any order.
void write_cut_stream(const hierarchy_stream_writer::sink& out, const hierarchy& hier,
                      const volume& vol, double isovalue,
                      std::span<const share_splits* const> shares);

/// The mesh of the cut made in shares, without a stream: the one process's cut of the same goal
/// vertex for vertex (canonical order, clipped to the data box, physical coordinates), in `parts`
/// pieces through `run`. Reads `vol` at the root corners alone: every other sample is a split's
/// centre, which its share_split carries.
/// `shares` as for write_cut_stream().
[[nodiscard]] triangle_mesh mesh_of_shares(const hierarchy& hier, const volume& vol,
                                           double isovalue,
                                           std::span<const share_splits* const> shares,
                                           const parallel_loop& run = {}, std::size_t parts = 1);

}  // namespace progiso::detail
