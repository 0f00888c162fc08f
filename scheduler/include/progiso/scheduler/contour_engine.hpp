// progiso/scheduler/contour_engine.hpp — the progressive isocontour engine: the engine of
// engine.hpp for 2D images.
//
// What it is. A contour_engine owns one image's hierarchy and range data (built by the first
// run, which needs them; the root contour published at construction needs none) and the
// progressive contour of the current isovalue. It runs the four scenarios of the paper as the
// 3D engine does, with the same calls and the same guarantees:
//  - quality-driven:  refine_until(ε) splits until every remaining error is ≤ ε;
//  - time-critical:   refine_for(τ) or refine(refine_goal::until(t));
//  - asynchronous:    start(goal) returns at once; cancel() from any thread stops the run within
//                     one split, and what was published stays;
//  - dynamic:         set_isovalue(w) from any thread cancels in-flight work, publishes the new
//                     isovalue's root contour at once and resumes the interrupted goal.
// A budget goal (refine_goal::triangles(k)) counts segments: the cut keeps at most k segments
// before clipping to the image.
//
// Records are those of contour_refiner (contour_frontier.hpp makes both): one per split, its
// new segments placed when it is made, published in dependency order (every record after its
// parents') every 64 splits and at the end of a run. Splits go largest nested error first, by
// bands (refine/detail/ready_queue.hpp), last in first out for full refinement; a run's splits
// are those the sequential refiner makes for the same goal (error goals: the same set).
//
// Snapshots. As in engine.hpp: a root holds one isovalue and an append_log of records (no array
// per grid vertex: a snapshot marks its cut's splits when an extraction or is_split() needs
// them); snapshot() pins an epoch guard, protects the root pointer and acquire-loads the record
// count: O(1), no lock, never waiting for the writer nor delaying it.
// The cut is exactly the first W records; a snapshot holds one isovalue and one parent-closed
// cut. An isovalue change swaps the root and retires the old one through the epoch domain.
//
// Threads. A contour run is one thread: the driver splits in a loop (a 2D split is cheap, and a
// whole image refines in less time than spreading the work would cost; bench/README.md).
// Readers may be any number of other threads.
//
// Thread safety: as engine.hpp. Every member function may be called from any thread; control
// calls serialise on a mutex; readers never take it. A contour_snapshot belongs to the thread
// that took it and must be destroyed on that thread before the engine.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <progiso/concurrent/epoch.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/contour/range_data2d.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso {

class contour_engine;

namespace detail {
struct contour_root;
struct contour_engine_impl;
class cut_index;
}  // namespace detail

struct contour_engine_options {
  /// Reclamation of retired roots (as engine_options::reclamation).
  epoch_options reclamation{1, 1, 3, true};
  /// Fill retired roots with a poison pattern before freeing them (stress tests).
  bool poison_retired = false;
  /// Called with the generation of every root as it is destroyed (stress tests count them).
  std::function<void(std::uint64_t generation)> on_reclaim;
  /// Called from the run's thread about every `progress_interval` splits; `triangles` is the
  /// cut's segment count. It may call cancel() (a stop request) and any reader; an exception
  /// it throws stops the run and is rethrown by wait() / refine().
  std::function<void(const engine_progress&)> progress;
  std::uint64_t progress_interval = 4096;
};

/// Counters of the current isovalue's refinement (and of the engine's life), readable while
/// running: each exact at some moment of the run.
struct contour_engine_statistics {
  contour_statistics refine;     ///< of the current root (isovalue)
  std::uint64_t published = 0;   ///< records published (including the root record)
  std::uint64_t generation = 0;  ///< isovalue changes so far
  /// When the current isovalue's first contour (its root contour) became visible to snapshots.
  std::chrono::steady_clock::time_point surface_published_at{};
  std::uint64_t runs = 0;  ///< runs started (engine life)
  std::uint64_t cancelled_runs = 0;
  epoch_statistics reclamation;
  std::uint64_t snapshot_retries = 0;
};

/// An immutable view of one published cut of one isovalue. O(1) to take, O(cut records) to
/// extract. Destroy it on the thread that took it, before the engine. Move-only.
class contour_snapshot {
 public:
  contour_snapshot() = default;
  contour_snapshot(contour_snapshot&& other) noexcept;
  contour_snapshot& operator=(contour_snapshot&& other) noexcept;
  contour_snapshot(const contour_snapshot&) = delete;
  contour_snapshot& operator=(const contour_snapshot&) = delete;
  ~contour_snapshot();

