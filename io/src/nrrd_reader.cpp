#include <progiso/io/detail/nrrd_reader.hpp>

#include <algorithm>
#include <bit>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/gzip_input.hpp>
#include <progiso/io/detail/header_text.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t chunk_bytes = 64 * 1024;
constexpr std::size_t max_ascii_token = 1024;           // bytes of one ascii value
constexpr unsigned max_dimension = 16;                  // NRRD_DIM_MAX
constexpr unsigned max_space_dimension = 8;             // NRRD_SPACE_DIM_MAX
constexpr std::int64_t max_volumes = INT32_MAX;         // as --volume and MetaImage
constexpr std::int64_t max_pattern_number = INT32_MAX;  // the %d argument is a C int

// =============================================================================================
// Text helpers.

std::string dims_text(const index3& dims) {
  return std::to_string(dims[0]) + "," + std::to_string(dims[1]) + "," + std::to_string(dims[2]);
}

// =============================================================================================
// Fields: every field of the NRRD format (NRRD0001 … NRRD0005) and its spellings.

enum class field : std::uint8_t {
  content,
  number,
  type,
  block_size,
  dimension,
  space,
  space_dimension,
  sizes,
  spacings,
  thicknesses,
  axis_mins,
  axis_maxs,
  space_directions,
  centers,
  kinds,
  labels,
  units,
  min,
  max,
  old_min,
  old_max,
  endian,
  encoding,
  line_skip,
  byte_skip,
  sample_units,
  space_units,
  space_origin,
  measurement_frame,
  data_file,
};
constexpr std::size_t field_count = static_cast<std::size_t>(field::data_file) + 1;

constexpr std::string_view field_names[field_count] = {
    "content",
    "number",
    "type",
    "block size",
    "dimension",
    "space",
    "space dimension",
    "sizes",
    "spacings",
    "thicknesses",
    "axis mins",
    "axis maxs",
    "space directions",
    "centers",
    "kinds",
    "labels",
    "units",
    "min",
    "max",
    "old min",
    "old max",
    "endian",
    "encoding",
    "line skip",
    "byte skip",
    "sample units",
    "space units",
    "space origin",
    "measurement frame",
    "data file",
};

struct field_spelling {
  std::string_view text;
  field id;
};
// Teem's equivalents: each multi-word name may also be written without its spaces, and
// "centerings" is the older name of "centers".
constexpr field_spelling field_spellings[] = {
    {"content", field::content},
    {"number", field::number},
    {"type", field::type},
    {"block size", field::block_size},
    {"blocksize", field::block_size},
    {"dimension", field::dimension},
    {"space", field::space},
    {"space dimension", field::space_dimension},
    {"spacedimension", field::space_dimension},
    {"sizes", field::sizes},
    {"spacings", field::spacings},
    {"thicknesses", field::thicknesses},
    {"axis mins", field::axis_mins},
    {"axismins", field::axis_mins},
    {"axis maxs", field::axis_maxs},
    {"axismaxs", field::axis_maxs},
    {"space directions", field::space_directions},
    {"spacedirections", field::space_directions},
    {"centers", field::centers},
    {"centerings", field::centers},
    {"kinds", field::kinds},
    {"labels", field::labels},
    {"units", field::units},
    {"min", field::min},
    {"max", field::max},
    {"old min", field::old_min},
    {"oldmin", field::old_min},
    {"old max", field::old_max},
    {"oldmax", field::old_max},
    {"endian", field::endian},
    {"encoding", field::encoding},
    {"line skip", field::line_skip},
    {"lineskip", field::line_skip},
    {"byte skip", field::byte_skip},
    {"byteskip", field::byte_skip},
    {"sample units", field::sample_units},
    {"sampleunits", field::sample_units},
    {"space units", field::space_units},
    {"spaceunits", field::space_units},
    {"space origin", field::space_origin},
    {"spaceorigin", field::space_origin},
    {"measurement frame", field::measurement_frame},
    {"measurementframe", field::measurement_frame},
    {"data file", field::data_file},
    {"datafile", field::data_file},
};

std::optional<field> find_field(std::string_view name) {
  const std::string key = lower(name);
  for (const field_spelling& s : field_spellings) {
    if (s.text == key) return s.id;
  }
  return std::nullopt;
}

struct type_spelling {
  std::string_view text;
  std::optional<sample_type> type;  ///< nullopt: a NRRD type progiso does not support
};
constexpr type_spelling type_spellings[] = {
    {"signed char", sample_type::i8},
    {"int8", sample_type::i8},
    {"int8_t", sample_type::i8},
    {"uchar", sample_type::u8},
    {"unsigned char", sample_type::u8},
    {"uint8", sample_type::u8},
    {"uint8_t", sample_type::u8},
    {"short", sample_type::i16},
    {"short int", sample_type::i16},
    {"signed short", sample_type::i16},
    {"signed short int", sample_type::i16},
    {"int16", sample_type::i16},
    {"int16_t", sample_type::i16},
    {"ushort", sample_type::u16},
    {"unsigned short", sample_type::u16},
    {"unsigned short int", sample_type::u16},
    {"uint16", sample_type::u16},
    {"uint16_t", sample_type::u16},
    {"int", sample_type::i32},
    {"signed int", sample_type::i32},
    {"int32", sample_type::i32},
    {"int32_t", sample_type::i32},
    {"uint", sample_type::u32},
    {"unsigned int", sample_type::u32},
    {"uint32", sample_type::u32},
    {"uint32_t", sample_type::u32},
    {"float", sample_type::f32},
    {"double", sample_type::f64},
    {"longlong", std::nullopt},
    {"long long", std::nullopt},
    {"long long int", std::nullopt},
    {"signed long long", std::nullopt},
    {"signed long long int", std::nullopt},
    {"int64", std::nullopt},
    {"int64_t", std::nullopt},
    {"ulonglong", std::nullopt},
    {"unsigned long long", std::nullopt},
    {"unsigned long long int", std::nullopt},
    {"uint64", std::nullopt},
    {"uint64_t", std::nullopt},
    {"block", std::nullopt},
};

struct space_spelling {
  std::string_view text;  ///< lower case
  unsigned dimension;
};
constexpr space_spelling space_spellings[] = {
    {"right-up", 2},
    {"right up", 2},
    {"right-down", 2},
    {"right down", 2},
    {"right-anterior-superior", 3},
    {"right anterior superior", 3},
    {"rightanteriorsuperior", 3},
    {"ras", 3},
    {"left-anterior-superior", 3},
    {"left anterior superior", 3},
    {"leftanteriorsuperior", 3},
    {"las", 3},
    {"left-posterior-superior", 3},
    {"left posterior superior", 3},
    {"leftposteriorsuperior", 3},
    {"lps", 3},
    {"right-anterior-superior-time", 4},
    {"right anterior superior time", 4},
    {"rightanteriorsuperiortime", 4},
    {"rast", 4},
    {"left-anterior-superior-time", 4},
    {"left anterior superior time", 4},
    {"leftanteriorsuperiortime", 4},
    {"last", 4},
    {"left-posterior-superior-time", 4},
    {"left posterior superior time", 4},
    {"leftposteriorsuperiortime", 4},
    {"lpst", 4},
    {"scanner-xyz", 3},
    {"scanner-xyz-time", 4},
    {"scanner-xyzt", 4},
    {"3d-right-handed", 3},
    {"3d right handed", 3},
    {"3drighthanded", 3},
    {"3d-left-handed", 3},
    {"3d left handed", 3},
    {"3dlefthanded", 3},
    {"3d-right-handed-time", 4},
    {"3d right handed time", 4},
    {"3drighthandedtime", 4},
    {"3d-left-handed-time", 4},
    {"3d left handed time", 4},
    {"3dlefthandedtime", 4},
};

