// progiso/io/detail/nrrd_reader.hpp — progiso's own NRRD reader: a bounded header parser and
// a decoder for raw, gzip, ascii and hex data, behind read_nrrd() and volume_input_files().
//
// Our own parser rather than Teem's, because Teem expands a detached header's data-file pattern
// with sprintf into a buffer sized for the pattern plus ten digits (docs/formats.md).
//
// parse_nrrd_header() reads the header of an opened .nrrd or .nhdr file line by line, checks
// every field it knows (order-independent, each at most once), ignores key/value lines without
// storing them, expands the "data file" field (one name, LIST, or a %d pattern expanded here,
// never by printf) into resolved paths, and reduces the result to what a progiso volume needs.
// read_nrrd_samples() then checks, before allocating anything, that the data present can hold
// the declared size (so memory follows the data, never the declaration), and decodes every
// piece straight into one buffer in host byte order.
//
// Bounds: a header line is at most nrrd_max_line_bytes; a header names at most
// nrrd_max_data_files data files, whose resolved names take at most nrrd_max_name_bytes; an
// axis has at most nrrd_max_axis_size samples (the volume's limit); gzip data is taken to
// expand at most gzip_max_ratio:1 (deflate's limit is about 1032:1) plus gzip_slack_bytes
// (gzip_input.hpp). Header parsing is linear in the header size.
//
// Thread safety: no global state; different files may be read concurrently. Every failure
// throws progiso::error with one line naming the file that failed (the data file for detached
// data).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/header_text.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

inline constexpr std::size_t nrrd_max_line_bytes = header_max_line_bytes;
inline constexpr std::size_t nrrd_max_data_files = std::size_t{1} << 20;
inline constexpr std::size_t nrrd_max_name_bytes = std::size_t{64} << 20;
inline constexpr std::int64_t nrrd_max_axis_size = (std::int64_t{1} << 15) + 1;

/// The data encodings progiso decodes (bzip2 and zrl are recognised and refused). zlib is
/// MetaImage's compressed data (deflate in a zlib wrapper), decoded as gzip is (gzip_input
/// takes either wrapper); NRRD headers never give it.
enum class nrrd_encoding : std::uint8_t { raw, gzip, ascii, hex, zlib };

/// "raw", "gzip", "ascii", "hex", "zlib".
[[nodiscard]] std::string_view to_string(nrrd_encoding encoding) noexcept;

/// Whether the data is deflate-compressed (gzip or zlib): byte skips then count decompressed
/// bytes, and capacity follows gzip_can_hold().
[[nodiscard]] constexpr bool deflated(nrrd_encoding e) noexcept {
  return e == nrrd_encoding::gzip || e == nrrd_encoding::zlib;
}

/// A checked NRRD header, reduced to what reading a 3-D progiso volume needs.
struct nrrd_header {
  index3 dims{};  ///< each in 2..nrrd_max_axis_size
  /// Volumes of dims each, one after the other in the data (a MetaImage of NDims 4); 1 for a
  /// single volume.
  std::int64_t volumes = 1;
  /// The volumes' axis is the fastest (a 4-D NRRD whose first axis is the list, as diffusion
  /// MRI holds one value per gradient direction per voxel): the volumes' samples alternate, and
  /// volume k is every volumes-th sample from the k-th. Otherwise the volumes follow each other.
  bool interleaved = false;
  sample_type type = sample_type::u8;
  nrrd_encoding encoding = nrrd_encoding::raw;
  bool big_endian = false;     ///< byte order of raw, gzip and hex data (samples > 1 byte)
  std::int64_t byte_skip = 0;  ///< ≥ -1; -1: the data is the last bytes of each file (raw)
  std::uint64_t line_skip = 0;
  /// The detached data files in order, resolved against the header's directory; empty when
  /// the data is attached. Each holds an equal share of the samples.
  std::vector<std::filesystem::path> data_files;
  std::uint64_t data_offset = 0;  ///< attached data: offset of the byte after the empty line
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  /// Grid index to the header's space: the three "space directions" as columns and the "space
  /// origin" (0 where absent) as translation, when the space has 3 dimensions, no axis is
  /// "none", every entry is finite and the directions are independent; else none.
  std::optional<index_to_world> world;
  /// The format named in messages about the data ("NRRD"; "MetaImage" when the MetaImage
  /// reader describes its data with this header, detail/metaimage_reader.hpp).
  std::string_view format = "NRRD";
};

/// Parses the header of `header_file` (opened at its start). Throws progiso::error naming the
/// file for a missing or wrong magic, an over-long line, a NUL byte, an unknown or duplicated
/// field, a value that does not parse (the message quotes at most 40 bytes of it), a missing
/// required field, an array that is not 3-D with 2..32769 samples per axis, an unsupported
/// type or encoding, and a "data file" field that is malformed or names too many files.
[[nodiscard]] nrrd_header parse_nrrd_header(input_file& header_file);

/// Reads the samples of volume `volume` (0 ≤ volume < header.volumes) of what `header`
/// describes (from `header_file` when attached, else from the data files that hold it, opened
/// through input_file) in host byte order; the volumes before it are skipped (raw data by a
/// seek, other encodings decoded and dropped). Before allocating, checks that each source can
/// hold its share of every declared volume: raw data needs its bytes, gzip data at most
/// gzip_max_ratio times its size plus slack, ascii 2 bytes per value, hex 2 digits per
/// byte; throws "FILE: … cannot hold …" otherwise. Throws "FILE: NRRD data ends after X of Y
/// bytes" for data that ends early, and names zlib's message for corrupt gzip data.
/// Volume `volume`'s samples mapped in place (map_bytes()) instead of read, when they can be:
/// at least map_min_bytes of them, stored uncompressed, raw (neither interleaved nor split over
/// data files, no line skip), in host byte order, and every declared volume present as the read
/// requires; nullopt otherwise (read the samples: that read says what is wrong with a file that
/// cannot hold them).
[[nodiscard]] std::optional<mapped_bytes> map_nrrd_samples(const nrrd_header& header,
                                                           const input_file& header_file,
                                                           std::int64_t volume);
[[nodiscard]] std::vector<std::byte> read_nrrd_samples(const nrrd_header& header,
                                                       input_file& header_file,
                                                       std::int64_t volume = 0);

/// Reverses the bytes of every `item`-byte sample of `bytes` in place (item 1, 2, 4 or 8).
void swap_sample_bytes(std::span<std::byte> bytes, std::size_t item) noexcept;

}  // namespace progiso::detail
