// progiso/mpi/detail/distributed_cut.hpp — an error cut made by the ranks of a communicator in
// rounds of falling thresholds, each rank splitting the diamonds centred in its own planes
// (core/refine/error_cut_share.hpp), with the splits gathered on one rank.
//
// What "consistent" means across ranks: a cut is the union of every rank's splits for one common
// error threshold at one isovalue. That union is the one process's cut of refine_goal::error at
// that threshold (parent-closed because range and error are nested), whatever each rank's order
// inside a round. A round that some rank did not finish is never gathered.
//
// Every member function but the accessors is collective: all ranks of the communicator call it in
// the same order with the same arguments (the stop callbacks aside).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/error_cut_share.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/mpi/detail/mpi_c.hpp>

namespace progiso::detail {

/// The splits gathered on the root, one piece per rank and round, each with group indices of its
/// own: immutable once made, so a snapshot shares the pieces of its cut instead of copying them.
using cut_pieces = std::vector<std::shared_ptr<const share_splits>>;

/// The mesh of gathered pieces: the one process's cut of the same goal, vertex for vertex
/// (mesh_of_shares), in `threads`' parts.
[[nodiscard]] triangle_mesh mesh_of_pieces(const hierarchy& hier, const volume& vol,
                                           double isovalue, const cut_pieces& pieces,
                                           unsigned threads);

/// What a distributed_snapshot meshes: the pieces of its cut, and its mesh once made.
struct snapshot_cut {
  std::shared_ptr<const hierarchy> hier;
  const volume* vol = nullptr;
  double isovalue = 0.0;
  cut_pieces pieces;
  unsigned threads = 0;
  mutable std::once_flag once;
  mutable std::shared_ptr<const triangle_mesh> mesh;  // set once, under `once`
};

class distributed_cut {
 public:
  /// The share of this rank of `comm`; `vol` outlives the cut. The communicator is used as
  /// given (the caller duplicates it when other messages may travel on it).
  distributed_cut(MPI_Comm comm, int root, const volume& vol, double isovalue);
  distributed_cut(const distributed_cut&) = delete;
  distributed_cut& operator=(const distributed_cut&) = delete;
  ~distributed_cut();

  /// Builds the range data's pieces of this rank's planes (in steps of `threads`' parts, asking
  /// `stop` between steps, when `stop` is given), copies every rank's pieces to every rank and
  /// finishes the coarser levels and errors. True when every rank built its pieces; otherwise
  /// the cut stays the root surface.
  bool build_ranges(unsigned threads, const std::function<bool()>& stop = {});

  /// The next round's threshold: half the largest error still waiting on any rank, and at least
  /// `floor`. None when nothing waits above `floor`, when the ranges are not built, or when any
  /// rank says `stop_now`.
  std::optional<double> next_threshold(double floor, bool stop_now);

  /// Splits every diamond of this rank's planes whose nested range straddles the isovalue and
  /// whose nested error exceeds `threshold`. `stop`, asked between pieces, ends it early. True
  /// when every rank finished: the round is then the cut. After a round some rank did not finish,
  /// only restart() goes on.
  bool round(double threshold, unsigned threads, const std::function<bool()>& stop = {});

  /// Sends the splits of finished rounds not sent yet to the root, up a binomial tree (each rank
  /// forwards its subtree's with its own), and the root adds them to pieces() as one piece per
  /// rank, in rank order.
  void gather();

  /// A new isovalue: every rank drops its splits and starts from the roots again, keeping the
  /// range data (which does not depend on the isovalue).
  void restart(double isovalue);

  [[nodiscard]] int rank() const noexcept { return rank_; }
  [[nodiscard]] int size() const noexcept { return size_; }
  [[nodiscard]] int root() const noexcept { return root_; }
  [[nodiscard]] const hierarchy& hier() const noexcept { return hier_; }
  [[nodiscard]] double isovalue() const noexcept { return isovalue_; }
  /// The threshold of the last finished round (infinity: the root surface).
  [[nodiscard]] double threshold() const noexcept { return threshold_; }
  [[nodiscard]] int rounds() const noexcept { return rounds_; }
  /// A round was left unfinished: going on needs restart().
  [[nodiscard]] bool broken() const noexcept { return broken_; }
  /// On the root, every rank's splits gathered; elsewhere empty.
  [[nodiscard]] const cut_pieces& pieces() const noexcept { return pieces_; }
  [[nodiscard]] std::uint64_t gathered_splits() const noexcept { return gathered_; }
  /// On the root, the mesh of the gathered cut (the one process's cut of error > threshold(),
  /// vertex for vertex), in `threads`' parts.
  [[nodiscard]] triangle_mesh mesh(unsigned threads) const;

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1, root_ = 0;
  const volume& vol_;
  hierarchy hier_;
  range_data ranges_;
  cut_share share_;
  double isovalue_;
  bool built_ = false;
  bool broken_ = false;
  double threshold_;
  int rounds_ = 0;
  std::unique_ptr<error_cut_walk> walk_;
  std::size_t sent_splits_ = 0, sent_groups_ = 0;  // of walk_'s finished rounds
  std::size_t committed_ = 0;                      // walk_'s splits of finished rounds
  cut_pieces pieces_;                              // root
  std::vector<std::uint64_t> groups_seen_;         // root: groups gathered from each rank
  std::uint64_t gathered_ = 0;
};

}  // namespace progiso::detail