// =============================================================================================
// Header parsing, pass 1: the lines, split into fields (each kept once, with its line number),
// key/value pairs (dropped) and comments (dropped).

struct field_value {
  std::string text;  ///< after "name: ", blanks trimmed
  std::size_t line = 0;
};

struct header_lines {
  std::array<std::optional<field_value>, field_count> fields;
  std::vector<std::string> list_names;  ///< the lines after "data file: LIST"
  bool empty_line = false;              ///< the header ended at an empty line (not at EOF)
  std::uint64_t data_offset = 0;
};

bool is_list_form(std::string_view value) {
  const std::vector<std::string_view> w = words(value);
  return !w.empty() && w[0] == "LIST";
}

void check_magic(const line_reader& lines, const fs::path& file) {
  const std::string_view head = lines.head(8);
  const bool nrrd = head.size() == 8 && head.substr(0, 7) == "NRRD000";
  if (nrrd && head[7] >= '1' && head[7] <= '5') return;
  if (nrrd) {
    throw error(file.string() + ": unsupported NRRD format version " + detail::quoted(head) +
                " (expected NRRD0001 to NRRD0005)");
  }
  throw error(file.string() + ": not a NRRD file (expected the magic \"NRRD0001\" to " +
              "\"NRRD0005\", found " + detail::quoted(head) + ")");
}

header_lines read_header_lines(input_file& in) {
  const fs::path& file = in.path();
  line_reader lines(in, "NRRD");
  check_magic(lines, file);
  std::string line;
  lines.next(line);
  if (line.size() != 8) {
    throw error(file.string() + ": expected the NRRD magic alone on the first line, found " +
                detail::quoted(line));
  }

  header_lines out;
  while (lines.next(line)) {
    if (line.empty()) {
      out.empty_line = true;
      break;
    }
    if (line.front() == '#') continue;
    const std::string_view text(line);
    const std::size_t colon = text.find(": ");
    const std::optional<field> id =
        colon == std::string_view::npos ? std::nullopt : find_field(text.substr(0, colon));
    if (!id) {
      // A key/value pair: accepted and dropped, so that any number of them costs linear time.
      if (text.find(":=") != std::string_view::npos) continue;
      if (colon != std::string_view::npos) {
        throw error(file.string() + ": unknown NRRD field " +
                    detail::quoted(text.substr(0, colon)) + " on header line " +
                    std::to_string(lines.number()));
      }
      throw error(file.string() + ": expected \"field: value\" or \"key:=value\" on NRRD " +
                  "header line " + std::to_string(lines.number()) + ", found " +
                  detail::quoted(text));
    }
    auto& slot = out.fields[static_cast<std::size_t>(*id)];
    if (slot) {
      throw error(file.string() + ": NRRD field \"" +
                  std::string(field_names[static_cast<std::size_t>(*id)]) +
                  "\" is given twice (header lines " + std::to_string(slot->line) + " and " +
                  std::to_string(lines.number()) + ")");
    }
    slot = field_value{std::string(trim(text.substr(colon + 2))), lines.number()};

    if (*id == field::data_file && is_list_form(slot->text)) {
      // "data file: LIST": every further line names one data file, to the end of the file.
      std::size_t name_bytes = 0;
      while (lines.next(line)) {
        if (line.empty()) continue;
        if (out.list_names.size() == nrrd_max_data_files) {
          throw error(file.string() + ": NRRD \"data file: LIST\" names more than " +
                      std::to_string(nrrd_max_data_files) + " data files");
        }
        name_bytes += line.size();
        if (name_bytes > nrrd_max_name_bytes) {
          throw error(file.string() + ": NRRD \"data file: LIST\" names take more than " +
                      std::to_string(nrrd_max_name_bytes) + " bytes");
        }
        out.list_names.push_back(line);
      }
      break;
    }
  }
  out.data_offset = lines.offset();
  return out;
}

// =============================================================================================
// Header parsing, pass 2: each field checked and reduced to a nrrd_header.

class header_parser {
 public:
  header_parser(const fs::path& file, header_lines lines) : file_(file), lines_(std::move(lines)) {}

  nrrd_header run() {
    nrrd_header h;
    h.type = parse_type();
    parse_dimension();
    parse_sizes();
    h.encoding = parse_encoding();
    parse_byte_order(h);
    parse_skips(h);
    parse_space();
    h.dims = choose_axes(h);
    h.spacing = parse_spacing();
    h.origin = parse_origin();
    h.world = parse_world(h.origin);
    check_descriptive_fields();
    h.data_files = parse_data_files();

    if (h.data_files.empty() && !lines_.empty_line) {
      throw error(file_.string() + ": NRRD header ends at the end of the file without a " +
                  "\"data file\" field (attached data must follow an empty line)");
    }
    h.data_offset = lines_.data_offset;
    return h;
  }

 private:
  [[nodiscard]] const field_value* get(field f) const {
    const auto& slot = lines_.fields[static_cast<std::size_t>(f)];
    return slot ? &*slot : nullptr;
  }
  const field_value& require(field f) const {
    const field_value* v = get(f);
    if (v == nullptr) {
      throw error(file_.string() + ": missing required NRRD field \"" +
                  std::string(field_names[static_cast<std::size_t>(f)]) + "\"");
    }
    return *v;
  }
  /// A field the caller knows is present.
  const field_value& given(field f) const {
    const field_value* v = get(f);
    PROGISO_ASSERT(v != nullptr);
    if (v == nullptr) throw error(file_.string() + ": internal error: NRRD field not present");
    return *v;
  }
  /// Throws "FILE: NRRD field "NAME" (header line N): WHAT".
  [[noreturn]] void fail(field f, const std::string& what) const {
    const field_value* v = get(f);
    throw error(file_.string() + ": NRRD field \"" +
                std::string(field_names[static_cast<std::size_t>(f)]) + "\" (header line " +
                std::to_string(v != nullptr ? v->line : 0) + "): " + what);
  }

  void parse_byte_order(nrrd_header& h) const {
    if (const field_value* v = get(field::endian)) {
      const std::string e = lower(v->text);
      if (e != "little" && e != "big") {
        fail(field::endian, "expected little or big, found " + detail::quoted(v->text));
      }
      h.big_endian = e == "big";
    } else if (sample_size(h.type) > 1 && h.encoding != nrrd_encoding::ascii) {
      throw error(file_.string() + ": NRRD field \"endian\" is required for " +
                  std::string(to_string(h.type)) + " samples in " +
                  std::string(to_string(h.encoding)) + " encoding");
    }
  }

