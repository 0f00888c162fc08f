// Tests for progiso's own NRRD reader (core/detail/nrrd_reader.hpp, through read_nrrd() and
// volume_input_files()).
//
// Differential: Teem's nrrdLoad, the reference reader (a test-only dependency), reads the same
// files, and the two must agree exactly on dims, sample type, every sample byte, spacing and
// origin: generated volumes of every sample type in raw, gzip, ascii and hex encodings, both
// byte orders, attached and detached (one file, LIST, %d patterns, with and without a
// subdimension), with line and byte skips; header spellings and layouts; and the shared real
// volumes written as NRRD.
//
// Hostile: printf conversions in data file patterns, huge headers, declared sizes far beyond
// the data, corrupt and truncated gzip, FIFOs and devices as data files, numbers out of every
// range, malformed lines. Each must fail quickly with one line that names the right file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <teem/nrrd.h>
#include <zlib.h>
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace {

namespace fs = std::filesystem;
using progiso::index3;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::gzip;

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-nrrd-reader-test-") {}
};

void write_file(const fs::path& file, const std::string& bytes) {
  progiso::test::write_file(file, bytes);
}

/// The one-line message of the progiso::error `f` throws, which must start with `file`.
template <class F>
std::string error_naming(const fs::path& file, F&& f) {
  return progiso::test::error_message_naming(file, std::forward<F>(f));
}

// =============================================================================================
// The reference: Teem.

struct reference_volume {
  bool ok = false;
  std::string message;
  index3 dims{};
  std::optional<sample_type> type;
  std::vector<std::byte> samples;
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
};

std::optional<sample_type> from_teem_type(int type) {
  switch (type) {
    case nrrdTypeUChar:
      return sample_type::u8;
    case nrrdTypeChar:
      return sample_type::i8;
    case nrrdTypeUShort:
      return sample_type::u16;
    case nrrdTypeShort:
      return sample_type::i16;
    case nrrdTypeUInt:
      return sample_type::u32;
    case nrrdTypeInt:
      return sample_type::i32;
    case nrrdTypeFloat:
      return sample_type::f32;
    case nrrdTypeDouble:
      return sample_type::f64;
    default:
      return std::nullopt;
  }
}

/// Reads `file` with Teem and reduces it the way progiso documents: spacing from the space
/// direction's length or the |spacings| entry (unknown, zero or non-finite → 1), origin from
/// the finite first three components of the space origin.
reference_volume teem_reduce(const Nrrd* n) {
  reference_volume r;
  r.ok = n->dim == 3;
  for (unsigned a = 0; a < 3 && r.ok; ++a) r.dims[a] = static_cast<std::int64_t>(n->axis[a].size);
  r.type = from_teem_type(n->type);
  if (r.ok && r.type) {
    const std::size_t bytes = nrrdElementNumber(n) * nrrdElementSize(n);
    r.samples.resize(bytes);
    std::memcpy(r.samples.data(), n->data, bytes);
    for (unsigned a = 0; a < 3; ++a) {
      double spacing = 0.0;
      double direction[NRRD_SPACE_DIM_MAX];
      const int status = nrrdSpacingCalculate(n, a, &spacing, direction);
      const bool known = status == nrrdSpacingStatusScalarNoSpace ||
                         status == nrrdSpacingStatusScalarWithSpace ||
                         status == nrrdSpacingStatusDirection;
      spacing = std::fabs(spacing);
      r.spacing[a] = known && std::isfinite(spacing) && spacing > 0.0 ? spacing : 1.0;
    }
    for (unsigned a = 0; a < std::min(n->spaceDim, 3u); ++a) {
      if (std::isfinite(n->spaceOrigin[a])) r.origin[a] = n->spaceOrigin[a];
    }
  }
  return r;
}

/// Loads `file` with Teem; nullptr (and `message` set) when Teem refuses it.
Nrrd* teem_load(const fs::path& file, std::string& message) {
  Nrrd* n = nrrdNew();
  nrrdStateVerboseIO = 0;
  if (nrrdLoad(n, file.string().c_str(), nullptr) != 0) {
    char* err = biffGetDone(NRRD);
    message = err != nullptr ? err : "?";
    std::free(err);
    nrrdNuke(n);
    return nullptr;
  }
  return n;
}

/// Reads `file` with Teem, reduced as above; with `slice` (axis, position), the slice of the
/// loaded array there (volume k of a 4-D series: its series axis at k).
reference_volume teem_read(const fs::path& file,
                           std::optional<std::pair<unsigned, std::size_t>> slice = {}) {
  reference_volume r;
  Nrrd* n = teem_load(file, r.message);
  if (n == nullptr) return r;
  Nrrd* sliced = nullptr;
  if (slice) {
    sliced = nrrdNew();
    if (nrrdSlice(sliced, n, slice->first, slice->second) != 0) {
      char* err = biffGetDone(NRRD);
      r.message = err != nullptr ? err : "?";
      std::free(err);
      nrrdNuke(sliced);
      nrrdNuke(n);
      return r;
    }
  }
  r = teem_reduce(sliced != nullptr ? sliced : n);
  if (sliced != nullptr) nrrdNuke(sliced);
  nrrdNuke(n);
  return r;
}

/// Reads `file` with progiso and with Teem; they must agree exactly.
void expect_same_as_teem(const fs::path& file) {
  SCOPED_TRACE(file.filename().string());
  const reference_volume ref = teem_read(file);
  ASSERT_TRUE(ref.ok) << "Teem cannot read the test file: " << ref.message;
  ASSERT_TRUE(ref.type.has_value());
  std::optional<progiso::volume> ours;
  try {
    ours.emplace(progiso::read_nrrd(file));
  } catch (const progiso::error& e) {
    FAIL() << e.what();
  }
  EXPECT_EQ(ours->dims(), ref.dims);
  EXPECT_EQ(ours->type(), *ref.type);
  ASSERT_EQ(ours->byte_size(), ref.samples.size());
  EXPECT_EQ(std::memcmp(ours->bytes(), ref.samples.data(), ref.samples.size()), 0);
  EXPECT_EQ(ours->spacing(), ref.spacing);
  EXPECT_EQ(ours->origin(), ref.origin);
}

// =============================================================================================
// Writing NRRD files of every kind.

template <class T>
struct nrrd_type;
template <>
struct nrrd_type<std::uint8_t> {
  static constexpr const char* name = "uint8";
};
template <>
struct nrrd_type<std::int8_t> {
  static constexpr const char* name = "int8_t";
};
template <>
struct nrrd_type<std::uint16_t> {
  static constexpr const char* name = "unsigned short int";
};
template <>
struct nrrd_type<std::int16_t> {
  static constexpr const char* name = "int16";
};
template <>
struct nrrd_type<std::uint32_t> {
  static constexpr const char* name = "uint32_t";
};
template <>
struct nrrd_type<std::int32_t> {
  static constexpr const char* name = "signed int";
};
template <>
struct nrrd_type<float> {
  static constexpr const char* name = "float";
};
template <>
struct nrrd_type<double> {
  static constexpr const char* name = "double";
};

