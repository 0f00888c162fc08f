// Tests for progiso/io/image_io.hpp: binary PGM (8 and 16-bit, comments, maxval, every
// malformed header and raster), grayscale PNG written here with libpng (8, 16 and sub-byte
// depths, alpha, interlacing), rejection of colour, truncated and corrupt PNGs, dispatch by
// extension, and the shared real images.
#include <progiso/io/image_io.hpp>

#include <gtest/gtest.h>

#include <png.h>
#include <zlib.h>
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"

#include <algorithm>
#include <csetjmp>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/test_data.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::volume;

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-image-io-test-") {}
};

void write_bytes(const fs::path& file, const std::string& bytes) {
  progiso::test::write_file(file, bytes);
}

template <class F>
std::string error_message(const fs::path& file, F&& f) {
  return progiso::test::error_message_naming(file, std::forward<F>(f));
}

using progiso::test::contains;

/// The samples of a one-sample-thick volume, row by row, as doubles.
std::vector<double> samples_of(const volume& v) {
  std::vector<double> out(v.voxel_count());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = v.at(i);
  return out;
}

// =============================================================================================
// A PNG encoder for the tests, straight on libpng (independent of progiso's own PNG code).

struct png_spec {
  png_uint_32 width = 0;
  png_uint_32 height = 0;
  int bit_depth = 8;
  int color_type = PNG_COLOR_TYPE_GRAY;
  bool interlaced = false;
};

void append_to_string(png_structp png, png_bytep data, png_size_t size) {
  static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<char*>(data), size);
}
void no_flush(png_structp) {}
void quiet(png_structp, png_const_charp) {}
[[noreturn]] void jump_back(png_structp png, png_const_charp) { png_longjmp(png, 1); }

// The setjmp frame holds nothing with a destructor (libpng leaves it by longjmp).
bool encode_stage(png_structp png, png_infop info, const png_spec* spec, png_bytepp rows,
                  std::string* out) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  png_set_write_fn(png, out, append_to_string, no_flush);
  png_set_IHDR(png, info, spec->width, spec->height, spec->bit_depth, spec->color_type,
               spec->interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (spec->color_type == PNG_COLOR_TYPE_PALETTE) {
    png_color palette[2] = {{0, 0, 0}, {255, 0, 0}};
    png_set_PLTE(png, info, palette, 2);
  }
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

/// A PNG file's bytes; `rows` hold each row packed as PNG stores it (16-bit big-endian).
std::string encode_png(const png_spec& spec, std::vector<std::string> rows) {
  std::vector<png_bytep> pointers;
  for (std::string& r : rows) pointers.push_back(reinterpret_cast<png_bytep>(r.data()));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, jump_back, quiet);
  png_infop info = png_create_info_struct(png);
  std::string out;
  const bool ok = encode_stage(png, info, &spec, pointers.data(), &out);
  png_destroy_write_struct(&png, &info);
  EXPECT_TRUE(ok) << "the test's PNG encoder failed";
  return out;
}

/// Rows of 8-bit samples.
std::vector<std::string> rows_u8(const std::vector<std::vector<int>>& values) {
  std::vector<std::string> rows;
  for (const auto& r : values) {
    std::string s;
    for (int v : r) s += static_cast<char>(v);
    rows.push_back(s);
  }
  return rows;
}

/// Rows of 16-bit samples, big-endian as PNG and PGM store them.
std::vector<std::string> rows_u16(const std::vector<std::vector<int>>& values) {
  std::vector<std::string> rows;
  for (const auto& r : values) {
    std::string s;
    for (int v : r) {
      s += static_cast<char>((v >> 8) & 0xff);
      s += static_cast<char>(v & 0xff);
    }
    rows.push_back(s);
  }
  return rows;
}

/// Rewrites the IHDR width and height of a PNG (and its CRC).
std::string with_ihdr_size(std::string png, std::uint32_t width, std::uint32_t height) {
  // Signature (8), IHDR length (4), "IHDR" (4), then width and height big-endian.
  for (int i = 0; i < 4; ++i) {
    png[16 + static_cast<std::size_t>(i)] = static_cast<char>((width >> (24 - 8 * i)) & 0xffu);
    png[20 + static_cast<std::size_t>(i)] = static_cast<char>((height >> (24 - 8 * i)) & 0xffu);
  }
  const auto crc =
      static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(png.data() + 12), 4 + 13));
  for (int i = 0; i < 4; ++i) {
    png[29 + static_cast<std::size_t>(i)] = static_cast<char>((crc >> (24 - 8 * i)) & 0xffu);
  }
  return png;
}

