// progiso/core/ranges/range_data.hpp — per-diamond value ranges and nested errors, built once per
// volume.
//
// For every diamond D, range(D) = [lo, hi] covers the field values at every grid vertex of every
// tetrahedron that D or any of its descendants ever has, and error(D) is at least the largest
// split error |f(centre) - (f(spine0) + f(spine1)) / 2| over D and its descendants. Both are
// nested: they never grow from a diamond to its children, so "range(D) straddles w" and "error(D) >
// ε" each select a parent-closed set of diamonds, a valid cut of the hierarchy. A diamond whose
// range does not straddle w (lo <= w < hi fails) holds no surface now and never will, so refinement
// never visits it: extraction is output sensitive. Neither depends on the isovalue, so a new
// isovalue reuses the same data.
//
// Diamonds whose subtree lies wholly in the padding beyond the data box get an empty range
// (their pieces of surface would all be clipped away).
//
// Storage: diamonds of scale 1 (7/8 of all) are computed on demand from fixed stencils of
// samples that depend only on the centre mod 4 (about 60 reads for a cube centre, fewer for the
// others): exact away from the data boundary, read with clamped samples within 2 of it (a
// superset, still sound and nested). Diamonds of scale h ≥ 2 take the merge of a min/max pyramid's
// bricks that meet a box holding their subtree (range_data.cpp says which box and which level):
// a superset of the subtree's values and errors, so culling stays sound and ranges stay nested,
// at the price of refining some diamonds whose own subtree would have been culled. The pyramid
// holds 3 samples per 4 × 4 × 4 grid vertices (about 5% of the volume's bytes) and is built in
// one streaming pass, in slabs that the caller may run in parallel.
//
// Thread safety: immutable after construction (after finish() when staged); concurrent get() calls
// are safe. Pieces of a staged build may be built concurrently; finish() runs alone.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/borrow.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/detail/sample_threshold.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>

namespace progiso {

/// Range and nested error of one diamond.
struct diamond_range {
  double lo = 0.0;
  double hi = -1.0;
  double error = 0.0;

  /// True when the diamond's subtree has vertices of both colours at isovalue w.
  [[nodiscard]] bool straddles(double w) const noexcept { return lo <= w && w < hi; }
  [[nodiscard]] bool empty() const noexcept { return lo > hi; }
};

/// Whether a diamond's range straddles an isovalue, and its error (range_data::test_upto()).
struct straddle_and_error {
  bool straddles = false;
  double error = 0.0;
};

/// The range data of one volume.
class range_data {
 public:
  /// How the build may run its independent pieces (progiso::parallel_loop).
  using parallel_loop = progiso::parallel_loop;

  /// Builds the data: one pass over the volume, O(voxels); pieces of it through `run` when
  /// given, else one after another on this thread.
  explicit range_data(const volume& vol, const hierarchy& hier, const parallel_loop& run = {});

