// progiso/io/detail/dicom_reader.hpp — progiso's own reader of DICOM images (the format CT
// and MRI scanners write), behind read_dicom() and volume_input_files(): a series of one file per
// slice in a directory, or multi-frame images that hold many frames in one file: enhanced images
// (Enhanced CT and MR, what current scanners export) and RT dose grids.
//
// Our own parser of the DICOM structure rather than DCMTK's, because DCMTK parses nested
// sequences recursively and a deep enough nesting overflows its stack; ours stops at a bounded
// depth. Compressed frames go to libraries: lossless JPEG to DCMTK's IJG decoders, JPEG 2000 to
// OpenJPEG; RLE stays ours (detail/dicom_rle.hpp says why). docs/formats.md.
//
// Input: a directory, or one file. Every regular file in a directory that is a DICOM Part 10 file
// (128 bytes, then "DICM") holding pixel data is read; other files (DICOMDIR, reports, non-DICOM
// files) are skipped. Each frame is a slice: a classic file holds one, an enhanced file
// NumberOfFrames (up to 32769), each placed by its item of PerFrameFunctionalGroupsSequence
// (5200,9230) — Plane Position, and where given there Plane Orientation, Pixel Measures and Pixel
// Value Transformation — falling back to SharedFunctionalGroupsSequence (5200,9229), then to the
// dataset's own elements. An RT dose grid (a treatment plan's dose: isodose surfaces) places its
// frames by GridFrameOffsetVector (3004,000C) from ImagePositionPatient — offsets along the normal
// when the first is 0, else, on an axial grid, z coordinates starting at ImagePositionPatient's —
// and its values are the stored ones × DoseGridScaling (3004,000E) (× RescaleSlope, plus
// RescaleIntercept, where a file gives those too). Any other multi-frame file is refused
// (nothing places its frames). All slices must belong to one series (SeriesInstanceUID; where
// the directory holds several, the caller names one; an enhanced series may span several files)
// and agree on Rows, Columns, BitsAllocated, PixelRepresentation, PixelSpacing and
// ImageOrientationPatient; they are ordered by their ImagePositionPatient along the slice normal
// (row × column direction) and must be evenly spaced (a gap, a duplicate or a tilt is refused,
// naming the file and frame). A series with the same number of frames at every position holds
// that many volumes (time points, echoes), one chosen by index: frames at a position ordered by
// TemporalPositionIndex, else InstanceNumber, then file and frame. One file alone must hold at
// least two frames.
//
// Accepted: transfer syntaxes implicit VR little endian, explicit VR little endian and explicit
// VR big endian (uncompressed pixel data), and lossless JPEG (1.2.840.10008.1.2.4.70 and .57,
// the compression of most archives' CT and MR: 8 or 16 bits allocated, each frame in one or more
// fragments, decoded by detail/jpeg_lossless.hpp), RLE Lossless (1.2.840.10008.1.2.5: a
// fragment per frame, detail/dicom_rle.hpp) and JPEG 2000 (1.2.840.10008.1.2.4.90 lossless and
// .91: a codestream per frame, in one or more fragments, decoded by OpenJPEG through
// detail/dicom_jpeg2000.hpp); SamplesPerPixel 1 (MONOCHROME1 or MONOCHROME2);
// BitsAllocated 8, 16 or 32, signed or unsigned, BitsStored ≤ BitsAllocated (the bits above
// are masked off, and signed values sign-extended from BitsStored); RescaleSlope and
// RescaleIntercept applied per frame when not 1 and 0 (the samples become f32, in the units they
// give: Hounsfield units for CT). Refused by name: the other compressed transfer syntaxes (lossy
// JPEG, JPEG-LS, High-Throughput JPEG 2000, JPEG 2000 multi-component, deflate), colour,
// multi-frame files that do not place their frames, float pixel data.
//
// Geometry: spacing (PixelSpacing's column spacing, its row spacing, the slices' step); origin
// the first slice's ImagePositionPatient; the index-to-patient map (LPS, as DICOM gives it): the
// row direction × column spacing, the column direction × row spacing, the normal × step, plus the
// first position (dicom_series::world).
//
// Bounds: sequences are walked by their lengths or their delimiters, at most 16 deep; a value
// progiso reads is at most 1 KiB (GridFrameOffsetVector 17 bytes a frame); a series holds at
// most 32769 slices (the axis limit), a directory at most 4 × 32769 per-frame groups and dose
// offsets; memory follows the data: each file must hold its frames before the volume is
// allocated (lossless JPEG codes each sample in at least one bit, an RLE run of two bytes makes
// at most 128, and a JPEG 2000 codestream may decode to at most 4096 times its size, so the
// fragments bound the frames they can hold).
//
// Thread safety: no global state. Every failure throws progiso::error with one line naming the
// file (and the frame, in a multi-frame file) or the directory that failed.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/io/volume_io.hpp>