const std::vector<std::vector<int>> small_u8 = {{0, 10, 20}, {30, 40, 255}};

// =============================================================================================
// PGM.

TEST(ImageIo, pgm_8_bit_with_comments_reads_row_major_u8_samples) {
  const scratch_dir dir;
  write_bytes(dir / "a.pgm", "P5\n# made by hand\n3 # width\n# height next\n2\n255\n" +
                                 std::string("\x00\x0a\x14\x1e\x28\xff", 6));
  const volume v = progiso::read_pgm(dir / "a.pgm");
  EXPECT_EQ(v.dims(), (progiso::index3{3, 2, 1}));
  EXPECT_EQ(v.type(), sample_type::u8);
  EXPECT_EQ(samples_of(v), (std::vector<double>{0, 10, 20, 30, 40, 255}));
  EXPECT_EQ(v.value(2, 0, 0), 20.0);  // x = column
  EXPECT_EQ(v.value(0, 1, 0), 30.0);  // y = row
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.0, 1.0, 1.0}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{0.0, 0.0, 0.0}));
}

TEST(ImageIo, pgm_16_bit_samples_are_big_endian_and_read_as_u16) {
  const scratch_dir dir;
  write_bytes(dir / "a.pgm", "P5 2 2 65535\n" + std::string("\x01\x02\xff\xfe\x00\x00\x80\x01", 8));
  const volume v = progiso::read_pgm(dir / "a.pgm");
  EXPECT_EQ(v.dims(), (progiso::index3{2, 2, 1}));
  EXPECT_EQ(v.type(), sample_type::u16);
  EXPECT_EQ(samples_of(v), (std::vector<double>{0x0102, 0xfffe, 0, 0x8001}));
}

TEST(ImageIo, pgm_maxval_below_256_gives_u8_and_from_256_gives_u16_with_values_unscaled) {
  const scratch_dir dir;
  write_bytes(dir / "one.pgm", "P5\n2 2\n1\n" + std::string("\x00\x01\x01\x00", 4));
  const volume one = progiso::read_pgm(dir / "one.pgm");
  EXPECT_EQ(one.type(), sample_type::u8);
  EXPECT_EQ(samples_of(one), (std::vector<double>{0, 1, 1, 0}));

  write_bytes(dir / "255.pgm", "P5\n2 2\n255\n" + std::string("\x00\x01\xfe\xff", 4));
  EXPECT_EQ(progiso::read_pgm(dir / "255.pgm").type(), sample_type::u8);

  write_bytes(dir / "256.pgm",
              "P5\n2 2\n256\n" + std::string("\x00\x00\x01\x00\x00\x07\x00\xff", 8));
  const volume wide = progiso::read_pgm(dir / "256.pgm");
  EXPECT_EQ(wide.type(), sample_type::u16);
  EXPECT_EQ(samples_of(wide), (std::vector<double>{0, 256, 7, 255}));
  EXPECT_EQ(wide.value_range(), (std::array<double, 2>{0, 256}));
}

TEST(ImageIo, pgm_single_whitespace_after_maxval_starts_the_raster) {
  const scratch_dir dir;
  // The raster begins with bytes that are whitespace ('\n', ' ') and '#': they are samples.
  write_bytes(dir / "a.pgm", "P5\n2 2\n255\n" + std::string("\n #\t", 4));
  EXPECT_EQ(samples_of(progiso::read_pgm(dir / "a.pgm")),
            (std::vector<double>{'\n', ' ', '#', '\t'}));
  // A comment right after maxval runs to its newline, which is the one whitespace byte.
  write_bytes(dir / "b.pgm", "P5\n2 2\n255# comment\n" + std::string("\x01\x02\x03\x04", 4));
  EXPECT_EQ(samples_of(progiso::read_pgm(dir / "b.pgm")), (std::vector<double>{1, 2, 3, 4}));
}

