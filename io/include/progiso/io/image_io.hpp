// progiso/io/image_io.hpp — grayscale images (binary PGM, PNG) read as one-sample-thick
// volumes.
//
// Images are the input of the 2D path: progressive isocontours over hierarchy2d. Each reader
// returns a volume with dims {width, height, 1} (x = column, y = row, row 0 first as stored in
// the file), unit spacing and zero origin, holding the file's sample values unchanged: u8 for
// 8-bit data (and for 1, 2 and 4-bit PNGs, expanded to 0..255), u16 for 16-bit data, always
// in host byte order.
//
// read_pgm() reads binary PGM ("P5") only, the format netpbm and most image tools write for
// 8 and 16-bit grayscale rasters; read_png() reads grayscale PNG through libpng and rejects
// colour PNGs rather than converting them, because a luminance mix of RGB is rarely the field
// a user means to contour. read_image() picks one by the file extension. Use read_volume()
// (volume_io.hpp) for 3D data instead.
//
// Every failure caused by the input — a missing file, another format, a malformed or
// truncated header or raster, an image narrower or lower than 2 samples — throws
// progiso::error with one line that names the file, what was expected and what was found.
// Nothing here aborts or prints on malformed input.
//
// Cost: one pass over the file; the raster is decoded straight into the volume's storage
// (PGM reads the file into memory first, so it peaks at about twice the raster size).
//
// Thread safety: the functions may be called concurrently (libpng keeps all its state per
// call).
#pragma once

#include <filesystem>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso {

/// Reads a binary PGM ("P5") file: header tokens width, height, maxval separated by
/// whitespace and '#' comments, then exactly one whitespace byte and width × height samples,
/// one byte each when maxval < 256 (sample_type::u8), else two bytes, most significant first
/// (sample_type::u16, converted to host order). Throws progiso::error naming the file when it
/// cannot be read, is not P5 (plain PGM, PBM, PPM … are named in the message), has a malformed
/// or truncated header, a maxval outside 1..65535, a width or height < 2, a raster shorter or
/// longer than width × height samples, or a sample larger than maxval.
[[nodiscard]] volume read_pgm(const std::filesystem::path& file);

/// Reads a grayscale PNG (colour type gray or gray + alpha; any bit depth, interlaced or not)
/// through libpng. Bit depths 1, 2 and 4 are expanded to 8 (0..255, sample_type::u8), 8 gives
/// u8 and 16 gives u16 in host order; an alpha channel and any tRNS chunk are dropped, gamma
/// is ignored, the stored values are returned. Throws progiso::error naming the file when it
/// cannot be read, is not a PNG, is a colour PNG (RGB, RGB + alpha or palette), has a width or
/// height < 2, or is corrupt or truncated (libpng's diagnosis is quoted).
[[nodiscard]] volume read_png(const std::filesystem::path& file);

/// Reads an image as read_pgm() or read_png() according to the extension of `file` (.pgm or
/// .png, any case). Throws progiso::error "FILE: unknown image format (expected .pgm or
/// .png)" for any other extension, and whatever the chosen reader throws.
[[nodiscard]] volume read_image(const std::filesystem::path& file);

}  // namespace progiso
