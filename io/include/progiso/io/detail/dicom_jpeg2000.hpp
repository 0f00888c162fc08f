// progiso/io/detail/dicom_jpeg2000.hpp — one JPEG 2000 frame of DICOM pixel data (JPEG 2000
// Image Compression, lossless only 1.2.840.10008.1.2.4.90, and lossy allowed .91; PS3.5 A.4.4),
// decoded by OpenJPEG.
//
// A frame is one codestream (the fragments from one that starts with a codestream's SOC marker,
// or a JP2 signature box, up to the next such one): one component of exactly the DICOM image's
// rows and columns, at most its BitsStored of precision, signed as PixelRepresentation says.
// Before OpenJPEG decodes a sample, the codestream's header is checked against the DICOM header
// and the frame's samples against 4096 × the codestream's bytes (lossless JPEG 2000 compresses
// CT and MR two to four times; a larger ratio is what a decompression bomb has). OpenJPEG's
// messages are caught, never printed: every failure throws progiso::error with one line saying
// what was wrong (the caller adds the file and frame). Thread safety: no global state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace progiso::detail {

/// Whether a fragment starts a JPEG 2000 frame: a codestream's SOC and SIZ markers
/// (FF 4F FF 51), or a JP2 file's signature box.
[[nodiscard]] bool starts_jpeg2000_frame(std::span<const std::uint8_t> fragment) noexcept;

/// The largest number of samples' bytes a codestream of `bytes` bytes may decode to.
inline constexpr std::uint64_t jpeg2000_largest_expansion = 4096;

/// Decodes one frame's codestream into `out` (rows × columns samples of `bytes` = 1, 2 or 4
/// bytes each, host order; signed samples in two's complement when `is_signed`). `bits_stored`
/// bounds the codestream's precision.
void decode_dicom_jpeg2000(std::span<const std::uint8_t> codestream, std::uint32_t rows,
                           std::uint32_t columns, std::size_t bytes, unsigned bits_stored,
                           bool is_signed, std::span<std::byte> out);

}  // namespace progiso::detail