TEST(ImageIo, pgm_rejects_other_netpbm_and_other_formats_naming_what_it_found) {
  const scratch_dir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"P2\n2 2\n255\n0 1 2 3\n", "\"P2\" (plain PGM"},
      {"P1\n2 2\n0 1 1 0\n", "\"P1\" (plain PBM"},
      {"P3\n2 2\n255\n", "\"P3\" (plain PPM"},
      {"P4\n2 2\n\x00\x00", "\"P4\" (binary PBM"},
      {"P6\n2 2\n255\n", "\"P6\" (binary PPM, a colour image"},
      {"\x89PNG\r\n\x1a\n", "found \"\\x89P\""},
      {"", "found an empty file"},
      {"P5", "found the end of the file"},
      {"P55 2 2 255\n", "expected whitespace after \"P5\", found \"5\""},
  };
  for (const auto& [bytes, fragment] : cases) {
    const fs::path file = dir / "bad.pgm";
    write_bytes(file, bytes);
    const std::string message = error_message(file, [&] { (void)progiso::read_pgm(file); });
    EXPECT_TRUE(contains(message, fragment)) << message << "\n  expected: " << fragment;
    if (bytes.size() >= 2 && bytes[0] == 'P' && bytes[1] != '5') {
      EXPECT_TRUE(contains(message, "expected a binary PGM file (magic number \"P5\")")) << message;
    }
  }
}

TEST(ImageIo, pgm_rejects_malformed_headers_with_one_line_messages) {
  const scratch_dir dir;
  const std::string four(4, '\x01');
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"P5\n3 x 2\n255\n" + four, "expected the height as a decimal number, found \"x\""},
      {"P5\n-3 2\n255\n" + four, "expected the width as a decimal number, found \"-3\""},
      {"P5\n2 2\n", "expected the maxval as a decimal number, found the end of the file"},
      {"P5\n2 2 # no maxval", "expected the maxval as a decimal number, found the end of"},
      {"P5\n2 2\n2.5\n" + four, "expected the maxval as a decimal number, found \"2.5\""},
      {"P5\n2 2\n99999999999\n" + four, "found \"99999999999\""},
      {"P5\n2 2\n0\n" + four, "expected a PGM maxval from 1 to 65535, found 0"},
      {"P5\n2 2\n65536\n" + four, "expected a PGM maxval from 1 to 65535, found 65536"},
      {"P5\n1 5\n255\n" + std::string(5, '\0'), "at least 2, found 1 x 5"},
      {"P5\n5 1\n255\n" + std::string(5, '\0'), "at least 2, found 5 x 1"},
      {"P5\n0 0\n255\n", "at least 2, found 0 x 0"},
      {"P5\n3000000000 2\n255\n",
       "at most 32769 (the largest image progiso contours), found 3000000000 x 2"},
      {"P5\n40000 2\n255\n", "at most 32769 (the largest image progiso contours), found 40000 x 2"},
      {"P5\n2 2\n255", "expected one whitespace byte and the raster after maxval, found the end"},
  };
  for (const auto& [bytes, fragment] : cases) {
    const fs::path file = dir / "bad.pgm";
    write_bytes(file, bytes);
    const std::string message = error_message(file, [&] { (void)progiso::read_pgm(file); });
    EXPECT_TRUE(contains(message, fragment)) << message << "\n  expected: " << fragment;
  }
}

TEST(ImageIo, pgm_rejects_a_raster_shorter_or_longer_than_width_times_height) {
  const scratch_dir dir;
  const fs::path file = dir / "a.pgm";
  write_bytes(file, "P5\n3 2\n255\n" + std::string(5, '\x07'));
  std::string message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message,
                       "expected 3 x 2 x 1 = 6 bytes of samples after the header, "
                       "found 5 (the file is truncated)"))
      << message;

  write_bytes(file, "P5\n3 2\n255\n" + std::string(7, '\x07'));
  message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message, "found 7 (trailing data after the image")) << message;

  write_bytes(file, "P5\n2 2\n1000\n" + std::string(7, '\x01'));
  message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message, "expected 2 x 2 x 2 = 8 bytes")) << message;
  EXPECT_TRUE(contains(message, "found 7 (the file is truncated)")) << message;

  // A second image after the first (netpbm allows it) is not read silently.
  write_bytes(
      file, "P5\n2 2\n255\n" + std::string(4, '\x01') + "P5\n2 2\n255\n" + std::string(4, '\x01'));
  message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message, "trailing data after the image")) << message;
}

