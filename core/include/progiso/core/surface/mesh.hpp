// progiso/core/surface/mesh.hpp — the indexed triangle mesh that extraction produces.
//
// Vertices are stored once and shared by index; a vertex shared by several triangles is
// bit-identical for all of them by construction (extraction computes each surface vertex once,
// from a canonical ordering of its grid edge). Triangles are oriented counter-clockwise seen
// from the side of decreasing field values: the right-hand normal points out of the region
// f > isovalue. Coordinates are physical: origin + grid index * spacing.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

using vec3 = std::array<double, 3>;

/// An indexed triangle mesh.
struct triangle_mesh {
  std::vector<vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;

  [[nodiscard]] bool empty() const noexcept { return triangles.empty(); }
};

}  // namespace progiso
