// progiso/io/detail/zarr_reader.hpp — progiso's own reader of Zarr v2 arrays and OME-Zarr
// multiscale images (OME-NGFF 0.1 to 0.4), the chunked format of light-sheet and electron
// microscopy, behind read_zarr().
//
// Accepted: a directory holding `.zattrs` with "multiscales" (its first multiscale: the datasets,
// finest first, each an array directory; "axes" in 0.4 as objects, in 0.3 as names, absent in
// 0.1 and 0.2, which are t, c, z, y, x) or a lone array directory (`.zarray`). An array is
// `zarr_format` 2 with "shape", "chunks", "dtype" (b/u/i 1, 2, 4 bytes and f 4, 8 bytes; "|",
// "<" or ">" byte order), "order" C or F, "fill_value" (a number, "NaN", "Infinity", "-Infinity"
// or null: 0), "dimension_separator" "." or "/", "filters" null, and "compressor" null, blosc,
// zstd, zlib or gzip (decoded by c-blosc, libzstd and zlib: Debian's libblosc-dev, libzstd-dev,
// zlib1g-dev). The last three axes are z, y, x (space); leading axes (time, channel) make a
// series whose volume the caller picks (volume_choice::volume, in row-major order over them),
// and the level by volume_choice::level (0: the finest). Spacing and origin come from the
// level's "scale" and "translation" coordinate transformations (spatial entries); a lone array's
// are 1 and 0.
//
// Chunks: each chunk file holds the chunk's whole box (edge chunks padded, as Zarr writes them).
// A missing chunk is fill_value, as Zarr defines; a level whose chunks of the chosen volume are
// all missing holds no data and is refused.
//
// Bounds: metadata files are at most 1 MiB, parsed by nlohmann::json after a scan that refuses
// nesting deeper than 64; shapes and chunks are checked (spatial axes 2 to 32769 samples, a
// chunk at most 2^31 − 1 bytes decoded) before anything is allocated. A chunk file larger than
// its codec's largest encoding of the chunk's bytes is refused unread; decoding writes at most
// the chunk's bytes (blosc's header, zstd's frame size and zlib's stream all checked against
// them), so a decompression bomb stops at one chunk. Every failure throws progiso::error naming
// the file, what was expected and what was found.
//
// Thread safety: no global state (blosc is called through its context functions); different
// arrays may be read concurrently.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include <progiso/core/base/parallel_loop.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

enum class zarr_codec { none, blosc, zstd, zlib, gzip };

/// One array of a Zarr image (a pyramid level), checked.
struct zarr_level {
  std::filesystem::path dir;         ///< the array's directory (holding .zarray)
  std::vector<std::int64_t> shape;   ///< slowest axis first; the last three z, y, x
  std::vector<std::int64_t> chunks;  ///< the same axes
  sample_type type = sample_type::u8;
  bool big_endian = false;
  bool fortran = false;  ///< order "F": the first axis fastest within a chunk
  char separator = '.';
  zarr_codec codec = zarr_codec::none;
  double fill = 0.0;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};  ///< x, y, z
  std::array<double, 3> origin{0.0, 0.0, 0.0};   ///< x, y, z
  /// The grid, x fastest: {shape[n − 1], shape[n − 2], shape[n − 3]}.
  [[nodiscard]] index3 dims() const noexcept;
  /// Bytes of one decoded chunk.
  [[nodiscard]] std::uint64_t chunk_bytes() const noexcept;
};

/// A Zarr image: its levels, finest first, and its series (the leading axes).
struct zarr_image {
  std::vector<zarr_level> levels;
  std::int64_t volumes = 1;  ///< product of the leading axes' sizes (the same at every level)
  std::vector<std::filesystem::path> files;  ///< the metadata files read
};

/// Whether `dir` is a directory holding `.zattrs` or `.zarray`.
[[nodiscard]] bool is_zarr_directory(const std::filesystem::path& dir);
/// Reads and checks the metadata of the image or array at `dir` (see the file comment).
[[nodiscard]] zarr_image read_zarr_header(const std::filesystem::path& dir);
/// Throws progiso::error naming the array unless enough chunk files of volume `volume` of level
/// `level` are present to size it by (at least one in 64; see read_zarr_samples()).
void check_zarr_chunks(const zarr_image& image, std::size_t level, std::int64_t volume);
/// Planes [z_begin, z_end) of volume `volume` of level `level` into `out`, which holds exactly
/// their bytes (x fastest, host byte order), missing chunks filled: only the chunks whose planes
/// meet the range are decoded, those of one chunk row at once through `run` (each writes its own
/// box). false, with `out` partly written, when `stop` (asked before each chunk, when not empty)
/// answered true. Throws as read_zarr_samples() for a chunk; does not check the chunks' presence
/// (check_zarr_chunks() does, once).
[[nodiscard]] bool read_zarr_planes(const zarr_image& image, std::size_t level, std::int64_t volume,
                                    std::int64_t z_begin, std::int64_t z_end,
                                    std::span<std::byte> out, const parallel_loop& run = {},
                                    const std::function<bool()>& stop = {});
/// The samples of volume `volume` (0 ≤ volume < image.volumes) of level `level`, x fastest, in
/// host byte order, missing chunks filled; nullopt when `stop` (asked before each chunk, when not
/// empty) answers true. Throws progiso::error naming the chunk file for a chunk that is too
/// large, corrupt, or decodes to another size than the chunk's, and naming the array when too
/// few of the volume's chunks are present.
[[nodiscard]] std::optional<std::vector<std::byte>> read_zarr_samples(
    const zarr_image& image, std::size_t level, std::int64_t volume,
    const std::function<bool()>& stop = {});

}  // namespace progiso::detail
