#include <progiso/io/detail/zarr_reader.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include <blosc.h>
#include <zlib.h>
#include <zstd.h>
#include <nlohmann/json.hpp>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr std::uint64_t max_metadata_bytes = std::uint64_t{1} << 20;
constexpr int max_json_depth = 64;
constexpr std::int64_t max_axis = (std::int64_t{1} << 15) + 1;
constexpr std::uint64_t max_chunk_bytes = (std::uint64_t{1} << 31) - 1;

std::string text_of(const json& j) { return detail::quoted(j.dump(), 40); }

/// A metadata file, read bounded and parsed. Nesting is checked first (outside strings), so
/// that no input drives the parser or the destructor deep.
json read_json(const fs::path& file, std::string_view kind) {
  input_file in(file, kind);
  if (in.size() > max_metadata_bytes) {
    throw error(file.string() + ": " + std::to_string(in.size()) + " bytes, more than the " +
                std::to_string(max_metadata_bytes) + " a Zarr metadata file may have");
  }
  const std::vector<char> bytes = in.read_all();
  const std::string_view text(bytes.data(), bytes.size());
  int depth = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') in_string = true;
    if (c == '[' || c == '{') {
      if (++depth > max_json_depth) {
        throw error(file.string() + ": JSON nested deeper than " + std::to_string(max_json_depth) +
                    " levels");
      }
    }
    if (c == ']' || c == '}') --depth;
  }
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw error(file.string() + ": not valid JSON (" + std::string(e.what()) + ")");
  }
}

/// The member `key` of object `j` in `file`; throws naming what was expected.
const json& member(const fs::path& file, const json& j, const char* key, const char* expected) {
  if (!j.is_object() || !j.contains(key)) {
    throw error(file.string() + ": expected \"" + key + "\" (" + expected + "), found none");
  }
  return j.at(key);
}

std::int64_t positive_integer(const fs::path& file, const json& v, const char* what) {
  if (!v.is_number_integer() || v.get<std::int64_t>() < 1) {
    throw error(file.string() + ": expected a positive integer in \"" + what + "\", found " +
                text_of(v));
  }
  return v.get<std::int64_t>();
}

std::vector<std::int64_t> integer_list(const fs::path& file, const json& j, const char* key) {
  const json& v = member(file, j, key, "a list of positive integers");
  if (!v.is_array() || v.empty() || v.size() > 32) {
    throw error(file.string() + ": expected \"" + key +
                "\" to be a list of 1 to 32 positive integers, found " + text_of(v));
  }
  std::vector<std::int64_t> out;
  for (const json& e : v) out.push_back(positive_integer(file, e, key));
  return out;
}

void parse_dtype(const fs::path& file, const json& v, zarr_level& a) {
  const std::string s = v.is_string() ? v.get<std::string>() : std::string();
  const auto refuse = [&] {
    throw error(file.string() + ": dtype " + text_of(v) +
                " is not supported (expected |u1, |i1, |b1, <u2, <i2, <u4, <i4, <f4, <f8 or the "
                "same with >)");
  };
  if (s.size() != 3 || (s[0] != '<' && s[0] != '>' && s[0] != '|')) refuse();
  const std::string kind = s.substr(1);
  if (kind == "u1" || kind == "b1") {
    a.type = sample_type::u8;
  } else if (kind == "i1") {
    a.type = sample_type::i8;
  } else if (kind == "u2") {
    a.type = sample_type::u16;
  } else if (kind == "i2") {
    a.type = sample_type::i16;
  } else if (kind == "u4") {
    a.type = sample_type::u32;
  } else if (kind == "i4") {
    a.type = sample_type::i32;
  } else if (kind == "f4") {
    a.type = sample_type::f32;
  } else if (kind == "f8") {
    a.type = sample_type::f64;
  } else {
    refuse();
  }
  a.big_endian = s[0] == '>';
}