  [[nodiscard]] bool valid() const noexcept { return root_ != nullptr; }
  [[nodiscard]] double isovalue() const noexcept;
  /// Number of isovalue changes before this snapshot's root.
  [[nodiscard]] std::uint64_t generation() const noexcept;
  /// Split diamonds in the cut (records − 1).
  [[nodiscard]] std::uint64_t split_count() const noexcept { return published_ - 1; }
  /// Segments in the cut before clipping to the image: O(1).
  [[nodiscard]] std::uint64_t segment_count() const noexcept;
  /// Whether the diamond centred at c is split in the cut (false outside the grid). The first
  /// call marks the cut's splits (O(cut records), a bit per grid vertex, kept with the
  /// snapshot); every call after it is O(1). Safe from several threads at once.
  [[nodiscard]] bool is_split(const ipoint2& centre) const;
  /// The cut as polylines (pixel units, clipped to the image), as contour_refiner::extract().
  [[nodiscard]] contour_set extract() const;
  /// The sub-cut of split diamonds whose nested error exceeds max_error.
  [[nodiscard]] contour_set extract_cut(double max_error) const;
  /// Whether the root is alive and every record of the cut is well-formed, each diamond split
  /// once (stress tests; a bit per grid vertex of scratch).
  [[nodiscard]] bool check_integrity() const;

 private:
  friend class contour_engine;
  template <class InCut>
  contour_set build(InCut&& in_cut) const;

  // The cut's splits, a bit per grid vertex, made by the first is_split() call.
  [[nodiscard]] const detail::cut_index& split_bits() const;

  epoch_guard guard_;
  const contour_engine* owner_ = nullptr;
  const detail::contour_root* root_ = nullptr;
  std::uint64_t published_ = 0;
  // Owned; published by compare-and-swap so that concurrent first calls agree on one.
  mutable std::atomic<const detail::cut_index*> split_bits_{nullptr};
};

/// The contour engine. See the file comment.
class contour_engine {
 public:
  /// Builds the hierarchy of `image` (dims w, h, 1; it must outlive the engine) and publishes
  /// the root contour of `isovalue`. Throws progiso::error when the image is not 2D or the
  /// isovalue is not finite.
  contour_engine(const volume& image, double isovalue, contour_engine_options options = {});
  /// The same for an image the engine takes over (a temporary binds here).
  contour_engine(volume&& image, double isovalue, contour_engine_options options = {});
  /// The same for an image shared with the caller. Throws progiso::error for a null pointer.
  contour_engine(std::shared_ptr<const volume> image, double isovalue,
                 contour_engine_options options = {});
  /// Cancels any run and waits for it. Precondition: no snapshot of this engine is alive.
  ~contour_engine();
  contour_engine(const contour_engine&) = delete;
  contour_engine& operator=(const contour_engine&) = delete;

  /// As engine::set_isovalue().
  void set_isovalue(double w);
  /// As engine::start(); refine_goal::triangles(k) is a budget of k segments.
  void start(const refine_goal& goal);
  /// As engine::cancel().
  void cancel();
  /// As engine::wait().
  void wait();
  /// As engine::refine(): true when the goal was reached.
  bool refine(const refine_goal& goal);
  bool refine_full() { return refine(refine_goal::full()); }
  bool refine_until(double max_error) { return refine(refine_goal::error(max_error)); }
  bool refine_for(std::chrono::steady_clock::duration budget) {
    return refine(refine_goal::until(deadline_after(std::chrono::steady_clock::now(), budget)));
  }

  /// A consistent view of the last published cut. O(1); never waits. Any thread.
  [[nodiscard]] contour_snapshot snapshot() const;
  [[nodiscard]] double isovalue() const;
  [[nodiscard]] bool running() const noexcept;
  /// True when no ready diamond is left (the cut is full resolution).
  [[nodiscard]] bool done() const;
  [[nodiscard]] contour_engine_statistics statistics() const;

  [[nodiscard]] const volume& image() const noexcept;
  [[nodiscard]] const hierarchy2d& hierarchy_of() const noexcept;
  /// The range data; built by the first run, or here (any thread but the progress callback's).
  [[nodiscard]] const range_data2d& ranges() const;
  /// Seconds the range data took to build; 0 until it is built.
  [[nodiscard]] double range_build_seconds() const noexcept;

 private:
  friend class contour_snapshot;
  void init(std::shared_ptr<const volume> owned, const volume& image, double isovalue,
            contour_engine_options options);
  std::unique_ptr<detail::contour_engine_impl> impl_;
};

}  // namespace progiso
