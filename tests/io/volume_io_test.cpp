// Tests for progiso/io/volume_io.hpp: raw files of every sample type and byte order, NRRD
// files (raw and gzip encodings, attached and detached data, spacing and origin from the
// header), dispatch by read_volume(), and the messages for every kind of bad input. The NRRD
// reader's comparison with Teem and its hostile inputs are in nrrd_reader_test.cpp.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <zlib.h>
#include "support/scratch_dir.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include <progiso/core/base/error.hpp>

namespace {

namespace fs = std::filesystem;
using progiso::index3;
using progiso::raw_layout;
using progiso::sample_type;

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-volume-io-test-") {}
};

void write_bytes(const fs::path& file, const void* data, std::size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  ASSERT_TRUE(out.good()) << file;
}

void write_text(const fs::path& file, const std::string& text) {
  write_bytes(file, text.data(), text.size());
}

void append_bytes(const fs::path& file, const void* data, std::size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::app);
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  ASSERT_TRUE(out.good()) << file;
}

// Appends `size` bytes to `file` as one gzip member.
void append_gzip(const fs::path& file, const void* data, std::size_t size) {
  gzFile gz = gzopen(file.string().c_str(), "ab");
  ASSERT_NE(gz, nullptr) << file;
  const int written = gzwrite(gz, data, static_cast<unsigned>(size));
  EXPECT_EQ(static_cast<std::size_t>(written), size);
  EXPECT_EQ(gzclose(gz), Z_OK);
}

// Runs `f`, expects progiso::error, and returns its message.
template <class F>
std::string error_message(F&& f) {
  try {
    f();
  } catch (const progiso::error& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected progiso::error";
  return {};
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// The sample type of each C++ type, its NRRD type name, and a spread of test values including
// both extremes of the type.
template <class T>
struct sample_traits;
template <>
struct sample_traits<std::uint8_t> {
  static constexpr sample_type type = sample_type::u8;
  static constexpr const char* nrrd = "uchar";
};
template <>
struct sample_traits<std::int8_t> {
  static constexpr sample_type type = sample_type::i8;
  static constexpr const char* nrrd = "signed char";
};
template <>
struct sample_traits<std::uint16_t> {
  static constexpr sample_type type = sample_type::u16;
  static constexpr const char* nrrd = "ushort";
};
template <>
struct sample_traits<std::int16_t> {
  static constexpr sample_type type = sample_type::i16;
  static constexpr const char* nrrd = "short";
};
template <>
struct sample_traits<std::uint32_t> {
  static constexpr sample_type type = sample_type::u32;
  static constexpr const char* nrrd = "uint";
};
template <>
struct sample_traits<std::int32_t> {
  static constexpr sample_type type = sample_type::i32;
  static constexpr const char* nrrd = "int";
};
template <>
struct sample_traits<float> {
  static constexpr sample_type type = sample_type::f32;
  static constexpr const char* nrrd = "float";
};
template <>
struct sample_traits<double> {
  static constexpr sample_type type = sample_type::f64;
  static constexpr const char* nrrd = "double";
};

template <class T>
std::vector<T> test_values(std::size_t n) {
  std::vector<T> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int base = static_cast<int>((i * 37) % 101) - (std::is_signed_v<T> ? 50 : 0);
    if constexpr (std::is_floating_point_v<T>) {
      v[i] = static_cast<T>(base) + static_cast<T>(0.25);
    } else {
      v[i] = static_cast<T>(base);
    }
  }
  // Extremes exercise every byte of the sample, so a wrong swap cannot go unnoticed.
  v[0] = std::numeric_limits<T>::lowest();
  v[1] = std::numeric_limits<T>::max();
  if constexpr (std::is_floating_point_v<T>) v[2] = static_cast<T>(-1.0e-3);
  return v;
}

// The bytes of `values` in big-endian order.
template <class T>
std::vector<unsigned char> big_endian_bytes(const std::vector<T>& values) {
  std::vector<unsigned char> bytes(values.size() * sizeof(T));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  if constexpr (std::endian::native == std::endian::little) {
    for (std::size_t i = 0; i < bytes.size(); i += sizeof(T)) {
      std::reverse(bytes.begin() + static_cast<std::ptrdiff_t>(i),
                   bytes.begin() + static_cast<std::ptrdiff_t>(i + sizeof(T)));
    }
  }
  return bytes;
}

template <class T>
std::vector<unsigned char> little_endian_bytes(const std::vector<T>& values) {
  std::vector<unsigned char> bytes(values.size() * sizeof(T));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  if constexpr (std::endian::native == std::endian::big) {
    for (std::size_t i = 0; i < bytes.size(); i += sizeof(T)) {
      std::reverse(bytes.begin() + static_cast<std::ptrdiff_t>(i),
                   bytes.begin() + static_cast<std::ptrdiff_t>(i + sizeof(T)));
    }
  }
  return bytes;
}

template <class T>
void expect_samples(const progiso::volume& v, const std::vector<T>& values) {
  ASSERT_EQ(v.voxel_count(), values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(v.at(i), static_cast<double>(values[i])) << "sample " << i;
  }
}

constexpr index3 small_dims{3, 4, 5};
constexpr std::size_t small_count = 3 * 4 * 5;

// =============================================================================================
// Raw files.

template <class T>
class VolumeIoRaw : public ::testing::Test {};
using all_sample_types = ::testing::Types<std::uint8_t, std::int8_t, std::uint16_t, std::int16_t,
                                          std::uint32_t, std::int32_t, float, double>;
TYPED_TEST_SUITE(VolumeIoRaw, all_sample_types);

TYPED_TEST(VolumeIoRaw, little_endian_samples_are_read_unchanged) {
  using T = TypeParam;
  const scratch_dir dir;
  const auto values = test_values<T>(small_count);
  const auto bytes = little_endian_bytes(values);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());

  const progiso::volume v =
      progiso::read_raw(dir / "v.raw", raw_layout{small_dims, sample_traits<T>::type, false});
  EXPECT_EQ(v.dims(), small_dims);
  EXPECT_EQ(v.type(), sample_traits<T>::type);
  expect_samples(v, values);
}