/// A spread of values with both extremes of the type (every byte of a sample matters).
template <class T>
std::vector<T> test_values(std::size_t n) {
  std::vector<T> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int base = static_cast<int>((i * 37) % 101) - (std::is_signed_v<T> ? 50 : 0);
    if constexpr (std::is_floating_point_v<T>) {
      v[i] = static_cast<T>(base) / static_cast<T>(7) + static_cast<T>(0.25);
    } else {
      v[i] = static_cast<T>(base);
    }
  }
  v[0] = std::numeric_limits<T>::lowest();
  v[1] = std::numeric_limits<T>::max();
  if constexpr (std::is_floating_point_v<T>) {
    v[2] = std::numeric_limits<T>::denorm_min();
    v[3] = static_cast<T>(-1.0e-3);
  }
  return v;
}

template <class T>
std::string sample_bytes(const T* values, std::size_t n, bool big_endian) {
  std::string out(n * sizeof(T), '\0');
  std::memcpy(out.data(), values, out.size());
  if (sizeof(T) > 1 && big_endian != (std::endian::native == std::endian::big)) {
    for (std::size_t i = 0; i < out.size(); i += sizeof(T)) {
      std::reverse(out.begin() + static_cast<std::ptrdiff_t>(i),
                   out.begin() + static_cast<std::ptrdiff_t>(i + sizeof(T)));
    }
  }
  return out;
}

template <class T>
std::string ascii_text(const T* values, std::size_t n) {
  std::string out;
  for (std::size_t i = 0; i < n; ++i) {
    if constexpr (std::is_floating_point_v<T>) {
      char buf[64];
      const auto r = std::to_chars(buf, buf + sizeof buf, values[i]);
      out.append(buf, r.ptr);
    } else {
      out += std::to_string(static_cast<long long>(values[i]));
    }
    out += i % 7 == 6 ? "\n" : " ";
  }
  return out + "\n";
}

std::string hex_text(const std::string& bytes) {
  static constexpr char digits[] = "0123456789abcdef";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const auto u = static_cast<unsigned char>(bytes[i]);
    out += digits[u >> 4];
    out += digits[u & 15];
    if (i % 16 == 15) out += '\n';
  }
  return out + "\n";
}

enum class data_form { attached, single, list, pattern, pattern_subdim3, list_subdim1 };

struct nrrd_case {
  std::string encoding = "raw";  // raw, gzip, ascii, hex
  bool big_endian = false;
  data_form form = data_form::attached;
  int line_skip = 0;
  int byte_skip = 0;   // -1: the data ends each file (raw)
  bool space = false;  // space directions and origin instead of spacings
};

std::string case_name(const nrrd_case& c) {
  static constexpr const char* forms[] = {"attached", "single",   "list",
                                          "pattern",  "pattern3", "list1"};
  return c.encoding + (c.big_endian ? "-big-" : "-little-") + forms[static_cast<int>(c.form)] +
         "-ls" + std::to_string(c.line_skip) + "-bs" + std::to_string(c.byte_skip) +
         (c.space ? "-space" : "");
}

/// What goes in front of each piece of data: `line_skip` lines, then for uncompressed
/// encodings `byte_skip` bytes (compressed data skips them inside the stream, and byte skip
/// -1 puts arbitrary bytes before the data).
std::string file_prefix(const nrrd_case& c) {
  std::string out;
  for (int i = 0; i < c.line_skip; ++i) out += "skipped line " + std::to_string(i) + "\n";
  if (c.byte_skip > 0 && c.encoding != "gzip")
    out += std::string(static_cast<std::size_t>(c.byte_skip), 'X');
  if (c.byte_skip < 0) out += "whatever comes before the data";
  return out;
}

/// One piece of the data, encoded.
template <class T>
std::string encode_piece(const nrrd_case& c, const T* values, std::size_t n) {
  std::string data;
  if (c.encoding == "ascii") {
    data = ascii_text(values, n);
  } else {
    data = sample_bytes(values, n, c.big_endian);
    if (c.encoding == "hex") data = hex_text(data);
    if (c.encoding == "gzip") {
      data = gzip(std::string(static_cast<std::size_t>(std::max(c.byte_skip, 0)), 'Z') + data);
    }
  }
  return file_prefix(c) + data;
}

std::string padded(int v, int width) {
  std::string s = std::to_string(v);
  return std::string(static_cast<std::size_t>(std::max(0, width - static_cast<int>(s.size()))),
                     '0') +
         s;
}

/// Writes `values` (dims x fastest) as the NRRD `c` describes into `dir`; returns the header.
template <class T>
fs::path write_nrrd_case(const fs::path& dir, const nrrd_case& c, const index3& dims,
                         const std::vector<T>& values) {
  const std::string name = case_name(c);
  std::string header = "NRRD0005\n# a comment\ntype: " + std::string(nrrd_type<T>::name) +
                       "\ndimension: 3\nsizes: " + std::to_string(dims[0]) + " " +
                       std::to_string(dims[1]) + " " + std::to_string(dims[2]) + "\n";
  if (c.space) {
    header +=
        "space: left-posterior-superior\nspace directions: (0.6,0.8,0) (0,-2,0) (0,0,3.5)\n"
        "space origin: (1.5,-2,30)\n";
  } else {
    header += "spacings: 0.5 -2 nan\n";
  }
  header += "kinds: domain domain domain\nencoding: " + c.encoding + "\n";
  if (sizeof(T) > 1 || c.big_endian)
    header += std::string("endian: ") + (c.big_endian ? "big\n" : "little\n");
  if (c.line_skip != 0) header += "line skip: " + std::to_string(c.line_skip) + "\n";
  if (c.byte_skip != 0) header += "byte skip: " + std::to_string(c.byte_skip) + "\n";
  header += "a key:=a value\n";

  const std::size_t count = values.size();
  const auto slice = static_cast<std::size_t>(dims[0] * dims[1]);
  const auto row = static_cast<std::size_t>(dims[0]);
  const fs::path nhdr = dir / (name + ".nhdr");
  switch (c.form) {
    case data_form::attached: {
      const fs::path nrrd = dir / (name + ".nrrd");
      write_file(nrrd, header + "\n" + encode_piece(c, values.data(), count));
      return nrrd;
    }
    case data_form::single:
      write_file(dir / (name + ".data"), encode_piece(c, values.data(), count));
      write_file(nhdr, header + "datafile: " + name + ".data\n");
      return nhdr;
    case data_form::list:
    case data_form::list_subdim1: {
      const bool rows = c.form == data_form::list_subdim1;
      const std::size_t piece = rows ? row : slice;
      fs::create_directories(dir / (name + "-parts"));
      std::string list = rows ? "data file: LIST 1\n" : "data file: LIST\n";
      for (std::size_t i = 0; i * piece < count; ++i) {
        const std::string part = name + "-parts/part" + std::to_string(i) + ".data";
        write_file(dir / part, encode_piece(c, values.data() + i * piece, piece));
        list += part + "\n";
      }
      write_file(nhdr, header + list);
      return nhdr;
    }
    case data_form::pattern: {
      // One slice per file, numbered 10, 8, 6, … (a negative step).
      const int slices = static_cast<int>(dims[2]);
      for (int i = 0; i < slices; ++i) {
        write_file(dir / (name + "-" + padded(10 - 2 * i, 3) + ".data"),
                   encode_piece(c, values.data() + static_cast<std::size_t>(i) * slice, slice));
      }
      write_file(nhdr, header + "data file: " + name + "-%03d.data 10 " +
                           std::to_string(10 - 2 * (slices - 1)) + " -2\n");
      return nhdr;
    }
    case data_form::pattern_subdim3: {
      // Three files of 3-D pieces, each a third of the slices.
      const std::size_t third = count / 3;
      for (int i = 0; i < 3; ++i) {
        write_file(dir / (name + "%" + std::to_string(i + 1) + ".data"),
                   encode_piece(c, values.data() + static_cast<std::size_t>(i) * third, third));
      }
      write_file(nhdr, header + "data file: " + name + "%%%d.data 1 3 1 3\n");
      return nhdr;
    }
  }
  return nhdr;
}

