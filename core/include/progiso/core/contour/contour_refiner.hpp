// progiso/core/contour/contour_refiner.hpp — progressive isocontours of an image (paper §3, §5).
//
// The 2D counterpart of refiner.hpp. A contour_refiner holds one isovalue's progressive contour:
// split diamonds (parent-closed) and their records, each a list of oriented segments tagged with
// the diamond owning their triangle, plus the split's case and primitive sequence
// (contour_split.hpp). Contour vertices are placed once, when the record that creates them is
// published, and kept in a table by edge key, so the contour hierarchy is traversable on its
// own (Figure 10): extract(), extract_cut(ε) and extract_region(box) read the records and the
// vertex table only, never the image.
//
// Every cut is the marching-triangles contour of a conforming bisection mesh: each vertex is
// used by at most two segments, open chains end on the image border, no two segments cross, and
// the black region (f > w) lies on the left of every polyline. Fully refined, it equals plain
// marching triangles on the finest mesh. Ranges (range_data2d.hpp) keep refinement out of
// regions the contour cannot reach.
//
// Thread safety: a contour_refiner is single-threaded; several over one image may run at once.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/borrow.hpp>
#include <progiso/core/base/detail/chunked_store.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/contour/contour_split.hpp>
#include <progiso/core/contour/detail/contour_frontier.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/contour/range_data2d.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/refine/goal.hpp>

namespace progiso {

/// Counters of a contour refinement.
struct contour_statistics {
  std::uint64_t splits = 0;
  std::uint64_t visited = 0;
  std::uint64_t culled = 0;
  std::uint64_t segments = 0;         ///< in the current cut, before clipping to the image
  std::uint64_t record_segments = 0;  ///< held by all records
  std::array<std::uint64_t, contour_case_count> cases{};
  std::array<std::uint64_t, contour_primitive_count> primitives{};
};

/// Order of splits: breadth first (coarse to fine) or largest nested error first.
enum class contour_order { breadth_first, largest_error_first };

/// Sequential progressive contouring at one isovalue.
class contour_refiner {
 public:
  /// Starts at the root cut. Throws progiso::error for a non-finite isovalue.
  contour_refiner(const volume& image, const hierarchy2d& hier, const range_data2d& ranges,
                  double isovalue, contour_order order = contour_order::largest_error_first);
  /// Refused at compile time: the refiner keeps references to all three (detail/borrow.hpp).
  template <class V, class H, class R>
  requires detail::any_rvalue<V, H, R> contour_refiner(
      V&&, H&&, R&&, double, contour_order = contour_order::largest_error_first)
  = delete;
  ~contour_refiner();
  contour_refiner(const contour_refiner&) = delete;
  contour_refiner& operator=(const contour_refiner&) = delete;

  [[nodiscard]] double isovalue() const noexcept { return isovalue_; }
  [[nodiscard]] bool done() const noexcept;
  /// As refiner::next_error() and refiner::aim_at_error().
  [[nodiscard]] double next_error() const noexcept;
  void aim_at_error(double max_error);
  [[nodiscard]] int next_depth() const noexcept;
  /// Splits the next ready diamond (if the cut then has at most max_segments segments).
  bool split_next(std::uint64_t max_segments = ~std::uint64_t{0});
  void refine_full();
  void refine_to_error(double max_error);
  void refine_until(std::chrono::steady_clock::time_point deadline);

  [[nodiscard]] std::uint64_t segment_count() const noexcept { return stats_.segments; }
  [[nodiscard]] const contour_statistics& statistics() const noexcept;
  [[nodiscard]] bool is_split(const ipoint2& centre) const noexcept;
  /// Summary (case, primitives) of the most recent split.
  [[nodiscard]] contour_split_summary last_split() const;