TEST(ImageIo, pgm_rejects_samples_above_maxval_naming_the_pixel) {
  const scratch_dir dir;
  const fs::path file = dir / "a.pgm";
  write_bytes(file, "P5\n2 2\n100\n" + std::string("\x00\x64\x65\x00", 4));
  std::string message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message, "at most maxval 100, found 101 at column 0, row 1")) << message;

  write_bytes(file, "P5\n2 2\n1000\n" + std::string("\x00\x00\x03\xe8\x03\xe9\x00\x00", 8));
  message = error_message(file, [&] { (void)progiso::read_pgm(file); });
  EXPECT_TRUE(contains(message, "at most maxval 1000, found 1001 at column 0, row 1")) << message;
}

TEST(ImageIo, missing_files_are_reported_with_their_name) {
  const scratch_dir dir;
  for (const char* name : {"none.pgm", "none.png"}) {
    const fs::path file = dir / name;
    const std::string message = error_message(file, [&] { (void)progiso::read_image(file); });
    EXPECT_TRUE(contains(message, "cannot open")) << message;
  }
}

// =============================================================================================
// PNG.

TEST(ImageIo, png_8_bit_grayscale_reads_as_u8) {
  const scratch_dir dir;
  write_bytes(dir / "a.png", encode_png({3, 2, 8, PNG_COLOR_TYPE_GRAY}, rows_u8(small_u8)));
  const volume v = progiso::read_png(dir / "a.png");
  EXPECT_EQ(v.dims(), (progiso::index3{3, 2, 1}));
  EXPECT_EQ(v.type(), sample_type::u8);
  EXPECT_EQ(samples_of(v), (std::vector<double>{0, 10, 20, 30, 40, 255}));
}

TEST(ImageIo, png_16_bit_grayscale_reads_as_u16_in_host_order) {
  const scratch_dir dir;
  write_bytes(dir / "a.png", encode_png({2, 3, 16, PNG_COLOR_TYPE_GRAY},
                                        rows_u16({{0x0102, 0xfffe}, {0, 65535}, {256, 1}})));
  const volume v = progiso::read_png(dir / "a.png");
  EXPECT_EQ(v.dims(), (progiso::index3{2, 3, 1}));
  EXPECT_EQ(v.type(), sample_type::u16);
  EXPECT_EQ(samples_of(v), (std::vector<double>{0x0102, 0xfffe, 0, 65535, 256, 1}));
}

TEST(ImageIo, png_1_2_and_4_bit_grayscale_expand_to_the_full_8_bit_range) {
  const scratch_dir dir;
  // 1 bit: 10 pixels per row, packed most significant bit first: 1011 0010 | 01.. ....
  write_bytes(dir / "1.png", encode_png({10, 2, 1, PNG_COLOR_TYPE_GRAY},
                                        {std::string("\xb2\x40", 2), std::string("\x00\xc0", 2)}));
  const volume one = progiso::read_png(dir / "1.png");
  EXPECT_EQ(one.type(), sample_type::u8);
  EXPECT_EQ(samples_of(one), (std::vector<double>{255, 0, 255, 255, 0, 0, 255, 0, 0,   255,  //
                                                  0,   0, 0,   0,   0, 0, 0,   0, 255, 255}));
  // 2 bit: 0 1 2 3 → 0 85 170 255.
  write_bytes(dir / "2.png", encode_png({4, 2, 2, PNG_COLOR_TYPE_GRAY},
                                        {std::string("\x1b", 1), std::string("\xe4", 1)}));
  EXPECT_EQ(samples_of(progiso::read_png(dir / "2.png")),
            (std::vector<double>{0, 85, 170, 255, 255, 170, 85, 0}));
  // 4 bit: 0 15 7 1 → 0 255 119 17.
  write_bytes(dir / "4.png", encode_png({2, 2, 4, PNG_COLOR_TYPE_GRAY},
                                        {std::string("\x0f", 1), std::string("\x71", 1)}));
  EXPECT_EQ(samples_of(progiso::read_png(dir / "4.png")), (std::vector<double>{0, 255, 119, 17}));
}

