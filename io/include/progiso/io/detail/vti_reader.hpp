// progiso/io/detail/vti_reader.hpp — progiso's own reader of VTK's XML image data (.vti),
// what ParaView and VTK write for a regular grid (simulation output, processed scans), behind
// read_vti() and volume_input_files().
//
// Our own reader because VTK, the only other, is a very large dependency whose headers do not
// compile as C++20; it stays the tests' reference (docs/formats.md).
//
// Accepted: <VTKFile type="ImageData"> (version 0.1 to 2.x) with byte_order LittleEndian or
// BigEndian, header_type UInt32 (the default) or UInt64, and no compressor or
// vtkZLibDataCompressor; <ImageData> with WholeExtent (2 to 32769 points per axis), Origin,
// Spacing and Direction (all optional), holding one <Piece> whose Extent is the whole extent;
// its <PointData> array named by the Scalars attribute, else the first <DataArray> there, of
// one component and type Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32 or Float64, in
// any of the writer's data modes: format="ascii" (numbers in the element), "binary" (base64 in
// the element) or "appended" (at `offset` in <AppendedData>, encoding "raw" or "base64"),
// each binary block a header (byte count, or block count, sizes and compressed sizes) then the
// data, compressed or not. Refused with a message: other dataset types, several pieces, cell
// data only, vectors, 64-bit integers, LZ4 and LZMA compression, and XML the writer never
// makes (CDATA sections, a document whose elements do not nest).
//
// The XML is scanned, never held: a streaming tokenizer reads tags (each at most
// header_max_line_bytes) through one 64 KiB buffer, skips every element's text, and stops at
// the underscore that starts the appended data, so a file of gigabytes of appended data costs
// its header's bytes. Only the chosen array's data is then decoded, from its offset.
//
// Bounds: before the samples are allocated, the bytes after the array's start must be able to
// hold them (raw: the bytes themselves; base64: 4 characters per 3 bytes; ascii: 2 bytes a
// value; zlib: the declared compressed sizes must lie in the file and inflate to at most
// gzip_max_ratio × their size). A block header's counts are checked against the file before
// its table is allocated, and every block must inflate to exactly its declared size.
//
// Geometry: VTK places point (i, j, k) of the extent at Origin + Direction · (Spacing ⊙ (i, j,
// k)), with (i, j, k) counted from 0 at the extent's origin, not from its first index: so the
// volume's origin is Origin + Spacing ⊙ (x0, y0, z0) when Direction is the identity (the world
// map holds the general case), and its spacing |Spacing| (zero or non-finite: 1).
//
// Thread safety: no global state. Every failure throws progiso::error with one line naming the
// file.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

enum class vti_data_format : std::uint8_t { ascii, binary, appended };

/// A .pvti names at most this many pieces.
inline constexpr std::size_t vti_max_pieces = std::size_t{1} << 20;

struct vti_header {
  std::array<std::int64_t, 6> extent{};  ///< WholeExtent: x0 x1 y0 y1 z0 z1
  index3 dims{};                         ///< points per axis, each in 2..32769
  sample_type type = sample_type::u8;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  index_to_world world;         ///< point index → the file's coordinates
  bool big_endian = false;      ///< byte order of binary data
  bool uint64_headers = false;  ///< header_type="UInt64"
  bool zlib = false;            ///< compressor="vtkZLibDataCompressor"
  vti_data_format format = vti_data_format::ascii;
  bool base64 = false;            ///< binary data (inline, or appended with encoding base64)
  std::uint64_t data_offset = 0;  ///< the array's first byte (or character) in the file
  std::string array;              ///< the array's Name, for messages
};

/// One piece a .pvti names: its extent (inside the whole one) and its .vti file, resolved
/// against the .pvti's directory.
struct pvti_piece {
  std::array<std::int64_t, 6> extent{};
  std::filesystem::path file;
};

/// A parallel image (.pvti): the whole grid, its geometry and point array, and its pieces.
struct pvti_header {
  std::array<std::int64_t, 6> extent{};
  index3 dims{};
  sample_type type = sample_type::u8;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  index_to_world world;
  std::string array;
  std::vector<pvti_piece> pieces;
};

/// Parses a .vti file (opened at its start) up to its appended data: its grid, geometry and the
/// point array read as the volume (`array` when given, else the one Scalars names, else the
/// first). Throws progiso::error naming the file for anything outside the accepted subset above.
[[nodiscard]] vti_header parse_vti_header(input_file& file, std::string_view array = {});

/// Decodes the chosen array's samples (host byte order), after the capacity checks above.
[[nodiscard]] std::vector<std::byte> read_vti_samples(const vti_header& header, input_file& file);

/// Parses a .pvti (VTK's parallel image data: <PImageData> with its WholeExtent, Origin, Spacing
/// and Direction, <PPointData> naming the arrays, one <Piece Extent Source> per piece file).
[[nodiscard]] pvti_header parse_pvti_header(input_file& file);

/// The whole grid's samples from the pieces: each piece's .vti read (the array by name, of the
/// same type, its WholeExtent the extent the .pvti gives, inside the whole one) and copied to its
/// place; points two pieces share (VTK's pieces overlap by one layer) take the later piece's
/// value. Before the grid is allocated, every piece's data must be able to hold its samples
/// and the pieces together at least the grid's; afterwards every point must have come from a
/// piece. Errors in a piece name the piece's file and the .pvti.
[[nodiscard]] std::vector<std::byte> read_pvti_samples(const pvti_header& header,
                                                       const std::filesystem::path& pvti);

/// Whether a file name asks for the .vti reader: .vti (any case).
[[nodiscard]] bool has_vti_name(const std::filesystem::path& file);
/// Whether a file name asks for the .pvti reader: .pvti (any case).
[[nodiscard]] bool has_pvti_name(const std::filesystem::path& file);

}  // namespace progiso::detail
