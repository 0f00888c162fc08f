// progiso/core/refine/goal.hpp — what a run refines towards: the one vocabulary of goals.
//
// Every entry that refines takes a refine_goal: the one-shot calls (extract_isosurface(),
// extract_contours() through their options' `goal`), both engines (scheduler::engine and
// scheduler::contour_engine: start(goal), refine(goal)) and the command (--full, --error,
// --max-triangles / --max-segments, --time-ms). The paper's scenarios map onto it: quality
// driven is kind::error, time critical kind::deadline; asynchronous interruption and dynamic
// isovalues are the engines' cancel() and set_isovalue() during a run towards any goal.
//
// Adding a goal: an enumerator here, its factory, a check in check_goal(), and one case in each
// strategy that switches on `kind` (docs/ARCHITECTURE.md, "Where to change what").
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/refine/deadline.hpp>

namespace progiso {

/// Where a run refines first (what a view needs): a box of grid coordinates, or a point (lo ==
/// hi). A run by priority keys each ready diamond by its error times its weight: 1 when the
/// diamond's reach (focus_reach()) meets the box, else falloff / (falloff + d), d the distance
/// from the box to the reach (0 outside when falloff is 0). Weights never grow from a diamond to
/// its children (a child's reach lies in each parent's), so keys stay nested, the cut stays
/// closed under parents, and inside the box every goal behaves as without a focus: an error
/// target splits there exactly the diamonds of error above it, and outside it to the target over
/// the weight (a screen-space error when the point is the eye). Full runs ignore the focus (they
/// split everything), and an error target in any order is taken by priority. The 3D engine
/// honours it (scheduler/engine.hpp); core's sequential extract_isosurface() and the 2D paths
/// ignore it.
///
/// A view adds its frustum: planes a·x + b·y + c·z + d ≥ 0 (grid coordinates) that the part of
/// the box on screen lies inside. A diamond whose reach lies wholly outside one of them is out of
/// view, and its weight is multiplied by `outside` (0: never split for this focus). Out of view
/// is nested too (a child's reach lies in its parent's, so a parent out of view has its children
/// out of view), so the cut stays closed under parents. With the eye as the point and a falloff
/// small beside the distances, error × weight is the error over the distance to the eye, the
/// screen-space error of a diamond hierarchy (Gregorski et al. 2002), culled to the frustum.
struct refine_focus {
  std::array<double, 3> lo{};
  std::array<double, 3> hi{};
  double falloff = 0.0;                           ///< grid units, non-negative
  std::array<std::array<double, 4>, 6> planes{};  ///< the first plane_count are the frustum's
  std::uint32_t plane_count = 0;                  ///< at most 6
  double outside = 1.0;                           ///< weight factor out of view, in [0, 1]
  friend bool operator==(const refine_focus&, const refine_focus&) = default;
};

/// Half the side of the cube around a diamond's centre that holds its region and every
/// descendant's: 8h, 6h, 5h for types 0, 1, 2 at scale h. A parent's centre is h from its
/// child's along some axes (types 0→1, 1→2) or h/2 (type 2 → type 0 at h/2, whose reach is 4h
/// of the parent's h), so each child's cube lies in each parent's.
[[nodiscard]] constexpr double focus_reach(std::int32_t h, int type) noexcept {
  return static_cast<double>(h) * (type == 0 ? 8.0 : (type == 1 ? 6.0 : 5.0));
}

/// The weight of the diamond centred at c (scale h, type) under `f` (see refine_focus).
[[nodiscard]] inline double focus_weight(const refine_focus& f,
                                         const std::array<std::int32_t, 3>& c, std::int32_t h,
                                         int type) noexcept {
  const double r = focus_reach(h, type);
  double d2 = 0.0;
  for (std::size_t q = 0; q < 3; ++q) {
    const double lo = static_cast<double>(c[q]) - r;
    const double hi = static_cast<double>(c[q]) + r;
    const double gap = lo > f.hi[q] ? lo - f.hi[q] : (hi < f.lo[q] ? f.lo[q] - hi : 0.0);
    d2 += gap * gap;
  }
  double w = 1.0;
  if (d2 != 0.0) {
    if (f.falloff <= 0.0) return 0.0;
    w = f.falloff / (f.falloff + std::sqrt(d2));
  }
  for (std::uint32_t k = 0; k < f.plane_count && k < f.planes.size(); ++k) {
    const std::array<double, 4>& p = f.planes[k];
    // The reach cube's corner farthest along the plane's normal: below the plane, all is.
    const double farthest = p[0] * c[0] + p[1] * c[1] + p[2] * c[2] + p[3] +
                            r * (std::abs(p[0]) + std::abs(p[1]) + std::abs(p[2]));
    if (farthest < 0.0) return w * f.outside;
  }
  return w;
}

struct refine_goal {
  enum class kind {
    full,      ///< split every diamond whose range holds the isovalue: the finest cut
    error,     ///< split until every split left would change the surface by at most max_error
    budget,    ///< as many splits, largest error first, as keep max_elements (triangles in 3D,
               ///< segments in 2D)
    deadline,  ///< split largest error first until the clock reaches `deadline`
  };
  kind what = kind::full;
  double max_error = 0.0;                            ///< kind::error: non-negative
  std::uint64_t max_elements = 0;                    ///< kind::budget
  std::chrono::steady_clock::time_point deadline{};  ///< kind::deadline
  /// kind::error only: split the diamonds of error > max_error by grid plane, as a full run
  /// splits every straddling one, instead of largest error first. An error target fixes its
  /// split set, so the cut it ends on is the same either way; in any order it comes sooner
  /// because no priority queue orders the work, but the cuts published on the way are refined
  /// plane by plane, not the best of their size: for a caller that waits for the goal (a
  /// one-shot extraction), not for one that shows or interrupts the run. The 2D entries take
  /// their targets by priority either way.
  bool any_order = false;
  /// Refine here first (error, budget and deadline goals): see refine_focus.
  std::optional<refine_focus> focus;