void parse_fill(const fs::path& file, const json& v, zarr_level& a) {
  if (v.is_null()) {
    a.fill = 0.0;
  } else if (v.is_boolean()) {
    a.fill = v.get<bool>() ? 1.0 : 0.0;
  } else if (v.is_number()) {
    a.fill = v.get<double>();
  } else if (v.is_string() && v.get<std::string>() == "NaN") {
    a.fill = std::numeric_limits<double>::quiet_NaN();
  } else if (v.is_string() && v.get<std::string>() == "Infinity") {
    a.fill = std::numeric_limits<double>::infinity();
  } else if (v.is_string() && v.get<std::string>() == "-Infinity") {
    a.fill = -std::numeric_limits<double>::infinity();
  } else {
    throw error(file.string() +
                ": expected fill_value to be a number, \"NaN\", \"Infinity\", "
                "\"-Infinity\" or null, found " +
                text_of(v));
  }
  const bool integer = a.type != sample_type::f32 && a.type != sample_type::f64;
  if (integer) {
    const double lo =
        a.type == sample_type::u8 || a.type == sample_type::u16 || a.type == sample_type::u32
            ? 0.0
            : -std::ldexp(1.0, static_cast<int>(8 * sample_size(a.type)) - 1);
    const double hi =
        a.type == sample_type::u8 || a.type == sample_type::u16 || a.type == sample_type::u32
            ? std::ldexp(1.0, static_cast<int>(8 * sample_size(a.type))) - 1.0
            : std::ldexp(1.0, static_cast<int>(8 * sample_size(a.type)) - 1) - 1.0;
    if (!(a.fill >= lo && a.fill <= hi) || a.fill != std::floor(a.fill)) {
      throw error(file.string() + ": fill_value " + text_of(v) + " is not a " +
                  std::string(to_string(a.type)) + " value");
    }
  }
}

void parse_compressor(const fs::path& file, const json& v, zarr_level& a) {
  if (v.is_null()) {
    a.codec = zarr_codec::none;
    return;
  }
  const json& id = member(file, v, "id", "the compressor's name");
  const std::string name = id.is_string() ? id.get<std::string>() : std::string();
  if (name == "blosc") {
    a.codec = zarr_codec::blosc;
  } else if (name == "zstd") {
    a.codec = zarr_codec::zstd;
  } else if (name == "zlib") {
    a.codec = zarr_codec::zlib;
  } else if (name == "gzip") {
    a.codec = zarr_codec::gzip;
  } else {
    throw error(file.string() + ": compressor " + text_of(id) +
                " is not supported (expected blosc, zstd, zlib, gzip or null)");
  }
}

/// The array at `dir`: its .zarray, checked.
zarr_level read_array(const fs::path& dir, std::vector<fs::path>& files) {
  const fs::path file = dir / ".zarray";
  files.push_back(file);
  const json j = read_json(file, "Zarr array metadata");
  zarr_level a;
  a.dir = dir;
  const json& format = member(file, j, "zarr_format", "2");
  if (!format.is_number_integer() || format.get<std::int64_t>() != 2) {
    throw error(file.string() + ": expected zarr_format 2, found " + text_of(format));
  }
  a.shape = integer_list(file, j, "shape");
  a.chunks = integer_list(file, j, "chunks");
  if (a.chunks.size() != a.shape.size()) {
    throw error(file.string() + ": \"chunks\" has " + std::to_string(a.chunks.size()) +
                " entries, \"shape\" " + std::to_string(a.shape.size()));
  }
  if (a.shape.size() < 3) {
    throw error(file.string() + ": a " + std::to_string(a.shape.size()) +
                "-D array; expected at least 3 axes (z, y, x last)");
  }
  const std::size_t n = a.shape.size();
  for (std::size_t d = n - 3; d < n; ++d) {
    if (a.shape[d] < 2 || a.shape[d] > max_axis) {
      throw error(file.string() + ": spatial axis " + std::to_string(d) + " has " +
                  std::to_string(a.shape[d]) + " samples (expected 2 to " +
                  std::to_string(max_axis) + ")");
    }
  }
  parse_dtype(file, member(file, j, "dtype", "a NumPy type string"), a);
  std::uint64_t chunk = sample_size(a.type);
  for (const std::int64_t c : a.chunks) {
    chunk *= static_cast<std::uint64_t>(std::min<std::int64_t>(c, max_axis + 1));
    if (c > max_axis || chunk > max_chunk_bytes) {
      throw error(file.string() + ": chunks of more than " + std::to_string(max_chunk_bytes) +
                  " bytes (\"chunks\" " + text_of(j.at("chunks")) + ")");
    }
  }
  const json& order = member(file, j, "order", "\"C\" or \"F\"");
  if (order != "C" && order != "F") {
    throw error(file.string() + ": expected order \"C\" or \"F\", found " + text_of(order));
  }
  a.fortran = order == "F";
  parse_fill(file, member(file, j, "fill_value", "a number or null"), a);
  parse_compressor(file, member(file, j, "compressor", "an object or null"), a);
  if (j.contains("filters") && !j.at("filters").is_null() &&
      !(j.at("filters").is_array() && j.at("filters").empty())) {
    throw error(file.string() + ": filters " + text_of(j.at("filters")) +
                " are not supported (expected null)");
  }
  if (j.contains("dimension_separator")) {
    const json& s = j.at("dimension_separator");
    if (s != "." && s != "/") {
      throw error(file.string() + ": expected dimension_separator \".\" or \"/\", found " +
                  text_of(s));
    }
    a.separator = s == "/" ? '/' : '.';
  }
  return a;
}

