// progiso/core/contour/range_data2d.hpp — per-diamond value ranges and nested errors of a 2D image.
//
// The 2D counterpart of range_data.hpp. For every diamond D of a hierarchy2d, range(D) = [lo, hi]
// covers the image values at every grid vertex of every triangle that D or any of its
// descendants ever has (spine ends, apexes, centre), and error(D) is the largest split error
// |f(centre) − (f(spine0) + f(spine1)) / 2| over D and its descendants. Both are nested: they
// never grow from a diamond to its children, so "range straddles w" and "error > ε" each select
// a parent-closed set of diamonds, a valid cut. A diamond whose range does not straddle w holds
// no contour now and never will, so refinement never visits it. Neither depends on the isovalue.
// Padding vertices beyond the data box take the nearest data value (volume::value); diamonds
// whose region lies wholly beyond the data box (hierarchy2d::outside_data) contribute nothing,
// so a subtree made only of those has an empty range and error 0.
//
// Storage: entries {lo, hi, error} in the image's sample type (error as an unsigned integer of
// the same width, rounded up and saturated, or as float rounded up for floating-point images)
// for the diamonds of scale h ≥ 2, one array per scale holding only that scale's centres (3/4
// of the points c ≡ 0 mod h), clipped to c < data_max + subtree_reach(0, h) per axis: beyond
// that every descendant is outside the data box. That is one entry of 3 samples' width per
// ~4 pixels: about three quarters of the image's own bytes for every sample type, a little more
// on the shared images, where the clip margins count (bench/README.md). Diamonds of scale 1 (3/4
// of all) are computed on demand from at most 13 samples.
//
// For small or thin padded images (a side of about 10 to 20 samples), where the clip margins
// would outweigh the data, the finest stored scale is raised until the arrays fit in the
// image's bytes and the scales below it are computed on demand from the definition (in
// practice only scale 2, about 100 samples), so byte_size() ≤ image.byte_size() always holds.
// Integer errors are therefore exact (not rounded) for the scales computed on demand and
// rounded up for the stored ones; nesting holds either way, because every stored parent is
// built from its children's get().
//
// NaN samples are not supported. Cost: one pass over the stored diamonds, O(pixels).
//
// Thread safety: immutable after construction; concurrent get() calls are safe. The image and
// the hierarchy must outlive the range data (it keeps pointers to both).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/borrow.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/ranges/range_data.hpp>

namespace progiso {

/// The range data of one image.
class range_data2d {
 public:
  /// Builds the data for `image` (dims {w, h, 1}) on `hier` (built for w × h). Throws
  /// progiso::error when the image is not one sample thick or its size differs from the
  /// hierarchy's data box.
  range_data2d(const volume& image, const hierarchy2d& hier);
  /// Refused at compile time: the range data keeps pointers to both (detail/borrow.hpp).
  template <class V, class H>
  requires detail::any_rvalue<V, H> range_data2d(V&&, H&&)
  = delete;
  ~range_data2d();
  range_data2d(range_data2d&&) noexcept;
  range_data2d& operator=(range_data2d&&) noexcept;

  /// Nested range and error of diamond d. O(1) for stored scales, ≤ 13 samples for scale 1
  /// (about 100 for a scale below finest_stored_scale() other than 1).
  [[nodiscard]] diamond_range get(const diamond2& d) const noexcept;
  /// The same for the diamond centred at `centre` (precondition: hier.is_diamond(centre)).
  [[nodiscard]] diamond_range get(const ipoint2& centre) const noexcept;
  /// The same, for a caller that knows the diamond's scale (hier.scale_of(centre)).
  [[nodiscard]] diamond_range get(const ipoint2& centre, std::int32_t scale) const noexcept;
  /// Own (not nested) range and split error of d: centre, spine ends and in-grid apexes;
  /// empty with error 0 when d lies wholly beyond the data box.
  [[nodiscard]] diamond_range own(const diamond2& d) const noexcept;
  /// Bytes held by the stored entries; never more than the image's byte_size() (for a
  /// smoothed image, smoothing.hpp: its rows and a min/max pyramid of the data).
  [[nodiscard]] std::size_t byte_size() const noexcept;
  /// The smallest stored scale (2 except for tiny padded images; larger than any diamond's
  /// scale when nothing is stored).
  [[nodiscard]] std::int32_t finest_stored_scale() const noexcept;

  /// How far, per axis, the subtree of a diamond of this type and scale h reaches below its
  /// centre: every descendant D' (D included) has c'_q − h' ≥ c_q − reach on both axes. A
  /// diamond with c_q ≥ data_max_q + reach on some axis therefore has only descendants wholly
  /// beyond the data box: an empty range and error 0. Type 1: 2h − 1 (own h, or h/2 to a child
  /// of type 0 and scale h/2 plus its reach); type 0: 3h − 1 (h to a type-1 child of the same
  /// scale plus its reach). Tight: some descendant attains it.
  [[nodiscard]] static constexpr std::int32_t subtree_reach(int type, std::int32_t h) noexcept {
    return (type == 0 ? 3 : 2) * h - 1;
  }

  struct impl;

 private:
  std::unique_ptr<impl> impl_;
};

}  // namespace progiso
