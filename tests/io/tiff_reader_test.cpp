// Tests for read_tiff() (io/detail/tiff_reader.hpp): TIFF stacks written by libtiff itself
// (support/tiff_files.hpp) read back as the samples given, for every sample type, codec,
// predictor, strip or tile layout and byte order; directories of slices in natural order; ImageJ
// spacing and hyperstack frames; thumbnails skipped; and every refusal as one line naming the
// file and page, before any allocation that the file's data cannot back.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/tiff_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;
using test::tiff_page_spec;

// `pages` slices of width × height samples of `type`, random, each page's own.
std::vector<std::vector<std::byte>> random_slices(sample_type type, std::uint32_t width,
                                                  std::uint32_t height, std::size_t pages,
                                                  unsigned seed) {
  std::vector<std::vector<std::byte>> out;
  for (std::size_t k = 0; k < pages; ++k) {
    out.push_back(test::random_samples(type, std::size_t{width} * height,
                                       seed * 131u + static_cast<unsigned>(k)));
  }
  return out;
}

std::vector<std::byte> joined(const std::vector<std::vector<std::byte>>& slices) {
  std::vector<std::byte> all;
  for (const auto& s : slices) all.insert(all.end(), s.begin(), s.end());
  return all;
}

void expect_samples(const volume& v, const std::vector<std::byte>& want) {
  ASSERT_EQ(v.byte_size(), want.size());
  EXPECT_EQ(std::memcmp(v.bytes(), want.data(), want.size()), 0);
}

TEST(TiffReader, reads_every_type_codec_predictor_layout_and_byte_order_as_written) {
  const test::scratch_dir dir("progiso-tiff-test-");
  const std::array<sample_type, 8> types{sample_type::u8,  sample_type::i8,  sample_type::u16,
                                         sample_type::i16, sample_type::u32, sample_type::i32,
                                         sample_type::f32, sample_type::f64};
  const std::array<std::uint16_t, 4> codecs{COMPRESSION_NONE, COMPRESSION_LZW,
                                            COMPRESSION_ADOBE_DEFLATE, COMPRESSION_PACKBITS};
  unsigned seed = 1;
  int files = 0;
  for (const sample_type t : types) {
    for (const std::uint16_t codec : codecs) {
      for (int variant = 0; variant < 4; ++variant) {
        // 37 × 21 samples: neither a multiple of the 16-sample tiles nor of the 3-row strips.
        const auto slices = random_slices(t, 37, 21, 5, seed);
        std::vector<tiff_page_spec> pages;
        for (const auto& s : slices) {
          tiff_page_spec p = test::grey_page(37, 21, t, s);
          p.compression = codec;
          p.tiled = (variant & 1) != 0;
          if ((variant & 2) != 0 && codec != COMPRESSION_NONE && codec != COMPRESSION_PACKBITS) {
            p.predictor = t == sample_type::f32 || t == sample_type::f64 ? PREDICTOR_FLOATINGPOINT
                                                                         : PREDICTOR_HORIZONTAL;
          }
          pages.push_back(std::move(p));
        }
        // Big-endian files too, but not with the floating-point predictor: libtiff 4.5's
        // writer swaps a big-endian file's floats before it reorders their bytes, so what it
        // writes is not TIFF Technical Note 3's layout (its reader follows the note; the test
        // below checks a file made by the note by hand).
        const bool big_endian =
            (seed % 3) == 0 && pages.front().predictor != PREDICTOR_FLOATINGPOINT;
        const fs::path file = dir.path() / ("s" + std::to_string(seed++) + ".tif");
        ASSERT_TRUE(test::write_tiff(file, pages, big_endian)) << file;
        SCOPED_TRACE(file.string() + " " + std::string(to_string(t)) + " codec " +
                     std::to_string(codec) + " variant " + std::to_string(variant));
        const volume v = read_tiff(file);
        EXPECT_EQ(v.dims(), (index3{37, 21, 5}));
        EXPECT_EQ(v.type(), t);
        EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.0, 1.0, 1.0}));
        expect_samples(v, joined(slices));
        ++files;
      }
    }
  }
  EXPECT_EQ(files, 128);
  // BigTIFF, and the .tiff extension in capitals through read_volume().
  const auto slices = random_slices(sample_type::u16, 20, 30, 3, 99);
  std::vector<tiff_page_spec> pages;
  for (const auto& s : slices) pages.push_back(test::grey_page(20, 30, sample_type::u16, s));
  const fs::path big = dir.path() / "big.TIFF";
  ASSERT_TRUE(test::write_tiff(big, pages, false, true));
  expect_samples(read_volume(big, std::nullopt, std::nullopt), joined(slices));
}