// =============================================================================================
// Differential tests against Teem.

template <class T>
class NrrdReaderTyped : public ::testing::Test {};
using all_sample_types = ::testing::Types<std::uint8_t, std::int8_t, std::uint16_t, std::int16_t,
                                          std::uint32_t, std::int32_t, float, double>;
TYPED_TEST_SUITE(NrrdReaderTyped, all_sample_types);

TYPED_TEST(NrrdReaderTyped, every_encoding_byte_order_and_data_file_form_reads_like_teem) {
  using T = TypeParam;
  const scratch_dir dir;
  const index3 dims{3, 4, 6};
  const std::vector<T> values = test_values<T>(3 * 4 * 6);
  for (const char* encoding : {"raw", "gzip", "ascii", "hex"}) {
    for (bool big : {false, true}) {
      if (std::string(encoding) == "ascii" && big) continue;
      for (data_form form :
           {data_form::attached, data_form::single, data_form::list, data_form::pattern,
            data_form::pattern_subdim3, data_form::list_subdim1}) {
        for (const auto& [line_skip, byte_skip] :
             std::vector<std::pair<int, int>>{{0, 0}, {2, 5}, {1, -1}}) {
          if (byte_skip < 0 && std::string(encoding) != "raw") continue;
          nrrd_case c;
          c.encoding = encoding;
          c.big_endian = big;
          c.form = form;
          c.line_skip = line_skip;
          c.byte_skip = byte_skip;
          c.space = (line_skip + static_cast<int>(form)) % 2 == 1;
          expect_same_as_teem(write_nrrd_case(dir.path(), c, dims, values));
        }
      }
    }
  }
}

TEST(NrrdReader, every_nrrd_spelling_of_the_sample_types_reads_like_teem) {
  const scratch_dir dir;
  const char* spellings[] = {"uchar",
                             "unsigned char",
                             "uint8",
                             "uint8_t",
                             "signed char",
                             "int8",
                             "int8_t",
                             "short",
                             "short int",
                             "signed short",
                             "signed short int",
                             "int16",
                             "int16_t",
                             "ushort",
                             "unsigned short",
                             "unsigned short int",
                             "uint16",
                             "uint16_t",
                             "int",
                             "signed int",
                             "int32",
                             "int32_t",
                             "uint",
                             "unsigned int",
                             "uint32",
                             "uint32_t",
                             "float",
                             "double",
                             "UCHAR",
                             "Unsigned Short"};
  int k = 0;
  for (const char* type : spellings) {
    const fs::path file = dir / std::string("t").append(std::to_string(k++)).append(".nrrd");
    std::string data;
    for (int i = 0; i < 8; ++i) data += std::to_string(i * 11) + " ";
    write_file(file, std::string("NRRD0004\ntype: ") + type +
                         "\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n" + data);
    expect_same_as_teem(file);
  }
}

TEST(NrrdReader, header_spellings_line_endings_and_descriptive_fields_read_like_teem) {
  const scratch_dir dir;
  const std::string data(24, '\x07');
  // CRLF lines, comments, key/values, every descriptive field, field names in other case and
  // without spaces, older magics.
  write_file(dir / "crlf.nrrd",
             "NRRD0001\r\n# comment\r\ncontent: a test\r\ntype: uchar\r\ndimension: 3\r\n"
             "sizes: 2 3 4\r\nencoding: raw\r\n\r\n" +
                 data);
  write_file(dir / "descriptive.nrrd",
             "NRRD0005\ncontent: everything\nnumber: 24\ntype: uchar\n"
             "dimension: 3\nsizes: 2 3 4\nspacings: 1.5 2.5 -3.5\nthicknesses: 1 nan 2\n"
             "axis mins: 0 0 0\naxis maxs: 1 2 3\ncenterings: cell node ???\n"
             "kinds: domain space time\nlabels: \"x\" \"y \\\"q\\\"\" \"z\"\n"
             "units: \"mm\" \"mm\" \"s\"\nmin: 0\nmax: 255\nold min: -1\nold max: 1e3\n"
             "sample units: HU\nkey:=value\nENCODING: raw\nLineSkip: 0\nbyteskip: 0\n\n" +
                 data);
  write_file(dir / "space.nrrd",
             "NRRD0005\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nspace dimension: 3\n"
             "space units: \"mm\" \"mm\" \"mm\"\n"
             "space directions: (0.3,0.4,0) (-0.8,0.6,0) (0,0,2.25)\n"
             "space origin: (-10.5,20.25,-30)\nmeasurement frame: (1,0,0) (0,1,0) (0,0,1)\n"
             "encoding: raw\n\n" +
                 data);
  write_file(dir / "ras.nrrd",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nspace: RAS\n"
             "space directions: none (0,2,0) (0,0,3)\nspace origin: (nan,nan,nan)\n"
             "encoding: raw\n\n" +
                 data);
  write_file(dir / "v.data", "LINE\n" + data);
  write_file(dir / "eof.nhdr",
             "NRRD0003\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nencoding: raw\nline skip: 1\n"
             "data file: ./v.data\n");
  for (const char* name : {"crlf.nrrd", "descriptive.nrrd", "space.nrrd", "ras.nrrd", "eof.nhdr"}) {
    expect_same_as_teem(dir / name);
  }
  // Teem loses a last header line that has no "\n"; progiso reads it.
  write_file(dir / "no-newline.nhdr",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 3 4\nencoding: raw\nblock size: 1\n"
             "data file: v.data\r");
  write_file(dir / "v.data", data);
  const progiso::volume v = progiso::read_nrrd(dir / "no-newline.nhdr");
  EXPECT_EQ(v.at(23), 7.0);
}

TEST(NrrdReader, highly_compressible_gzip_data_within_deflates_limit_is_read_like_teem) {
  const scratch_dir dir;
  const std::string zeros(std::size_t{96} * 96 * 96 * 4, '\0');
  const fs::path file = dir / "zeros.nrrd";
  write_file(file,
             "NRRD0004\ntype: float\ndimension: 3\nsizes: 96 96 96\nendian: little\n"
             "encoding: gzip\n\n" +
                 gzip(zeros, 9));
  expect_same_as_teem(file);
}

TEST(NrrdReader, concatenated_gzip_members_are_read_like_teem) {
  const scratch_dir dir;
  std::string data;
  for (int i = 0; i < 60; ++i) data += static_cast<char>(i);
  const fs::path file = dir / "members.nrrd";
  write_file(file, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 4 5\nencoding: gz\n\n" +
                       gzip(data.substr(0, 25)) + gzip(data.substr(25)));
  expect_same_as_teem(file);
}