TEST(ImageIo, png_gray_with_alpha_keeps_the_gray_and_drops_the_alpha) {
  const scratch_dir dir;
  write_bytes(dir / "a8.png", encode_png({2, 2, 8, PNG_COLOR_TYPE_GRAY_ALPHA},
                                         rows_u8({{5, 255, 6, 0}, {7, 128, 8, 1}})));
  const volume v8 = progiso::read_png(dir / "a8.png");
  EXPECT_EQ(v8.type(), sample_type::u8);
  EXPECT_EQ(samples_of(v8), (std::vector<double>{5, 6, 7, 8}));

  write_bytes(dir / "a16.png", encode_png({2, 2, 16, PNG_COLOR_TYPE_GRAY_ALPHA},
                                          rows_u16({{1000, 65535, 2000, 0}, {3000, 1, 65535, 2}})));
  const volume v16 = progiso::read_png(dir / "a16.png");
  EXPECT_EQ(v16.type(), sample_type::u16);
  EXPECT_EQ(samples_of(v16), (std::vector<double>{1000, 2000, 3000, 65535}));
}

TEST(ImageIo, png_interlaced_reads_the_same_samples_as_non_interlaced) {
  const scratch_dir dir;
  std::vector<std::vector<int>> values(11, std::vector<int>(13));
  for (std::size_t y = 0; y < values.size(); ++y) {
    for (std::size_t x = 0; x < values[y].size(); ++x) {
      values[y][x] = static_cast<int>((x * 977 + y * 131) % 65536);
    }
  }
  write_bytes(dir / "plain.png", encode_png({13, 11, 16, PNG_COLOR_TYPE_GRAY}, rows_u16(values)));
  write_bytes(dir / "adam7.png",
              encode_png({13, 11, 16, PNG_COLOR_TYPE_GRAY, true}, rows_u16(values)));
  const volume plain = progiso::read_png(dir / "plain.png");
  const volume adam7 = progiso::read_png(dir / "adam7.png");
  EXPECT_EQ(samples_of(plain), samples_of(adam7));
  EXPECT_EQ(plain.value(12, 10, 0), static_cast<double>((12 * 977 + 10 * 131) % 65536));
}

TEST(ImageIo, png_in_colour_is_rejected_rather_than_converted) {
  const scratch_dir dir;
  const std::vector<std::pair<png_spec, std::string>> cases = {
      {{2, 2, 8, PNG_COLOR_TYPE_RGB}, "expected a grayscale PNG, found RGB"},
      {{2, 2, 8, PNG_COLOR_TYPE_RGB_ALPHA}, "expected a grayscale PNG, found RGB with alpha"},
      {{2, 2, 16, PNG_COLOR_TYPE_RGB}, "expected a grayscale PNG, found RGB"},
      {{2, 2, 8, PNG_COLOR_TYPE_PALETTE}, "expected a grayscale PNG, found a palette"},
  };
  for (const auto& [spec, fragment] : cases) {
    const int channels = spec.color_type == PNG_COLOR_TYPE_RGB         ? 3
                         : spec.color_type == PNG_COLOR_TYPE_RGB_ALPHA ? 4
                                                                       : 1;
    const std::string row(2 * static_cast<std::size_t>(channels * spec.bit_depth / 8), '\x01');
    const fs::path file = dir / "colour.png";
    write_bytes(file, encode_png(spec, {row, row}));
    const std::string message = error_message(file, [&] { (void)progiso::read_png(file); });
    EXPECT_TRUE(contains(message, fragment)) << message << "\n  expected: " << fragment;
  }
}

