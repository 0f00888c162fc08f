// tests/support/io_test_helpers.hpp — small helpers shared by the reader and writer tests.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso::test {

/// Writes `bytes` to `file` (binary, truncating); fails the test when that does not work.
inline void write_file(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << bytes;
  ASSERT_TRUE(out.good()) << file;
}

/// The message of the progiso::error that `f` throws; checks that it is one line starting with
/// the file name followed by `after` (": ", or ":" where a line number follows).
template <class F>
std::string error_message_naming(const std::filesystem::path& file, F&& f,
                                 const std::string& after = ": ") {
  try {
    f();
  } catch (const progiso::error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind(file.string() + after, 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message;
  }
  ADD_FAILURE() << "expected progiso::error for " << file;
  return {};
}

/// The whole file as bytes ("" when it cannot be read).
inline std::string read_whole_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// `data` as one gzip member (zlib's deflate, independent of the readers' inflate); with
/// `zlib_wrapper`, as one zlib stream instead (what MetaIO writes for compressed data).
inline std::string gzip(const std::string& data, int level = 6, bool zlib_wrapper = false) {
  z_stream zs{};
  EXPECT_EQ(
      deflateInit2(&zs, level, Z_DEFLATED, zlib_wrapper ? 15 : 15 + 16, 8, Z_DEFAULT_STRATEGY),
      Z_OK);
  std::string out(deflateBound(&zs, static_cast<uLong>(data.size())) + 64, '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  zs.avail_in = static_cast<uInt>(data.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return out;
}

/// A single-file NIfTI-1 volume (magic "n+1", host byte order, data at byte 352) of `dims`
/// samples of NIfTI `datatype` with `bitpix` bits, spacing in pixdim, no qform or sform, and
/// `payload` as its data (any length: hostile files declare more than they hold). With `pair`,
/// the 348-byte header of a header and data pair instead (magic "ni1", data at byte 0 of the
/// .img beside it), and `payload` is not used.
inline std::string nifti1_file(const std::array<std::int16_t, 3>& dims, std::int16_t datatype,
                               std::int16_t bitpix, const std::array<float, 3>& spacing,
                               const std::string& payload, bool pair = false) {
  std::string h(352, '\0');
  const auto put = [&h](std::size_t at, const auto value) {
    std::memcpy(h.data() + at, &value, sizeof value);
  };
  put(0, std::int32_t{348});
  put(40, std::int16_t{3});
  for (std::size_t i = 0; i < 3; ++i) {
    put(42 + 2 * i, dims[i]);
    put(80 + 4 * i, spacing[i]);
  }
  for (std::size_t i = 3; i < 7; ++i) put(42 + 2 * i, std::int16_t{1});
  put(70, datatype);
  put(72, bitpix);
  put(76, 1.0f);
  put(108, pair ? 0.0f : 352.0f);
  std::memcpy(h.data() + 344, pair ? "ni1" : "n+1", 4);
  if (pair) return h.substr(0, 348);
  return h + payload;
}

/// A nifti1_file() made a time series of `volumes` (dim[0] = 4, dim[4] = volumes); its payload
/// holds (or is meant to lack) the volumes one after the other.
inline std::string nifti1_series(std::string file, std::int16_t volumes) {
  const std::int16_t four = 4;
  std::memcpy(file.data() + 40, &four, sizeof four);        // dim[0]
  std::memcpy(file.data() + 48, &volumes, sizeof volumes);  // dim[4]
  return file;
}

/// Sample i of `v` as a double, loaded by the test from the volume's bytes (not through
/// volume::at(), so that a reader test checks the bytes independently of the library).
inline double stored_sample(const volume& v, std::size_t i) {
  const std::byte* p = v.bytes() + i * sample_size(v.type());
  const auto load = [p](auto x) {
    std::memcpy(&x, p, sizeof x);
    return static_cast<double>(x);
  };
  switch (v.type()) {
    case sample_type::u8:
      return load(std::uint8_t{});
    case sample_type::i8:
      return load(std::int8_t{});
    case sample_type::u16:
      return load(std::uint16_t{});
    case sample_type::i16:
      return load(std::int16_t{});
    case sample_type::u32:
      return load(std::uint32_t{});
    case sample_type::i32:
      return load(std::int32_t{});
    case sample_type::f32:
      return load(float{});
    case sample_type::f64:
      return load(double{});
  }
  return 0.0;
}

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

/// `count` samples of `type` in host byte order: random bytes for integers, random finite
/// values for floats (within ±1e3 for f32, ±1e6 for f64).
inline std::vector<std::byte> random_samples(sample_type type, std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  const std::size_t item = sample_size(type);
  std::vector<std::byte> out(count * item);
  for (std::size_t i = 0; i < count; ++i) {
    std::byte* p = out.data() + i * item;
    if (type == sample_type::f32) {
      const float v = std::uniform_real_distribution<float>(-1e3f, 1e3f)(rng);
      std::memcpy(p, &v, sizeof v);
    } else if (type == sample_type::f64) {
      const double v = std::uniform_real_distribution<double>(-1e6, 1e6)(rng);
      std::memcpy(p, &v, sizeof v);
    } else {
      for (std::size_t b = 0; b < item; ++b) p[b] = static_cast<std::byte>(rng());
    }
  }
  return out;
}

/// Sample i of `samples` (host byte order) as text: integers in decimal, floats with enough
/// digits to read back the same value (%.9g, %.17g).
inline std::string sample_text(sample_type type, const std::vector<std::byte>& samples,
                               std::size_t i) {
  const std::byte* p = samples.data() + i * sample_size(type);
  const auto load = [p](auto x) {
    std::memcpy(&x, p, sizeof x);
    return x;
  };
  char buf[64];
  switch (type) {
    case sample_type::u8:
      return std::to_string(load(std::uint8_t{}));
    case sample_type::i8:
      return std::to_string(load(std::int8_t{}));
    case sample_type::u16:
      return std::to_string(load(std::uint16_t{}));
    case sample_type::i16:
      return std::to_string(load(std::int16_t{}));
    case sample_type::u32:
      return std::to_string(load(std::uint32_t{}));
    case sample_type::i32:
      return std::to_string(load(std::int32_t{}));
    case sample_type::f32:
      std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(load(float{})));
      return buf;
    case sample_type::f64:
      std::snprintf(buf, sizeof buf, "%.17g", load(double{}));
      return buf;
  }
  return {};
}

}  // namespace progiso::test
