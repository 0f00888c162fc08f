// progiso/io/detail/tiff_reader.hpp — TIFF stacks: one multi-page TIFF, or a directory of
// TIFF files, one slice per page, as micro-CT scanners, confocal and light-sheet microscopes
// and ImageJ/Fiji save volumes.
//
// Pages are slices in order: a file's pages in order, and in a directory the files in natural
// order of their names (digit runs compared as numbers: slice2 before slice10; other files
// ignored). Pages marked as reduced-resolution images (thumbnails, NewSubfileType bit 0) are
// skipped. Every page must be one grey channel (SamplesPerPixel 1, photometric MinIsBlack or
// MinIsWhite, whose stored values are read as they are) of the same width, height and type: 8,
// 16, 32 or 64 bits of unsigned or signed integers or floats (u8 … f64 but 64-bit integers),
// in strips or tiles, uncompressed or compressed with LZW, Deflate or PackBits (with or
// without a predictor). x is the column, y the row (the first row first), z the page.
//
// ImageJ's description ("ImageJ=…" in the first page's ImageDescription) gives the spacing
// (x and y from XResolution and YResolution, pixels per unit; z from "spacing=") and, for one
// file, the hyperstack layout: "frames=T" volumes of "slices=Z" pages each (a time series, whose
// volume the caller chooses, as for NIfTI); more than one channel is refused, and so is a
// description that counts more images than the file has pages (ImageJ's stacks over 4 GB keep
// the pages after the first outside TIFF's directories). An OME-TIFF's OME-XML (Bio-Formats,
// microscope software) gives the same from its Pixels element: PhysicalSizeX/Y/Z (in µm,
// converted from nm, mm, cm or m), and for one file SizeT volumes of SizeZ planes, taken in
// DimensionOrder (T before Z: plane (z, t) is page t + SizeT·z); SizeC > 1 is refused, and so is
// SizeZ × SizeT other than the pages (a dataset split over files). Without either description
// the spacing is 1.
//
// libtiff decodes; progiso opens every file through input_file (regular files only; libtiff
// reads through it) and bounds every allocation before making it: the samples by what the
// pages' strips can hold at their codec's largest expansion (none 1, PackBits 64, Deflate 1032,
// LZW 4096), libtiff's own allocations by the file's size. libtiff's messages never reach the
// terminal: its first error becomes the error's text, naming the file and page.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include <progiso/core/field/volume.hpp>

namespace progiso::detail {

/// Whether `file` is named .tif or .tiff (any case).
[[nodiscard]] bool has_tiff_name(const std::filesystem::path& file);
/// Whether `directory` holds at least one regular file with a TIFF name (a stack of slices).
[[nodiscard]] bool is_tiff_directory(const std::filesystem::path& directory);

/// One slice: which file, which TIFF directory (page) in it.
struct tiff_page {
  std::size_t file = 0;
  std::uint32_t directory = 0;
};

/// A stack's layout, from its pages' headers.
struct tiff_stack {
  std::filesystem::path input;               ///< the file or directory named
  std::vector<std::filesystem::path> files;  ///< in slice order
  std::vector<tiff_page> pages;              ///< every slice, in order
  std::int64_t volumes = 1;                  ///< an ImageJ hyperstack's frames
  index3 dims{};                             ///< of one volume: dims[2] × volumes == pages
  sample_type type = sample_type::u8;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
};

/// Reads the pages' headers of a TIFF file or a directory of TIFF files. Throws progiso::error
/// naming the file and page on any failure.
[[nodiscard]] tiff_stack read_tiff_stack(const std::filesystem::path& input);
/// Decodes the pages [first, first + dims[2]) of the stack (volume first / dims[2]) into one
/// sample array (host byte order, x fastest). Throws progiso::error naming the file and page
/// on any failure.
[[nodiscard]] std::vector<std::byte> read_tiff_samples(const tiff_stack& stack,
                                                       std::size_t first = 0);

}  // namespace progiso::detail