  /// The staged build, for a caller that spreads the pass over time (the engine refines while
  /// it builds): range_data(vol, hier, staged) reads nothing; build_pieces() over [0,
  /// piece_count()) in any order and grouping, then finish() (the ranges: a min/max pass at
  /// memory speed), then the same for the errors (below), make the same data as the
  /// constructor above. Until complete(), only empty() may be asked (it reads no samples).
  struct staged_t {};
  static constexpr staged_t staged{};
  range_data(const volume& vol, const hierarchy& hier, staged_t);
  /// Independent pieces of the pass (slabs of bricks): two calls may build different pieces at
  /// the same time.
  [[nodiscard]] std::size_t piece_count() const noexcept;
  /// The relative cost of building pieces [first, last) of the min/max pass: the sample planes
  /// they read. Pieces differ (the first and last slabs lie mostly in the padding and read one
  /// plane each; the others four), so a caller estimating the time a staged build has left
  /// from the pieces built so far weighs them by this.
  [[nodiscard]] std::uint64_t piece_work(std::size_t first, std::size_t last) const noexcept;
  void build_pieces(std::size_t first, std::size_t last, const parallel_loop& run = {});
  /// The coarser levels, once every piece is built (independent planes of each level through
  /// `run` when given); then complete(): ranges are final, and errors of scale ≥ 2 are the bound
  /// hi − lo (sound and nested, but coarser) until the error pass is finished too.
  void finish(const parallel_loop& run = {});
  [[nodiscard]] bool complete() const noexcept { return complete_; }
  /// The error pass, after finish(): pieces in any order and grouping (concurrently with get()
  /// calls from other threads), then finish_errors(); errors_exact() from then on.
  [[nodiscard]] std::size_t error_piece_count() const noexcept;
  void build_error_pieces(std::size_t first, std::size_t last, const parallel_loop& run = {});
  void finish_errors(const parallel_loop& run = {});
  [[nodiscard]] bool errors_exact() const noexcept;
  /// Both passes of pieces [first, last) at once, each piece's samples read into cache once;
  /// only when error_piece_count() == piece_count() (no error pass counts as already done).
  void build_pieces_with_errors(std::size_t first, std::size_t last, const parallel_loop& run = {});
  /// The bytes that pieces [first, last) of a staged build hold (both passes), contiguous: for
  /// processes that each build different pieces (MPI ranks) and copy every piece's bytes to the
  /// others before finish() and finish_errors(), which then make the same data as one process.
  /// A piece's bytes depend only on the volume, so a copy is as good as a build. Empty where the
  /// data has no such pieces (a smoothed field's bound needs no pass to share).
  [[nodiscard]] std::span<std::byte> piece_bytes(std::size_t first, std::size_t last) noexcept;
  /// Refused at compile time: the range data keeps pointers to both (detail/borrow.hpp).
  template <class V, class H>
  requires detail::any_rvalue<V, H> range_data(V&&, H&&)
  = delete;
  template <class V, class H, class R>
  requires detail::any_rvalue<V, H> range_data(V&&, H&&, R&&)
  = delete;
  ~range_data();
  range_data(range_data&&) noexcept;
  range_data& operator=(range_data&&) noexcept;

  /// Nested range and error of diamond d: ≤ 64 bricks for scale ≥ 2, ≤ 69 samples for scale 1.
  [[nodiscard]] diamond_range get(const diamond& d) const noexcept;
  /// The same for the diamond centred at `centre` (a diamond of the hierarchy), without
  /// building the diamond when it is not needed.
  [[nodiscard]] diamond_range get(const ipoint& centre) const noexcept;
  /// The same when the diamond's scale h is known (hierarchy::scale_of(centre)).
  [[nodiscard]] diamond_range get(const ipoint& centre, std::int32_t scale) const noexcept;
  /// get(centre, scale).straddles(w.w), reading only as many samples as it takes to decide (no
  /// error computed). `w` is made once per isovalue.
  [[nodiscard]] bool straddles(const ipoint& centre, std::int32_t scale,
                               const detail::sample_threshold& w) const noexcept;
  /// get(centre, scale).error alone. At scale 1 it reads only the samples of the subtree's
  /// splits (a cube centre's: 27 of its 69), not the range's: an error-driven refinement asks it
  /// for every ready diamond once a straddle test (or owning a piece of its parent's surface)
  /// has kept it.
  [[nodiscard]] double error(const ipoint& centre, std::int32_t scale) const noexcept;
  /// get(centre, scale).straddles(w.w) and its error, for a caller that needs the error only up
  /// to `bound` (a refinement to an error target ≤ bound, in any order): the error is get()'s
  /// when at most `bound`, otherwise some value above `bound` (not necessarily the diamond's).
  /// Reads only as much as it takes to know both.
  [[nodiscard]] straddle_and_error test_upto(const ipoint& centre, std::int32_t scale, double bound,
                                             const detail::sample_threshold& w) const noexcept;
  /// error(centre, scale) the same way: exact when at most `bound`, else some value above it.
  [[nodiscard]] double error_upto(const ipoint& centre, std::int32_t scale,
                                  double bound) const noexcept;
  /// True when get(centre, scale) is empty (the subtree lies wholly in the padding), without
  /// computing the range: O(1), no samples read.
  [[nodiscard]] bool empty(const ipoint& centre, std::int32_t scale) const noexcept;
  /// Own (not nested) range and split error of d, from its spine, ring and centre.
  [[nodiscard]] diamond_range own(const diamond& d) const noexcept;
  /// Bytes held.
  [[nodiscard]] std::size_t byte_size() const noexcept;

  struct impl;

 private:
  std::unique_ptr<impl> impl_;
  bool complete_ = false;
};

}  // namespace progiso