namespace progiso::detail {

inline constexpr std::size_t dicom_max_slices = (std::size_t{1} << 15) + 1;

/// How a file's pixel data is stored: native, or encapsulated (fragments) in a compression.
enum class dicom_codec : std::uint8_t { native, jpeg_lossless, rle, jpeg2000 };

/// One slice of a series: where its frame lies and how to read it.
struct dicom_slice {
  std::filesystem::path file;
  std::int64_t frame = -1;  ///< its frame (0-based) in a multi-frame file; −1 for one frame
  std::uint64_t pixel_offset = 0;  ///< the frame's bytes, or (jpeg) the file's first fragment item
  bool big_endian = false;
  dicom_codec codec = dicom_codec::native;  ///< encapsulated: frame `frame` of the fragments
  std::array<double, 3> position{};
  double slope = 1.0;
  double intercept = 0.0;
  double along = 0.0;  ///< position · normal, the sort key

  /// The slice in messages: its file, and for a frame of a multi-frame file "(frame K)",
  /// 1-based as DICOM counts frames.
  [[nodiscard]] std::string name() const {
    return frame < 0 ? file.string() : file.string() + " (frame " + std::to_string(frame + 1) + ")";
  }
};

/// A checked series, its slices in order.
struct dicom_series {
  index3 dims{};  ///< Columns, Rows, slices
  sample_type stored = sample_type::u16;
  unsigned bits_stored = 16;
  bool scaled = false;  ///< some slice has a rescale other than (1, 0): samples as f32
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{};
  index_to_world world;
  std::vector<dicom_slice> slices;

  [[nodiscard]] sample_type volume_type() const noexcept {
    return scaled ? sample_type::f32 : stored;
  }
};

/// Reads and checks the headers of every file in `input` (a directory, or one file): the one
/// series there, or the one `series` names (its UID, or its number in UID order) among several;
/// of a series holding several volumes (the same number of frames at every position: time
/// points, echoes), the one `volume` names (0-based, frames at a position ordered by
/// TemporalPositionIndex, else InstanceNumber, then file and frame). Throws progiso::error
/// naming the input or the file at fault; for several series and no choice, or a choice that
/// names none of them, the message lists them by number, UID and image count; for several
/// volumes and no choice, it gives their count.
[[nodiscard]] dicom_series read_dicom_series(const std::filesystem::path& input,
                                             const std::optional<std::string>& series = {},
                                             const std::optional<std::int64_t>& volume = {});

/// Reads the frames of `series` into one array (x fastest, slices in order), host byte order,
/// masked and sign-extended to BitsStored, rescaled when the series says so.
[[nodiscard]] std::vector<std::byte> read_dicom_samples(const dicom_series& series);

/// Whether `file` is a regular file that starts as DICOM Part 10 does (128 bytes, then "DICM"):
/// how an input without a known extension is recognised. False when it cannot be read.
[[nodiscard]] bool has_dicom_preamble(const std::filesystem::path& file);

}  // namespace progiso::detail