TEST(TiffReader, big_endian_floats_with_the_floating_point_predictor_follow_tech_note_3) {
  // Made by hand from TIFF Technical Note 3: each row's floats split into byte planes, most
  // significant first, then every byte minus the one before it; deflated, in a big-endian file
  // (Photoshop's and old Macs' byte order). Two pages of 6 × 4 floats.
  const test::scratch_dir dir("progiso-tiff-test-");
  constexpr std::uint32_t w = 6;
  constexpr std::uint32_t h = 4;
  std::vector<float> values(2 * w * h);
  for (std::size_t i = 0; i < values.size(); ++i) {
    values[i] = static_cast<float>(i) * 1.25f - 17.5f + (i % 5 == 0 ? 1e6f : 0.0f);
  }
  std::vector<std::string> strips;
  for (std::uint32_t page = 0; page < 2; ++page) {
    std::string raw;
    for (std::uint32_t y = 0; y < h; ++y) {
      std::string row(4 * w, '\0');
      for (std::uint32_t x = 0; x < w; ++x) {
        std::uint32_t bits = 0;
        std::memcpy(&bits, &values[(page * h + y) * w + x], 4);
        for (std::uint32_t k = 0; k < 4; ++k) {
          row[k * w + x] = static_cast<char>((bits >> (8 * (3 - k))) & 0xff);
        }
      }
      for (std::size_t j = row.size() - 1; j > 0; --j) {
        row[j] = static_cast<char>(static_cast<unsigned char>(row[j]) -
                                   static_cast<unsigned char>(row[j - 1]));
      }
      raw += row;
    }
    strips.push_back(test::gzip(raw, 6, true));
  }
  const std::string file =
      test::hand_made_tiff(true, w, h, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_ADOBE_DEFLATE,
                           PREDICTOR_FLOATINGPOINT, strips);
  const fs::path path = dir.path() / "note3.tif";
  test::write_file(path, file);
  const volume v = read_tiff(path);
  ASSERT_EQ(v.dims(), (index3{w, h, 2}));
  ASSERT_EQ(v.type(), sample_type::f32);
  for (std::size_t i = 0; i < values.size(); ++i)
    EXPECT_EQ(v.at(i), static_cast<double>(values[i])) << i;
}

TEST(TiffReader, a_directory_is_its_slices_in_natural_order_other_files_ignored) {
  const test::scratch_dir dir("progiso-tiff-test-");
  // slice1 … slice12 (slice10 sorts after slice9, not after slice1), written out of order; a
  // two-page file in the middle; files of other kinds beside them.
  const auto slices = random_slices(sample_type::u8, 16, 9, 14, 7);
  std::vector<std::string> names;
  for (int i = 1; i <= 12; ++i) names.push_back("slice" + std::to_string(i) + ".tif");
  std::vector<std::vector<std::byte>> want;
  for (int i = 12; i >= 1; --i) {
    std::vector<tiff_page_spec> pages{
        test::grey_page(16, 9, sample_type::u8, slices[static_cast<std::size_t>(i - 1)])};
    if (i == 5) pages.push_back(test::grey_page(16, 9, sample_type::u8, slices[12]));
    ASSERT_TRUE(test::write_tiff(dir.path() / names[static_cast<std::size_t>(i - 1)], pages));
  }
  for (int i = 1; i <= 12; ++i) {
    want.push_back(slices[static_cast<std::size_t>(i - 1)]);
    if (i == 5) want.push_back(slices[12]);
  }
  test::write_file(dir.path() / "scan.log", "Scanner=SkyScan 1272\n");
  test::write_file(dir.path() / "preview.png", "not a slice");
  fs::create_directory(dir.path() / "recon.tif");  // a directory named like a slice: not one
  const volume v = read_volume(dir.path(), std::nullopt, std::nullopt);
  EXPECT_EQ(v.dims(), (index3{16, 9, 13}));
  expect_samples(v, joined(want));
  // The command's input list: the directory, then each slice file in order.
  const std::vector<fs::path> files = volume_input_files(dir.path(), std::nullopt);
  ASSERT_EQ(files.size(), 13u);
  EXPECT_EQ(files[0], dir.path());
  EXPECT_EQ(files[1].filename(), "slice1.tif");
  EXPECT_EQ(files[10].filename(), "slice10.tif");
  EXPECT_EQ(files[12].filename(), "slice12.tif");
}