TEST(NrrdReader, space_directions_give_the_world_map_teem_reads) {
  // The index-to-space map: the space directions as columns and the space origin, in the
  // header's own space; none without space directions, with a "none" axis or dependent ones.
  scratch_dir dir;
  const std::string cube(4 * 3 * 2, '\x07');
  const auto header = [&](const std::string& space_fields) {
    return "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\n" + space_fields +
           "encoding: raw\n\n" + cube;
  };
  const fs::path oriented = dir.path() / "oriented.nrrd";
  write_file(oriented, header("space: left-posterior-superior\n"
                              "space directions: (-0.9,0.1,0) (0.05,1.1,-0.2) (0,0.3,1.4)\n"
                              "space origin: (90.5,-126,-72.25)\n"));
  const std::optional<progiso::index_to_world> w =
      progiso::read_volume_world(oriented, std::nullopt);
  ASSERT_TRUE(w.has_value());
  Nrrd* n = nrrdNew();
  ASSERT_EQ(nrrdLoad(n, oriented.string().c_str(), nullptr), 0);
  for (unsigned c = 0; c < 3; ++c) {
    for (unsigned r = 0; r < 3; ++r) EXPECT_EQ(w->m[r][c], n->axis[c].spaceDirection[r]) << r << c;
  }
  for (unsigned r = 0; r < 3; ++r) EXPECT_EQ(w->m[r][3], n->spaceOrigin[r]) << r;
  nrrdNuke(n);
  EXPECT_LT(w->determinant(), 0.0);  // the first direction mirrors x
  // No origin: translation 0.
  const fs::path no_origin = dir.path() / "no_origin.nrrd";
  write_file(no_origin, header("space dimension: 3\nspace directions: (2,0,0) (0,2,0) (0,0,3)\n"));
  const auto w2 = progiso::read_volume_world(no_origin, std::nullopt);
  ASSERT_TRUE(w2.has_value());
  EXPECT_EQ(w2->apply({1, 1, 1}), (std::array<double, 3>{2, 2, 3}));
  // None: spacings only, a "none" axis, a 2-D space, dependent directions.
  for (const std::string& fields :
       {std::string("spacings: 1 2 3\n"),
        std::string("space dimension: 3\nspace directions: (1,0,0) none (0,0,1)\n"),
        std::string("space dimension: 2\nspace directions: (1,0) (0,1) (1,1)\n"),
        std::string("space dimension: 3\nspace directions: (1,0,0) (2,0,0) (0,0,1)\n")}) {
    const fs::path file = dir.path() / "none.nrrd";
    write_file(file, header(fields));
    EXPECT_FALSE(progiso::read_volume_world(file, std::nullopt).has_value()) << fields;
  }
}

TEST(NrrdReader, shared_volumes_written_as_nrrd_read_like_teem) {
  const std::optional<fs::path> data = progiso::test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found (../shared/data or $PROGISO_DATA_DIR)";
  const scratch_dir dir;
  for (const progiso::test::shared_volume& info : progiso::test::shared_volumes()) {
    SCOPED_TRACE(std::string(info.name));
    const fs::path source = fs::absolute(*data / info.file);
    const std::string type = info.type == sample_type::i16 ? "short" : "uchar";
    const std::string sizes = std::to_string(info.dims[0]) + " " + std::to_string(info.dims[1]) +
                              " " + std::to_string(info.dims[2]);
    const std::string head = "NRRD0004\ntype: " + type + "\ndimension: 3\nsizes: " + sizes +
                             "\nspacings: " + std::to_string(info.spacing[0]) + " " +
                             std::to_string(info.spacing[1]) + " " +
                             std::to_string(info.spacing[2]) + "\nendian: little\n";
    std::string bytes(static_cast<std::size_t>(fs::file_size(source)), '\0');
    {
      std::FILE* f = std::fopen(source.string().c_str(), "rb");
      ASSERT_NE(f, nullptr);
      ASSERT_EQ(std::fread(bytes.data(), 1, bytes.size(), f), bytes.size());
      std::fclose(f);
    }
    const std::string name(info.name);
    // The shared file itself as the detached data, by absolute path.
    write_file(dir / (name + "-abs.nhdr"),
               head + "encoding: raw\ndata file: " + source.string() + "\n");
    expect_same_as_teem(dir / (name + "-abs.nhdr"));
    // Attached gzip.
    write_file(dir / (name + ".nrrd"), head + "encoding: gzip\n\n" + gzip(bytes, 1));
    expect_same_as_teem(dir / (name + ".nrrd"));
    // One raw file per slice, through a pattern.
    const std::size_t slice = bytes.size() / static_cast<std::size_t>(info.dims[2]);
    for (std::int64_t z = 0; z < info.dims[2]; ++z) {
      write_file(dir / (name + "-" + std::to_string(z) + ".raw"),
                 bytes.substr(static_cast<std::size_t>(z) * slice, slice));
    }
    write_file(dir / (name + "-slices.nhdr"), head + "encoding: raw\ndata file: " + name +
                                                  "-%d.raw 0 " + std::to_string(info.dims[2] - 1) +
                                                  " 1\n");
    expect_same_as_teem(dir / (name + "-slices.nhdr"));
  }
}

// =============================================================================================
// Behaviour on valid input beyond the comparison.

// A 4-D series: 3 volumes of 4 × 3 × 2 samples of i16, value 100 k + 7 x + 13 y + 29 z − 50 at
// (x, y, z) of volume k, laid out with the series axis first (interleaved, as diffusion MRI
// holds them) or last (volumes one after the other, as Slicer's sequences).
struct series_case {
  bool first = false;       // the series axis is axis 0
  std::string axis_fields;  // kinds / space directions that say which axis it is
  std::string encoding = "raw";
  int files = 0;  // 0: attached; 1: one detached file; 3: a LIST of one file per volume
};

std::string series_bytes(bool first, const std::string& encoding) {
  std::string raw;
  std::string text;
  const auto put = [&](int k, int x, int y, int z) {
    const auto v = static_cast<std::int16_t>(100 * k + 7 * x + 13 * y + 29 * z - 50);
    const auto u = static_cast<std::uint16_t>(v);
    raw += static_cast<char>(u >> 8);  // big-endian
    raw += static_cast<char>(u & 0xff);
    text += std::to_string(v) + " ";
  };
  if (first) {
    for (int z = 0; z < 2; ++z)
      for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 4; ++x)
          for (int k = 0; k < 3; ++k) put(k, x, y, z);
  } else {
    for (int k = 0; k < 3; ++k)
      for (int z = 0; z < 2; ++z)
        for (int y = 0; y < 3; ++y)
          for (int x = 0; x < 4; ++x) put(k, x, y, z);
  }
  if (encoding == "ascii") return text + "\n";
  if (encoding == "gzip") return progiso::test::gzip(raw);
  if (encoding == "hex") {
    std::string hex;
    static constexpr char digits[] = "0123456789abcdef";
    for (const char c : raw) {
      hex += digits[static_cast<unsigned char>(c) >> 4];
      hex += digits[static_cast<unsigned char>(c) & 15];
    }
    return hex + "\n";
  }
  return raw;
}