  void parse_skips(nrrd_header& h) const {
    if (const field_value* v = get(field::line_skip)) {
      const auto n = to_integer<std::uint64_t>(v->text);
      if (!n) fail(field::line_skip, "expected an integer ≥ 0, found " + detail::quoted(v->text));
      h.line_skip = *n;
    }
    if (const field_value* v = get(field::byte_skip)) {
      const auto n = to_integer<std::int64_t>(v->text);
      if (!n || *n < -1) {
        fail(field::byte_skip, "expected an integer ≥ -1 (-1: the data ends the file), found " +
                                   detail::quoted(v->text));
      }
      h.byte_skip = *n;
      if (*n == -1 && h.encoding != nrrd_encoding::raw) {
        const std::string what =
            "-1 (the data ends the file) is supported with raw encoding only, found " +
            std::string(to_string(h.encoding)) + " encoding";
        fail(field::byte_skip, what);
      }
    }
  }

  sample_type parse_type() const {
    const field_value& v = require(field::type);
    const std::string key = lower(v.text);
    for (const type_spelling& s : type_spellings) {
      if (s.text != key) continue;
      if (!s.type) {
        throw error(file_.string() + ": unsupported NRRD sample type " + detail::quoted(v.text) +
                    " (expected one of u8 i8 u16 i16 u32 i32 f32 f64)");
      }
      return *s.type;
    }
    fail(field::type, "unknown sample type " + detail::quoted(v.text));
  }

  void parse_dimension() {
    const field_value& v = require(field::dimension);
    const auto d = to_integer<unsigned>(v.text);
    if (!d || *d < 1 || *d > max_dimension) {
      fail(field::dimension, "expected an integer from 1 to " + std::to_string(max_dimension) +
                                 ", found " + detail::quoted(v.text));
    }
    dimension_ = *d;
  }

  /// Every axis's size (sizes_), checked for count and syntax.
  void parse_sizes() {
    const field_value& v = require(field::sizes);
    const std::vector<std::string_view> w = words(v.text);
    if (w.size() != dimension_) {
      fail(field::sizes, "expected " + std::to_string(dimension_) +
                             " sizes (the dimension), found " + detail::quoted(v.text));
    }
    for (std::string_view s : w) {
      const auto n = to_integer<std::uint64_t>(s);
      if (!n)
        fail(field::sizes, "cannot parse " + detail::quoted(s) + " as an unsigned 64-bit integer");
      sizes_.push_back(*n);
    }
    if (dimension_ != 3 && dimension_ != 4) {
      throw error(file_.string() + ": expected a 3-D NRRD array (or a 4-D one: a series of " +
                  "volumes), found dimension " + std::to_string(dimension_));
    }
  }

  /// Whether an axis kind is a non-spatial one (a list of values, vector components, colours,
  /// time points): anything but "domain" and "space" (and the unknown "???" and "none").
  static bool series_kind(std::string_view kind) {
    const std::string k = lower(kind);
    return k != "domain" && k != "space" && k != "???" && k != "none";
  }

  /// A 4-D array's series axis: the one axis whose kind is not spatial, else the one whose
  /// space direction is "none", else the last; it must be the first or the last.
  unsigned series_axis() const {
    std::vector<unsigned> found;
    // A kinds field of the wrong length is refused later, by the descriptive fields' check.
    if (const field_value* v = get(field::kinds); v != nullptr && words(v->text).size() == 4) {
      const std::vector<std::string_view> k = words(v->text);
      for (unsigned a = 0; a < k.size(); ++a) {
        if (series_kind(k[a])) found.push_back(a);
      }
      if (found.size() > 1) {
        fail(field::kinds, "names " + std::to_string(found.size()) + " non-spatial axes in " +
                               detail::quoted(v->text) +
                               ": a 4-D array must have one (the series of volumes)");
      }
    }
    if (found.empty() && get(field::space_directions) != nullptr) {
      const std::vector<std::vector<double>> d = parse_vectors(field::space_directions, 4);
      for (unsigned a = 0; a < 4; ++a) {
        if (d[a].empty()) found.push_back(a);
      }
      if (found.size() != 1) {
        fail(field::space_directions,
             "gives " + std::to_string(4 - found.size()) +
                 " directions: a 4-D array needs 3 and \"none\" for its series axis");
      }
    }
    const unsigned axis = found.empty() ? 3u : found.front();
    if (axis != 0 && axis != 3) {
      throw error(file_.string() + ": the series axis of a 4-D NRRD array is axis " +
                  std::to_string(axis) + " (sizes " + detail::quoted(given(field::sizes).text) +
                  "): progiso reads a series whose volumes follow each other (the last axis) or " +
                  "alternate sample by sample (the first)");
    }
    return axis;
  }

  /// The grid's sizes (the spatial axes), and a 4-D array's volumes.
  index3 choose_axes(nrrd_header& h) {
    if (dimension_ == 4) {
      series_axis_ = series_axis();
      const std::uint64_t n = sizes_[series_axis_];
      if (n < 1 || n > static_cast<std::uint64_t>(max_volumes)) {
        throw error(file_.string() + ": the series axis of the NRRD array holds " +
                    std::to_string(n) + " volumes, expected 1 to " + std::to_string(max_volumes));
      }
      h.volumes = static_cast<std::int64_t>(n);
      h.interleaved = series_axis_ == 0 && n > 1;
    }
    std::vector<std::uint64_t> sizes;
    for (unsigned a = 0; a < dimension_; ++a) {
      if (a != series_axis_) sizes.push_back(sizes_[a]);
    }
    const std::string listed =
        std::to_string(sizes[0]) + "," + std::to_string(sizes[1]) + "," + std::to_string(sizes[2]);
    for (std::uint64_t s : sizes) {
      if (s < 2) {
        throw error(file_.string() + ": expected every axis of the NRRD array to have at least " +
                    "2 samples, found sizes " + listed);
      }
    }
    for (std::uint64_t s : sizes) {
      if (s > static_cast<std::uint64_t>(nrrd_max_axis_size)) {
        throw error(file_.string() + ": NRRD axis sizes above " +
                    std::to_string(nrrd_max_axis_size) + " are not supported, found sizes " +
                    listed);
      }
    }
    return {static_cast<std::int64_t>(sizes[0]), static_cast<std::int64_t>(sizes[1]),
            static_cast<std::int64_t>(sizes[2])};
  }

  /// The three spatial axes' entries of a per-axis list (every axis's).
  template <class T>
  std::vector<T> spatial(std::vector<T> all) const {
    if (dimension_ == 4) all.erase(all.begin() + series_axis_);
    return all;
  }