/// The spatial (z, y, x) entries of a "scale" or "translation" list of `n` numbers, as x, y, z.
std::array<double, 3> spatial(const fs::path& file, const json& v, std::size_t n, bool scale) {
  if (!v.is_array() || v.size() != n) {
    throw error(file.string() + ": expected a " + (scale ? "scale" : "translation") + " of " +
                std::to_string(n) + " numbers, found " + text_of(v));
  }
  std::array<double, 3> out{};
  for (std::size_t k = 0; k < 3; ++k) {
    const json& e = v.at(n - 1 - k);
    const double x = e.is_number() ? e.get<double>() : std::numeric_limits<double>::quiet_NaN();
    if (!std::isfinite(x) || (scale && !(x > 0.0))) {
      throw error(file.string() + ": expected " + (scale ? "positive finite" : "finite") +
                  " numbers in the " + (scale ? "scale" : "translation") + ", found " + text_of(e));
    }
    out[k] = x;
  }
  return out;
}

/// Applies a list of coordinate transformations (scale, then translation) to spacing and origin.
void transform(const fs::path& file, const json& list, std::size_t n,
               std::array<double, 3>& spacing, std::array<double, 3>& origin) {
  if (!list.is_array() || list.size() > 8) {
    throw error(file.string() + ": expected coordinateTransformations to be a list, found " +
                text_of(list));
  }
  for (const json& t : list) {
    const json& type = member(file, t, "type", "scale, translation or identity");
    if (type == "scale") {
      const std::array<double, 3> s = spatial(file, member(file, t, "scale", "numbers"), n, true);
      for (std::size_t k = 0; k < 3; ++k) {
        spacing[k] *= s[k];
        origin[k] *= s[k];
      }
    } else if (type == "translation") {
      const std::array<double, 3> o =
          spatial(file, member(file, t, "translation", "numbers"), n, false);
      for (std::size_t k = 0; k < 3; ++k) origin[k] += o[k];
    } else if (type != "identity") {
      throw error(file.string() + ": coordinate transformation " + text_of(type) +
                  " is not supported (expected scale, translation or identity)");
    }
  }
}

