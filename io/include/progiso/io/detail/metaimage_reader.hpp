// progiso/io/detail/metaimage_reader.hpp — progiso's own MetaImage reader (.mha, .mhd: the
// format of ITK, 3D Slicer's older exports and many CT research collections), behind
// read_metaimage() and volume_input_files().
//
// Our own reader because Debian ships MetaIO only inside ITK and VTK (docs/formats.md).
//
// A MetaImage header is text, one "Key = Value" field per line, ended by the ElementDataFile
// field: LOCAL (the data follows that line in the same file), one file name, "LIST [kD]" (the
// names follow, one per line) or a pattern "NAME%0Nd.raw MIN MAX STEP [kD]" (one slice per
// file unless k says otherwise). Keys are matched exactly, as MetaIO matches them; unknown keys
// are ignored, as MetaIO ignores them; a key given twice is refused. Accepted: NDims 3 (or more
// with sizes of 1 above the third), DimSize of 2 to 32769 per axis, ElementType MET_UCHAR,
// MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_ULONG, MET_LONG (4 bytes, as in
// MetaIO), MET_FLOAT, MET_DOUBLE, one channel, binary data in either byte order
// (ElementByteOrderMSB or BinaryDataByteOrderMSB), zlib-compressed (CompressedData) or ASCII
// (BinaryData = False), HeaderSize bytes skipped before the data (-1: the data ends the file;
// with LOCAL data a positive HeaderSize is an offset from the start of the file, as MetaIO reads
// it). Refused with a message: other objects than Image, 2-D images, vector and 64-bit types,
// several channels, a HeaderSize with compressed data.
//
// MetaImage's data layouts are a subset of NRRD's (raw, zlib and ascii data; one file, a list
// or a pattern of files with equal shares; bytes to skip, or "the data ends the file"), so the
// header is reduced to a nrrd_header (format "MetaImage") and read by read_nrrd_samples(), with
// its capacity checks before allocation (memory follows the data present) and its messages.
//
// Geometry: spacing per axis is |ElementSpacing| (else |ElementSize|; zero or non-finite: 1),
// the origin is Offset (or its synonyms Position and Origin); the direction cosines
// (TransformMatrix, or Rotation, Orientation) are not applied to the volume, whose positions are
// origin + index × spacing, but nrrd_header::world keeps the whole index-to-space map: row i of
// TransformMatrix is the direction of index axis i, as ITK reads it.
//
// Thread safety: no global state; different files may be read concurrently. Every failure
// throws progiso::error with one line naming the file.
#pragma once

#include <filesystem>

#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {

/// At most this many dimensions (MetaIO's own limit is 10).
inline constexpr unsigned metaimage_max_dimensions = 10;

/// Parses the header of `header_file` (opened at its start). Throws progiso::error naming the
/// file for a line without "=", an over-long line, a NUL byte, a key given twice, a value that
/// does not parse (quoted, at most 40 bytes), a missing NDims, DimSize, ElementType or
/// ElementDataFile, and every unsupported feature.
[[nodiscard]] nrrd_header parse_metaimage_header(input_file& header_file);

/// Whether a file name asks for the MetaImage reader: .mha or .mhd (any case).
[[nodiscard]] bool has_metaimage_name(const std::filesystem::path& file);

}  // namespace progiso::detail