  nrrd_encoding parse_encoding() const {
    const field_value& v = require(field::encoding);
    const std::string e = lower(v.text);
    if (e == "raw") return nrrd_encoding::raw;
    if (e == "gzip" || e == "gz") return nrrd_encoding::gzip;
    if (e == "ascii" || e == "text" || e == "txt") return nrrd_encoding::ascii;
    if (e == "hex") return nrrd_encoding::hex;
    if (e == "bzip2" || e == "bz2" || e == "zrl") {
      throw error(file_.string() + ": unsupported NRRD encoding " + detail::quoted(v.text) +
                  " (expected raw, gzip, ascii or hex)");
    }
    fail(field::encoding,
         "unknown encoding " + detail::quoted(v.text) + " (expected raw, gzip, ascii or hex)");
  }

  void parse_space() {
    const field_value* space = get(field::space);
    const field_value* dim = get(field::space_dimension);
    if (space != nullptr && dim != nullptr) {
      fail(field::space_dimension, "cannot be given together with the field \"space\"");
    }
    if (space != nullptr) {
      const std::string key = lower(space->text);
      for (const space_spelling& s : space_spellings) {
        if (s.text == key) space_dimension_ = s.dimension;
      }
      if (space_dimension_ == 0) fail(field::space, "unknown space " + detail::quoted(space->text));
    }
    if (dim != nullptr) {
      const auto d = to_integer<unsigned>(dim->text);
      if (!d || *d < 1 || *d > max_space_dimension) {
        fail(field::space_dimension, "expected an integer from 1 to " +
                                         std::to_string(max_space_dimension) + ", found " +
                                         detail::quoted(dim->text));
      }
      space_dimension_ = *d;
    }
  }

  /// `count` vectors of space_dimension_ components each, written "(a,b,c)" or "none" and
  /// separated by blanks; a "none" vector is empty.
  std::vector<std::vector<double>> parse_vectors(field f, std::size_t count) const {
    const field_value& v = given(f);
    if (space_dimension_ == 0) {
      fail(f, "needs the field \"space\" or \"space dimension\"");
    }
    const std::string_view text = v.text;
    std::vector<std::vector<double>> out;
    std::size_t i = 0;
    for (;;) {
      while (i < text.size() && is_blank(text[i])) ++i;
      if (i == text.size()) break;
      if (out.size() == count) {
        fail(f, "expected " + std::to_string(count) + " vectors, found more in " +
                    detail::quoted(text));
      }
      if (text.substr(i, 4) == "none" && (i + 4 == text.size() || is_blank(text[i + 4]))) {
        out.emplace_back();
        i += 4;
        continue;
      }
      const std::size_t close = text.find(')', i);
      if (text[i] != '(' || close == std::string_view::npos) {
        fail(f, "expected \"(x,y,...)\" or \"none\", found " + detail::quoted(text.substr(i)));
      }
      const std::string_view inner = text.substr(i + 1, close - i - 1);
      std::vector<double> vec;
      std::size_t start = 0;
      for (;;) {
        const std::size_t comma = inner.find(',', start);
        const std::string_view part = trim(inner.substr(start, comma - start));
        const auto x = to_real<double>(part);
        if (!x) fail(f, "cannot parse " + detail::quoted(part) + " as a number");
        vec.push_back(*x);
        if (comma == std::string_view::npos) break;
        start = comma + 1;
      }
      if (vec.size() != space_dimension_) {
        fail(f, "expected " + std::to_string(space_dimension_) +
                    " components (the space dimension), found " +
                    detail::quoted(text.substr(i, close + 1 - i)));
      }
      out.push_back(std::move(vec));
      i = close + 1;
    }
    if (out.size() != count) {
      fail(f, "expected " + std::to_string(count) + " vectors, found " +
                  std::to_string(out.size()) + " in " + detail::quoted(text));
    }
    return out;
  }