TYPED_TEST(VolumeIoRaw, big_endian_samples_are_swapped_to_host_order) {
  using T = TypeParam;
  const scratch_dir dir;
  const auto values = test_values<T>(small_count);
  const auto bytes = big_endian_bytes(values);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());

  const progiso::volume v =
      progiso::read_raw(dir / "v.raw", raw_layout{small_dims, sample_traits<T>::type, true});
  expect_samples(v, values);
}

TEST(VolumeIo, raw_big_endian_u16_is_swapped_to_host_order) {
  const scratch_dir dir;
  std::vector<unsigned char> bytes;
  for (unsigned char i = 0; i < 8; ++i) {
    bytes.push_back(0x01);
    bytes.push_back(i);
  }
  write_bytes(dir / "be.raw", bytes.data(), bytes.size());
  write_bytes(dir / "le.raw", bytes.data(), bytes.size());

  const auto be = progiso::read_raw(dir / "be.raw", {{2, 2, 2}, sample_type::u16, true});
  const auto le = progiso::read_raw(dir / "le.raw", {{2, 2, 2}, sample_type::u16, false});
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(be.at(i), static_cast<double>(0x0100 + i));
    EXPECT_EQ(le.at(i), static_cast<double>(0x0001 + 0x100 * i));
  }
}

TEST(VolumeIo, raw_samples_are_laid_out_x_fastest_then_y_then_z) {
  const scratch_dir dir;
  std::vector<std::uint8_t> bytes(small_count);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::uint8_t>(i);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());

  const auto v = progiso::read_raw(dir / "v.raw", {small_dims, sample_type::u8});
  for (std::int64_t z = 0; z < 5; ++z) {
    for (std::int64_t y = 0; y < 4; ++y) {
      for (std::int64_t x = 0; x < 3; ++x) {
        EXPECT_EQ(v.value(x, y, z), static_cast<double>(x + 3 * (y + 4 * z)));
      }
    }
  }
}