/// Checks a multiscale's axes: `n` of them, the last three spatial (z, y, x), no other spatial.
void check_axes(const fs::path& file, const json& ms, std::size_t n) {
  if (!ms.contains("axes")) {
    // OME-NGFF 0.1 and 0.2: always t, c, z, y, x.
    if (n != 5) {
      throw error(file.string() + ": a multiscale without \"axes\" (t, c, z, y, x) over " +
                  std::to_string(n) + "-D arrays");
    }
    return;
  }
  const json& axes = ms.at("axes");
  if (!axes.is_array() || axes.size() != n) {
    throw error(file.string() + ": expected " + std::to_string(n) +
                " axes (one per array dimension), found " + text_of(axes));
  }
  for (std::size_t d = 0; d < n; ++d) {
    const json& a = axes.at(d);
    std::string name, type;
    if (a.is_string()) {
      name = a.get<std::string>();
    } else if (a.is_object() && a.contains("name") && a.at("name").is_string()) {
      name = a.at("name").get<std::string>();
      if (a.contains("type") && a.at("type").is_string()) type = a.at("type").get<std::string>();
    } else {
      throw error(file.string() + ": expected an axis name or object, found " + text_of(a));
    }
    const bool space = type.empty() ? (name == "x" || name == "y" || name == "z") : type == "space";
    if (space != (d + 3 >= n)) {
      throw error(file.string() + ": axis " + std::to_string(d) + " (" + detail::quoted(name) +
                  ") " +
                  (space ? "is spatial; expected the spatial axes last (z, y, x)"
                         : "is not spatial; expected the last three axes to be z, y, x"));
    }
  }
}

}  // namespace

index3 zarr_level::dims() const noexcept {
  const std::size_t n = shape.size();
  return {shape[n - 1], shape[n - 2], shape[n - 3]};
}

std::uint64_t zarr_level::chunk_bytes() const noexcept {
  std::uint64_t b = sample_size(type);
  for (const std::int64_t c : chunks) b *= static_cast<std::uint64_t>(c);
  return b;
}

bool is_zarr_directory(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  return fs::exists(dir / ".zattrs", ec) || fs::exists(dir / ".zarray", ec);
}

zarr_image read_zarr_header(const fs::path& dir) {
  zarr_image image;
  std::error_code ec;
  const fs::path attrs = dir / ".zattrs";
  std::optional<json> multiscales;
  if (fs::exists(attrs, ec)) {
    image.files.push_back(attrs);
    const json j = read_json(attrs, "Zarr attributes");
    if (j.is_object() && j.contains("multiscales")) {
      const json& list = j.at("multiscales");
      if (!list.is_array() || list.empty()) {
        throw error(attrs.string() + ": expected \"multiscales\" to be a non-empty list, found " +
                    text_of(list));
      }
      multiscales = list.at(0);
    }
  }
  if (!multiscales) {
    if (!fs::exists(dir / ".zarray", ec)) {
      throw error(dir.string() +
                  ": a Zarr group without \"multiscales\" in .zattrs and without "
                  ".zarray (expected an OME-Zarr image or a Zarr array)");
    }
    image.levels.push_back(read_array(dir, image.files));
  } else {
    const json& ms = *multiscales;
    const json& datasets = member(attrs, ms, "datasets", "the levels, finest first");
    if (!datasets.is_array() || datasets.empty() || datasets.size() > 32) {
      throw error(attrs.string() + ": expected 1 to 32 datasets, found " + text_of(datasets));
    }
    for (const json& d : datasets) {
      const json& path = member(attrs, d, "path", "the level's array directory");
      const std::string p = path.is_string() ? path.get<std::string>() : std::string();
      // A relative path inside the image: no "..", no root, no empty name.
      const fs::path rel(p);
      const bool inside =
          !p.empty() && rel.is_relative() &&
          std::none_of(rel.begin(), rel.end(), [](const fs::path& part) { return part == ".."; });
      if (!inside) {
        throw error(attrs.string() + ": expected a dataset path inside the image, found " +
                    text_of(path));
      }
      zarr_level level = read_array(dir / rel, image.files);
      const std::size_t n = level.shape.size();
      if (d.contains("coordinateTransformations")) {
        transform(attrs, d.at("coordinateTransformations"), n, level.spacing, level.origin);
      }
      if (ms.contains("coordinateTransformations")) {
        transform(attrs, ms.at("coordinateTransformations"), n, level.spacing, level.origin);
      }
      image.levels.push_back(std::move(level));
    }
    check_axes(attrs, ms, image.levels[0].shape.size());
  }
  const zarr_level& finest = image.levels[0];
  const std::size_t n = finest.shape.size();
  std::uint64_t volumes = 1;
  for (std::size_t d = 0; d + 3 < n; ++d) {
    volumes *= static_cast<std::uint64_t>(finest.shape[d]);
    if (volumes > (std::uint64_t{1} << 31)) {
      throw error(finest.dir.string() + ": more than 2^31 volumes along the leading axes");
    }
  }
  image.volumes = static_cast<std::int64_t>(volumes);
  for (const zarr_level& l : image.levels) {
    if (l.shape.size() != n ||
        !std::equal(l.shape.begin(), l.shape.end() - 3, finest.shape.begin())) {
      throw error(l.dir.string() + ": a level whose leading axes differ from the finest's");
    }
  }
  return image;
}