  /// `count` blank-separated numbers; "nan", "unknown" and "none" give NaN.
  std::vector<double> parse_numbers(field f, std::size_t count) const {
    const field_value& v = given(f);
    const std::vector<std::string_view> w = words(v.text);
    if (w.size() != count) {
      fail(f, "expected " + std::to_string(count) + " numbers, found " + detail::quoted(v.text));
    }
    std::vector<double> out;
    for (std::string_view s : w) {
      const std::string key = lower(s);
      if (key == "unknown" || key == "none") {
        out.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      const auto x = to_real<double>(s);
      if (!x) fail(f, "cannot parse " + detail::quoted(s) + " as a number");
      out.push_back(*x);
    }
    return out;
  }

  /// Per axis: the length of its "space directions" vector, else the magnitude of its
  /// "spacings" entry; 1 where that is unknown, zero or not finite.
  std::array<double, 3> parse_spacing() const {
    std::array<double, 3> spacing{1.0, 1.0, 1.0};
    std::vector<double> scalar(3, std::numeric_limits<double>::quiet_NaN());
    if (get(field::spacings) != nullptr) {
      scalar = spatial(parse_numbers(field::spacings, dimension_));
    }
    std::vector<std::vector<double>> directions(3);
    if (get(field::space_directions) != nullptr) {
      directions = spatial(parse_vectors(field::space_directions, dimension_));
      if (dimension_ == 4 && !parse_vectors(field::space_directions, 4)[series_axis_].empty()) {
        fail(field::space_directions, "gives the series axis " + std::to_string(series_axis_) +
                                          " a direction: expected \"none\" there");
      }
    }
    for (std::size_t a = 0; a < 3; ++a) {
      double s = std::fabs(scalar[a]);
      if (!directions[a].empty()) {
        double sum = 0.0;
        for (double c : directions[a]) sum += c * c;
        s = std::sqrt(sum);
      }
      if (std::isfinite(s) && s > 0.0) spacing[a] = s;
    }
    return spacing;
  }

  /// The index-to-space map of nrrd_header::world, when the header declares one.
  std::optional<index_to_world> parse_world(const std::array<double, 3>& origin) const {
    if (get(field::space_directions) == nullptr || space_dimension_ != 3) return std::nullopt;
    const std::vector<std::vector<double>> directions =
        spatial(parse_vectors(field::space_directions, dimension_));
    index_to_world w;
    for (std::size_t c = 0; c < 3; ++c) {
      if (directions.size() <= c || directions[c].size() != 3) return std::nullopt;
      for (std::size_t r = 0; r < 3; ++r) {
        if (!std::isfinite(directions[c][r])) return std::nullopt;
        w.m[r][c] = directions[c][r];
      }
    }
    for (std::size_t r = 0; r < 3; ++r) w.m[r][3] = origin[r];
    if (w.determinant() == 0.0) return std::nullopt;
    return w;
  }

  /// The first three components of "space origin" that are finite, else 0.
  std::array<double, 3> parse_origin() const {
    std::array<double, 3> origin{0.0, 0.0, 0.0};
    if (get(field::space_origin) == nullptr) return origin;
    const std::vector<std::vector<double>> o = parse_vectors(field::space_origin, 1);
    for (std::size_t a = 0; a < std::min<std::size_t>(3, o[0].size()); ++a) {
      if (std::isfinite(o[0][a])) origin[a] = o[0][a];
    }
    return origin;
  }

  /// `count` blank-separated double-quoted strings (\" inside).
  void check_quoted_strings(field f, std::size_t count) const {
    const std::string_view text = given(f).text;
    std::size_t found = 0;
    std::size_t i = 0;
    for (;;) {
      while (i < text.size() && is_blank(text[i])) ++i;
      if (i == text.size()) break;
      if (text[i] != '"')
        fail(f, "expected double-quoted strings, found " + detail::quoted(text.substr(i)));
      ++i;
      while (i < text.size() && text[i] != '"') {
        i += text[i] == '\\' && i + 1 < text.size() ? 2u : 1u;
      }
      if (i >= text.size()) fail(f, "a string has no closing '\"' in " + detail::quoted(text));
      ++i;
      ++found;
    }
    if (found != count) {
      fail(f, "expected " + std::to_string(count) + " strings, found " + std::to_string(found));
    }
  }

  /// The fields progiso does not use: their syntax is checked (counts, numbers, quotes),
  /// their values are dropped.
  void check_descriptive_fields() const {
    for (field f : {field::thicknesses, field::axis_mins, field::axis_maxs}) {
      if (get(f) != nullptr) (void)parse_numbers(f, dimension_);
    }
    for (field f : {field::old_min, field::old_max}) {
      if (get(f) != nullptr) (void)parse_numbers(f, 1);
    }
    for (field f : {field::kinds, field::centers}) {
      if (const field_value* v = get(f); v != nullptr && words(v->text).size() != dimension_) {
        fail(f,
             "expected " + std::to_string(dimension_) + " words, found " + detail::quoted(v->text));
      }
    }
    for (field f : {field::labels, field::units}) {
      if (get(f) != nullptr) check_quoted_strings(f, dimension_);
    }
    if (get(field::space_units) != nullptr) {
      if (space_dimension_ == 0) {
        fail(field::space_units, "needs the field \"space\" or \"space dimension\"");
      }
      check_quoted_strings(field::space_units, space_dimension_);
    }
    if (get(field::measurement_frame) != nullptr) {
      (void)parse_vectors(field::measurement_frame, space_dimension_);
    }
    if (const field_value* v = get(field::block_size);
        v != nullptr && !to_integer<std::uint64_t>(v->text)) {
      fail(field::block_size,
           "cannot parse " + detail::quoted(v->text) + " as an unsigned integer");
    }
  }

  // ------------------------------------------------------------------------------------------
  // data file

  /// Parses a "%d" pattern; nullopt when `text` has no conversion (a plain name, "%%" kept).
  std::optional<name_pattern> parse_pattern(std::string_view text) const {
    std::string problem;
    std::optional<name_pattern> p = parse_name_pattern(text, problem);
    if (!problem.empty()) fail(field::data_file, problem);
    return p;
  }

  /// The subdimension of a LIST or pattern form: 1 to the dimension, default one less (a slice
  /// of the slowest axis per file).
  unsigned parse_subdimension(std::string_view text) const {
    const auto d = to_integer<unsigned>(text);
    if (!d || *d < 1 || *d > dimension_) {
      fail(field::data_file, "expected a data file dimension from 1 to " +
                                 std::to_string(dimension_) + ", found " + detail::quoted(text));
    }
    return *d;
  }

  /// Checks that `count` files of `subdim`-dimensional pieces make up the array.
  void check_pieces(std::uint64_t count, unsigned subdim) const {
    std::string listed;
    for (std::uint64_t n : sizes_) listed += (listed.empty() ? "" : ",") + std::to_string(n);
    if (subdim < dimension_) {
      std::uint64_t pieces = 1;
      for (unsigned a = subdim; a < dimension_; ++a) pieces *= sizes_[a];
      if (count != pieces) {
        fail(field::data_file, "names " + std::to_string(count) + " data files, but sizes " +
                                   listed + " make " + std::to_string(pieces) + " " +
                                   std::to_string(subdim) + "-D pieces");
      }
    } else {
      const std::uint64_t slices = sizes_[dimension_ - 1];
      if (count > slices || slices % count != 0) {
        fail(field::data_file, "names " + std::to_string(count) + " data files of " +
                                   std::to_string(dimension_) +
                                   "-D pieces, which do not divide the " + std::to_string(slices) +
                                   " slices of the slowest axis");
      }
    }
  }

  fs::path resolve(std::string_view name) const {
    if (name == "-") {
      fail(field::data_file, "\"-\" (standard input) is not supported");
    }
    const fs::path p{std::string(name)};
    return p.is_absolute() ? p : file_.parent_path() / p;
  }

  std::vector<fs::path> parse_data_files() const {
    const field_value* v = get(field::data_file);
    if (v == nullptr) return {};
    const std::vector<std::string_view> w = words(v->text);
    if (w.empty()) fail(field::data_file, "expected a file name, found nothing");
    const std::size_t dir_bytes = file_.parent_path().native().size() + 1;
    std::vector<fs::path> files;

    if (w[0] == "LIST") {
      if (w.size() > 2) {
        fail(field::data_file, "expected \"LIST [subdim]\", found " + detail::quoted(v->text));
      }
      const unsigned subdim = w.size() == 2 ? parse_subdimension(w[1]) : dimension_ - 1;
      if (lines_.list_names.empty()) fail(field::data_file, "LIST is followed by no file names");
      check_pieces(lines_.list_names.size(), subdim);
      std::size_t bytes = 0;
      for (const std::string& name : lines_.list_names) bytes += dir_bytes + name.size();
      if (bytes > nrrd_max_name_bytes) {
        fail(field::data_file, "the resolved data file names take more than " +
                                   std::to_string(nrrd_max_name_bytes) + " bytes");
      }
      files.reserve(lines_.list_names.size());
      for (const std::string& name : lines_.list_names) files.push_back(resolve(name));
      return files;
    }

    const std::optional<name_pattern> pattern = parse_pattern(w[0]);
    if (!pattern) {
      files.push_back(resolve(v->text));
      return files;
    }
    if (w.size() != 4 && w.size() != 5) {
      fail(field::data_file,
           "expected \"PATTERN MIN MAX STEP [SUBDIM]\", found " + detail::quoted(v->text));
    }
    std::array<std::int64_t, 3> mms{};
    for (std::size_t k = 0; k < 3; ++k) {
      const auto n = to_integer<std::int64_t>(w[k + 1]);
      if (!n || *n < -max_pattern_number - 1 || *n > max_pattern_number) {
        fail(field::data_file, "cannot parse " + detail::quoted(w[k + 1]) + " as a 32-bit integer");
      }
      mms[k] = *n;
    }
    const auto [first, last, step] = mms;
    if (step == 0) fail(field::data_file, "the file number step must not be 0");
    if ((last > first && step < 0) || (last < first && step > 0)) {
      fail(field::data_file, "file number " + std::to_string(last) + " is not reached from " +
                                 std::to_string(first) + " by step " + std::to_string(step));
    }
    const auto count = static_cast<std::uint64_t>((last - first) / step + 1);
    if (count > nrrd_max_data_files) {
      fail(field::data_file, "the pattern names " + std::to_string(count) +
                                 " data files, more than the " +
                                 std::to_string(nrrd_max_data_files) + " supported");
    }
    const unsigned subdim = w.size() == 5 ? parse_subdimension(w[4]) : dimension_ - 1;
    check_pieces(count, subdim);
    const std::uint64_t bytes =
        count * (dir_bytes + pattern->prefix.size() + pattern->suffix.size() + 11 + pattern->width);
    if (bytes > nrrd_max_name_bytes) {
      fail(field::data_file, "the expanded data file names take more than " +
                                 std::to_string(nrrd_max_name_bytes) + " bytes");
    }
    files.reserve(static_cast<std::size_t>(count));
    for (std::int64_t i = first; step > 0 ? i <= last : i >= last; i += step) {
      files.push_back(resolve(
          pattern->prefix + format_number(i, pattern->zero_pad, pattern->width) + pattern->suffix));
    }
    return files;
  }

  const fs::path& file_;
  header_lines lines_;
  unsigned dimension_ = 0;
  unsigned space_dimension_ = 0;
  std::vector<std::uint64_t> sizes_;  ///< every axis's
  unsigned series_axis_ = 4;          ///< a 4-D array's series axis (4: none)
};

// =============================================================================================
// Data: capacity checks (before allocating), then decoding straight into the sample buffer.

std::string encoding_bound(nrrd_encoding e) {
  switch (e) {
    case nrrd_encoding::raw:
      return "";
    case nrrd_encoding::gzip:
    case nrrd_encoding::zlib:
      return "; " + std::string(to_string(e)) + " expands at most " +
             std::to_string(gzip_max_ratio) + ":1";
    case nrrd_encoding::ascii:
      return "; ascii takes at least 2 bytes per value";
    case nrrd_encoding::hex:
      return "; hex takes 2 digits per byte";
  }
  return "";
}

/// "X,Y,Z", and " × N volumes" for a series.
std::string shape_text(const nrrd_header& h) {
  return dims_text(h.dims) +
         (h.volumes > 1 ? " × " + std::to_string(h.volumes) + " volumes" : std::string());
}

struct data_plan {
  const nrrd_header& header;
  std::uint64_t total = 0;  ///< declared bytes
  std::uint64_t piece = 0;  ///< bytes per data file
  std::size_t files = 1;
};

/// Throws unless the data in `in` from `start` can hold one piece. Adds the bytes of data
/// found to `found`.
void check_capacity(const data_plan& plan, input_file& in, std::uint64_t start,
                    std::uint64_t& found) {
  const nrrd_header& h = plan.header;
  std::uint64_t avail = in.size() > start ? in.size() - start : 0;
  avail -= std::min(avail, h.line_skip);  // every skipped line holds at least its "\n"
  if (h.byte_skip > 0 && !deflated(h.encoding)) {
    avail -= std::min(avail, static_cast<std::uint64_t>(h.byte_skip));
  }
  found += avail;
  bool fits = true;
  switch (h.encoding) {
    case nrrd_encoding::raw:
      fits = avail >= plan.piece;
      break;
    case nrrd_encoding::gzip:
    case nrrd_encoding::zlib: {
      const std::uint64_t need =
          plan.piece + static_cast<std::uint64_t>(std::max<std::int64_t>(h.byte_skip, 0));
      fits = gzip_can_hold(avail, need);
      break;
    }
    case nrrd_encoding::ascii:
      fits = avail >= 2 * (plan.piece / sample_size(h.type)) - 1;
      break;
    case nrrd_encoding::hex:
      fits = avail / 2 >= plan.piece;
      break;
  }
  if (fits) return;
  std::string what = in.path().string() + ": the " + std::to_string(avail) + " bytes of " +
                     std::string(to_string(h.encoding)) + " data cannot hold ";
  if (plan.files > 1) {
    what += "this file's share, " + std::to_string(plan.piece) + " bytes, of ";
  }
  what += "the declared " + std::to_string(plan.total) + " bytes (sizes " + shape_text(h) + " of " +
          std::string(to_string(h.type));
  if (plan.files > 1) what += " in " + std::to_string(plan.files) + " data files";
  throw error(what + encoding_bound(h.encoding) + ")");
}

[[noreturn]] void data_ends(std::string_view format, const input_file& in, std::uint64_t got,
                            std::uint64_t want, std::string_view why = {}) {
  throw error(in.path().string() + ": " + std::string(format) + " data ends after " +
              std::to_string(got) + " of " + std::to_string(want) + " bytes" + std::string(why));
}

/// The offset just after the `count` lines that follow `pos`.
std::uint64_t skip_lines(std::string_view format, input_file& in, std::uint64_t pos,
                         std::uint64_t count) {
  if (count == 0) return pos;
  in.seek(pos);
  std::vector<char> buf(chunk_bytes);
  std::uint64_t skipped = 0;
  for (;;) {
    const std::size_t got = in.read(buf.data(), buf.size());
    if (got == 0) break;
    const char* p = buf.data();
    const char* const end = p + got;
    while (p < end) {
      const auto* nl =
          static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
      if (nl == nullptr) break;
      p = nl + 1;
      if (++skipped == count) return pos + static_cast<std::uint64_t>(p - buf.data());
    }
    pos += got;
  }
  throw error(in.path().string() + ": " + std::string(format) + " data ends after " +
              std::to_string(skipped) + " of the " + std::to_string(count) +
              " lines to skip (line skip)");
}

void read_raw_piece(std::string_view format, input_file& in, std::span<std::byte> out) {
  const std::size_t got = in.read(out.data(), out.size());
  if (got < out.size()) data_ends(format, in, got, out.size());
}

/// Inflates gzip (or zlib) data, one or more concatenated members, into `out` after dropping
/// `skip` decompressed bytes; stops as soon as `out` is full.
void inflate_piece(const nrrd_header& h, input_file& in, std::uint64_t skip,
                   std::span<std::byte> out) {
  gzip_input gz(in, std::string(h.format) + " " + std::string(to_string(h.encoding)) + " data");
  const std::uint64_t skipped = gz.skip(skip);
  const std::size_t produced = skipped == skip ? gz.read(out) : 0;
  if (produced < out.size()) {
    data_ends(h.format, in, produced, out.size(),
              " (the " + std::string(to_string(h.encoding)) + " stream ends early)");
  }
}

template <class Int>
parse_status store_integer(std::string_view token, std::byte* dst) {
  std::int64_t v = 0;
  const parse_status status = to_integer(token, v);
  if (status != parse_status::ok) return status;
  if (v < static_cast<std::int64_t>(std::numeric_limits<Int>::min()) ||
      v > static_cast<std::int64_t>(std::numeric_limits<Int>::max())) {
    return parse_status::range;
  }
  const auto x = static_cast<Int>(v);
  std::memcpy(dst, &x, sizeof x);
  return parse_status::ok;
}

template <class Real>
parse_status store_real(std::string_view token, std::byte* dst) {
  const std::optional<Real> x = to_real<Real>(token);
  if (!x) return parse_status::syntax;
  std::memcpy(dst, &*x, sizeof *x);
  return parse_status::ok;
}

parse_status store_ascii_value(sample_type type, std::string_view token, std::byte* dst) {
  switch (type) {
    case sample_type::u8:
      return store_integer<std::uint8_t>(token, dst);
    case sample_type::i8:
      return store_integer<std::int8_t>(token, dst);
    case sample_type::u16:
      return store_integer<std::uint16_t>(token, dst);
    case sample_type::i16:
      return store_integer<std::int16_t>(token, dst);
    case sample_type::u32:
      return store_integer<std::uint32_t>(token, dst);
    case sample_type::i32:
      return store_integer<std::int32_t>(token, dst);
    case sample_type::f32:
      return store_real<float>(token, dst);
    case sample_type::f64:
      break;
  }
  return store_real<double>(token, dst);
}

bool is_ascii_separator(char c) noexcept {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v' || c == ',';
}

/// Reads whitespace- or comma-separated values, one per sample, after `skip` values parsed and
/// dropped (the volumes before a chosen one); values after the last sample are ignored.
void read_ascii_piece(std::string_view format, input_file& in, sample_type type,
                      std::span<std::byte> out, std::uint64_t skip = 0) {
  const std::size_t item = sample_size(type);
  const std::uint64_t values = skip + out.size() / item;
  std::vector<char> buf(chunk_bytes);
  std::string token;
  std::uint64_t done = 0;
  std::array<std::byte, 8> dropped{};
  const auto take = [&] {
    if (token.empty()) return;
    std::byte* const dst =
        done < skip ? dropped.data() : out.data() + static_cast<std::size_t>(done - skip) * item;
    const parse_status status = store_ascii_value(type, token, dst);
    if (status != parse_status::ok) {
      throw error(
          in.path().string() + ": " + std::string(format) + " ascii value " +
          std::to_string(done + 1) + " of " + std::to_string(values) + ", " +
          detail::quoted(token) +
          (status == parse_status::range ? ", is out of range for " : ", cannot be parsed as ") +
          std::string(to_string(type)));
    }
    ++done;
    token.clear();
  };
  while (done < values) {
    const std::size_t got = in.read(buf.data(), buf.size());
    if (got == 0) {
      take();
      break;
    }
    for (std::size_t i = 0; i < got && done < values; ++i) {
      if (is_ascii_separator(buf[i])) {
        take();
      } else if (token.size() == max_ascii_token) {
        throw error(in.path().string() + ": " + std::string(format) + " ascii value " +
                    std::to_string(done + 1) + " is longer than " +
                    std::to_string(max_ascii_token) + " bytes");
      } else {
        token += buf[i];
      }
    }
  }
  if (done < values) {
    throw error(in.path().string() + ": " + std::string(format) + " ascii data ends after " +
                std::to_string(done) + " of " + std::to_string(values) + " values");
  }
}

int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// Reads two hex digits per byte, whitespace ignored, after `skip` bytes' digits dropped.
void read_hex_piece(std::string_view format, input_file& in, std::span<std::byte> out,
                    std::uint64_t skip = 0) {
  std::vector<char> buf(chunk_bytes);
  const std::uint64_t want = skip + out.size();
  std::uint64_t done = 0;
  int high = -1;
  while (done < want) {
    const std::size_t got = in.read(buf.data(), buf.size());
    if (got == 0) break;
    for (std::size_t i = 0; i < got && done < want; ++i) {
      const int d = hex_digit(buf[i]);
      if (d < 0) {
        if (is_ascii_separator(buf[i]) && buf[i] != ',') continue;
        throw error(in.path().string() + ": " + std::string(format) + " hex data holds " +
                    detail::quoted(std::string_view(&buf[i], 1)) + " after " +
                    std::to_string(done) + " bytes (expected hex digits)");
      }
      if (high < 0) {
        high = d;
      } else {
        if (done >= skip)
          out[static_cast<std::size_t>(done - skip)] = static_cast<std::byte>((high << 4) | d);
        ++done;
        high = -1;
      }
    }
  }
  if (done < want) {
    data_ends(format, in, done, want, high >= 0 ? " (an odd number of hex digits)" : "");
  }
}

/// Decodes one piece from `in`, whose data (before any line and byte skip) starts at `start`.
/// `out` receives the piece's bytes from `skip` on (a chosen volume's part of it); `piece` is
/// the whole piece's size.
void decode_piece(const nrrd_header& h, input_file& in, std::uint64_t start,
                  std::span<std::byte> out, std::uint64_t skip, std::uint64_t piece) {
  PROGISO_ASSERT(skip + out.size() <= piece);
  std::uint64_t pos = start;
  if (h.byte_skip == -1) {
    // The data ends the file; the capacity check made sure it lies after `start`.
    if (in.size() < start + piece)
      data_ends(h.format, in, in.size() - std::min(in.size(), start), piece);
    pos = in.size() - piece;
  } else {
    pos = skip_lines(h.format, in, pos, h.line_skip);
    // Compressed data skips its bytes inside the decompressed stream.
    if (!deflated(h.encoding)) pos += static_cast<std::uint64_t>(h.byte_skip);
  }
  switch (h.encoding) {
    case nrrd_encoding::raw:
      in.seek(pos + skip);
      read_raw_piece(h.format, in, out);
      break;
    case nrrd_encoding::gzip:
    case nrrd_encoding::zlib:
      in.seek(pos);
      inflate_piece(h, in, static_cast<std::uint64_t>(h.byte_skip) + skip, out);
      break;
    case nrrd_encoding::ascii:
      in.seek(pos);
      read_ascii_piece(h.format, in, h.type, out, skip / sample_size(h.type));
      break;
    case nrrd_encoding::hex:
      in.seek(pos);
      read_hex_piece(h.format, in, out, skip);
      break;
  }
}

/// Runs `f` and adds which header names the data file to any error it throws.
template <class F>
void for_data_file(const fs::path& header, std::size_t index, std::size_t count, F&& f) {
  try {
    f();
  } catch (const error& e) {
    throw error(std::string(e.what()) + " (data file " + std::to_string(index + 1) + " of " +
                std::to_string(count) + " named by " + header.string() + ")");
  }
}

}  // namespace

