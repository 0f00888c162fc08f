// progiso/io/detail/dicom_rle.hpp — progiso's own decoder of DICOM RLE Lossless
// (1.2.840.10008.1.2.5, PS3.5 Annex G): a frame is one fragment, a 64-byte header (the number of
// segments and their offsets) then one PackBits segment per byte of a sample, most significant
// byte first.
//
// Our own code rather than DCMTK's DcmRLEDecoder, because that one reads the PackBits code -128
// as a repeat run of 129 bytes, where PS3.5 G.3.1 makes it output nothing
// (tests/io/dicom_enhanced_test.cpp checks both).
//
// Every failure (a segment count that does not match the sample size, an offset outside the
// fragment, a run past the frame, a segment that ends early) throws progiso::error with one line
// saying what was wrong (the caller adds the file's name). Thread safety: no global state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace progiso::detail {

/// Decodes one RLE fragment into `out`: `out.size()` / `bytes` samples of `bytes` (1, 2 or 4)
/// bytes each, host order.
void decode_dicom_rle(std::span<const std::uint8_t> fragment, std::size_t bytes,
                      std::span<std::byte> out);

}  // namespace progiso::detail
