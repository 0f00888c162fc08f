// bench/surface_distance.hpp — how much of one surface lies near another: the measure of the
// quality a deadline buys (peer_bench.cpp, BM_deadline_quality).
#pragma once

#include <cstddef>
#include <cstdint>

#include <progiso/core/surface/mesh.hpp>

namespace progiso::bench {

struct area_coverage {
  double fraction = 0.0;    ///< of the reference's area within the radius of the cut
  std::size_t samples = 0;  ///< points drawn on the reference
};

/// The fraction of `reference`'s area that lies within `radius` of the surface `cut`. Estimated
/// from `samples` points drawn uniformly by area on the reference (a fixed seed: the same points
/// for every cut of one reference), each with its exact Euclidean distance to the cut's
/// triangles (a CGAL AABB tree). 0 for an empty cut; 1 for an empty reference.
[[nodiscard]] area_coverage area_within(const triangle_mesh& reference, const triangle_mesh& cut,
                                        double radius, std::size_t samples, std::uint64_t seed = 1);

}  // namespace progiso::bench
