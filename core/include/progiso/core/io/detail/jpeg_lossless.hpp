// progiso/core/io/detail/jpeg_lossless.hpp — progiso's own decoder of lossless JPEG (ITU-T T.81
// process 14: SOF3, Huffman coding, predictors 1 to 7, point transform), the compression of most
// DICOM archives' CT and MR ("JPEG Lossless, Non-Hierarchical, First-Order Prediction",
// 1.2.840.10008.1.2.4.70, and the general process 14, 1.2.840.10008.1.2.4.57).
//
// Accepted: one image per call, one component, precision 2 to 16 bits, one scan, any predictor
// 1 to 7 and point transform below the precision, Huffman tables in any number of DHT segments,
// APPn and COM segments (skipped). Refused with a message: other processes (baseline,
// extended, progressive, arithmetic coding, hierarchical), several components or scans,
// restart intervals, DNL, a scan that ends before its samples, a code no table holds.
//
// Cost: one pass over the stream; codes of up to 9 bits are decoded by one table lookup, longer
// ones bit by bit. Memory: the caller's output and four 512-entry tables.
//
// Thread safety: no global state. Every failure throws progiso::error with one line saying what
// was wrong (the caller adds the file's name).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace progiso::detail {

/// Decodes the lossless JPEG image that starts at `at` in `data` (at its SOI marker) into `out`:
/// `rows` × `columns` samples, row by row, each the reconstructed value shifted left by the
/// point transform. The image must be that size and at most `max_precision` bits deep. Returns
/// the offset just past its EOI marker.
std::size_t decode_lossless_jpeg(std::span<const std::uint8_t> data, std::size_t at,
                                 std::uint32_t rows, std::uint32_t columns, unsigned max_precision,
                                 std::span<std::uint16_t> out);

}  // namespace progiso::detail