namespace {

/// The decoded bytes of chunk `file` into `out` (chunk_bytes() of them).
void decode_chunk(const zarr_level& a, const fs::path& file, std::vector<std::byte>& out) {
  const std::uint64_t want = a.chunk_bytes();
  input_file in(file, "Zarr chunk");
  const std::uint64_t size = in.size();
  std::uint64_t largest = want;
  switch (a.codec) {
    case zarr_codec::none:
      break;
    case zarr_codec::blosc:
      largest = want + BLOSC_MAX_OVERHEAD;
      break;
    case zarr_codec::zstd:
      largest = ZSTD_compressBound(static_cast<std::size_t>(want));
      break;
    case zarr_codec::zlib:
    case zarr_codec::gzip:
      largest = compressBound(static_cast<uLong>(want)) + 1024;  // gzip's header may name a file
      break;
  }
  if (size > largest || (a.codec == zarr_codec::none && size != want)) {
    throw error(file.string() + ": a chunk of " + std::to_string(size) + " bytes; expected " +
                (a.codec == zarr_codec::none ? "exactly " : "at most ") + std::to_string(largest) +
                " for " + std::to_string(want) + " bytes of samples");
  }
  const std::vector<char> src = in.read_all();
  out.resize(static_cast<std::size_t>(want));
  const auto corrupt = [&](const std::string& why) {
    return error(file.string() + ": corrupt chunk (" + why + ")");
  };
  switch (a.codec) {
    case zarr_codec::none:
      std::memcpy(out.data(), src.data(), out.size());
      return;
    case zarr_codec::blosc: {
      std::size_t nbytes = 0;
      if (blosc_cbuffer_validate(src.data(), src.size(), &nbytes) != 0) {
        throw corrupt("not a blosc buffer");
      }
      if (nbytes != want) {
        throw error(file.string() + ": a blosc chunk of " + std::to_string(nbytes) +
                    " bytes; expected " + std::to_string(want));
      }
      const int got = blosc_decompress_ctx(src.data(), out.data(), out.size(), 1);
      if (got < 0 || static_cast<std::uint64_t>(got) != want) throw corrupt("blosc failed");
      return;
    }
    case zarr_codec::zstd: {
      const std::size_t got = ZSTD_decompress(out.data(), out.size(), src.data(), src.size());
      if (ZSTD_isError(got) != 0) throw corrupt(ZSTD_getErrorName(got));
      if (got != want) {
        throw error(file.string() + ": a zstd chunk of " + std::to_string(got) +
                    " bytes; expected " + std::to_string(want));
      }
      return;
    }
    case zarr_codec::zlib:
    case zarr_codec::gzip: {
      z_stream z{};
      if (inflateInit2(&z, a.codec == zarr_codec::gzip ? 16 + MAX_WBITS : MAX_WBITS) != Z_OK) {
        throw error(file.string() + ": zlib could not start");
      }
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(src.data()));
      z.avail_in = static_cast<uInt>(src.size());
      z.next_out = reinterpret_cast<Bytef*>(out.data());
      z.avail_out = static_cast<uInt>(out.size());
      const int r = inflate(&z, Z_FINISH);
      const uLong got = z.total_out;
      const std::string message = z.msg != nullptr ? z.msg : "";
      inflateEnd(&z);
      if (r == Z_STREAM_END && got == want) return;
      if (r == Z_STREAM_END || r == Z_BUF_ERROR) {
        throw error(
            file.string() + ": a " + (a.codec == zarr_codec::gzip ? "gzip" : "zlib") +
            " chunk of " +
            (r == Z_STREAM_END ? std::to_string(got) : "more than " + std::to_string(want)) +
            " bytes; expected " + std::to_string(want));
      }
      throw corrupt(message.empty() ? "inflate failed" : message);
    }
  }
}