TEST(TiffReader, imagej_gives_the_spacing_and_a_hyperstack_of_frames_is_a_time_series) {
  const test::scratch_dir dir("progiso-tiff-test-");
  // 3 frames of 4 slices; 0.5 × 0.25 µm pixels (2 and 4 pixels per µm), 2.5 µm between slices.
  const auto slices = random_slices(sample_type::u16, 12, 10, 12, 3);
  std::vector<tiff_page_spec> pages;
  for (std::size_t k = 0; k < slices.size(); ++k) {
    tiff_page_spec p = test::grey_page(12, 10, sample_type::u16, slices[k]);
    p.x_resolution = 2.0f;
    p.y_resolution = 4.0f;
    if (k == 0) {
      p.description =
          "ImageJ=1.54f\nimages=12\nslices=4\nframes=3\nhyperstack=true\nunit=micron\n"
          "spacing=2.5\nloop=false\n";
    }
    pages.push_back(std::move(p));
  }
  const fs::path file = dir.path() / "timelapse.tif";
  ASSERT_TRUE(test::write_tiff(file, pages));
  for (std::int64_t k = 0; k < 3; ++k) {
    const volume v = read_tiff(file, {std::nullopt, k});
    EXPECT_EQ(v.dims(), (index3{12, 10, 4}));
    EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 0.25, 2.5}));
    const std::vector<std::vector<std::byte>> frame(slices.begin() + 4 * k,
                                                    slices.begin() + 4 * k + 4);
    expect_samples(v, joined(frame));
  }
  const std::string unchosen = test::error_message_naming(file, [&] { (void)read_tiff(file); });
  EXPECT_NE(unchosen.find("time series of 3 volumes"), std::string::npos) << unchosen;
  const std::string beyond = test::error_message_naming(file, [&] {
    (void)read_tiff(file, {std::nullopt, 3});
  });
  EXPECT_NE(beyond.find("volume 3"), std::string::npos) << beyond;
  // --spacing replaces ImageJ's.
  EXPECT_EQ(read_volume(file, std::nullopt, std::array<double, 3>{1.0, 2.0, 3.0}, {std::nullopt, 1})
                .spacing(),
            (std::array<double, 3>{1.0, 2.0, 3.0}));
  // A series is for DICOM only.
  const std::string series = test::error_message_naming(file, [&] {
    (void)read_volume(file, std::nullopt, std::nullopt, {std::string("1"), 0});
  });
  EXPECT_NE(series.find("not a DICOM directory"), std::string::npos) << series;
}

TEST(TiffReader, ome_tiff_gives_physical_sizes_and_a_time_series_in_its_dimension_order) {
  // An OME-TIFF as Bio-Formats writes one: 2 time points of 3 slices, planes in DimensionOrder
  // XYTZC (T varies fastest: page t + 2z), 0.65 µm pixels and 2000 nm between slices.
  const test::scratch_dir dir("progiso-tiff-test-");
  const auto planes = random_slices(sample_type::u16, 14, 9, 6, 21);
  const std::string xml =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?><OME xmlns=\"http://www.openmicroscopy.org/"
      "Schemas/OME/2016-06\"><Image ID=\"Image:0\"><Pixels BigEndian=\"false\" "
      "DimensionOrder=\"XYTZC\" ID=\"Pixels:0\" PhysicalSizeX=\"0.65\" PhysicalSizeY=\"0.65\" "
      "PhysicalSizeZ=\"2000\" PhysicalSizeZUnit=\"nm\" SizeC=\"1\" SizeT=\"2\" SizeX=\"14\" "
      "SizeY=\"9\" SizeZ=\"3\" Type=\"uint16\"><TiffData/></Pixels></Image></OME>";
  std::vector<tiff_page_spec> pages;
  for (const auto& p : planes) pages.push_back(test::grey_page(14, 9, sample_type::u16, p));
  pages[0].description = xml;
  const fs::path file = dir.path() / "cells.ome.tif";
  ASSERT_TRUE(test::write_tiff(file, pages));
  for (std::int64_t t = 0; t < 2; ++t) {
    const volume v = read_tiff(file, {std::nullopt, t});
    EXPECT_EQ(v.dims(), (index3{14, 9, 3}));
    for (std::size_t a = 0; a < 3; ++a) {
      EXPECT_DOUBLE_EQ(v.spacing()[a], (std::array<double, 3>{0.65, 0.65, 2.0})[a]);
    }
    std::vector<std::vector<std::byte>> want;
    for (std::size_t z = 0; z < 3; ++z) want.push_back(planes[static_cast<std::size_t>(t) + 2 * z]);
    expect_samples(v, joined(want));
  }
  const std::string unchosen = test::error_message_naming(file, [&] { (void)read_tiff(file); });
  EXPECT_NE(unchosen.find("time series of 2 volumes"), std::string::npos) << unchosen;
  // Two channels; planes in other files (SizeZ × SizeT above the pages): refused.
  std::string two = xml;
  two.replace(two.find("SizeC=\"1\""), 9, "SizeC=\"2\"");
  pages[0].description = two;
  const fs::path channels = dir.path() / "channels.ome.tif";
  ASSERT_TRUE(test::write_tiff(channels, pages));
  EXPECT_NE(test::error_message_naming(channels, [&] { (void)read_tiff(channels); })
                .find("an OME-TIFF of 2 channels"),
            std::string::npos);
  std::string split = xml;
  split.replace(split.find("SizeT=\"2\""), 9, "SizeT=\"5\"");
  pages[0].description = split;
  const fs::path parts = dir.path() / "part.ome.tif";
  ASSERT_TRUE(test::write_tiff(parts, pages));
  EXPECT_NE(test::error_message_naming(parts, [&] { (void)read_tiff(parts); })
                .find("describes 3 × 5 planes (SizeZ × SizeT), the file has 6 pages"),
            std::string::npos);
}