TEST(VolumeIo, raw_spacing_and_origin_are_passed_through) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(8, 7);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());
  const auto v = progiso::read_raw(dir / "v.raw", {{2, 2, 2}, sample_type::u8}, {0.5, 2.0, 3.0},
                                   {-1.0, 0.0, 10.0});
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 3.0}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{-1.0, 0.0, 10.0}));
}

TEST(VolumeIo, raw_size_mismatch_message_gives_both_sizes_dims_and_type) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(1000, 1);
  write_bytes(dir / "x.raw", bytes.data(), bytes.size());

  const std::string msg = error_message([&] {
    (void)progiso::read_raw(dir / "x.raw", {{10, 10, 11}, sample_type::u8});
  });
  EXPECT_TRUE(contains(msg, (dir / "x.raw").string())) << msg;
  EXPECT_TRUE(contains(msg, "size 1000 bytes")) << msg;
  EXPECT_TRUE(contains(msg, "10,10,11")) << msg;
  EXPECT_TRUE(contains(msg, "u8")) << msg;
  EXPECT_TRUE(contains(msg, "1100 bytes")) << msg;

  const std::string msg16 = error_message([&] {
    (void)progiso::read_raw(dir / "x.raw", {{10, 10, 10}, sample_type::i16});
  });
  EXPECT_TRUE(contains(msg16, "i16")) << msg16;
  EXPECT_TRUE(contains(msg16, "2000 bytes")) << msg16;
}

TEST(VolumeIo, raw_missing_file_error_names_the_file) {
  const scratch_dir dir;
  const std::string msg = error_message([&] {
    (void)progiso::read_raw(dir / "absent.raw", {{2, 2, 2}, sample_type::u8});
  });
  EXPECT_TRUE(contains(msg, (dir / "absent.raw").string())) << msg;
  EXPECT_TRUE(contains(msg, "cannot open")) << msg;
}

TEST(VolumeIo, raw_directory_instead_of_file_is_an_error) {
  const scratch_dir dir;
  fs::create_directory(dir / "d.raw");
  const std::string msg = error_message([&] {
    (void)progiso::read_raw(dir / "d.raw", {{2, 2, 2}, sample_type::u8});
  });
  EXPECT_TRUE(contains(msg, (dir / "d.raw").string())) << msg;
}

TEST(VolumeIo, raw_dims_below_two_are_rejected_with_the_file_name) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(4, 0);
  write_bytes(dir / "flat.raw", bytes.data(), bytes.size());
  const std::string msg = error_message([&] {
    (void)progiso::read_raw(dir / "flat.raw", {{2, 2, 1}, sample_type::u8});
  });
  EXPECT_TRUE(contains(msg, (dir / "flat.raw").string())) << msg;
  EXPECT_TRUE(contains(msg, "2,2,1")) << msg;
}

TEST(VolumeIo, raw_huge_dims_do_not_overflow_the_size_check) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(8, 0);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());
  const std::int64_t big = std::int64_t{1} << 40;
  const std::string msg = error_message([&] {
    (void)progiso::read_raw(dir / "v.raw", {{big, big, big}, sample_type::f64});
  });
  EXPECT_TRUE(contains(msg, "size 8 bytes")) << msg;
}

// =============================================================================================
// NRRD files.

template <class T>
class VolumeIoNrrd : public ::testing::Test {};
TYPED_TEST_SUITE(VolumeIoNrrd, all_sample_types);