std::string_view to_string(nrrd_encoding encoding) noexcept {
  switch (encoding) {
    case nrrd_encoding::raw:
      return "raw";
    case nrrd_encoding::gzip:
      return "gzip";
    case nrrd_encoding::zlib:
      return "zlib";
    case nrrd_encoding::ascii:
      return "ascii";
    case nrrd_encoding::hex:
      return "hex";
  }
  return "?";
}

nrrd_header parse_nrrd_header(input_file& header_file) {
  return header_parser(header_file.path(), read_header_lines(header_file)).run();
}

std::optional<mapped_bytes> map_nrrd_samples(const nrrd_header& header,
                                             const input_file& header_file, std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < header.volumes);
  const std::size_t item = sample_size(header.type);
  if (header.encoding != nrrd_encoding::raw || header.interleaved || header.data_files.size() > 1 ||
      header.line_skip != 0) {
    return std::nullopt;
  }
  if (item > 1 && header.big_endian != (std::endian::native == std::endian::big)) {
    return std::nullopt;
  }
  std::uint64_t bytes = item;  // of one volume: ≤ 32769³ × 8 < 2^48
  for (std::int64_t d : header.dims) bytes *= static_cast<std::uint64_t>(d);
  if (bytes < map_min_bytes) return std::nullopt;
  const auto volumes = static_cast<std::uint64_t>(header.volumes);
  std::optional<input_file> detached;
  if (!header.data_files.empty()) {
    detached.emplace(header.data_files[0], std::string(header.format) + " data");
  }
  const input_file& in = detached ? *detached : header_file;
  const std::uint64_t start = detached ? 0 : header.data_offset;
  if (start > in.size() || volumes > (in.size() - start) / bytes) return std::nullopt;
  const std::uint64_t total = bytes * volumes;
  std::uint64_t first = in.size() - total;  // byte skip -1: the data ends the file
  if (header.byte_skip >= 0) {
    const auto skip = static_cast<std::uint64_t>(header.byte_skip);
    if (skip > in.size() - start - total) return std::nullopt;
    first = start + skip;
  }
  return map_bytes(in, first + static_cast<std::uint64_t>(volume) * bytes, bytes);
}

