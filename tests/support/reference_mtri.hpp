// tests/support/reference_mtri.hpp — the independent 2D reference extractor (oracle of
// invariant 1 for images), and the shared 2D test images.
//
// Plain marching triangles over the finest mesh of the 2D longest-edge bisection hierarchy:
// every unit square [i, i+1] × [j, j+1] inside the image is cut into 2 triangles by the diagonal
// that joins its all-even corner to its all-odd corner (docs/ARCHITECTURE.md, "The hierarchy"), and
// each triangle is marched on its own. The rules, re-implemented here from their statement
// alone (nothing of progiso's hierarchy or extraction code is called):
//
//  * black if f > w, white if f <= w; an edge is crossed when its ends differ in colour;
//  * the contour vertex on a crossed edge is interpolated from its canonically ordered ends
//    (lower (y, x) first, row before column): t = (w − fa) / (fb − fa), clamped into
//    [1/4096, 1 − 1/4096], grid position a + t (b − a) per axis, then origin + grid × spacing
//    (the image's first two axes; exact identity for the default origin 0 and spacing 1);
//  * it is named by the edge's key: the doubled midpoint a + b packed x | y << 32 (the packing
//    of progiso::edge_key2);
//  * a crossed triangle gives one segment joining its two crossed edges, directed so that the
//    black region is on its left in the (x, y) frame: cross(q − p, b − p) > 0 for segment p → q
//    and a black corner b, decided exactly on the doubled midpoints.
//
// The fully refined progressive contour must equal this one segment for segment (same
// positions, bit for bit, same directions). Cost O(pixels) time, O(contour) memory; NaN samples
// are not supported.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

#include <progiso/core/contour/contour.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::test {

/// One directed contour segment of the finest mesh: positions and edge keys of its two ends.
struct segment {
  std::array<vec2, 2> p{};
  std::array<std::uint64_t, 2> keys{};
};

/// Marching triangles at isovalue w on the finest mesh of `image` (dims {w, h, 1}), one segment
/// per crossed triangle, triangles in row-major order of their unit squares. Throws
/// progiso::error when the isovalue is NaN or the image is not one sample thick.
[[nodiscard]] std::vector<segment> reference_segments(const volume& image, double isovalue);

/// The same segments chained by shared edge keys into maximal polylines: open chains first (in
/// order of their first segment), then closed loops; one vertex per crossed edge; every
/// polyline carries `isovalue`. Throws like reference_segments().
[[nodiscard]] contour_set reference_contours(const volume& image, double isovalue);

/// One shared 2D test image: file name (binary PGM) and the isovalues its README suggests.
struct shared_image {
  std::string_view name;
  std::string_view file;
  std::vector<double> isovalues;
};

/// The shared 2D images (data README.md): camera, coins (8-bit) and the Jacksboro DEM
/// (16-bit).
[[nodiscard]] const std::vector<shared_image>& shared_images();

/// Reads a binary PGM (P5, maxval < 256: u8 samples, else big-endian u16) into an image
/// volume {w, h, 1}, on purpose independent of progiso's own image reader. Throws
/// progiso::error naming the file when it cannot be read or is not such a PGM.
[[nodiscard]] volume load_pgm(const std::filesystem::path& path);

/// A w × h float image sampling f(x, y) at the pixel centres' grid coordinates.
[[nodiscard]] volume make_test_image(std::int64_t w, std::int64_t h, double (*f)(double, double));

}  // namespace progiso::test
