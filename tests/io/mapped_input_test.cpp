// Inputs of at least detail::map_min_bytes are mapped in place, not read, wherever their samples
// lie in the file as the volume holds them (uncompressed, unscaled, x fastest, host byte order):
// raw files, raw NRRD (attached or detached, byte skips, a chosen volume), NIfTI (.nii and
// .hdr/.img, a chosen volume) and MRC. A mapped volume borrows the file's pages (so a volume
// larger than the memory a process may allocate still opens: tests/apps/out_of_core_test.cpp);
// its samples are the file's. Data that must be converted (another byte order, gzip, scaling)
// is read as before, to the same samples.
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "support/io_test_helpers.hpp"
#include "support/mrc_files.hpp"
#include "support/scratch_dir.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

// 512 × 512 × 256 one-byte samples: exactly map_min_bytes.
constexpr index3 dims{512, 512, 256};
constexpr std::size_t count = 512 * 512 * 256;
static_assert(count == detail::map_min_bytes);

// Deterministic bytes that differ from volume to volume and along every axis.
std::string pattern(std::size_t n, std::uint32_t seed) {
  std::string s(n, '\0');
  std::uint32_t x = seed * 2654435761u + 1u;
  for (char& c : s) {
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    c = static_cast<char>(x & 0xffu);
  }
  return s;
}

void expect_samples(const volume& v, const std::string& want, bool mapped) {
  EXPECT_EQ(v.dims(), dims);
  EXPECT_EQ(v.borrowed(), mapped);
  ASSERT_EQ(v.byte_size(), want.size());
  EXPECT_EQ(std::memcmp(v.bytes(), want.data(), want.size()), 0);
}

void write(const fs::path& p, const std::string& bytes) { test::write_file(p, bytes); }

TEST(MappedInput, raw_nrrd_attached_detached_and_skipped_are_mapped_to_the_file_samples) {
  const test::scratch_dir dir("progiso-mapped-input-");
  const std::string v0 = pattern(count, 1), v1 = pattern(count, 2);
  // Raw: mapped.
  write(dir.path() / "a.raw", v0);
  expect_samples(read_raw(dir.path() / "a.raw", {dims, sample_type::u8}), v0, true);

  const std::string head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 512 512 256\n";
  // Attached, after a byte skip: mapped.
  write(dir.path() / "attached.nrrd",
        head + "encoding: raw\nbyte skip: 7\n\n" + std::string(7, 'x') + v0);
  expect_samples(read_nrrd(dir.path() / "attached.nrrd"), v0, true);
  // Detached, the data ending the file (byte skip -1), the second of two volumes: mapped.
  write(dir.path() / "tail.raw", std::string(100, 'y') + v0 + v1);
  write(dir.path() / "detached.nhdr",
        "NRRD0004\ntype: uint8\ndimension: 4\nsizes: 512 512 256 2\nencoding: raw\n"
        "byte skip: -1\ndata file: tail.raw\n");
  expect_samples(read_nrrd(dir.path() / "detached.nhdr", {std::nullopt, 1}), v1, true);
  // 16-bit samples in the other byte order: read (swapped), the same values.
  std::string swapped(v0.size(), '\0');
  for (std::size_t i = 0; i + 1 < v0.size(); i += 2) {
    swapped[i] = v0[i + 1];
    swapped[i + 1] = v0[i];
  }
  const bool little = std::endian::native == std::endian::little;
  write(dir.path() / "other.nrrd", std::string("NRRD0004\ntype: uint16\ndimension: 3\n") +
                                       "sizes: 512 512 128\nencoding: raw\nendian: " +
                                       (little ? "big" : "little") + "\n\n" + swapped);
  const volume other = read_nrrd(dir.path() / "other.nrrd");
  EXPECT_FALSE(other.borrowed());
  ASSERT_EQ(other.byte_size(), v0.size());
  EXPECT_EQ(std::memcmp(other.bytes(), v0.data(), v0.size()), 0);
  // A file too short for its volumes is not mapped: the read says so.
  write(dir.path() / "short.nrrd", head + "encoding: raw\n\n" + v0.substr(1));
  EXPECT_THROW((void)read_nrrd(dir.path() / "short.nrrd"), error);
}

TEST(MappedInput, nifti_single_file_and_pair_are_mapped_and_a_chosen_volume_is_its_own) {
  const test::scratch_dir dir("progiso-mapped-input-");
  const std::string v0 = pattern(count, 3), v1 = pattern(count, 4);
  const std::array<std::int16_t, 3> n{512, 512, 256};
  write(dir.path() / "one.nii",
        test::nifti1_series(test::nifti1_file(n, 2, 8, {1.0f, 1.0f, 1.0f}, v0 + v1), 2));
  expect_samples(read_nifti(dir.path() / "one.nii", {std::nullopt, 0}), v0, true);
  expect_samples(read_nifti(dir.path() / "one.nii", {std::nullopt, 1}), v1, true);
  write(dir.path() / "two.hdr", test::nifti1_file(n, 2, 8, {1.0f, 1.0f, 1.0f}, {}, true));
  write(dir.path() / "two.img", v1);
  expect_samples(read_nifti(dir.path() / "two.hdr"), v1, true);
  // The pair's data one byte short: refused by the read, with the data file's name.
  write(dir.path() / "two.img", v1.substr(1));
  try {
    (void)read_nifti(dir.path() / "two.hdr");
    ADD_FAILURE() << "a short .img was accepted";
  } catch (const error& e) {
    EXPECT_NE(std::string(e.what()).find("two.img"), std::string::npos) << e.what();
  }
}

TEST(MappedInput, mrc_in_column_order_is_mapped_and_a_permuted_map_is_read) {
  const test::scratch_dir dir("progiso-mapped-input-");
  const std::string v0 = pattern(count, 5);
  test::mrc_file f;
  f.n = {512, 512, 256};
  f.m = {512, 512, 256};
  f.mode = 0;  // signed 8-bit (MRC2014)
  f.item = 1;
  f.samples.resize(count);
  std::memcpy(f.samples.data(), v0.data(), count);
  write(dir.path() / "map.mrc", f.bytes());
  const volume v = read_mrc(dir.path() / "map.mrc");
  EXPECT_EQ(v.type(), sample_type::i8);
  expect_samples(v, v0, true);
  // Sections along X (MAPC 3, MAPR 2, MAPS 1, stored 256 × 512 × 512): reordered, so read.
  f.map = {3, 2, 1};
  f.n = {256, 512, 512};
  write(dir.path() / "permuted.mrc", f.bytes());
  const volume p = read_mrc(dir.path() / "permuted.mrc");
  EXPECT_FALSE(p.borrowed());
  EXPECT_EQ(p.dims(), dims);
}

}  // namespace
}  // namespace progiso
