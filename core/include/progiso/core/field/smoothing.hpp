// progiso/core/field/smoothing.hpp — the smoothed field of a volume (paper §6): the values at the
// vertices refinement inserts come from the interpolatory tensor-product 4-point subdivision rule
// instead of from the data, so a smooth surface is refined, cut, interrupted and extracted exactly
// like the data's own, with every guarantee of a refined one.
//
// The rule. Mask m = [−α/16, (8+α)/16, (8+α)/16, −α/16]; one subdivision level halves the grid
// spacing. A new edge midpoint takes m over the 4 samples of the coarser level along its axis, a
// face centre m ⊗ m over 4 × 4 in its plane, a cube centre m ⊗ m ⊗ m over 4 × 4 × 4; old samples
// keep their values (interpolation). 0 < α < 2(√5 − 1) converges to a smooth limit; α = 1
// reproduces tensor-product cubics.
//
// Boundary rule. A stencil that reaches past the ends of an axis uses a ghost sample extrapolated
// linearly from the two nearest samples of the same level: f(−1) = 2 f(0) − f(1), and likewise at
// the far end. Linear functions are reproduced everywhere; cubics wherever no ghost is involved.
//
// The field (`smoothing`):
// - levels = S: S subdivision levels below the data, each halving the spacing. The smoothed
//   volume has (n − 1)·2^S + 1 samples per axis, spacing / 2^S, the same origin.
// - from = K: the data is used only at every 2^K-th sample (the control grid); K more levels of
//   the rule bring it back to the data's resolution. When 2^K does not divide n − 1 the last
//   control point lies past the data and is a ghost (boundary rule).
// - region: a box in the data's index coordinates (inclusive). Smoothing applies to the points
//   of the fine grid inside it; outside it the field is the data's own values, interpolated
//   linearly between data samples when S > 0 (the rule with α = 0 and K = 0). One field on one
//   grid, so the refined mesh is conforming across the box's faces and every cut stays valid.
//
// Lazy values. The composition of the per-level rule is, along each axis, one linear map from the
// data samples to the fine samples; each fine sample takes at most 7 data samples per axis
// (6 of the 4-point rule's support, one more where a ghost is extrapolated). Those rows are built
// once per axis (O(n·2^S) doubles), and a fine sample is the tensor product of three rows applied
// to the data: computed only when refinement or extraction reads it, never stored. No volume of
// 8^S times the data is ever made; the memory per smoothing level is the rows (a few kilobytes)
// and a min/max pyramid of the data (2 doubles per 4³ samples, built once).
//
// Ranges stay sound. Every row sums to 1, so a fine value v = Σ w_i f_i satisfies
// min f − λ (max f − min f) ≤ v ≤ max f + λ (max f − min f) over the data samples of its rows,
// with λ = (Σ|w| − 1) / 2 ≤ (Π_q L_q − 1) / 2, L_q the largest absolute row sum on axis q. The
// range data of a smoothed volume takes that bound over the data samples that the rows of a
// diamond's subtree box reach (range_data.cpp): sound for culling, and nested.
//
// Thread safety: a smoothed volume is immutable after construction; concurrent reads are safe.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>

#include <progiso/core/field/volume.hpp>

namespace progiso {

/// What to smooth, and how (see the header comment).
struct smoothing {
  int levels = 0;  ///< S: 0 to 3 levels below the data's resolution
  int from = 0;    ///< K ≥ 0: the data is used on every 2^K-th sample only
  /// X0, Y0, Z0, X1, Y1, Z1 in the data's index coordinates, inclusive; none: everywhere.
  std::optional<std::array<std::int64_t, 6>> region;
  double alpha = 1.0;  ///< the mask's α, in (0, 2(√5 − 1))

  /// Whether the field differs from the data (S ≥ 1 or K ≥ 1).
  [[nodiscard]] bool active() const noexcept { return levels > 0 || from > 0; }
};

/// The largest α for which the rule converges: 2(√5 − 1).
inline constexpr double max_smoothing_alpha = 2.4721359549995794;

/// The smoothed field of `data` as a volume (its samples computed on demand; it keeps `data`
/// alive). Throws progiso::error naming the bad parameter when S is outside 0…3, K < 0, 2^K
/// exceeds n − 1 on an axis with more than one sample, α is outside (0, 2(√5 − 1)), the region
/// is reversed or leaves the data, or the fine grid would exceed 32769 samples per axis.
[[nodiscard]] volume smooth(std::shared_ptr<const volume> data, const smoothing& s);

/// Checks `s` against a volume of these dims without building anything; throws as smooth() does.
void check_smoothing(const index3& dims, const smoothing& s);

}  // namespace progiso
