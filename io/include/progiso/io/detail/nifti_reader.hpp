// progiso/io/detail/nifti_reader.hpp — progiso's own NIfTI reader (NIfTI-1 and NIfTI-2, the
// formats of MRI and much of CT research data), behind read_nifti() and volume_input_files().
//
// Our own reader rather than nifti_clib's, because nifti_clib accepts dims of 0 or less and
// NIfTI-2 dims that wrap, allocates the declared size before reading and reports on stderr
// (docs/formats.md).
//
// Accepted: a single file (.nii, magic "n+1" / "n+2", data at vox_offset) or a header and data
// pair (.hdr with magic "ni1" / "ni2", data in the .img beside it, or .img.gz when no .img
// exists), either byte order (told by the header size field, 348 or 540), each file plain or
// gzip-compressed (told by its first two bytes, not its name); the header extensions between
// the header and vox_offset are skipped unread. The array must be 3-D with 2 to 32769 samples
// per axis (trailing dimensions of size 1 allowed, so a 4-D file with one time point reads) and
// one of the types u8 i8 u16 i16 u32 i32 f32 f64 (datatype codes 2, 256, 512, 4, 768, 8, 16,
// 64; bitpix, redundant, is ignored as nifti_clib ignores it). A time series (dim[4] > 1, each
// dimension above the fourth of size 1) is a sequence of 3-D volumes, of which one is read: the
// caller picks it (volume_choice::volume). Refused with a message: Analyze 7.5 headers (no NIfTI
// magic), arrays with a fifth or higher dimension above 1 (vector, matrix and other
// per-voxel data), complex, RGB and 64-bit integer types.
//
// Geometry: spacing per axis is |pixdim[i]| (zero or non-finite: 1); the origin is the
// translation of the sform when sform_code > 0, else of the qform when qform_code > 0, else 0.
// Rotations and axis flips are not applied to the volume: as for NRRD, positions are origin +
// index × spacing; the whole index-to-scanner map (sform, else qform) is kept in
// nifti_header::world for a caller to map vertices with (progiso extract --world;
// docs/formats.md, "Reading NIfTI"). Values: when scl_slope is finite and
// non-zero and (scl_slope, scl_inter) is not (1, 0), the samples are scaled to
// scl_slope × stored + scl_inter, stored as f32 (f64 for 32-bit integer and f64 data), so that
// isovalues are given in the file's physical units (Hounsfield units for CT, say).
//
// Bounds: memory follows the data present, never the declared size, and holds one volume of a
// time series. Before allocating, a plain data file must hold vox_offset + the bytes of every
// volume declared, and a gzip file's compressed size must be able to inflate to them
// (gzip_can_hold()); the volumes before the chosen one are skipped (a plain file seeks over
// them, a gzip file inflates them into a small buffer). Every failure throws progiso::error with
// one line that names the file, what was expected and what was found.
//
// Thread safety: no global state; different files may be read concurrently.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

inline constexpr std::size_t nifti1_header_bytes = 348;
inline constexpr std::size_t nifti2_header_bytes = 540;
inline constexpr std::int64_t nifti_max_axis_size = (std::int64_t{1} << 15) + 1;

/// A checked NIfTI header, reduced to what reading a 3-D progiso volume needs.
struct nifti_header {
  int version = 1;  ///< 1 or 2
  bool big_endian = false;
  index3 dims{};  ///< each in 2..nifti_max_axis_size
  /// dim[4] of a time series (each volume dims[0] × dims[1] × dims[2]); 1 otherwise.
  std::int64_t volumes = 1;
  sample_type stored = sample_type::u8;
  /// scl_slope × stored + scl_inter applies (see the file comment).
  bool scaled = false;
  double slope = 1.0;
  double inter = 0.0;
  std::uint64_t vox_offset = 0;
  /// The .img (or .img.gz) of a header and data pair; empty for a single file.
  std::optional<std::filesystem::path> data_file;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  /// Grid index (i, j, k) to scanner coordinates: the sform when sform_code > 0, else the qform
  /// when qform_code > 0 (NIfTI-1's method 2: quaternion, qfac, pixdim, offset), else none;
  /// none too when an entry is not finite or the 3 × 3 part is singular.
  std::optional<index_to_world> world;

  /// The sample type of the volume read: `stored`, or f32 / f64 when scaled.
  [[nodiscard]] sample_type volume_type() const noexcept;
};

/// Reads and checks the header of `file` (plain or gzip). Throws progiso::error naming the file
/// for a file that ends inside the header, a header size field other than 348 or 540 (either
/// byte order), a missing magic, and every unsupported or inconsistent field; for a pair it
/// names the data file it looked for when neither .img nor .img.gz exists.
[[nodiscard]] nifti_header read_nifti_header(const std::filesystem::path& file);

/// Reads the samples of volume `volume` (0 ≤ volume < header.volumes) of what `header`
/// describes from `file` (or its data file) in host byte order, scaled when the header says so.
/// Throws progiso::error naming the data file when it cannot hold every declared volume, ends
/// early or is corrupt.
/// Volume `volume`'s samples mapped in place (map_bytes()) instead of read, when they can be:
/// at least map_min_bytes of them, stored uncompressed, unscaled, in host byte order, and every
/// declared volume present as the read requires; nullopt otherwise (read the samples: that read
/// says what is wrong with a file that cannot hold them).
[[nodiscard]] std::optional<mapped_bytes> map_nifti_samples(const nifti_header& header,
                                                            const std::filesystem::path& file,
                                                            std::int64_t volume);
[[nodiscard]] std::vector<std::byte> read_nifti_samples(const nifti_header& header,
                                                        const std::filesystem::path& file,
                                                        std::int64_t volume = 0);

/// Whether a file name asks for the NIfTI reader: .nii, .nii.gz, .hdr, .hdr.gz (any case).
[[nodiscard]] bool has_nifti_name(const std::filesystem::path& file);

}  // namespace progiso::detail
