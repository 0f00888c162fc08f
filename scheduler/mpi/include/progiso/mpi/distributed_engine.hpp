// progiso/mpi/distributed_engine.hpp — the progressive engine across the ranks of an MPI
// communicator: every rank refines the diamonds centred in its own planes of the grid, in rounds
// of falling error thresholds, and one rank (the root) gathers each finished round into a
// snapshot, takes the commands (goals, isovalue changes, cancel) and hands them to every rank.
//
// Consistency across ranks. A snapshot is the union of every rank's splits for one common
// threshold at one isovalue, which is the one process's cut of refine_goal::error(threshold) at
// that isovalue, vertex for vertex (docs/MPI.md): never a mix of rounds or of isovalues. Each
// round only adds splits (the split set of a smaller threshold contains that of a larger one), so
// snapshots of one isovalue refine monotonically; a round that some rank did not finish (its
// deadline, a command arriving on the root) is never shown.
//
// Protocol. Each rank runs one thread of its own that makes every MPI call of the engine, on a
// duplicate of the communicator. Before each round the root broadcasts a control block (the
// pending command, or "go on"); then one all-reduce agrees on the threshold (half the largest
// error still waiting on any rank) and on whether any rank is out of time, the round runs, one
// all-reduce agrees that every rank finished it, and its new splits go to the root, which meshes
// the cut and publishes it. An isovalue change reaches every rank at the next control block; the
// root stops its own round at once, so a change waits for at most the slowest rank's current
// round. Idle ranks wait for the next control block without spinning. An error on a rank's thread
// (out of memory) is printed and aborts the job (MPI_Abort): the other ranks would otherwise wait
// for that rank forever.
//
// Requirements: MPI initialised with MPI_THREAD_MULTIPLE (the engine's threads call MPI while the
// host's may too); every rank of the communicator constructs an engine on the same grid with the
// same isovalue and root, and destroys it before MPI_Finalize. Construction and destruction are
// collective.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/mpi/detail/mpi_c.hpp>

namespace progiso {

namespace detail {
class distributed_cut;
struct snapshot_cut;
}  // namespace detail

/// One cut gathered on the root: the one process's cut of refine_goal::error(max_error) at
/// `isovalue`. It holds the gathered splits (shared with the engine and later snapshots, not
/// copied); its mesh is made when first asked for.
struct distributed_snapshot {
  double isovalue = 0.0;
  double max_error = 0.0;              ///< the round's threshold; infinity for the root surface
  std::uint64_t splits = 0;            ///< the splits of all ranks
  int round = 0;                       ///< rounds since the isovalue was set (0: the root surface)
  std::uint64_t isovalue_changes = 0;  ///< set_isovalue() calls that reached the ranks

  /// The cut's mesh (canonical order, grid coordinates): made by the first call, on the
  /// caller's thread and the engine's worker count, and kept, so that every later call (any
  /// thread) returns the same mesh. Reads the volume's root corners: the volume must still live.
  [[nodiscard]] std::shared_ptr<const triangle_mesh> mesh() const;

  std::shared_ptr<const detail::snapshot_cut> cut;  ///< what mesh() meshes (internal)
};

class distributed_engine {
 public:
  struct options {
    int root = 0;          ///< the rank that gathers snapshots and takes commands
    unsigned threads = 0;  ///< worker threads per rank (0: oneTBB's default)
    /// On the root, called with every snapshot as it is published, in order, the first (the
    /// root surface) included: what a reader that must see each round (a stream, a log) takes
    /// instead of polling snapshot(), which shows only the latest. Runs on the engine's own
    /// thread: it may call snapshot() and mesh(), never wait() or the destructor, and a slow one
    /// delays the next round. An exception from it aborts the job (MPI_Abort), as any failure
    /// of the engine's thread does.
    std::function<void(const std::shared_ptr<const distributed_snapshot>&)> on_snapshot;
  };

  /// Collective over `comm`: every rank passes its view of the same volume (each reads only its
  /// own planes plus a few beyond, and the samples of the few coarse diamonds every rank tests).
  /// Starts building the range data at once; the root's first snapshot is the root surface.
  distributed_engine(MPI_Comm comm, const volume& vol, double isovalue, options opt);
  distributed_engine(MPI_Comm comm, const volume& vol, double isovalue)
      : distributed_engine(comm, vol, isovalue, options{}) {}
  distributed_engine(const distributed_engine&) = delete;
  distributed_engine& operator=(const distributed_engine&) = delete;
  /// On the root, ends the engine on every rank (a round in progress is abandoned); on the other
  /// ranks, waits until the root's engine ends. Collective.
  ~distributed_engine();

  [[nodiscard]] int rank() const noexcept { return rank_; }
  [[nodiscard]] bool is_root() const noexcept { return rank_ == root_; }

  // The root's commands (other ranks get a progiso::error). Each returns at once; the ranks take
  // it at the next control block.

  /// Refines toward `goal`: error (rounds down to its threshold), deadline (rounds until the
  /// time, on each rank's clock, from the moment the ranks take the command), budget (the last
  /// round whose cut has at most max_elements triangles) or full (down to error 0: the finest
  /// surface's geometry). A focus is refused.
  void start(const refine_goal& goal);
  /// Moves every rank to isovalue `w`: the splits are dropped, the range data kept, and the last
  /// goal started (reached or not, unless cancelled) is refined again from the new root surface,
  /// a deadline with its whole time again.
  void set_isovalue(double w);
  /// Ends the run after the round in progress (the root's own part stops at once).
  void cancel();

  /// On the root, the latest snapshot (never null); elsewhere null. Any thread, any time.
  [[nodiscard]] std::shared_ptr<const distributed_snapshot> snapshot() const;
  /// On the root, waits until the run has ended (its goal, deadline or budget reached, or
  /// cancelled) with no command pending; on the other ranks, until the root's engine ends.
  void wait();

 private:
  void serve();
  /// On the root: the cut gathered so far as the latest snapshot, with its mesh when given;
  /// on_snapshot hears of it when `tell`.
  void publish(std::uint64_t changes, std::shared_ptr<const triangle_mesh> mesh, bool tell = true);

  MPI_Comm comm_ = MPI_COMM_NULL;
  int rank_ = 0;
  int root_ = 0;
  unsigned threads_ = 0;
  std::function<void(const std::shared_ptr<const distributed_snapshot>&)> on_snapshot_;
  const volume& vol_;
  std::shared_ptr<const hierarchy> hier_;  // shared with the snapshots
  std::unique_ptr<detail::distributed_cut> cut_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  // Under mutex_: the root's pending command, its state, the latest snapshot.
  struct pending_command {
    bool start = false;
    refine_goal goal;
    bool isovalue = false;
    double w = 0.0;
    bool cancel = false;
    bool quit = false;
  } pending_;
  bool busy_ = false;  // a run in progress or a command not yet taken
  bool ended_ = false;
  std::shared_ptr<const distributed_snapshot> latest_;
  // A command is pending: the root stops its part of a round at once. A hint read between pieces
  // of work (the command itself is read under mutex_), so relaxed.
  std::atomic<bool> interrupt_{false};
  std::thread thread_;
};

}  // namespace progiso