TYPED_TEST(VolumeIoNrrd, every_supported_type_is_read_with_its_values) {
  using T = TypeParam;
  const scratch_dir dir;
  const auto values = test_values<T>(small_count);
  const auto bytes = big_endian_bytes(values);
  const fs::path file = dir / "v.nrrd";
  write_text(file, std::string("NRRD0004\ntype: ") + sample_traits<T>::nrrd +
                       "\ndimension: 3\nsizes: 3 4 5\nendian: big\nencoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const progiso::volume v = progiso::read_nrrd(file);
  EXPECT_EQ(v.dims(), small_dims);
  EXPECT_EQ(v.type(), sample_traits<T>::type);
  expect_samples(v, values);
}

TEST(VolumeIo, nrrd_raw_encoding_gives_samples_spacings_and_zero_origin) {
  const scratch_dir dir;
  const auto values = test_values<std::uint16_t>(small_count);
  const auto bytes = little_endian_bytes(values);
  const fs::path file = dir / "v.nrrd";
  write_text(file,
             "NRRD0004\n# a comment\ntype: unsigned short\ndimension: 3\nsizes: 3 4 5\n"
             "spacings: 0.5 2 1.5\nendian: little\nencoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const auto v = progiso::read_nrrd(file);
  EXPECT_EQ(v.dims(), small_dims);
  EXPECT_EQ(v.type(), sample_type::u16);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 1.5}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{0.0, 0.0, 0.0}));
  expect_samples(v, values);
}

TEST(VolumeIo, nrrd_gzip_encoding_is_decoded) {
  const scratch_dir dir;
  const auto values = test_values<std::int16_t>(small_count);
  const auto bytes = little_endian_bytes(values);
  const fs::path file = dir / "v.nrrd";
  write_text(file,
             "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4 5\nendian: little\n"
             "encoding: gzip\n\n");
  append_gzip(file, bytes.data(), bytes.size());

  const auto v = progiso::read_nrrd(file);
  EXPECT_EQ(v.type(), sample_type::i16);
  expect_samples(v, values);
}

TEST(VolumeIo, nhdr_reads_its_detached_gzip_data_file_relative_to_the_header) {
  const scratch_dir dir;
  const auto values = test_values<float>(small_count);
  const auto bytes = little_endian_bytes(values);
  fs::create_directory(dir / "sub");
  write_text(dir / "sub" / "v.nhdr",
             "NRRD0004\ntype: float\ndimension: 3\nsizes: 3 4 5\nendian: little\n"
             "encoding: gzip\ndata file: v.raw.gz\n");
  append_gzip(dir / "sub" / "v.raw.gz", bytes.data(), bytes.size());

  const auto v = progiso::read_nrrd(dir / "sub" / "v.nhdr");
  EXPECT_EQ(v.type(), sample_type::f32);
  expect_samples(v, values);
}

TEST(VolumeIo, nrrd_space_directions_give_spacing_and_space_origin_gives_origin) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(small_count, 9);
  write_text(dir / "v.nhdr",
             "NRRD0005\ntype: uchar\ndimension: 3\nsizes: 3 4 5\n"
             "space: right-anterior-superior\n"
             "space directions: (0.5,0,0) (0,-2,0) (0,0,3)\n"
             "space origin: (1.5,-2,30)\nencoding: raw\ndata file: v.raw\n");
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());

  const auto v = progiso::read_nrrd(dir / "v.nhdr");
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 3.0}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{1.5, -2.0, 30.0}));
}