fs::path write_series(const fs::path& dir, const std::string& stem, const series_case& c) {
  const std::string sizes = c.first ? "3 4 3 2" : "4 3 2 3";
  std::string h = "NRRD0005\ntype: short\ndimension: 4\nsizes: " + sizes +
                  "\nendian: big\nencoding: " + c.encoding + "\n" + c.axis_fields;
  const std::string data = series_bytes(c.first, c.encoding);
  if (c.files == 0) {
    write_file(dir / (stem + ".nrrd"), h + "\n" + data);
    return dir / (stem + ".nrrd");
  }
  if (c.files == 1) {
    write_file(dir / (stem + ".data"), data);
    write_file(dir / (stem + ".nhdr"), h + "data file: " + stem + ".data\n");
    return dir / (stem + ".nhdr");
  }
  // One file per volume (the series axis last): the raw data cut in three, each encoded alone.
  const std::string raw = series_bytes(false, "raw");
  std::string list = "data file: LIST 3\n";
  for (int k = 0; k < 3; ++k) {
    std::string piece = raw.substr(static_cast<std::size_t>(k) * 48, 48);
    if (c.encoding == "gzip") piece = progiso::test::gzip(piece);
    const std::string name = stem + "_" + std::to_string(k) + ".data";
    write_file(dir / name, piece);
    list += name + "\n";
  }
  write_file(dir / (stem + ".nhdr"), h + list);
  return dir / (stem + ".nhdr");
}

TEST(NrrdReader, every_volume_of_a_4d_series_reads_as_teems_slice_of_it) {
  const scratch_dir dir;
  const std::string space = "space: right-anterior-superior\nspace origin: (1,2,3)\n";
  const std::vector<series_case> layouts{
      {false, "kinds: domain domain domain list\n" + space +
                  "space directions: (0.5,0,0) (0,2,0) (0,0,1.25) none\n"},
      {false, ""},  // no axis information: the last axis
      {false, "spacings: 0.5 2 1.25 NaN\n"},
      {true, "kinds: list space space space\n"},
      {true, space + "space directions: none (0.5,0,0) (0,2,0) (0,0,1.25)\n"},
      {true, "kinds: vector domain domain domain\nspacings: nan 0.5 2 1.25\n"}};
  int files = 0;
  for (std::size_t l = 0; l < layouts.size(); ++l) {
    for (const char* encoding : {"raw", "gzip", "ascii", "hex"}) {
      for (int where : {0, 1, 3}) {
        series_case c = layouts[l];
        c.encoding = encoding;
        c.files = where;
        if (where == 3 && (c.first || c.encoding == "ascii" || c.encoding == "hex")) continue;
        const fs::path file =
            write_series(dir.path(), "s" + std::to_string(l) + encoding + std::to_string(where), c);
        SCOPED_TRACE(file.filename().string());
        ++files;
        for (std::int64_t k = 0; k < 3; ++k) {
          const reference_volume ref =
              teem_read(file, std::pair{c.first ? 0u : 3u, static_cast<std::size_t>(k)});
          ASSERT_TRUE(ref.ok) << ref.message;
          const progiso::volume v = progiso::read_nrrd(file, {.volume = k});
          EXPECT_EQ(v.dims(), (index3{4, 3, 2}));
          EXPECT_EQ(v.type(), sample_type::i16);
          ASSERT_EQ(v.byte_size(), ref.samples.size());
          EXPECT_EQ(std::memcmp(v.bytes(), ref.samples.data(), ref.samples.size()), 0);
          EXPECT_EQ(v.spacing(), ref.spacing);
          EXPECT_EQ(v.origin(), ref.origin);
          // The value at (1, 2, 1) of volume k.
          std::int16_t at = 0;
          std::memcpy(&at, v.bytes() + 2 * (1 + 4 * (2 + 3 * 1)), 2);
          EXPECT_EQ(at, 100 * k + 7 + 26 + 29 - 50);
        }
      }
    }
  }
  EXPECT_EQ(files, 6 * 4 * 2 + 3 * 2);
}

TEST(NrrdReader, a_4d_series_needs_a_volume_and_a_series_axis_first_or_last) {
  const scratch_dir dir;
  series_case c{false, "space dimension: 3\nspace directions: (1,0,0) (0,1,0) (0,0,1) none\n"};
  const fs::path file = write_series(dir.path(), "series", c);
  std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg,
                       "a time series of 3 volumes (sizes[3] = 3): choose one by its "
                       "index, 0 to 2"))
      << msg;
  msg = error_naming(
      file, [&] { (void)progiso::read_volume(file, std::nullopt, std::nullopt, {.volume = 3}); });
  EXPECT_TRUE(contains(msg, "volume 3 was chosen, but the input is a time series of 3 volumes"))
      << msg;
  c.first = true;
  c.axis_fields = "kinds: list domain domain domain\n";
  const fs::path dwi = write_series(dir.path(), "dwi", c);
  msg = error_naming(dwi, [&] { (void)progiso::read_nrrd(dwi); });
  EXPECT_TRUE(contains(msg, "(sizes[0] = 3)")) << msg;
  // The world map skips the series axis.
  c.first = false;
  c.axis_fields =
      "space: left-posterior-superior\nspace directions: (-2,0,0) (0,1.5,0) "
      "(0,0,0.5) none\nspace origin: (10,20,30)\n";
  const fs::path oriented = write_series(dir.path(), "oriented", c);
  const auto world = progiso::read_volume_world(oriented, std::nullopt, {.volume = 1});
  ASSERT_TRUE(world.has_value());
  EXPECT_EQ(world->apply({1, 1, 1}), (std::array<double, 3>{8, 21.5, 30.5}));
  EXPECT_EQ(progiso::volume_input_files(oriented, std::nullopt, {.volume = 2}),
            std::vector<fs::path>{oriented});
  // Refused: a series axis in the middle, two of them, directions that do not say, a series
  // axis with a direction, 2^31 volumes, a pattern of 4-D pieces that does not divide.
  const auto refused = [&](const std::string& stem, const std::string& header,
                           const std::string& what) {
    const fs::path f = dir / (stem + ".nrrd");
    write_file(f, "NRRD0005\ntype: uchar\ndimension: 4\n" + header + "encoding: raw\n\n" +
                      std::string(72, '\x01'));
    const std::string m = error_naming(f, [&] { (void)progiso::read_nrrd(f, {.volume = 0}); });
    EXPECT_TRUE(contains(m, what)) << stem << ": " << m;
  };
  refused("middle", "sizes: 4 3 3 2\nkinds: domain domain list domain\n",
          "the series axis of a 4-D NRRD array is axis 2");
  refused("two", "sizes: 3 4 3 2\nkinds: list domain vector domain\n", "2 non-spatial axes");
  refused("nones",
          "sizes: 3 4 3 2\nspace dimension: 3\n"
          "space directions: none (1,0,0) none (0,0,1)\n",
          "a 4-D array needs 3 and \"none\" for its series axis");
  refused("direction",
          "sizes: 3 4 3 2\nkinds: list domain domain domain\nspace dimension: 3\n"
          "space directions: (1,0,0) (1,0,0) (0,1,0) (0,0,1)\n",
          "expected \"none\" there");
  refused("many", "sizes: 4 3 2 2147483648\n", "expected 1 to 2147483647");
  refused("thin", "sizes: 4 1 2 3\n", "found sizes 4,1,2");
  refused("kindscount", "sizes: 3 4 3 2\nkinds: list domain domain\n", "expected 4 words");
}

