// progiso/core/range_data.hpp — per-diamond value ranges and nested errors, built once per volume.
//
// For every diamond D, range(D) = [lo, hi] covers the field values at every grid vertex of every
// tetrahedron that D or any of its descendants ever has, and error(D) is the largest split error
// |f(centre) - (f(spine0) + f(spine1)) / 2| over D and its descendants. Both are nested: they
// never grow from a diamond to its children, so "range(D) straddles w" and "error(D) > ε" each
// select a parent-closed set of diamonds, a valid cut of the hierarchy. A diamond whose range
// does not straddle w (lo <= w < hi fails) holds no surface now and never will, so refinement
// never visits it: extraction is output sensitive. Neither depends on the isovalue, so a new
// isovalue reuses the same data.
//
// Diamonds whose subtree lies wholly in the padding beyond the data box get an empty range
// (their pieces of surface would all be clipped away).
//
// Storage: entries {lo, hi, error} in the volume's sample type (error as an unsigned integer of
// the same width, rounded up, or as float for floating-point volumes) for every diamond of scale
// h ≥ 2, in one dense array per scale clipped to the data box plus the margin a subtree can
// reach. That is about 1/8 of the grid vertices: about 0.44× the volume's own bytes for large
// volumes, up to ~0.86× for small ones where the margin counts. Diamonds of scale 1 (7/8 of
// all) are computed on demand from fixed stencils of samples that depend only on the centre
// mod 4 (about 60 reads for a cube centre, fewer for the others). Within 2 of the data
// boundary the stencils read clamped samples, a superset of the exact range and error: still
// sound for culling and still nested, because the build and every query use the same function.
//
// Thread safety: immutable after construction; concurrent get() calls are safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include <progiso/core/config.hpp>
#include <progiso/core/detail/borrow.hpp>
#include <progiso/core/detail/sample_threshold.hpp>
#include <progiso/core/error.hpp>
#include <progiso/core/hierarchy.hpp>
#include <progiso/core/volume.hpp>

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

/// The range data of one volume.
class range_data {
 public:
  /// Builds the data: one pass over the hierarchy, O(voxels).
  range_data(const volume& vol, const hierarchy& hier);
  /// Refused at compile time: the range data keeps pointers to both (detail/borrow.hpp).
  template <class V, class H>
  requires detail::any_rvalue<V, H> range_data(V&&, H&&)
  = delete;
  ~range_data();
  range_data(range_data&&) noexcept;
  range_data& operator=(range_data&&) noexcept;

  /// Nested range and error of diamond d. Cost O(1) for stored scales, ≤ 51 samples otherwise.
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
};

}  // namespace progiso