/// The chunk file of chunk indices `index`.
fs::path chunk_path(const zarr_level& a, const std::vector<std::int64_t>& index) {
  if (a.separator == '/') {
    fs::path p = a.dir;
    for (const std::int64_t i : index) p /= std::to_string(i);
    return p;
  }
  std::string key;
  for (std::size_t d = 0; d < index.size(); ++d) {
    if (d > 0) key += '.';
    key += std::to_string(index[d]);
  }
  return a.dir / key;
}

/// Whether `name` is a decimal chunk index (no sign, no leading zero but "0").
bool chunk_number(std::string_view name, std::int64_t& value) {
  if (name.empty() || name.size() > 10 || (name.size() > 1 && name[0] == '0')) return false;
  value = 0;
  for (const char c : name) {
    if (c < '0' || c > '9') return false;
    value = value * 10 + (c - '0');
  }
  return true;
}

/// The chunk files present of the volume whose leading chunk indices `index` holds (its last
/// three entries ignored), found by listing directories: bounded by the files that exist, never
/// by the chunk grid a header declares.
std::uint64_t present_chunks(const zarr_level& a, const std::vector<std::int64_t>& index) {
  const std::size_t n = a.shape.size();
  const auto grid = [&a](std::size_t d) { return (a.shape[d] + a.chunks[d] - 1) / a.chunks[d]; };
  std::uint64_t found = 0;
  std::error_code ec;
  if (a.separator == '/') {
    fs::path dir = a.dir;
    for (std::size_t d = 0; d + 3 < n; ++d) dir /= std::to_string(index[d]);
    // dir/z/y/x, each a chunk index within the grid.
    std::vector<std::pair<fs::path, std::size_t>> stack{{dir, n - 3}};
    while (!stack.empty()) {
      const auto [at, d] = stack.back();
      stack.pop_back();
      for (fs::directory_iterator it(at, ec), end; !ec && it != end; it.increment(ec)) {
        std::int64_t v = 0;
        if (!chunk_number(it->path().filename().string(), v) || v >= grid(d)) continue;
        if (d + 1 == n) {
          found += it->is_regular_file(ec) ? 1U : 0U;
        } else if (it->is_directory(ec)) {
          stack.emplace_back(it->path(), d + 1);
        }
      }
    }
    return found;
  }
  for (fs::directory_iterator it(a.dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::size_t d = 0, from = 0;
    bool match = true;
    while (match && d < n) {
      const std::size_t dot = d + 1 < n ? name.find('.', from) : name.size();
      std::int64_t v = 0;
      match = dot != std::string::npos &&
              chunk_number(std::string_view(name).substr(from, dot - from), v) && v < grid(d) &&
              (d + 3 >= n || v == index[d]);
      from = dot + 1;
      ++d;
    }
    if (match && from == name.size() + 1) found += it->is_regular_file(ec) ? 1U : 0U;
  }
  return found;
}

/// Sample `value` in `type`, as bytes in host order.
std::array<std::byte, 8> sample_bytes(sample_type type, double value) {
  std::array<std::byte, 8> b{};
  const auto put = [&b](auto v) { std::memcpy(b.data(), &v, sizeof v); };
  switch (type) {
    case sample_type::u8:
      put(static_cast<std::uint8_t>(value));
      break;
    case sample_type::i8:
      put(static_cast<std::int8_t>(value));
      break;
    case sample_type::u16:
      put(static_cast<std::uint16_t>(value));
      break;
    case sample_type::i16:
      put(static_cast<std::int16_t>(value));
      break;
    case sample_type::u32:
      put(static_cast<std::uint32_t>(value));
      break;
    case sample_type::i32:
      put(static_cast<std::int32_t>(value));
      break;
    case sample_type::f32:
      put(static_cast<float>(value));
      break;
    case sample_type::f64:
      put(value);
      break;
  }
  return b;
}

}  // namespace