  /// The current cut as polylines (pixel units, clipped to the image).
  [[nodiscard]] contour_set extract() const;
  /// The sub-cut of split diamonds with nested error > max_error.
  [[nodiscard]] contour_set extract_cut(double max_error) const;
  /// The sub-cut of split diamonds whose subtree reaches into the box [x0, x1] × [y0, y1]:
  /// fine inside the box, coarse away from it.
  [[nodiscard]] contour_set extract_region(double x0, double y0, double x1, double y1) const;

 private:
  struct record {
    std::uint64_t diamond;                   // grid index, or ~0 for the root record
    const detail::placed_segment* segments;  // in segments_ (root_segments_ for the root)
    std::uint32_t count;
    double error;
  };
  struct queue;

  template <class InCut>
  contour_set build(InCut&& in_cut) const;

  const volume& image_;
  const hierarchy2d& hier_;
  const range_data2d& ranges_;
  double isovalue_;
  std::array<double, 2> origin_{};  // copied so that extraction never reads the image
  std::array<double, 2> spacing_{};
  detail::contour_frontier frontier_;  // per grid vertex: split flag, split parents
  // The root record's segments (any number), then every split's (at most 4 each) in chunks that
  // never move: growth copies nothing.
  std::vector<detail::placed_segment> root_segments_;
  detail::chunked_store<detail::placed_segment> segments_;
  detail::chunked_store<record> records_;
  std::unique_ptr<queue> queue_;
  // Cases and primitives are counted by split class and added up when the statistics are read.
  mutable contour_statistics stats_;
  mutable std::array<std::uint64_t, contour_split_classes> class_counts_{};
  mutable bool counts_pending_ = false;
  std::uint64_t last_index_ = ~std::uint64_t{0};  // grid index of the last split diamond
};

// -------------------------------------------------------------------------------------------
// One-shot contouring of several isovalues (what `progiso contour` runs).

/// Isovalues are refined one after the other, in the order given, each to the goal, and
/// each one's contours are handed to `sink` (or gathered into contour_result::contours) before
/// the next starts, so memory holds one isovalue's refinement at a time: the image, its range
/// data and one refiner, however many isovalues there are. A segment budget or a deadline is
/// shared: each isovalue gets an equal part of what the isovalues before it left over.
struct contour_options {
  /// What to refine towards (core/refine/goal.hpp): a budget counts segments over all
  /// isovalues together, a deadline ends them all. kind::full without frames gives each
  /// isovalue's finest cut by finest_contours() (contour/finest_contours.hpp), two passes over
  /// the pixels, rather than by refining the hierarchy to the end: the same contours, numbered
  /// in grid order.
  refine_goal goal;
  /// Called with the current contours at each refinement stage (for --frames): after 0, 1, 2,
  /// 4, 8, … splits in all and at the end; each frame holds the isovalues finished so far and
  /// the current one's cut (so with frames, the finished contours stay in memory).
  std::function<void(const contour_set&, int stage)> frame;
  /// Called with each isovalue's contours (and its index in the list) as soon as it is
  /// finished. When set, contour_result::contours stays empty.
  std::function<void(const contour_set&, std::size_t index)> sink;
};

struct contour_result {
  contour_set contours;
  std::vector<contour_statistics> stats;  ///< per isovalue
  double range_build_seconds = 0.0;
  double first_contour_seconds = 0.0;
  double refine_seconds = 0.0;
  double total_seconds = 0.0;
  /// Image in memory → every isovalue's polylines in memory: total_seconds less the time spent
  /// in the frame and sink callbacks (writing files).
  double pipeline_seconds = 0.0;
  std::size_t range_bytes = 0;
  /// The contours came from finest_contours(): no range data, no splits; refine_seconds is the
  /// passes' time.
  bool finest_direct = false;
};

/// Contours of `image` (dims w, h, 1) at each isovalue. Throws progiso::error on bad input
/// (not an image, no isovalue, a non-finite isovalue, a negative error target), and
/// whatever the callbacks throw.
[[nodiscard]] contour_result extract_contours(const volume& image,
                                              const std::vector<double>& isovalues,
                                              const contour_options& options);

}  // namespace progiso