TEST(NrrdReader, ascii_values_may_be_separated_by_commas) {
  const scratch_dir dir;
  const fs::path file = dir / "commas.nrrd";
  write_file(file,
             "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n"
             "1,2 , 3,\n-4\t5,,6 +7 -32768 99 100\n");
  const progiso::volume v = progiso::read_nrrd(file);
  const double expected[] = {1, 2, 3, -4, 5, 6, 7, -32768};
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(v.at(i), expected[i]) << i;
}

TEST(NrrdReader, ascii_subnormal_double_is_accepted) {
  const scratch_dir dir;
  const fs::path file = dir / "tiny.nrrd";
  write_file(file,
             "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 2 2\nencoding: text\n\n"
             "1e-320 -1e-320 4.9406564584124654e-324 0 1e-400 2 3 4\n");
  const progiso::volume v = progiso::read_nrrd(file);
  EXPECT_EQ(v.at(0), std::strtod("1e-320", nullptr));
  EXPECT_GT(v.at(0), 0.0);
  EXPECT_EQ(v.at(1), -std::strtod("1e-320", nullptr));
  EXPECT_EQ(v.at(2), std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(v.at(4), 0.0);
  expect_same_as_teem(file);
}

TEST(NrrdReader, volume_input_files_lists_the_header_then_every_data_file_in_order) {
  const scratch_dir dir;
  write_file(dir / "p.nhdr",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 3\nencoding: raw\n"
             "data file: s%02d.raw 4 0 -2\n");
  EXPECT_EQ(
      progiso::volume_input_files(dir / "p.nhdr", std::nullopt),
      (std::vector<fs::path>{dir / "p.nhdr", dir / "s04.raw", dir / "s02.raw", dir / "s00.raw"}));
  write_file(dir / "l.nhdr",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
             "data file: LIST\nsub/a.raw\n/abs/b.raw\n");
  EXPECT_EQ(progiso::volume_input_files(dir / "l.nhdr", std::nullopt),
            (std::vector<fs::path>{dir / "l.nhdr", dir / "sub" / "a.raw", "/abs/b.raw"}));
  write_file(dir / "a.nrrd",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n");
  EXPECT_EQ(progiso::volume_input_files(dir / "a.nrrd", std::nullopt),
            (std::vector<fs::path>{dir / "a.nrrd"}));
  EXPECT_EQ(
      progiso::volume_input_files(dir / "x.raw", progiso::raw_layout{{2, 2, 2}, sample_type::u8}),
      (std::vector<fs::path>{dir / "x.raw"}));
  write_file(dir / "pct.nhdr",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
             "data file: 100%%-%d.raw 1 2 1\n");
  EXPECT_EQ(progiso::volume_input_files(dir / "pct.nhdr", std::nullopt),
            (std::vector<fs::path>{dir / "pct.nhdr", dir / "100%-1.raw", dir / "100%-2.raw"}));
  const fs::path bad = dir / "bad.nhdr";
  write_file(bad,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
             "data file: %s\n");
  (void)error_naming(bad, [&] { (void)progiso::volume_input_files(bad, std::nullopt); });
  (void)error_naming(dir / "v.vtk",
                     [&] { (void)progiso::volume_input_files(dir / "v.vtk", std::nullopt); });
}

// =============================================================================================
// Hostile input: each fails with one line naming the right file.

const std::string header_2x2x2 =
    "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n";

TEST(NrrdReader, detached_data_file_with_a_field_width_is_rejected_without_touching_printf) {
  const scratch_dir dir;
  for (const char* width : {"%64d", "%100000d", "%010d", "x%99999999999999999999d.raw"}) {
    SCOPED_TRACE(width);
    const fs::path file = dir / "w.nhdr";
    write_file(file, header_2x2x2 + "data file: " + width + " 0 1 1\n");
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, "field width")) << msg;
    EXPECT_TRUE(contains(msg, "data file")) << msg;
  }
}

TEST(NrrdReader, data_file_pattern_with_any_other_conversion_is_rejected) {
  const scratch_dir dir;
  for (const char* pattern : {"%s", "%n", "%n 0 1 1", "%x.raw 0 1 1", "%.3d 0 1 1", "%-4d 0 1 1",
                              "%ld 0 1 1", "name% 0 1 1", "%s%s%s%s%s%n"}) {
    SCOPED_TRACE(pattern);
    const fs::path file = dir / "c.nhdr";
    write_file(file, header_2x2x2 + "data file: " + pattern + "\n");
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, "unsupported conversion")) << msg;
  }
}

TEST(NrrdReader, data_file_pattern_with_two_conversions_is_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "two.nhdr";
  write_file(file, header_2x2x2 + "data file: a%db%d.raw 0 1 1\n");
  const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, "more than one conversion")) << msg;
}

TEST(NrrdReader, data_file_pattern_naming_too_many_files_is_rejected_before_expanding) {
  const scratch_dir dir;
  const fs::path file = dir / "many.nhdr";
  write_file(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 32769\nencoding: raw\n"
             "data file: s%d.raw -2147483648 2147483647 1 1\n");
  const std::string msg =
      error_naming(file, [&] { (void)progiso::volume_input_files(file, std::nullopt); });
  EXPECT_TRUE(contains(msg, "1048576")) << msg;
  write_file(file, header_2x2x2 + "data file: s%d.raw 0 5 1\n");
  const std::string pieces = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(pieces, "6 data files")) << pieces;
  write_file(file, header_2x2x2 + "data file: LIST\na\nb\nc\n");
  const std::string list = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(list, "3 data files")) << list;
  write_file(file, header_2x2x2 + "data file: s%d.raw 0 5 0\n");
  (void)error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  write_file(file, header_2x2x2 + "data file: s%d.raw 5 0 1\n");
  (void)error_naming(file, [&] { (void)progiso::read_nrrd(file); });
}

TEST(NrrdReader, hundred_thousand_key_value_lines_parse_in_linear_time) {
  const scratch_dir dir;
  std::string text = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n";
  for (int i = 0; i < 100000; ++i) text += "key" + std::to_string(i) + ":=value\n";
  text += "\n" + std::string(8, '\x05');
  const fs::path file = dir / "keys.nrrd";
  write_file(file, text);
  const auto start = std::chrono::steady_clock::now();
  const progiso::volume v = progiso::read_nrrd(file);
  const std::chrono::duration<double> took = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(v.at(7), 5.0);
  EXPECT_LT(took.count(), 2.0) << "header of " << text.size() << " bytes";
}

