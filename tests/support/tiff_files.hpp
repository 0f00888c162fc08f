// tests/support/tiff_files.hpp — TIFF files written by libtiff itself, the reference writer the
// TIFF reader tests read back: any sample type, codec, predictor, strips or tiles, byte order,
// ImageJ descriptions and resolutions, reduced-resolution pages. Header-only; the test binary
// links libtiff.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <tiffio.h>

#include <progiso/core/field/volume.hpp>

namespace progiso::test {

/// One page to write.
struct tiff_page_spec {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint16_t bits = 8;
  std::uint16_t format = SAMPLEFORMAT_UINT;
  std::uint16_t samples_per_pixel = 1;
  std::uint16_t photometric = PHOTOMETRIC_MINISBLACK;
  std::uint16_t compression = COMPRESSION_NONE;
  std::uint16_t predictor = PREDICTOR_NONE;
  bool tiled = false;
  std::uint32_t tile = 16;           ///< tile width and height when tiled
  std::uint32_t rows_per_strip = 3;  ///< when not tiled
  bool reduced = false;              ///< NewSubfileType: a reduced-resolution image
  std::string description;           ///< ImageDescription, when not empty
  float x_resolution = 0.0f;         ///< XResolution and YResolution, when above 0
  float y_resolution = 0.0f;
  std::vector<std::byte> samples;  ///< host byte order, rows first row first
};

/// The bits and sample format of a progiso sample type.
inline void set_type(tiff_page_spec& p, sample_type t) {
  switch (t) {
    case sample_type::u8:
    case sample_type::u16:
    case sample_type::u32:
      p.format = SAMPLEFORMAT_UINT;
      break;
    case sample_type::i8:
    case sample_type::i16:
    case sample_type::i32:
      p.format = SAMPLEFORMAT_INT;
      break;
    case sample_type::f32:
    case sample_type::f64:
      p.format = SAMPLEFORMAT_IEEEFP;
      break;
  }
  p.bits = static_cast<std::uint16_t>(8 * sample_size(t));
}

/// Writes `pages` with libtiff ("w", or "wb" for big-endian, "w8" for BigTIFF); false when
/// libtiff refuses something.
inline bool write_tiff(const std::filesystem::path& file, const std::vector<tiff_page_spec>& pages,
                       bool big_endian = false, bool big_tiff = false) {
  TIFF* tif = TIFFOpen(file.string().c_str(), big_tiff ? "w8" : big_endian ? "wb" : "wl");
  if (tif == nullptr) return false;
  bool ok = true;
  for (const tiff_page_spec& p : pages) {
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, p.width);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, p.height);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, p.bits);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, p.format);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, p.samples_per_pixel);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, p.photometric);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_COMPRESSION, p.compression);
    if (p.predictor != PREDICTOR_NONE) TIFFSetField(tif, TIFFTAG_PREDICTOR, p.predictor);
    if (p.reduced) TIFFSetField(tif, TIFFTAG_SUBFILETYPE, FILETYPE_REDUCEDIMAGE);
    if (!p.description.empty()) TIFFSetField(tif, TIFFTAG_IMAGEDESCRIPTION, p.description.c_str());
    if (p.x_resolution > 0.0f) {
      TIFFSetField(tif, TIFFTAG_XRESOLUTION, static_cast<double>(p.x_resolution));
      TIFFSetField(tif, TIFFTAG_YRESOLUTION, static_cast<double>(p.y_resolution));
      TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, RESUNIT_NONE);
    }
    if (p.photometric == PHOTOMETRIC_PALETTE) {
      std::vector<std::uint16_t> map(std::size_t{1} << p.bits, 0);
      TIFFSetField(tif, TIFFTAG_COLORMAP, map.data(), map.data(), map.data());
    }
    const std::size_t pixel = std::size_t{p.bits} * p.samples_per_pixel / 8;
    const std::size_t row = (std::size_t{p.width} * p.bits * p.samples_per_pixel + 7) / 8;
    if (p.tiled) {
      TIFFSetField(tif, TIFFTAG_TILEWIDTH, p.tile);
      TIFFSetField(tif, TIFFTAG_TILELENGTH, p.tile);
      std::vector<std::byte> tile(static_cast<std::size_t>(TIFFTileSize(tif)));
      for (std::uint32_t y0 = 0; y0 < p.height && ok; y0 += p.tile) {
        for (std::uint32_t x0 = 0; x0 < p.width && ok; x0 += p.tile) {
          std::fill(tile.begin(), tile.end(), std::byte{0});
          for (std::uint32_t y = y0; y < std::min(p.height, y0 + p.tile); ++y) {
            const std::size_t n = std::min(p.tile, p.width - x0) * pixel;
            std::memcpy(tile.data() + (y - y0) * p.tile * pixel,
                        p.samples.data() + y * row + x0 * pixel, n);
          }
          ok = TIFFWriteTile(tif, tile.data(), x0, y0, 0, 0) >= 0;
        }
      }
    } else {
      TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, p.rows_per_strip);
      std::vector<std::byte> line(row);
      for (std::uint32_t y = 0; y < p.height && ok; ++y) {
        std::memcpy(line.data(), p.samples.data() + y * row, row);  // libtiff may modify it
        ok = TIFFWriteScanline(tif, line.data(), y, 0) == 1;
      }
    }
    ok = ok && TIFFWriteDirectory(tif) == 1;
  }
  TIFFClose(tif);
  return ok;
}

