// progiso/core/io/detail/dicom_reader.hpp — progiso's own reader of DICOM series (the format CT
// and MRI scanners write: one file per slice, a directory per series), behind read_dicom() and
// volume_input_files().
//
// Input: a directory. Every regular file in it that is a DICOM Part 10 file (128 bytes, then
// "DICM") holding one frame of pixel data is a slice; other files (DICOMDIR, reports, non-DICOM
// files) are skipped. All slices must belong to one series (SeriesInstanceUID; where the
// directory holds several, the caller names one) and agree on
// Rows, Columns, BitsAllocated, PixelRepresentation, PixelSpacing and ImageOrientationPatient;
// they are ordered by their ImagePositionPatient along the slice normal (row × column
// direction) and must be evenly spaced (a gap or a tilt is refused, naming the slices).
//
// Accepted: transfer syntaxes implicit VR little endian, explicit VR little endian and explicit
// VR big endian (uncompressed pixel data); SamplesPerPixel 1 (MONOCHROME1 or MONOCHROME2);
// BitsAllocated 8, 16 or 32, signed or unsigned, BitsStored ≤ BitsAllocated (the bits above
// are masked off, and signed values sign-extended from BitsStored); RescaleSlope and
// RescaleIntercept applied per slice when not 1 and 0 (the samples become f32, in the units they
// give: Hounsfield units for CT). Refused by name: compressed transfer syntaxes (JPEG, JPEG-LS,
// JPEG 2000, RLE, deflate), colour, multi-frame files, float pixel data.
//
// Geometry: spacing (PixelSpacing's column spacing, its row spacing, the slices' step); origin
// the first slice's ImagePositionPatient; the index-to-patient map (LPS, as DICOM gives it): the
// row direction × column spacing, the column direction × row spacing, the normal × step, plus the
// first position (dicom_series::world).
//
// Bounds: sequences are skipped by their lengths or their delimiters, at most 16 deep; a value
// progiso reads is at most 1 KiB; a directory holds at most 32769 slices (the axis limit);
// memory follows the data: each file must hold its frame before the volume is allocated.
//
// Thread safety: no global state. Every failure throws progiso::error with one line naming the
// file (or the directory) that failed.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/io/volume_io.hpp>

namespace progiso::detail {

inline constexpr std::size_t dicom_max_slices = (std::size_t{1} << 15) + 1;

/// One slice of a series: where its frame lies and how to read it.
struct dicom_slice {
  std::filesystem::path file;
  std::uint64_t pixel_offset = 0;
  bool big_endian = false;
  std::array<double, 3> position{};
  double slope = 1.0;
  double intercept = 0.0;
  double along = 0.0;  ///< position · normal, the sort key
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

/// Reads and checks the headers of every file in `directory`: the one series there, or the one
/// `series` names (its UID, or its number in UID order) among several. Throws progiso::error
/// naming the directory or the file at fault; for several series and no choice, or a choice that
/// names none of them, the message lists them by number, UID and image count.
[[nodiscard]] dicom_series read_dicom_series(const std::filesystem::path& directory,
                                             const std::optional<std::string>& series = {});

/// Reads the frames of `series` into one array (x fastest, slices in order), host byte order,
/// masked and sign-extended to BitsStored, rescaled when the series says so.
[[nodiscard]] std::vector<std::byte> read_dicom_samples(const dicom_series& series);

}  // namespace progiso::detail