TEST(NrrdReader, declared_size_beyond_the_data_is_refused_before_allocating) {
  const scratch_dir dir;
  const std::string filler(33 * 1024, 'x');
  const fs::path raw = dir / "big.nrrd";
  write_file(raw, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2000 2000 1000\nencoding: raw\n\n" +
                      filler);
  const std::string msg = error_naming(raw, [&] { (void)progiso::read_nrrd(raw); });
  EXPECT_TRUE(contains(msg, "cannot hold the declared 4000000000 bytes")) << msg;

  const fs::path gz = dir / "big-gzip.nrrd";
  write_file(gz,
             "NRRD0004\ntype: double\ndimension: 3\nsizes: 2000 2000 1000\nendian: little\n"
             "encoding: gzip\n\n" +
                 gzip(std::string(std::size_t{32} << 20, '\0'), 9));
  EXPECT_LT(fs::file_size(gz), std::uintmax_t{64} << 10);
  const std::string gmsg = error_naming(gz, [&] { (void)progiso::read_nrrd(gz); });
  EXPECT_TRUE(contains(gmsg, "cannot hold the declared 32000000000 bytes")) << gmsg;
  EXPECT_TRUE(contains(gmsg, "1032:1")) << gmsg;

  // Detached: the data file that cannot hold its share is named.
  write_file(dir / "short.raw", "abc");
  const fs::path nhdr = dir / "short.nhdr";
  write_file(nhdr, header_2x2x2 + "data file: short.raw\n");
  const std::string dmsg = error_naming(dir / "short.raw", [&] { (void)progiso::read_nrrd(nhdr); });
  EXPECT_TRUE(contains(dmsg, "cannot hold")) << dmsg;
  EXPECT_TRUE(contains(dmsg, nhdr.string())) << dmsg;

  for (const char* encoding : {"ascii", "hex"}) {
    const fs::path file = dir / (std::string(encoding) + ".nrrd");
    write_file(file, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100 100 100\nencoding: " +
                         std::string(encoding) + "\n\n1 2 3\n");
    const std::string emsg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(emsg, "cannot hold")) << emsg;
  }
}

TEST(NrrdReader, truncated_gzip_stream_is_reported_as_data_ending_early) {
  const scratch_dir dir;
  std::string data(4096, '\0');
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<char>((i * 7919) % 251);
  const std::string packed = gzip(data);
  const fs::path file = dir / "cut.nrrd";
  write_file(file, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16 16 16\nencoding: gzip\n\n" +
                       packed.substr(0, packed.size() / 2));
  const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, "NRRD data ends after")) << msg;
  EXPECT_TRUE(contains(msg, "of 4096 bytes")) << msg;
}

TEST(NrrdReader, gzip_garbage_is_reported_as_corrupt_with_zlibs_message) {
  const scratch_dir dir;
  using namespace std::string_literals;
  for (const std::string& garbage : {"\x1f\x8b\x08\x00\xff\xfe this is not deflate data at all"s,
                                     "plain bytes, no gzip header at all"s}) {
    const fs::path file = dir / "garbage.nrrd";
    write_file(file,
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n" + garbage);
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, "corrupt NRRD gzip data (zlib: ")) << msg;
  }
}

TEST(NrrdReader, data_file_that_is_a_fifo_device_or_directory_is_refused_without_reading) {
  const scratch_dir dir;
  ASSERT_EQ(::mkfifo((dir / "fifo.raw").c_str(), 0600), 0);
  fs::create_directory(dir / "folder.raw");
  const std::vector<std::pair<fs::path, std::string>> cases{{dir / "fifo.raw", "a FIFO"},
                                                            {"/dev/zero", "a character device"},
                                                            {"/dev/urandom", "a character device"},
                                                            {dir / "folder.raw", "a directory"}};
  for (const auto& [data, what] : cases) {
    SCOPED_TRACE(data.string());
    if (!fs::exists(data)) continue;
    const fs::path file = dir / "d.nhdr";
    write_file(file, header_2x2x2 + "data file: " + data.string() + "\n");
    const std::string msg = error_naming(data, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, "expected a regular NRRD data file, found " + what)) << msg;
    EXPECT_TRUE(contains(msg, file.string())) << msg;
  }
  // The header itself, too.
  const std::string msg =
      error_naming(dir / "fifo.raw", [&] { (void)progiso::read_nrrd(dir / "fifo.raw"); });
  EXPECT_TRUE(contains(msg, "a FIFO")) << msg;
}

TEST(NrrdReader, sizes_beyond_64_bits_or_the_axis_limit_are_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "sizes.nrrd";
  const auto check = [&](const std::string& sizes, const std::string& expected) {
    SCOPED_TRACE(sizes);
    write_file(file, "NRRD0004\ntype: double\ndimension: 3\nsizes: " + sizes +
                         "\nendian: big\nencoding: raw\n\n");
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, expected)) << msg;
  };
  check("18446744073709551616 2 2", "cannot parse \"18446744073709551616\"");
  check("4294967296 4294967296 4294967296", "above 32769");
  check("2 32770 2", "above 32769");
  check("2 -4 2", "cannot parse \"-4\"");
  check("2 x 2", "cannot parse \"x\"");
  check("2 2", "expected 3 sizes");
  check("2 2 2 2", "expected 3 sizes");
  check("0 4 5", "found sizes 0,4,5");
}

TEST(NrrdReader, dimension_outside_one_to_sixteen_or_garbage_is_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "dim.nrrd";
  for (const char* dim : {"0", "17", "-3", "three", "3.0", "99999999999999999999999"}) {
    SCOPED_TRACE(dim);
    write_file(file, std::string("NRRD0004\ntype: uchar\ndimension: ") + dim +
                         "\nsizes: 2 2 2\nencoding: raw\n\n");
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg,
                         "NRRD field \"dimension\" (header line 3): expected an integer "
                         "from 1 to 16"))
        << msg;
  }
  write_file(file, "NRRD0004\ntype: uchar\ndimension: 5\nsizes: 2 2 2 2 2\nencoding: raw\n\n");
  const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg,
                       "expected a 3-D NRRD array (or a 4-D one: a series of volumes), "
                       "found dimension 5"))
      << msg;
}