TEST(ImageIo, png_truncated_or_corrupt_is_rejected_naming_the_file) {
  const scratch_dir dir;
  std::vector<std::vector<int>> values(64, std::vector<int>(64));
  for (std::size_t y = 0; y < 64; ++y) {
    for (std::size_t x = 0; x < 64; ++x) values[y][x] = static_cast<int>((x * 7 + y * y) % 256);
  }
  const std::string good = encode_png({64, 64, 8, PNG_COLOR_TYPE_GRAY}, rows_u8(values));
  ASSERT_GT(good.size(), 100u);

  const fs::path file = dir / "bad.png";
  // Cut inside the image data, inside the header chunk, and just before IEND's end.
  for (const std::size_t keep : {good.size() / 2, std::size_t{20}, good.size() - 3}) {
    write_bytes(file, good.substr(0, keep));
    const std::string message = error_message(file, [&] { (void)progiso::read_png(file); });
    EXPECT_TRUE(
        contains(message, "truncated PNG file (it ends before the image data does; libpng: "))
        << message;
  }
  // A flipped byte inside IDAT (its CRC no longer matches).
  std::string flipped = good;
  flipped[good.size() / 2] = static_cast<char>(flipped[good.size() / 2] ^ 0x5a);
  write_bytes(file, flipped);
  std::string message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "corrupt PNG file (libpng: ")) << message;

  // Not a PNG at all, or too short to hold the signature.
  write_bytes(file, "P5\n2 2\n255\n\x01\x02\x03\x04");
  message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "expected a PNG file")) << message;
  EXPECT_TRUE(contains(message, "found \"P5\\x0a2 2")) << message;
  write_bytes(file, "");
  message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "found an empty file")) << message;
}

TEST(ImageIo, png_announcing_more_pixels_than_its_data_can_hold_is_rejected_before_allocating) {
  const scratch_dir dir;
  const std::string tiny = encode_png({2, 2, 16, PNG_COLOR_TYPE_GRAY}, rows_u16({{1, 2}, {3, 4}}));
  const fs::path file = dir / "huge.png";
  // 30,000 x 30,000 x 2 bytes (within the axis limit) in a file of ~80 bytes.
  write_bytes(file, with_ihdr_size(tiny, 30000, 30000));
  const std::string message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "30000 x 30000 pixels cannot fit in")) << message;
  // Beyond the axis limit, refused by its size first.
  write_bytes(file, with_ihdr_size(tiny, 1000000, 1000000));
  const std::string huge = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(huge, "at most 32769")) << huge;
}

TEST(ImageIo, png_narrower_or_lower_than_two_pixels_is_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "thin.png";
  write_bytes(file, encode_png({1, 3, 8, PNG_COLOR_TYPE_GRAY}, rows_u8({{1}, {2}, {3}})));
  std::string message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "expected a width and height of at least 2, found 1 x 3"))
      << message;
  write_bytes(file, encode_png({3, 1, 8, PNG_COLOR_TYPE_GRAY}, rows_u8({{1, 2, 3}})));
  message = error_message(file, [&] { (void)progiso::read_png(file); });
  EXPECT_TRUE(contains(message, "found 3 x 1")) << message;
}

// =============================================================================================
// Dispatch.

TEST(ImageIo, read_image_picks_the_reader_by_extension_in_any_case) {
  const scratch_dir dir;
  write_bytes(dir / "a.PGM", "P5\n3 2\n255\n" + std::string("\x00\x0a\x14\x1e\x28\xff", 6));
  write_bytes(dir / "b.Png", encode_png({3, 2, 8, PNG_COLOR_TYPE_GRAY}, rows_u8(small_u8)));
  EXPECT_EQ(samples_of(progiso::read_image(dir / "a.PGM")),
            samples_of(progiso::read_image(dir / "b.Png")));

  // The extension decides, not the content.
  write_bytes(dir / "c.png", "P5\n2 2\n255\n\x01\x02\x03\x04");
  const std::string message =
      error_message(dir / "c.png", [&] { (void)progiso::read_image(dir / "c.png"); });
  EXPECT_TRUE(contains(message, "expected a PNG file")) << message;
}

TEST(ImageIo, read_image_rejects_an_unknown_extension) {
  const scratch_dir dir;
  for (const char* name : {"a.jpg", "a.pgm.gz", "pgm"}) {
    const fs::path file = dir / name;
    write_bytes(file, "P5\n2 2\n255\n\x01\x02\x03\x04");
    const std::string message = error_message(file, [&] { (void)progiso::read_image(file); });
    EXPECT_EQ(message, file.string() + ": unknown image format (expected .pgm or .png)");
  }
}