TEST(VolumeIo, nrrd_unknown_or_non_finite_spacing_becomes_one) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(small_count, 1);
  const fs::path file = dir / "v.nrrd";
  write_text(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 4 5\nspacings: nan 2.5 nan\n"
             "encoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());
  EXPECT_EQ(progiso::read_nrrd(file).spacing(), (std::array<double, 3>{1.0, 2.5, 1.0}));

  const fs::path bare = dir / "bare.nrrd";
  write_text(bare, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 4 5\nencoding: raw\n\n");
  append_bytes(bare, bytes.data(), bytes.size());
  EXPECT_EQ(progiso::read_nrrd(bare).spacing(), (std::array<double, 3>{1.0, 1.0, 1.0}));
}

TEST(VolumeIo, nrrd_two_dimensional_array_is_rejected) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(20, 1);
  const fs::path file = dir / "image.nrrd";
  write_text(file, "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 4 5\nencoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const std::string msg = error_message([&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, file.string())) << msg;
  EXPECT_TRUE(contains(msg, "3-D")) << msg;
  EXPECT_TRUE(contains(msg, "dimension 2")) << msg;
}

TEST(VolumeIo, nrrd_axis_of_one_sample_is_rejected) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(20, 1);
  const fs::path file = dir / "slab.nrrd";
  write_text(file, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 4 5\nencoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const std::string msg = error_message([&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, file.string())) << msg;
  EXPECT_TRUE(contains(msg, "1,4,5")) << msg;
}

TEST(VolumeIo, nrrd_unsupported_sample_type_is_rejected) {
  const scratch_dir dir;
  const std::vector<std::int64_t> values(8, 3);
  const fs::path file = dir / "wide.nrrd";
  write_text(file,
             "NRRD0004\ntype: long long\ndimension: 3\nsizes: 2 2 2\nendian: little\n"
             "encoding: raw\n\n");
  append_bytes(file, values.data(), values.size() * sizeof(std::int64_t));

  const std::string msg = error_message([&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, file.string())) << msg;
  EXPECT_TRUE(contains(msg, "unsupported NRRD sample type")) << msg;
}

TEST(VolumeIo, malformed_nrrd_files_throw_one_line_errors_naming_the_file) {
  const scratch_dir dir;
  std::vector<fs::path> files;

  files.push_back(dir / "banana.nrrd");
  write_text(files.back(),
             "NRRD0004\ntype: banana\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n"
             "12345678");

  files.push_back(dir / "truncated.nrrd");
  write_text(files.back(),
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n"
             "0123456789");

  files.push_back(dir / "cut_header.nrrd");
  write_text(files.back(), "NRRD0004\ntype: uchar\ndimen");

  files.push_back(dir / "bad_sizes.nrrd");
  write_text(files.back(), "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 x -4\nencoding: raw\n\n");

  // A gzip member header followed by garbage.
  files.push_back(dir / "bad_gzip.nrrd");
  using namespace std::string_literals;
  write_text(files.back(),
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n"
             "\x1f\x8b\x08\x00\xff\xfe this is not deflate data at all"s);

  files.push_back(dir / "missing_data.nhdr");
  write_text(files.back(),
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
             "data file: nowhere.raw\n");

  files.push_back(dir / "garbage.nrrd");
  std::mt19937 rng(12345);
  std::vector<unsigned char> garbage(4096);
  for (auto& b : garbage) b = static_cast<unsigned char>(rng());
  write_bytes(files.back(), garbage.data(), garbage.size());

  files.push_back(dir / "empty.nrrd");
  write_text(files.back(), "");

  for (const fs::path& file : files) {
    SCOPED_TRACE(file.filename().string());
    const std::string msg = error_message([&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, file.string())) << msg;
    EXPECT_FALSE(contains(msg, "\n")) << msg;
  }
}

TEST(VolumeIo, nrrd_missing_file_error_names_the_file) {
  const scratch_dir dir;
  const std::string msg = error_message([&] { (void)progiso::read_nrrd(dir / "absent.nrrd"); });
  EXPECT_TRUE(contains(msg, (dir / "absent.nrrd").string())) << msg;
  EXPECT_TRUE(contains(msg, "cannot open")) << msg;
}

// =============================================================================================
// read_volume dispatch.

TEST(VolumeIo, read_volume_with_raw_layout_reads_raw_whatever_the_extension) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(8, 5);
  write_bytes(dir / "v.nrrd", bytes.data(), bytes.size());

  const auto v =
      progiso::read_volume(dir / "v.nrrd", raw_layout{{2, 2, 2}, sample_type::u8}, std::nullopt);
  EXPECT_EQ(v.at(0), 5.0);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.0, 1.0, 1.0}));

  const auto w = progiso::read_volume(dir / "v.nrrd", raw_layout{{2, 2, 2}, sample_type::u8},
                                      std::array<double, 3>{2.0, 3.0, 4.0});
  EXPECT_EQ(w.spacing(), (std::array<double, 3>{2.0, 3.0, 4.0}));
}

TEST(VolumeIo, read_volume_picks_nrrd_by_extension_in_any_case) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(small_count, 4);
  const fs::path file = dir / "V.NRRD";
  write_text(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 4 5\nspacings: 2 2 2\n"
             "encoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const auto v = progiso::read_volume(file, std::nullopt, std::nullopt);
  EXPECT_EQ(v.dims(), small_dims);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{2.0, 2.0, 2.0}));
}

