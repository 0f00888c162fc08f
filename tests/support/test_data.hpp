// tests/support/test_data.hpp — finding and loading the shared real volumes.
//
// The project's real test volumes (classic volvis data sets, described in the data folder's
// README.md) live outside the repository, in ../shared/data relative to the project root, or
// wherever the environment variable PROGISO_DATA_DIR points. Tests that use them call
// shared_data_dir() and GTEST_SKIP() with a clear message when it returns nullopt; tests on
// analytic fields never skip. The loader reads the headerless raw files itself (x fastest,
// little-endian), on purpose independent of progiso's own readers, which are under test.
//
// Header-only; needs the compile definition PROGISO_SOURCE_DIR (the project root), which the
// progiso_test_support target provides. Loading throws progiso::error on a missing or
// short file.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#ifndef PROGISO_SOURCE_DIR
#error "test_data.hpp needs PROGISO_SOURCE_DIR (link progiso_test_support)"
#endif

namespace progiso::test {

/// The folder that holds the shared volumes: $PROGISO_DATA_DIR when set and non-empty (nullopt
/// if that is not a directory), else <project root>/../shared/data when it is a directory,
/// else nullopt.
inline std::optional<std::filesystem::path> shared_data_dir() {
  std::error_code ec;
  if (const char* env = std::getenv("PROGISO_DATA_DIR"); env != nullptr && *env != '\0') {
    std::filesystem::path dir(env);
    if (std::filesystem::is_directory(dir, ec)) return dir;
    return std::nullopt;
  }
  std::filesystem::path dir = std::filesystem::path(PROGISO_SOURCE_DIR) / ".." / "shared" / "data";
  if (std::filesystem::is_directory(dir, ec)) return dir.lexically_normal();
  return std::nullopt;
}

/// One shared volume: file name, grid, sample type (little-endian on disk), the isovalues its
/// README suggests, and spacing.
struct shared_volume {
  std::string_view name;
  std::string_view file;
  index3 dims;
  sample_type type;
  std::vector<double> isovalues;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
};

/// The shared 3D volumes (data README.md), smallest first.
inline const std::vector<shared_volume>& shared_volumes() {
  using enum sample_type;
  static const std::vector<shared_volume> table{
      {"bucky", "bucky_32x32x32_uint8.raw", {32, 32, 32}, u8, {51, 128}},
      {"nucleon", "nucleon_41x41x41_uint8.raw", {41, 41, 41}, u8, {60, 140}},
      {"neghip", "neghip_66x66x66_uint8.raw", {66, 66, 66}, u8, {30, 64, 128}},
      {"hipip", "hipip_68x68x68_uint8.raw", {68, 68, 68}, u8, {128, 30, 200}},
      {"headsq", "headsq_64x64x93_int16le.raw", {64, 64, 93}, i16, {500, 1150}, {3.2, 3.2, 1.5}},
      {"brainsmall", "brainsmall_128x128x84_uint8.raw", {128, 128, 84}, u8, {30, 50, 70}},
  };
  return table;
}

/// The table entry called `name`, or nullptr.
inline const shared_volume* find_shared_volume(std::string_view name) {
  for (const shared_volume& v : shared_volumes()) {
    if (v.name == name) return &v;
  }
  return nullptr;
}

/// Reads `info.file` from `dir` into a volume (samples converted to host byte order). Throws
/// progiso::error when the file cannot be read or its size is not dims × sample size.
inline volume load_shared_volume(const shared_volume& info, const std::filesystem::path& dir) {
  const std::filesystem::path path = dir / info.file;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw error(path.string() + ": cannot open shared test volume");
  std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t size = sample_size(info.type);
  const auto expected = static_cast<std::size_t>(info.dims[0] * info.dims[1] * info.dims[2]) * size;
  if (raw.size() != expected) {
    throw error(path.string() + ": expected " + std::to_string(expected) + " bytes, found " +
                std::to_string(raw.size()));
  }
  std::vector<std::byte> bytes(raw.size());
  for (std::size_t i = 0; i < raw.size(); i += size) {
    for (std::size_t b = 0; b < size; ++b) {
      // The files are little-endian; on a big-endian host each sample's bytes are reversed.
      const std::size_t from = std::endian::native == std::endian::little ? b : size - 1 - b;
      bytes[i + b] = static_cast<std::byte>(raw[i + from]);
    }
  }
  return volume(info.dims, info.type, std::move(bytes), info.spacing);
}

}  // namespace progiso::test
