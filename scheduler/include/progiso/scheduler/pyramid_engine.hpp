// progiso/scheduler/pyramid_engine.hpp — a multiscale input's progressive surface, coarse first.
//
// The paper's first contribution is "a coarse representation of the output … generated as soon
// as a coarse representation of the input is provided". A resolution pyramid (OME-Zarr, Imaris,
// BigDataViewer; level 0 the finest) provides coarse representations outright, so the surface
// can be on screen before the finest level has been read. A pyramid_engine holds one engine per
// level read:
//  - the constructor reads the coarsest level and makes its engine: its root surface is there at
//    once (engine's constructor publishes it);
//  - start(goal) refines the shown level towards the goal and, on a loader thread, reads each
//    finer level in turn (the read is asked to stop between chunks on cancel() and, for a
//    deadline, once it has passed), makes its engine on the current isovalue and refines it
//    towards the same goal out of sight;
//  - a finer level is shown once its cut holds at least as many triangles as the shown level's,
//    or once its run has reached its goal (a full, error or budget goal: the finer field's cut
//    is the better surface); a deadline that ends its run short of that leaves the coarser level
//    shown. The coarser level's run is then cancelled.
//
// Consistency. A pyramid level need not subsample the finer one (writers average), so each level
// is a field of its own and cuts of two levels do not mix. Every snapshot is one level's
// engine's: a valid cut of that level's field (its level named in the snapshot), never a part of
// one level beside a part of another. The level shown only gets finer. A renderer that follows
// the surface by changes (surface_snapshot::change_since) gets the whole new level's cut at a
// switch (`rebuilt`: the mark is of another engine), then changes again.
//
// Isovalue changes reach every level read: set_isovalue() sets it on each engine (the shown one
// publishes the new root surface at once), and a level read later starts on it.
//
// Thread safety: control calls (start, cancel, wait, set_isovalue) serialise on a mutex and may
// come from any thread; snapshot() and level() never take it and never wait for the loader.
// Every level's engine lives until the pyramid_engine goes, so a snapshot of a level no longer
// shown stays valid; as with engine, a snapshot must be destroyed on the thread that took it,
// before the pyramid_engine.
#pragma once

#include <atomic>
#include <cstddef>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/refine/goal.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso {

/// Reads level `level` of the pyramid (0: the finest); nullopt when `stop` answered true (it is
/// asked between chunks). Throws progiso::error for a bad level. volume_source::read_level() is
/// one (io/volume_io.hpp).
using pyramid_level_reader =
    std::function<std::optional<volume>(std::size_t level, const std::function<bool()>& stop)>;

/// One level's cut: the snapshot, the level it is of (0: the finest) and that level's engine
/// (its field(): dims, spacing and origin of the level; add_normals()).
struct pyramid_snapshot {
  surface_snapshot surface;
  std::size_t level = 0;
  const engine* source = nullptr;
};

/// See the file comment.
class pyramid_engine {
 public:
  /// Reads the coarsest of `levels` levels (levels − 1) and makes its engine on `isovalue` with
  /// `options` (every level's engine takes them). Throws progiso::error for no level, and what
  /// the read and the engine's constructor throw.
  pyramid_engine(pyramid_level_reader read, std::size_t levels, double isovalue,
                 engine_options options = {});
  /// Stops the loader and every run. Precondition: no snapshot of this pyramid_engine is alive.
  ~pyramid_engine();
  pyramid_engine(const pyramid_engine&) = delete;
  pyramid_engine& operator=(const pyramid_engine&) = delete;

  /// Refines the shown level towards `goal` and loads the finer levels (see the file comment),
  /// cancelling what runs. Returns at once.
  void start(const refine_goal& goal);
  /// Stops loading (a read in progress stops between chunks) and every level's run. What is
  /// shown stays; a later start() goes on from the levels already read.
  void cancel();
  /// Blocks until the loader has ended (the finest level shown, a deadline passed, or a read
  /// failed) and the shown level's run has. Rethrows what a read or an engine threw.
  void wait();
  /// Sets isovalue w on every level read (engine::set_isovalue; the shown level's root surface at
  /// once), and on the levels read later. Throws progiso::error for a non-finite w.
  void set_isovalue(double w);

  /// The shown level's cut. O(1) as engine::snapshot(); never waits. Any thread.
  [[nodiscard]] pyramid_snapshot snapshot() const;
  /// The level shown (0: the finest). Any thread.
  [[nodiscard]] std::size_t level() const noexcept;
  [[nodiscard]] std::size_t levels() const noexcept { return engines_.size(); }
  /// The current isovalue. Any thread.
  [[nodiscard]] double isovalue() const;
  /// Levels whose samples have been read (the coarsest included). Any thread.
  [[nodiscard]] std::size_t levels_read() const noexcept;

 private:
  void stop_loader();
  void load(refine_goal goal);
  [[nodiscard]] bool stopping(const refine_goal& goal) const;

  pyramid_level_reader read_;
  engine_options options_;
  // Slot k is written once, by the constructor or the loader under state_, before shown_ may
  // name it, and never again until destruction.
  std::vector<std::unique_ptr<engine>> engines_;
  // Release-stored by the loader after it fills the slot it names; acquire-loaded by snapshot()
  // and level(), which then read that slot without a lock.
  std::atomic<std::size_t> shown_{0};
  // Release-stored by the loader after each level's engine is made; acquire-loaded by
  // levels_read().
  std::atomic<std::size_t> read_count_{0};
  // A stop request to the loader and its reads: relaxed, nothing is published through it (the
  // join in stop_loader() orders what the loader did before control goes on).
  std::atomic<bool> stop_{false};
  std::mutex control_;        // start, cancel, wait, set_isovalue
  mutable std::mutex state_;  // isovalue_, failed_, the engines_ slots the loader fills
  double isovalue_ = 0.0;
  std::exception_ptr failed_;
  std::thread loader_;
};

}  // namespace progiso