/// A page of `type` samples (host order) over width × height.
inline tiff_page_spec grey_page(std::uint32_t width, std::uint32_t height, sample_type type,
                                std::vector<std::byte> samples) {
  tiff_page_spec p;
  p.width = width;
  p.height = height;
  set_type(p, type);
  p.samples = std::move(samples);
  return p;
}

/// A classic TIFF made by hand, byte by byte (for what libtiff would not write): one page per
/// entry of `strips`, each `width` × `height` samples of `bits` bits (SampleFormat `format`) in
/// one strip of the given bytes, with Compression `compression` and Predictor `predictor`;
/// big-endian ("MM") or little-endian ("II"). The strips come first, then the directories.
inline std::string hand_made_tiff(bool big_endian, std::uint32_t width, std::uint32_t height,
                                  std::uint16_t bits, std::uint16_t format,
                                  std::uint16_t compression, std::uint16_t predictor,
                                  const std::vector<std::string>& strips) {
  std::string file = big_endian ? "MM" : "II";
  const auto put = [&file, big_endian](std::uint32_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) {
      const int shift = 8 * (big_endian ? bytes - 1 - i : i);
      file += static_cast<char>((v >> shift) & 0xffu);
    }
  };
  put(42, 2);
  const std::uint16_t entries = 11;
  const std::uint32_t ifd_bytes = 2 + entries * 12 + 4;
  std::vector<std::uint32_t> at;
  std::uint32_t next = 8;
  for (const std::string& s : strips) {
    at.push_back(next);
    next += static_cast<std::uint32_t>(s.size());
  }
  put(next, 4);  // the first directory, after the strips
  for (const std::string& s : strips) file += s;
  for (std::size_t page = 0; page < strips.size(); ++page) {
    put(entries, 2);
    const auto entry = [&](std::uint16_t tag, std::uint16_t type, std::uint32_t value) {
      put(tag, 2);
      put(type, 2);
      put(1, 4);
      if (type == 3) {  // SHORT: left-justified in the value field
        put(value, 2);
        put(0, 2);
      } else {
        put(value, 4);
      }
    };
    entry(256, 4, width);
    entry(257, 4, height);
    entry(258, 3, bits);
    entry(259, 3, compression);
    entry(262, 3, PHOTOMETRIC_MINISBLACK);
    entry(273, 4, at[page]);
    entry(277, 3, 1);
    entry(278, 4, height);
    entry(279, 4, static_cast<std::uint32_t>(strips[page].size()));
    entry(317, 3, predictor);
    entry(339, 3, format);
    put(page + 1 < strips.size() ? next + static_cast<std::uint32_t>(page + 1) * ifd_bytes : 0, 4);
  }
  return file;
}

}  // namespace progiso::test