TEST(VolumeIo, read_volume_explicit_spacing_overrides_the_nrrd_header) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(small_count, 4);
  const fs::path file = dir / "v.nrrd";
  write_text(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 4 5\nspacings: 2 2 2\n"
             "encoding: raw\n\n");
  append_bytes(file, bytes.data(), bytes.size());

  const auto v = progiso::read_volume(file, std::nullopt, std::array<double, 3>{0.25, 0.5, 8.0});
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.25, 0.5, 8.0}));
}

TEST(VolumeIo, read_volume_rejects_an_unknown_format) {
  const scratch_dir dir;
  write_text(dir / "v.xyz", "whatever");
  const std::string msg =
      error_message([&] { (void)progiso::read_volume(dir / "v.xyz", std::nullopt, std::nullopt); });
  EXPECT_EQ(msg, (dir / "v.xyz").string() +
                     ": unknown volume format (expected .nrrd, .nhdr, .nii, .nii.gz, .hdr, .mha, "
                     ".mhd, .vtk, .vti, .pvti, .tif, .tiff, .mrc, .map, .ccp4, .rec, .ims, .h5, a "
                     "directory of DICOM files or of TIFF slices, a Zarr or OME-Zarr directory, an "
                     "enhanced DICOM "
                     "file, or a raw file with "
                     "--dims and --type)");
}

TEST(VolumeIo, read_volume_rejects_an_invalid_spacing_with_the_file_name) {
  const scratch_dir dir;
  const std::vector<std::uint8_t> bytes(8, 5);
  write_bytes(dir / "v.raw", bytes.data(), bytes.size());
  const std::string msg = error_message([&] {
    (void)progiso::read_volume(dir / "v.raw", raw_layout{{2, 2, 2}, sample_type::u8},
                               std::array<double, 3>{1.0, -1.0, 1.0});
  });
  EXPECT_TRUE(contains(msg, (dir / "v.raw").string())) << msg;
  EXPECT_TRUE(contains(msg, "spacing")) << msg;
}

// =============================================================================================
// Real data (../shared/data, see its README), skipped when absent.

fs::path data_dir() {
  if (const char* env = std::getenv("PROGISO_DATA_DIR"); env != nullptr && *env != '\0') {
    return env;
  }
#if defined(PROGISO_SOURCE_DIR)
  return fs::path(PROGISO_SOURCE_DIR) / ".." / "shared" / "data";
#else
  return {};
#endif
}

std::vector<unsigned char> file_bytes(const fs::path& file) {
  std::vector<unsigned char> bytes(static_cast<std::size_t>(fs::file_size(file)));
  std::ifstream in(file, std::ios::binary);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

TEST(VolumeIo, real_bucky_raw_reads_every_byte_unchanged) {
  const fs::path file = data_dir() / "bucky_32x32x32_uint8.raw";
  if (!fs::exists(file)) GTEST_SKIP() << "real data not found: " << file;

  const auto v = progiso::read_raw(file, {{32, 32, 32}, sample_type::u8});
  const auto bytes = file_bytes(file);
  ASSERT_EQ(bytes.size(), v.voxel_count());
  for (std::size_t i = 0; i < bytes.size(); ++i)
    ASSERT_EQ(v.at(i), static_cast<double>(bytes[i])) << "voxel " << i;
  EXPECT_GT(v.value_range()[1], 51.0);  // the README's suggested isovalue lies inside the data
}

TEST(VolumeIo, real_headsq_int16le_raw_has_the_documented_range) {
  const fs::path file = data_dir() / "headsq_64x64x93_int16le.raw";
  if (!fs::exists(file)) GTEST_SKIP() << "real data not found: " << file;

  const auto v = progiso::read_raw(file, {{64, 64, 93}, sample_type::i16, false}, {3.2, 3.2, 1.5});
  EXPECT_EQ(v.value_range(), (std::array<double, 2>{0.0, 3926.0}));
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{3.2, 3.2, 1.5}));
}

}  // namespace
