// progiso/io/detail/jpeg_lossless.hpp — lossless JPEG frames (ITU-T T.81 process 14: SOF3,
// Huffman coding, predictors 1 to 7, point transform), the compression of most DICOM archives'
// CT and MR ("JPEG Lossless, Non-Hierarchical, First-Order Prediction",
// 1.2.840.10008.1.2.4.70, and the general process 14, 1.2.840.10008.1.2.4.57).
//
// progiso checks the stream's headers and finds where it ends; DCMTK's IJG decoders (dcmjpeg:
// the 8-, 12- and 16-bit builds of the Independent JPEG Group's library with its lossless
// extension) decode the samples, because a well-kept decoder that DICOM toolkits share is
// sounder than one of our own (docs/formats.md, "Format libraries").
//
// Checked before any sample is decoded, each refusal one line saying what was wrong: SOI first;
// one SOF3 frame header of one component, 2 to 16 bits and at most the caller's depth, of
// exactly the caller's rows and columns (other processes are named by their marker); Huffman
// tables that fit their segments, and a scan that names a defined one, predictor 1 to 7 and a
// point transform below the precision; one scan, then EOI, all inside the data. The decoder's
// own failures (a code no table holds, a scan that ends early) come back as one line too.
//
// Cost: one pass over the headers and the scan's bytes to find its end, then DCMTK's decode.
// Thread safety: a decoder per call; DCMTK's log for dcmjpeg is silenced once, process-wide
// (its messages would reach stderr; ours carry them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace progiso::detail {

/// Decodes the lossless JPEG image that starts at `at` in `data` (at its SOI marker) into `out`:
/// `rows` × `columns` samples, row by row, each the reconstructed value shifted left by the
/// point transform. The image must be that size and at most `max_precision` bits deep. Returns
/// the offset just past its EOI marker. Throws progiso::error.
std::size_t decode_lossless_jpeg(std::span<const std::uint8_t> data, std::size_t at,
                                 std::uint32_t rows, std::uint32_t columns, unsigned max_precision,
                                 std::span<std::uint16_t> out);

}  // namespace progiso::detail