namespace {

/// Where volume `volume` of level `a` lies along the leading axes: its chunk indices (the last
/// three entries 0) and its element offset within those chunks, with a decoded chunk's strides.
struct volume_place {
  std::vector<std::int64_t> index;
  std::vector<std::uint64_t> stride;
  std::uint64_t base = 0;
};

volume_place place_of(const zarr_level& a, std::int64_t volume) {
  const std::size_t n = a.shape.size();
  volume_place p;
  p.index.assign(n, 0);
  p.stride.assign(n, 1);
  if (a.fortran) {
    for (std::size_t d = 1; d < n; ++d) {
      p.stride[d] = p.stride[d - 1] * static_cast<std::uint64_t>(a.chunks[d - 1]);
    }
  } else {
    for (std::size_t d = n - 1; d-- > 0;) {
      p.stride[d] = p.stride[d + 1] * static_cast<std::uint64_t>(a.chunks[d + 1]);
    }
  }
  std::int64_t rest = volume;
  for (std::size_t d = n - 3; d-- > 0;) {
    const std::int64_t at = rest % a.shape[d];
    rest /= a.shape[d];
    p.index[d] = at / a.chunks[d];
    p.base += static_cast<std::uint64_t>(at % a.chunks[d]) * p.stride[d];
  }
  return p;
}

}  // namespace

void check_zarr_chunks(const zarr_image& image, std::size_t level, std::int64_t volume) {
  PROGISO_ASSERT(level < image.levels.size());
  PROGISO_ASSERT(volume >= 0 && volume < image.volumes);
  const zarr_level& a = image.levels[level];
  const std::size_t n = a.shape.size();
  const index3 dims = a.dims();
  const volume_place place = place_of(a, volume);
  // Memory follows the data: the volume is sized only when its chunk files can hold a sixty-fourth
  // of it (missing chunks are fill_value, but a grid of them alone sizes nothing).
  const std::int64_t cz = a.chunks[n - 3], cy = a.chunks[n - 2], cx = a.chunks[n - 1];
  const std::uint64_t grid = static_cast<std::uint64_t>((dims[2] + cz - 1) / cz) *
                             static_cast<std::uint64_t>((dims[1] + cy - 1) / cy) *
                             static_cast<std::uint64_t>((dims[0] + cx - 1) / cx);
  const std::uint64_t present = present_chunks(a, place.index);
  if (present == 0 || grid > 64 * present) {
    throw error(
        a.dir.string() + ": " + std::to_string(present) + " of the " + std::to_string(grid) +
        " chunks of " +
        (image.volumes > 1 ? "volume " + std::to_string(volume) : std::string("the array")) +
        " are present (expected at least one in 64: the data must be there to size a "
        "volume by; chunk files are named like " +
        detail::quoted(chunk_path(a, place.index).lexically_relative(a.dir).string()) + ")");
  }
}

