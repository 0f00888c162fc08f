// progiso/io/detail/vtk_legacy_reader.hpp — progiso's own reader of VTK's legacy format
// (.vtk) for image data, the classic output of simulation codes and of VTK and ParaView, behind
// read_vtk_legacy() and volume_input_files().
//
// Our own reader because VTK, the only other, is a very large dependency whose headers do not
// compile as C++20; it stays the tests' reference (docs/formats.md).
//
// Accepted: "# vtk DataFile Version x.y", a title line, ASCII or BINARY (big-endian, as the
// format requires), DATASET STRUCTURED_POINTS with DIMENSIONS (2 to 32769 per axis), SPACING (or
// the old ASPECT_RATIO) and ORIGIN in any order, then POINT_DATA with the number of points and,
// first, either SCALARS name type [1] with its LOOKUP_TABLE line (which VTK requires) or a FIELD
// whose first array has one component per point; later attributes are not read. Keywords are
// matched in any case, as VTK matches them. Types: unsigned_char, char, signed_char,
// unsigned_short, short, unsigned_int, int, float, double. Refused with a message: other datasets,
// CELL_DATA before the point data, vectors, several components, bit and 64-bit types.
//
// The data lies after the header in the same file, raw big-endian or ASCII, so the header is
// reduced to a nrrd_header (format "VTK") and the samples are read by read_nrrd_samples(): the
// same capacity checks before allocation (memory follows the data present) and messages.
//
// Geometry: spacing |SPACING| per axis (zero or non-finite: 1), origin ORIGIN; structured points
// are axis-aligned, so the world map is origin + index × SPACING.
//
// Thread safety: no global state. Every failure throws progiso::error with one line naming the
// file.
#pragma once

#include <filesystem>

#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {

/// Parses the header of a legacy VTK file (opened at its start) up to its first point array.
/// Throws progiso::error naming the file for a missing magic, an unknown or repeated keyword, a
/// value that does not parse, a point count that is not DIMENSIONS' product, and every
/// unsupported feature.
[[nodiscard]] nrrd_header parse_vtk_legacy_header(input_file& file);

/// Whether a file name asks for the legacy VTK reader: .vtk (any case).
[[nodiscard]] bool has_vtk_legacy_name(const std::filesystem::path& file);

}  // namespace progiso::detail
