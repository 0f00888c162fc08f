// progiso/core/surface/detail/mesh_clip.hpp — how an extraction finishes a mesh: clipping the
// pieces that reach past the data box (only coarse tetrahedra of padded hierarchies do; crossing
// points are computed from the segment's ends in lexicographic order so neighbours agree
// exactly), physical coordinates, and dropping the vertices only clipped-away triangles used.
// Used by cut_mesher.hpp, the extraction of the refiner and of the engine.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/mesh.hpp>

namespace progiso::detail {

/// Sutherland–Hodgman clipping of one triangle (grid positions p, vertex ids ids) against
/// x_q ≤ box_q. Each crossing point is computed from the segment's ends in lexicographic order,
/// so the two triangles sharing a segment get the same point; a crossing point gets its id from
/// clip_vertex(position) only when a kept triangle uses it. Calls emit(ids) for each kept
/// triangle; returns, per corner, whether a kept triangle uses it (a corner outside the box
/// never is, and its id is never emitted).
template <class ClipVertex, class Emit>
std::array<bool, 3> clip_to_box(const std::array<vec3, 3>& p,
                                const std::array<std::uint32_t, 3>& ids, const vec3& box,
                                ClipVertex&& clip_vertex, Emit&& emit) {
  struct corner {
    vec3 p;
    std::uint32_t id;  // a vertex id, or none for a crossing point
  };
  constexpr std::uint32_t none = ~std::uint32_t{0};
  // Clipping a convex polygon by a plane adds at most one corner: at most 6 after 3 planes.
  std::array<corner, 8> poly{};
  std::array<corner, 8> next{};
  // From the corner with the smallest position, orientation kept: the clipped polygon's fan
  // then depends only on the oriented triangle, not on which corner a mesher lists first (the
  // engine's cuts and uniform_cut() list them differently and must clip alike).
  std::size_t first = 0;
  for (std::size_t i = 1; i < 3; ++i) {
    if (p[i] < p[first]) first = i;
  }
  for (std::size_t i = 0; i < 3; ++i) poly[i] = {p[(first + i) % 3], ids[(first + i) % 3]};
  std::size_t size = 3;
  for (std::size_t q = 0; q < 3 && size >= 3; ++q) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < size; ++i) {
      const corner& a = poly[i];
      const corner& b = poly[i + 1 == size ? 0 : i + 1];
      const bool ain = a.p[q] <= box[q];
      const bool bin = b.p[q] <= box[q];
      if (ain) next[kept++] = a;
      // A crossing whose inside end lies on the plane is that end itself, already emitted.
      const bool on_plane = ain ? a.p[q] == box[q] : b.p[q] == box[q];
      if (ain != bin && !on_plane) {
        vec3 lo = a.p;
        vec3 hi = b.p;
        if (hi < lo) std::swap(lo, hi);
        const double s = (box[q] - lo[q]) / (hi[q] - lo[q]);
        vec3 x{};
        for (std::size_t k = 0; k < 3; ++k) x[k] = lo[k] + s * (hi[k] - lo[k]);
        x[q] = box[q];
        next[kept++] = {x, none};
      }
    }
    PROGISO_ASSERT(kept <= 6);
    poly = next;
    size = kept;
  }
  std::array<bool, 3> used{};
  for (std::size_t i = 1; i + 1 < size; ++i) {
    const std::array<corner*, 3> t{&poly[0], &poly[i], &poly[i + 1]};
    if (t[0]->p == t[1]->p || t[1]->p == t[2]->p || t[0]->p == t[2]->p) continue;
    std::array<std::uint32_t, 3> tri{};
    for (std::size_t k = 0; k < 3; ++k) {
      if (t[k]->id == none) {
        t[k]->id = clip_vertex(t[k]->p);
      } else {
        for (std::size_t j = 0; j < 3; ++j) used[j] = used[j] || ids[j] == t[k]->id;
      }
      tri[k] = t[k]->id;
    }
    emit(tri);
  }
  return used;
}

/// Hash of a position's bit pattern (-0 as 0): crossing points of clipping are merged by
/// position (every crossing is computed the same way, so equal points are equal doubles).
struct position_hash {
  std::size_t operator()(const vec3& p) const noexcept;
};

/// Physical coordinates of a grid position of vol (origin + position × spacing); vol is a
/// volume or anything with its spacing() and origin().
template <class Field>
[[nodiscard]] inline vec3 physical_position(const Field& vol, const vec3& p) noexcept {
  const auto& sp = vol.spacing();
  const auto& org = vol.origin();
  return vec3{org[0] + p[0] * sp[0], org[1] + p[1] * sp[1], org[2] + p[2] * sp[2]};
}

/// Drops the vertices no triangle uses, when one of `suspects` (vertex ids) is among them,
/// renumbering the rest in order of first use. Whether one is: one scan of the triangles, in
/// `parts` pieces through `run` (on this thread when `run` is empty).
void drop_unused(triangle_mesh& m, const std::vector<std::uint32_t>& suspects,
                 const parallel_loop& run = {}, std::size_t parts = 1);

}  // namespace progiso::detail