TEST(TiffReader, reduced_resolution_pages_are_not_slices) {
  const test::scratch_dir dir("progiso-tiff-test-");
  const auto slices = random_slices(sample_type::f32, 10, 11, 3, 5);
  std::vector<tiff_page_spec> pages;
  tiff_page_spec thumb =
      test::grey_page(5, 5, sample_type::u8, test::random_samples(sample_type::u8, 25, 1));
  thumb.reduced = true;
  pages.push_back(thumb);
  for (const auto& s : slices) pages.push_back(test::grey_page(10, 11, sample_type::f32, s));
  pages.insert(pages.begin() + 2, thumb);
  const fs::path file = dir.path() / "pyramid.tif";
  ASSERT_TRUE(test::write_tiff(file, pages));
  const volume v = read_tiff(file);
  EXPECT_EQ(v.dims(), (index3{10, 11, 3}));
  expect_samples(v, joined(slices));
}

TEST(TiffReader, refuses_what_it_cannot_read_with_one_line_naming_the_file_and_page) {
  const test::scratch_dir dir("progiso-tiff-test-");
  const auto u8 = [](std::uint32_t w, std::uint32_t h, unsigned seed) {
    return test::grey_page(w, h, sample_type::u8,
                           test::random_samples(sample_type::u8, std::size_t{w} * h, seed));
  };
  struct refusal {
    std::string name;
    std::vector<tiff_page_spec> pages;
    std::string fragment;
  };
  std::vector<refusal> cases;
  {
    tiff_page_spec rgb = u8(8, 8, 1);
    rgb.samples_per_pixel = 3;
    rgb.photometric = PHOTOMETRIC_RGB;
    rgb.samples = test::random_samples(sample_type::u8, 8 * 8 * 3, 1);
    cases.push_back({"rgb.tif", {rgb, rgb}, "(page 0): expected one grey channel"});
  }
  {
    tiff_page_spec palette = u8(8, 8, 2);
    palette.photometric = PHOTOMETRIC_PALETTE;
    cases.push_back({"palette.tif", {palette, palette}, "photometric 3"});
  }
  {
    tiff_page_spec one_bit = u8(16, 8, 3);
    one_bit.bits = 1;
    one_bit.samples.resize(2 * 8);
    cases.push_back({"bits.tif", {one_bit, one_bit}, "found 1-bit unsigned integers"});
  }
  {
    tiff_page_spec half =
        test::grey_page(8, 8, sample_type::u16, test::random_samples(sample_type::u16, 64, 4));
    half.format = SAMPLEFORMAT_IEEEFP;
    cases.push_back({"half.tif", {half, half}, "found 16-bit floats"});
  }
  {
    tiff_page_spec wide =
        test::grey_page(8, 8, sample_type::f64, test::random_samples(sample_type::f64, 64, 5));
    wide.format = SAMPLEFORMAT_INT;
    cases.push_back({"int64.tif", {wide, wide}, "found 64-bit signed integers"});
  }
  cases.push_back({"sizes.tif", {u8(8, 8, 6), u8(8, 9, 7)}, "(page 1): 8 × 9 u8 samples, where"});
  {
    tiff_page_spec other =
        test::grey_page(8, 8, sample_type::u16, test::random_samples(sample_type::u16, 64, 8));
    cases.push_back({"types.tif", {u8(8, 8, 8), other}, "(expected one size and type)"});
  }
  if (TIFFIsCODECConfigured(COMPRESSION_ZSTD) != 0) {
    tiff_page_spec zstd = u8(8, 8, 9);
    zstd.compression = COMPRESSION_ZSTD;
    cases.push_back(
        {"zstd.tif", {zstd, zstd}, "is not read (expected none, LZW, Deflate or PackBits)"});
  }
  cases.push_back({"one.tif", {u8(8, 8, 10)}, "one slice"});
  {
    std::vector<tiff_page_spec> pages{u8(8, 8, 11), u8(8, 8, 12)};
    pages[0].description = "ImageJ=1.54f\nimages=2\nchannels=2\nslices=1\n";
    cases.push_back({"channels.tif", pages, "2 channels"});
  }
  {
    std::vector<tiff_page_spec> pages{u8(8, 8, 13), u8(8, 8, 14)};
    pages[0].description = "ImageJ=1.54f\nimages=400\nslices=400\n";
    cases.push_back({"bigstack.tif", pages, "counts 400 images, the file has 2 pages"});
  }
  for (const refusal& c : cases) {
    const fs::path file = dir.path() / c.name;
    ASSERT_TRUE(test::write_tiff(file, c.pages)) << c.name;
    const std::string message = test::error_message_naming(
        file, [&] { (void)read_tiff(file); }, "");
    EXPECT_NE(message.find(c.fragment), std::string::npos) << c.name << ": " << message;
  }

  // Not a TIFF, and a TIFF cut short in its strips.
  const fs::path text = dir.path() / "notes.tif";
  test::write_file(text, "these are not the slices you are looking for\n");
  const std::string not_tiff = test::error_message_naming(text, [&] { (void)read_tiff(text); });
  EXPECT_NE(not_tiff.find("cannot be read as TIFF"), std::string::npos) << not_tiff;

  const fs::path whole = dir.path() / "whole.tif";
  std::vector<tiff_page_spec> pages{u8(64, 64, 20), u8(64, 64, 21), u8(64, 64, 22)};
  for (auto& p : pages) p.compression = COMPRESSION_ADOBE_DEFLATE;
  ASSERT_TRUE(test::write_tiff(whole, pages));
  const std::string bytes = test::read_whole_file(whole);
  const fs::path cut = dir.path() / "cut.tif";
  // libtiff writes each page's strips before its directory: cutting the file in the middle of
  // the last page's strips keeps every directory but the last.
  test::write_file(cut, bytes.substr(0, bytes.size() * 3 / 4));
  EXPECT_NE(test::error_message_naming(
                cut, [&] { (void)read_tiff(cut); }, "")
                .find(cut.string()),
            std::string::npos);

  // A directory without TIFF files is not a TIFF stack (the command takes it for DICOM); read as
  // one, it holds none.
  const fs::path empty = dir.path() / "empty";
  fs::create_directory(empty);
  const std::string none = test::error_message_naming(empty, [&] { (void)read_tiff(empty); });
  EXPECT_NE(none.find("holds no .tif or .tiff file"), std::string::npos) << none;
}

TEST(TiffReader, a_page_that_declares_more_than_its_strips_can_hold_is_refused_before_allocating) {
  // A 30000 × 30000 page of 32-bit floats (3.6 GB) whose one LZW strip holds 4 bytes (at most
  // 16 KB decoded), made by hand (libtiff would not write it).
  const test::scratch_dir dir("progiso-tiff-test-");
  const std::string t =
      test::hand_made_tiff(false, 30000, 30000, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_LZW,
                           PREDICTOR_NONE, {std::string(4, '\0')});
  const fs::path file = dir.path() / "huge.tif";
  test::write_file(file, t);
  const std::string message = test::error_message_naming(
      file, [&] { (void)read_tiff(file); }, "");
  EXPECT_NE(message.find(
                "(page 0): 30000 × 30000 samples of 32 bits need 3600000000 bytes, more "
                "than its 4 bytes of strips can hold (compression 5 (LZW) expands at most 4096×)"),
            std::string::npos)
      << message;
}

}  // namespace
}  // namespace progiso