TEST(NrrdReader, duplicated_unknown_and_malformed_lines_are_rejected_with_their_line) {
  const scratch_dir dir;
  const fs::path file = dir / "lines.nrrd";
  const auto check = [&](const std::string& text, const std::string& expected) {
    SCOPED_TRACE(expected);
    write_file(file, text);
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, expected)) << msg;
  };
  check(header_2x2x2 + "type: uchar\n\n12345678", "\"type\" is given twice (header lines 2 and 6)");
  check(header_2x2x2 + "data file: a\ndatafile: b\n", "\"data file\" is given twice");
  check(header_2x2x2 + "spacings: 1 1 1\nSpacings: 1 1 1\n\n", "\"spacings\" is given twice");
  check(header_2x2x2 + "colour: blue\n\n12345678",
        "unknown NRRD field \"colour\" on header line 6");
  check(header_2x2x2 + "no separator here\n\n12345678",
        "header line 6, found \"no separator here\"");
  check(header_2x2x2 + "endian: middle\n\n12345678", "expected little or big, found \"middle\"");
  check(header_2x2x2 + "line skip: -1\n\n12345678", "NRRD field \"line skip\"");
  check(header_2x2x2 + "byte skip: -2\n\n12345678", "NRRD field \"byte skip\"");
  check(header_2x2x2 + "spacings: 1 one 1\n\n12345678", "cannot parse \"one\" as a number");
  check(header_2x2x2 + "space origin: (1,2,3)\n\n12345678", "needs the field \"space\"");
  check(header_2x2x2 + "space: RAS\nspace directions: (1,0) (0,1,0) (0,0,1)\n\n12345678",
        "expected 3 components");
  check(header_2x2x2 + "space: RAS\nspace dimension: 3\n\n12345678", "together");
  check(header_2x2x2 + "space: Mars\n\n12345678", "unknown space \"Mars\"");
  check(header_2x2x2 + "labels: \"x\" \"y\n\n12345678", "no closing");
  check(header_2x2x2 + "kinds: domain domain\n\n12345678", "expected 3 words");
  check(header_2x2x2 + "old min: low\n\n12345678", "NRRD field \"old min\"");
  check("NRRD0004\ntype: uchar\ndimension: 3\nencoding: raw\n\n12345678",
        "missing required NRRD field \"sizes\"");
  check("NRRD0004\ntype: banana\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n12345678",
        "unknown sample type \"banana\"");
  check("NRRD0004\ntype: int64\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nendian: big\n\n",
        "unsupported NRRD sample type \"int64\" (expected one of u8 i8 u16 i16 u32 i32 f32 f64)");
  check("NRRD0004\ntype: block\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n",
        "unsupported NRRD sample type \"block\"");
  check("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n\n",
        "unsupported NRRD encoding \"bzip2\"");
  check("NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n",
        "\"endian\" is required for i16 samples in raw encoding");
  check(header_2x2x2 + "data file: -\n", "standard input");
  check(header_2x2x2, "without a \"data file\" field");
  check("NRRD0006\n", "unsupported NRRD format version \"NRRD0006\"");
  check("NRRD0004 \n", "expected the NRRD magic alone on the first line");
  check("P5\n2 2\n255\n", "not a NRRD file");
}

TEST(NrrdReader, nul_byte_and_overlong_line_in_the_header_are_rejected) {
  const scratch_dir dir;
  const fs::path nul = dir / "nul.nrrd";
  write_file(nul, std::string("NRRD0004\ntype: uchar\ncontent: a\0b\n", 32) +
                      "dimension: 3\nsizes: 2 2 2\nencoding: raw\n\n12345678");
  const std::string msg = error_naming(nul, [&] { (void)progiso::read_nrrd(nul); });
  EXPECT_TRUE(contains(msg, "header line 3 holds a NUL byte")) << msg;

  const fs::path longer = dir / "long.nrrd";
  write_file(longer, header_2x2x2 + "content: " + std::string((std::size_t{1} << 20) + 10, 'a') +
                         "\n\n12345678");
  const std::string lmsg = error_naming(longer, [&] { (void)progiso::read_nrrd(longer); });
  EXPECT_TRUE(contains(lmsg, "header line 6 is longer than 1048576 bytes")) << lmsg;
}

TEST(NrrdReader, ascii_values_outside_the_type_or_unparsable_are_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "range.nrrd";
  const auto check = [&](const std::string& type, const std::string& values,
                         const std::string& expected) {
    SCOPED_TRACE(type + ": " + values);
    write_file(file, "NRRD0004\ntype: " + type +
                         "\ndimension: 3\nsizes: 2 2 2\n"
                         "encoding: ascii\n\n" +
                         values);
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, expected)) << msg;
  };
  check("uchar", "1 2 256 4 5 6 7 8", "NRRD ascii value 3 of 8, \"256\", is out of range for u8");
  check("uchar", "1 2 -1 4 5 6 7 8", "is out of range for u8");
  check("signed char", "-129 2 3 4 5 6 7 8", "is out of range for i8");
  check("short", "1 2 3 4 5 6 7 -32769", "value 8 of 8, \"-32769\", is out of range for i16");
  check("ushort", "65536 2 3 4 5 6 7 8", "is out of range for u16");
  check("int", "1 2 3 2147483648 5 6 7 8", "is out of range for i32");
  check("uint", "1 2 3 4294967296 5 6 7 8", "is out of range for u32");
  check("int", "1 2 3 99999999999999999999999 5 6 7 8", "is out of range for i32");
  check("int", "1 2 3 4.5 5 6 7 8", "\"4.5\", cannot be parsed as i32");
  check("float", "1 2 3 4 five 6 7 8", "cannot be parsed as f32");
  check("double", "1 2 3" + std::string(20, ' '), "NRRD ascii data ends after 3 of 8 values");
  check("uchar", "1 2 3 4 5 6 7 " + std::string(2000, '9'), "longer than 1024 bytes");
}

TEST(NrrdReader, hex_data_with_an_odd_digit_count_or_a_bad_character_is_rejected) {
  const scratch_dir dir;
  const fs::path file = dir / "hex.nrrd";
  write_file(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n\n"
             "0102030405060708090a0b0c0d0e0f10\n");
  EXPECT_EQ(progiso::read_nrrd(file).at(7), 8.0);
  write_file(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n\n"
             "01 02 03 04\n05 06 07 0\n\n\n");
  const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, "NRRD data ends after 7 of 8 bytes (an odd number of hex digits)"))
      << msg;
  write_file(file,
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n\n"
             "01 02 03 04 0g 06 07 08 09 10\n");
  const std::string bad = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(bad, "holds \"g\" after 4 bytes")) << bad;
}

TEST(NrrdReader, byte_skip_minus_one_is_refused_for_every_encoding_but_raw) {
  const scratch_dir dir;
  for (const char* encoding : {"gzip", "ascii", "hex"}) {
    const fs::path file = dir / "skip.nrrd";
    write_file(file, std::string("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                                 "encoding: ") +
                         encoding + "\nbyte skip: -1\n\n" + gzip("12345678"));
    const std::string msg = error_naming(file, [&] { (void)progiso::read_nrrd(file); });
    EXPECT_TRUE(contains(msg, "NRRD field \"byte skip\"")) << msg;
    EXPECT_TRUE(contains(msg, "raw encoding only")) << msg;
  }
}

TEST(NrrdReader, line_skip_past_the_end_of_the_data_is_rejected) {
  const scratch_dir dir;
  write_file(dir / "d.raw", "one line\n12345678");
  const fs::path file = dir / "skip.nhdr";
  write_file(file, header_2x2x2 + "line skip: 3\ndata file: d.raw\n");
  const std::string msg = error_naming(dir / "d.raw", [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, "1 of the 3 lines to skip")) << msg;
}

TEST(NrrdReader, missing_data_file_error_names_it_and_the_header) {
  const scratch_dir dir;
  for (int i = 0; i < 2; ++i) {
    write_file(dir / std::string("s").append(std::to_string(i)).append(".raw"), "1234");
  }
  const fs::path file = dir / "gap.nhdr";
  write_file(file, header_2x2x2 + "data file: s%d.raw 0 2 2 3\n");
  const std::string msg = error_naming(dir / "s2.raw", [&] { (void)progiso::read_nrrd(file); });
  EXPECT_TRUE(contains(msg, "cannot open NRRD data file")) << msg;
  EXPECT_TRUE(contains(msg, "(data file 2 of 2 named by " + file.string() + ")")) << msg;
}

}  // namespace
