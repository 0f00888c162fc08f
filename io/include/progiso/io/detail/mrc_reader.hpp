// progiso/io/detail/mrc_reader.hpp — progiso's own reader of MRC and CCP4 maps (MRC2014
// and its predecessors: cryo-EM maps as EMDB distributes them, tomograms as IMOD reconstructs
// them, X-ray electron density maps as CCP4 and Phenix write them), behind read_mrc().
//
// Our own reader rather than CCP4's cmaplib (Debian's libccp4-dev), because cmaplib stores one
// pointer per NLABL label in a fixed ten-slot array (a larger NLABL writes past it), opens by
// name, reads no gzip and knows no mode 12 (docs/formats.md).
//
// Accepted: the 1024-byte header, then NSYMBT bytes of extended header (skipped unread), then
// the samples, columns fastest, then rows, then sections; plain or gzip (told by the first two
// bytes: EMDB's .map.gz). Byte order from the machine stamp (MACHST, byte 212: 0x44 little
// endian, 0x11 big endian); a file without a valid stamp (older writers left it zero) is read
// in the byte order in which its MODE and NX make sense, little endian first. Modes 0 (8-bit
// integers: signed, as MRC2014 defines them, unless IMOD's stamp says they are not), 1 (int16),
// 2 (float32), 6 (uint16) and 12 (IEEE half floats, read as float32). MAPC, MAPR, MAPS, a
// permutation of 1, 2, 3 (0, 0, 0 read as 1, 2, 3), say which of X, Y, Z the columns, rows and
// sections run along; the volume is returned x fastest, so a map stored in another order (as
// crystallographic FFT programs write them) is transposed while it is read, one section at a
// time. A volume stack (ISPG 401 to 630: NZ = MZ × the number of volumes, axes in the standard
// order) is a series whose volume the caller picks (volume_choice::volume). Refused with a
// message: complex modes (3, 4), RGB (16), packed 4-bit data (101), any other mode, a single
// image (NZ = 1), MAPC/MAPR/MAPS that are not a permutation.
//
// Geometry: spacing along X, Y, Z is CELLA / (MX, MY, MZ) (a zero or non-finite ratio: 1). The
// origin is the ORIGIN field (MRC2014: the position of the first sample, Å) when one of its
// components is non-zero and all are finite, else the start indices (NXSTART, NYSTART, NZSTART,
// permuted to X, Y, Z) × spacing, as CCP4 maps place a box cut from the unit cell. A unit cell
// whose angles (CELLB) are not right is skewed: its axes a, b, c in Cartesian coordinates
// (a along x, b in the xy plane, the convention of the PDB and of crystallographic programs)
// divided by MX, MY, MZ are the grid's steps, which mrc_header::world holds for
// read_volume_world() (progiso extract --world); positions without it are origin + index ×
// spacing, as for every format.
//
// Bounds: memory follows the data present, never the declared size. Before allocating, a plain
// file must hold 1024 + NSYMBT + the bytes of every volume declared, and gzip data must be able
// to inflate to them (gzip_can_hold()). A transposed map needs one section of scratch beside
// the volume; half floats are widened in place. Every failure throws progiso::error with one
// line that names the file, what was expected and what was found.
//
// Thread safety: no global state; different files may be read concurrently.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

inline constexpr std::size_t mrc_header_bytes = 1024;
inline constexpr std::int64_t mrc_max_axis_size = (std::int64_t{1} << 15) + 1;

/// A checked MRC header, reduced to what reading a 3-D progiso volume needs.
struct mrc_header {
  bool big_endian = false;
  std::int32_t mode = 2;
  /// The samples as stored: u8, i8, i16, u16, f32; mode 12 is stored as 2-byte halves (`half`).
  sample_type stored = sample_type::f32;
  bool half = false;
  /// Columns, rows and sections of one volume as stored (NX, NY, NZ / volumes).
  std::array<std::int64_t, 3> stored_dims{};
  /// The axis (0 = X, 1 = Y, 2 = Z) that columns, rows and sections run along (MAPC − 1, …).
  std::array<int, 3> axis{0, 1, 2};
  /// Samples along X, Y, Z, each in 2..mrc_max_axis_size.
  index3 dims{};
  /// Volumes of a volume stack (ISPG 401–630); 1 otherwise.
  std::int64_t volumes = 1;
  /// Where the samples start: 1024 + NSYMBT.
  std::uint64_t data_offset = mrc_header_bytes;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  /// Grid index (x fastest) to Cartesian coordinates (Å): the unit cell's axes over the
  /// samples per cell, skewed when CELLB's angles are not right, and the origin.
  index_to_world world{};

  /// The sample type of the volume read: `stored`, or f32 for half floats.
  [[nodiscard]] sample_type volume_type() const noexcept {
    return half ? sample_type::f32 : stored;
  }
};

/// Reads and checks the header of `file` (plain or gzip). Throws progiso::error naming the file
/// for a file that ends inside the header and for every unsupported or inconsistent field.
[[nodiscard]] mrc_header read_mrc_header(const std::filesystem::path& file);

/// Reads volume `volume` (0 ≤ volume < header.volumes) of what `header` describes from `file`,
/// x fastest, in host byte order, half floats widened. Throws progiso::error naming the file
/// when it cannot hold every declared volume, ends early or is corrupt.
/// Volume `volume`'s samples mapped in place (map_bytes()) instead of read, when they can be:
/// at least map_min_bytes of them, stored uncompressed, x fastest, not half floats, in host byte
/// order, and every declared volume present as the read requires; nullopt otherwise (read the
/// samples: that read says what is wrong with a file that cannot hold them).
[[nodiscard]] std::optional<mapped_bytes> map_mrc_samples(const mrc_header& header,
                                                          const std::filesystem::path& file,
                                                          std::int64_t volume);
[[nodiscard]] std::vector<std::byte> read_mrc_samples(const mrc_header& header,
                                                      const std::filesystem::path& file,
                                                      std::int64_t volume = 0);

/// Whether a file name asks for the MRC reader: .mrc, .mrcs, .map, .ccp4, .rec, each optionally
/// followed by .gz (any case).
[[nodiscard]] bool has_mrc_name(const std::filesystem::path& file);

/// Whether a file holds MRC2014's identifier "MAP " at byte 208 (for names that say nothing).
[[nodiscard]] bool has_mrc_identifier(const std::filesystem::path& file);

/// IEEE 754 binary16 bits as a float (subnormals, infinities and NaNs included).
[[nodiscard]] float half_to_float(std::uint16_t bits) noexcept;

}  // namespace progiso::detail