// =============================================================================================
// Real images (shared data folder).

TEST(ImageIo, shared_camera_pgm_is_512_by_512_u8) {
  const auto dir = progiso::test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data folder not found (set PROGISO_DATA_DIR)";
  const volume v = progiso::read_image(*dir / "camera_512x512.pgm");
  EXPECT_EQ(v.dims(), (progiso::index3{512, 512, 1}));
  EXPECT_EQ(v.type(), sample_type::u8);
  const auto [lo, hi] = v.value_range();
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 255.0);
  EXPECT_LT(lo, hi);
}

TEST(ImageIo, shared_coins_pgm_is_384_wide_and_303_high) {
  const auto dir = progiso::test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data folder not found (set PROGISO_DATA_DIR)";
  const fs::path file = *dir / "coins_384x303.pgm";
  const volume v = progiso::read_pgm(file);
  EXPECT_EQ(v.dims(), (progiso::index3{384, 303, 1}));
  EXPECT_EQ(v.type(), sample_type::u8);
  // The raster is row-major: sample (x, y) is byte 15 + y * 384 + x of the file (header
  // "P5\n384 303\n255\n").
  std::string bytes(static_cast<std::size_t>(fs::file_size(file)), '\0');
  std::ifstream(file, std::ios::binary)
      .read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_EQ(bytes.size(), 15u + 384u * 303u);
  for (const auto& [x, y] : {std::pair{0, 0}, std::pair{383, 0}, std::pair{0, 302},
                             std::pair{383, 302}, std::pair{200, 150}}) {
    const auto offset = static_cast<std::size_t>(15 + y * 384 + x);
    EXPECT_EQ(v.value(x, y, 0), static_cast<double>(static_cast<unsigned char>(bytes[offset])));
  }
}

TEST(ImageIo, shared_dem_pgm_is_16_bit_with_heights_236_to_1076) {
  const auto dir = progiso::test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data folder not found (set PROGISO_DATA_DIR)";
  const volume v = progiso::read_image(*dir / "jacksboro_dem_403x344_u16.pgm");
  EXPECT_EQ(v.dims(), (progiso::index3{403, 344, 1}));
  EXPECT_EQ(v.type(), sample_type::u16);
  EXPECT_EQ(v.value_range(), (std::array<double, 2>{236, 1076}));
  EXPECT_EQ(v.value(0, 0, 0), 0x01e3);  // first samples of the file: 01 e3, 01 e7
  EXPECT_EQ(v.value(1, 0, 0), 0x01e7);
}

TEST(ImageIo, shared_images_read_the_same_from_pgm_and_from_png) {
  const auto dir = progiso::test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data folder not found (set PROGISO_DATA_DIR)";
  const scratch_dir out;
  for (const char* name : {"coins_384x303.pgm", "jacksboro_dem_403x344_u16.pgm"}) {
    const volume pgm = progiso::read_pgm(*dir / name);
    const auto width = static_cast<std::size_t>(pgm.dims()[0]);
    const bool wide = pgm.type() == sample_type::u16;
    std::vector<std::vector<int>> values(static_cast<std::size_t>(pgm.dims()[1]));
    for (std::size_t y = 0; y < values.size(); ++y) {
      for (std::size_t x = 0; x < width; ++x) {
        values[y].push_back(static_cast<int>(pgm.at(y * width + x)));
      }
    }
    const png_spec spec{static_cast<png_uint_32>(width), static_cast<png_uint_32>(values.size()),
                        wide ? 16 : 8, PNG_COLOR_TYPE_GRAY};
    write_bytes(out / "a.png", encode_png(spec, wide ? rows_u16(values) : rows_u8(values)));
    const volume png = progiso::read_png(out / "a.png");
    EXPECT_EQ(png.dims(), pgm.dims()) << name;
    EXPECT_EQ(png.type(), pgm.type()) << name;
    EXPECT_EQ(samples_of(png), samples_of(pgm)) << name;
  }
}

}  // namespace