std::vector<std::byte> read_nrrd_samples(const nrrd_header& header, input_file& header_file,
                                         std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < header.volumes);
  const std::size_t item = sample_size(header.type);
  data_plan plan{header};
  std::uint64_t bytes = item;  // of one volume: ≤ 32769³ × 8 < 2^48
  for (std::int64_t d : header.dims) bytes *= static_cast<std::uint64_t>(d);
  const auto volumes = static_cast<std::uint64_t>(header.volumes);
  if (volumes > std::numeric_limits<std::uint64_t>::max() / bytes) {
    throw error(header_file.path().string() + ": the declared " + dims_text(header.dims) + " × " +
                std::to_string(volumes) + " volumes of " + std::string(to_string(header.type)) +
                " pass 2^64 bytes");
  }
  plan.total = bytes * volumes;
  plan.files = header.data_files.empty() ? 1 : header.data_files.size();
  plan.piece = plan.total / plan.files;
  PROGISO_ASSERT(plan.piece * plan.files == plan.total);
  if (bytes > std::numeric_limits<std::size_t>::max()) {
    throw error(header_file.path().string() + ": the declared " + std::to_string(bytes) +
                " bytes do not fit in memory");
  }

  // Pass 1: every source must be able to hold its share before the buffer is allocated.
  std::uint64_t found = 0;
  if (header.data_files.empty()) {
    check_capacity(plan, header_file, header.data_offset, found);
  } else {
    for (std::size_t i = 0; i < plan.files; ++i) {
      for_data_file(header_file.path(), i, plan.files, [&] {
        input_file in(header.data_files[i], std::string(header.format) + " data");
        check_capacity(plan, in, 0, found);
      });
    }
    // Each file passed with its own slack; all together get one.
    if (deflated(header.encoding) && !gzip_can_hold(found, plan.total)) {
      throw error(header_file.path().string() + ": the " + std::to_string(found) + " bytes of " +
                  std::string(to_string(header.encoding)) + " data in " +
                  std::to_string(plan.files) + " data files cannot hold the declared " +
                  std::to_string(plan.total) + " bytes (sizes " + shape_text(header) + " of " +
                  std::string(to_string(header.type)) + encoding_bound(header.encoding) + ")");
    }
  }

  // Pass 2: decode the chosen volume's bytes, [first, first + bytes) of the data, in place.
  // Interleaved volumes are decoded whole and volume `volume` gathered from them: the file holds
  // every volume's samples (the capacity checks saw to that), so memory follows the data.
  if (header.interleaved) {
    if (plan.total > std::numeric_limits<std::size_t>::max()) {
      throw error(header_file.path().string() + ": the declared " + std::to_string(plan.total) +
                  " bytes do not fit in memory");
    }
    nrrd_header whole = header;
    whole.interleaved = false;
    whole.dims = {header.dims[0] * header.volumes, header.dims[1], header.dims[2]};
    whole.volumes = 1;
    const std::vector<std::byte> all = read_nrrd_samples(whole, header_file, 0);
    std::vector<std::byte> samples(static_cast<std::size_t>(bytes));
    const auto stride = static_cast<std::size_t>(header.volumes) * item;
    const std::byte* from = all.data() + static_cast<std::size_t>(volume) * item;
    for (std::size_t at = 0; at < samples.size(); at += item, from += stride) {
      std::memcpy(samples.data() + at, from, item);
    }
    return samples;
  }
  std::vector<std::byte> samples(static_cast<std::size_t>(bytes));
  const std::span<std::byte> all(samples);
  const std::uint64_t first = static_cast<std::uint64_t>(volume) * bytes;
  if (header.data_files.empty()) {
    decode_piece(header, header_file, header.data_offset, all, first, plan.piece);
  } else {
    for (std::size_t i = 0; i < plan.files; ++i) {
      const std::uint64_t lo = std::max<std::uint64_t>(first, i * plan.piece);
      const std::uint64_t hi = std::min<std::uint64_t>(first + bytes, (i + 1) * plan.piece);
      if (lo >= hi) continue;  // a file of other volumes
      for_data_file(header_file.path(), i, plan.files, [&] {
        input_file in(header.data_files[i], std::string(header.format) + " data");
        decode_piece(
            header, in, 0,
            all.subspan(static_cast<std::size_t>(lo - first), static_cast<std::size_t>(hi - lo)),
            lo - i * plan.piece, plan.piece);
      });
    }
  }
  const bool host_big = std::endian::native == std::endian::big;
  if (item > 1 && header.encoding != nrrd_encoding::ascii && header.big_endian != host_big) {
    swap_sample_bytes(all, item);
  }
  return samples;
}

void swap_sample_bytes(std::span<std::byte> bytes, std::size_t item) noexcept {
  std::byte* p = bytes.data();
  const std::size_t n = bytes.size();
  switch (item) {
    case 1:
      return;
    case 2:
      for (std::size_t i = 0; i + 2 <= n; i += 2) {
        std::uint16_t v;
        std::memcpy(&v, p + i, 2);
        v = __builtin_bswap16(v);
        std::memcpy(p + i, &v, 2);
      }
      return;
    case 4:
      for (std::size_t i = 0; i + 4 <= n; i += 4) {
        std::uint32_t v;
        std::memcpy(&v, p + i, 4);
        v = __builtin_bswap32(v);
        std::memcpy(p + i, &v, 4);
      }
      return;
    case 8:
      for (std::size_t i = 0; i + 8 <= n; i += 8) {
        std::uint64_t v;
        std::memcpy(&v, p + i, 8);
        v = __builtin_bswap64(v);
        std::memcpy(p + i, &v, 8);
      }
      return;
    default:
      for (std::size_t i = 0; i + item <= n; i += item) std::reverse(p + i, p + i + item);
      return;
  }
}

}  // namespace progiso::detail