bool read_zarr_planes(const zarr_image& image, std::size_t level, std::int64_t volume,
                      std::int64_t z_begin, std::int64_t z_end, std::span<std::byte> out,
                      const parallel_loop& run, const std::function<bool()>& stop) {
  PROGISO_ASSERT(level < image.levels.size());
  PROGISO_ASSERT(volume >= 0 && volume < image.volumes);
  const zarr_level& a = image.levels[level];
  const std::size_t n = a.shape.size();
  const std::size_t item = sample_size(a.type);
  const index3 dims = a.dims();
  PROGISO_ASSERT(0 <= z_begin && z_begin <= z_end && z_end <= dims[2]);
  const auto nx = static_cast<std::size_t>(dims[0]);
  const auto ny = static_cast<std::size_t>(dims[1]);
  PROGISO_ASSERT(out.size() == nx * ny * static_cast<std::size_t>(z_end - z_begin) * item);
  const volume_place place = place_of(a, volume);
  const std::vector<std::uint64_t>& stride = place.stride;
  const std::array<std::byte, 8> fill = sample_bytes(a.type, a.fill);
  const bool swap = item > 1 && a.big_endian != (std::endian::native == std::endian::big);
  const std::int64_t cz = a.chunks[n - 3], cy = a.chunks[n - 2], cx = a.chunks[n - 1];
  const std::int64_t rows_y = (dims[1] + cy - 1) / cy, rows_x = (dims[0] + cx - 1) / cx;
  // The chunk rows (one z index each) that meet [z_begin, z_end); in one row, each chunk writes
  // its own box of the planes, so the chunks of a row are decoded at once through `run`.
  for (std::int64_t z0 = z_begin / cz * cz; z0 < z_end; z0 += cz) {
    const std::int64_t za = std::max(z0, z_begin), zb = std::min({z_end, z0 + cz, dims[2]});
    std::mutex failed_mutex;
    std::exception_ptr failed;
    std::atomic<bool> stopped{false};
    run_loop(run, static_cast<std::size_t>(rows_y * rows_x), [&](std::size_t k) {
      try {
        if (stopped.load(std::memory_order_relaxed)) return;
        if (stop && stop()) {
          stopped.store(true, std::memory_order_relaxed);
          return;
        }
        std::vector<std::int64_t> index = place.index;
        const std::int64_t y0 = static_cast<std::int64_t>(k) / rows_x * cy;
        const std::int64_t x0 = static_cast<std::int64_t>(k) % rows_x * cx;
        index[n - 3] = z0 / cz;
        index[n - 2] = y0 / cy;
        index[n - 1] = x0 / cx;
        const fs::path file = chunk_path(a, index);
        std::error_code ec;
        const fs::file_status st = fs::symlink_status(file, ec);
        const bool missing = ec || st.type() == fs::file_type::not_found;  // fill_value
        std::vector<std::byte> chunk;
        if (!missing) decode_chunk(a, file, chunk);
        const std::int64_t y1 = std::min(dims[1], y0 + cy), x1 = std::min(dims[0], x0 + cx);
        const auto width = static_cast<std::size_t>(x1 - x0);
        for (std::int64_t z = za; z < zb; ++z) {
          for (std::int64_t y = y0; y < y1; ++y) {
            std::byte* to =
                out.data() +
                ((static_cast<std::size_t>(z - z_begin) * ny + static_cast<std::size_t>(y)) * nx +
                 static_cast<std::size_t>(x0)) *
                    item;
            if (missing) {
              for (std::size_t x = 0; x < width; ++x) std::memcpy(to + x * item, fill.data(), item);
              continue;
            }
            const std::uint64_t from = place.base +
                                       static_cast<std::uint64_t>(z - z0) * stride[n - 3] +
                                       static_cast<std::uint64_t>(y - y0) * stride[n - 2];
            if (stride[n - 1] == 1) {
              std::memcpy(to, chunk.data() + from * item, width * item);
            } else {
              for (std::size_t x = 0; x < width; ++x) {
                std::memcpy(to + x * item, chunk.data() + (from + x * stride[n - 1]) * item, item);
              }
            }
            if (swap) {
              for (std::size_t x = 0; x < width; ++x) {
                std::reverse(to + x * item, to + (x + 1) * item);
              }
            }
          }
        }
      } catch (...) {
        const std::lock_guard<std::mutex> lock(failed_mutex);
        // The first failure in chunk order would need every chunk tried; any one names its file.
        if (!failed) failed = std::current_exception();
        stopped.store(true, std::memory_order_relaxed);
      }
    });
    if (failed) std::rethrow_exception(failed);
    if (stopped.load(std::memory_order_relaxed)) return false;
  }
  return true;
}

std::optional<std::vector<std::byte>> read_zarr_samples(const zarr_image& image, std::size_t level,
                                                        std::int64_t volume,
                                                        const std::function<bool()>& stop) {
  check_zarr_chunks(image, level, volume);
  const zarr_level& a = image.levels[level];
  const index3 dims = a.dims();
  std::vector<std::byte> out(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]) *
                             sample_size(a.type));
  if (!read_zarr_planes(image, level, volume, 0, dims[2], out, {}, stop)) return std::nullopt;
  return out;
}

}  // namespace progiso::detail
