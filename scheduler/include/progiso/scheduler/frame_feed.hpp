// progiso/scheduler/frame_feed.hpp — a render thread's surface, fed by a thread of its own.
//
// What it is. A frame_feed keeps an engine's latest cut in a render_slots pool for one render
// thread, and does the work of each frame elsewhere: a producer thread (the feed's own) takes
// the engine's snapshots, asks each for the change since the last cut it handed over
// (surface_snapshot::change_since) and hands the change to the render thread through a
// single-producer single-consumer queue of Boost.Lockfree; a change that is the whole cut (an
// isovalue change, a uniform cut of engine_options::uniform_cuts) it first applies to a spare
// pool, and hands over the pool. The render thread's update() then costs what it applies: the
// changes' slots, or a pool swapped in whole (O(1)); it never waits, never takes a lock and
// never touches the engine. Changes, pools and their storage go back to the producer through a
// second queue and are reused.
//
// Latest wins. At most `depth` frames are in flight; while the render thread takes none, the
// producer makes none, and its next change is taken from the last cut it handed over to the
// newest cut: a slow render thread skips versions instead of queueing them, and memory stays
// bounded (at most depth + 2 pools and depth changes).
//
// Why a thread and a queue rather than snapshots on the render thread: a snapshot belongs to
// the thread that took it (epoch guard), and its change costs the decoding and interpolation of
// every corner added (bench/README.md, BM_follow); off the render thread that cost leaves its
// frames.
//
// Thread safety: update(), surface(), replaced(), written() and mark() belong to one render
// thread (any thread, one at a time); statistics() to any. The engine must outlive the feed.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include <progiso/core/surface/normals.hpp>
#include <progiso/core/surface/surface_change.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso {

struct frame_feed_options {
  /// Normals with every added piece (vertex_normals::gradient), as change_since() gives them.
  vertex_normals normals = vertex_normals::none;
  /// How often the producer looks for a newer cut.
  std::chrono::microseconds poll{1000};
  /// Frames handed over and not yet taken by the render thread, at most (1 … 64).
  std::size_t depth = 4;
};

/// Counters of a feed (any thread; each exact at some moment).
struct frame_feed_statistics {
  std::uint64_t frames = 0;       ///< frames handed over (changes and pools)
  std::uint64_t pools = 0;        ///< of which whole cuts in a pool
  std::uint64_t taken = 0;        ///< frames the render thread took
  double producer_seconds = 0.0;  ///< the producer's time making frames
};

class frame_feed {
 public:
  /// Starts the producer. Throws progiso::error for a depth outside [1, 64].
  explicit frame_feed(const engine& e, frame_feed_options options = {});
  /// Stops and joins the producer.
  ~frame_feed();
  frame_feed(const frame_feed&) = delete;
  frame_feed& operator=(const frame_feed&) = delete;

  /// Render thread: takes every frame handed over since the last call, in order: a change is
  /// applied to surface(), a pool replaces it. Never waits. Returns the frames taken (0: the
  /// surface is unchanged).
  std::size_t update();
  /// The render thread's surface: the cut of mark(), valid until the next update().
  [[nodiscard]] const render_slots& surface() const noexcept;
  /// Whether the last update() replaced the surface whole: upload all of it. Else written()
  /// lists the slots that update() wrote (a slot may repeat).
  [[nodiscard]] bool replaced() const noexcept;
  [[nodiscard]] std::span<const std::uint32_t> written() const noexcept;
  /// The cut surface() holds (no cut before the first frame).
  [[nodiscard]] cut_mark mark() const noexcept;
  [[nodiscard]] frame_feed_statistics statistics() const noexcept;

 private:
  struct state;
  std::unique_ptr<state> s_;
};

}  // namespace progiso