  static refine_goal full() { return {}; }
  static refine_goal error(double e) { return {kind::error, e, 0, {}, false, {}}; }
  static refine_goal error_in_any_order(double e) { return {kind::error, e, 0, {}, true, {}}; }
  /// A budget of k triangles (3D) …
  static refine_goal triangles(std::uint64_t k) { return {kind::budget, 0.0, k, {}, false, {}}; }
  /// … or of k segments (2D): the same goal, named for the element counted.
  static refine_goal segments(std::uint64_t k) { return triangles(k); }
  static refine_goal until(std::chrono::steady_clock::time_point t) {
    return {kind::deadline, 0.0, 0, t, false, {}};
  }
  /// A deadline `budget` from now; a budget past the clock's range is no deadline at all
  /// (deadline_after() saturates).
  static refine_goal within(std::chrono::duration<double> budget) {
    return until(deadline_after(std::chrono::steady_clock::now(), budget));
  }
  /// This goal, refined inside the box [lo, hi] (grid coordinates) first.
  [[nodiscard]] refine_goal focused(const std::array<double, 3>& lo,
                                    const std::array<double, 3>& hi, double falloff = 0.0) const {
    refine_goal g = *this;
    g.focus = refine_focus{lo, hi, falloff};
    return g;
  }
  /// … or around a point.
  [[nodiscard]] refine_goal focused(const std::array<double, 3>& point, double falloff) const {
    return focused(point, point, falloff);
  }
  /// … or as a view sees it: around the eye, and `outside` times as much out of the frustum
  /// (at most six planes, grid coordinates; see refine_focus).
  [[nodiscard]] refine_goal viewed(const std::array<double, 3>& eye, double falloff,
                                   std::span<const std::array<double, 4>> frustum,
                                   double outside) const {
    if (frustum.size() > 6) throw progiso::error("focus: expected at most 6 frustum planes");
    refine_goal g = focused(eye, falloff);
    for (std::size_t k = 0; k < frustum.size(); ++k) g.focus->planes[k] = frustum[k];
    g.focus->plane_count = static_cast<std::uint32_t>(frustum.size());
    g.focus->outside = outside;
    return g;
  }
};

/// Throws progiso::error for a goal no run can take: an error target that is negative or NaN.
inline void check_goal(const refine_goal& goal) {
  if (goal.what == refine_goal::kind::error && !(goal.max_error >= 0.0)) {
    throw error("error threshold: expected a non-negative number, found " +
                std::to_string(goal.max_error));
  }
  if (goal.focus) {
    const refine_focus& f = *goal.focus;
    for (std::size_t q = 0; q < 3; ++q) {
      if (!std::isfinite(f.lo[q]) || !std::isfinite(f.hi[q]) || f.lo[q] > f.hi[q]) {
        throw error("focus: expected a box of finite coordinates with lo <= hi on every axis");
      }
    }
    if (!(f.falloff >= 0.0) || !std::isfinite(f.falloff)) {
      throw error("focus: expected a finite non-negative falloff, found " +
                  std::to_string(f.falloff));
    }
    if (f.plane_count > f.planes.size()) {
      throw error("focus: expected at most 6 frustum planes, found " +
                  std::to_string(f.plane_count));
    }
    for (std::uint32_t k = 0; k < f.plane_count; ++k) {
      const std::array<double, 4>& p = f.planes[k];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]) ||
          !std::isfinite(p[3]) || (p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0)) {
        throw error("focus: expected frustum planes of finite coefficients and a normal");
      }
    }
    if (!(f.outside >= 0.0 && f.outside <= 1.0)) {
      throw error("focus: expected an out-of-view factor in [0, 1], found " +
                  std::to_string(f.outside));
    }
  }
}

}  // namespace progiso
