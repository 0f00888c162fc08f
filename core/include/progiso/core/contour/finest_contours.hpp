// progiso/core/contour/finest_contours.hpp — the finest cut's contours of an image in two
// passes over its pixels, without the hierarchy: what full 2D refinement ends at.
//
// The finest triangulation of an image cuts each unit square by its diagonal from the corner
// with even coordinates. Its marching-triangles contour is the finest cut's: the same segments
// (march_triangle(): black on the left), the same vertices (interpolate2() on the same edge
// ends, then origin + position × spacing), chained into polylines by the same rule as the
// refiner's extraction (each vertex has at most one segment out and one in; open polylines
// from the vertices with none in, then the closed ones, each from its lowest vertex id). Only
// the numbering differs: vertices follow their grid point (y, then x) and owned edge (+x, +y,
// the square's diagonal), where the refiner numbers them as its records meet them.
//
// How, as for the finest surface (surface/finest_surface.hpp): a first pass gives each pixel
// its square's corner colours and the owned edges it crosses, placing their vertices in order;
// a second pass names each crossed square's segment ends by their owners' running ids (two rows
// of counters) and links them; the chaining walks the links. No key table, no lookup per vertex.
//
// Cost: the pixels are read once (and the crossed edges' ends again); one byte per pixel, and
// two 4-byte links and a flag per contour vertex. Thread safety: reads `image` only.
#pragma once

#include <progiso/core/base/config.hpp>
#include <progiso/core/contour/contour.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso {

/// The contours of the finest cut of `image` (dims w, h, 1) at `isovalue` (see the file
/// comment), in physical coordinates. Throws progiso::error for a volume deeper than one
/// sample, a non-finite isovalue and 2^32 vertices or more.
[[nodiscard]] contour_set finest_contours(const volume& image, double isovalue);

}  // namespace progiso
