#include <progiso/io/detail/metaimage_reader.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/header_text.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t max_axis_size = nrrd_max_axis_size;
constexpr std::int64_t max_pattern_number = INT32_MAX;  // MetaIO's numbers are C ints
constexpr std::int64_t max_volumes = INT32_MAX;         // so are its sizes

// The keys progiso reads; every other key is ignored, as MetaIO ignores unknown keys. Synonyms
// share a slot (one of them per header).
enum class key : std::uint8_t {
  object_type,
  ndims,
  dim_size,
  element_type,
  channels,
  binary_data,
  byte_order,
  compressed,
  header_size,
  spacing,
  element_size,
  offset,
  transform,
};
constexpr std::size_t key_count = static_cast<std::size_t>(key::transform) + 1;

struct key_spelling {
  std::string_view name;
  key id;
};
constexpr std::array<key_spelling, 18> spellings{{
    {"ObjectType", key::object_type},
    {"NDims", key::ndims},
    {"DimSize", key::dim_size},
    {"ElementType", key::element_type},
    {"ElementNumberOfChannels", key::channels},
    {"BinaryData", key::binary_data},
    {"BinaryDataByteOrderMSB", key::byte_order},
    {"ElementByteOrderMSB", key::byte_order},
    {"CompressedData", key::compressed},
    {"HeaderSize", key::header_size},
    {"ElementSpacing", key::spacing},
    {"ElementSize", key::element_size},
    {"Offset", key::offset},
    {"Position", key::offset},
    {"Origin", key::offset},
    {"TransformMatrix", key::transform},
    {"Rotation", key::transform},
    {"Orientation", key::transform},
}};
// ElementDataFile is matched on its own: it ends the header.
constexpr std::string_view data_file_key = "ElementDataFile";

struct type_spelling {
  std::string_view name;
  sample_type type;
};
constexpr std::array<type_spelling, 10> types{{
    {"MET_UCHAR", sample_type::u8},
    {"MET_CHAR", sample_type::i8},
    {"MET_USHORT", sample_type::u16},
    {"MET_SHORT", sample_type::i16},
    {"MET_UINT", sample_type::u32},
    {"MET_INT", sample_type::i32},
    {"MET_ULONG", sample_type::u32},  // 4 bytes in MetaIO (MET_ValueTypeSize)
    {"MET_LONG", sample_type::i32},
    {"MET_FLOAT", sample_type::f32},
    {"MET_DOUBLE", sample_type::f64},
}};

struct value {
  std::string text;
  std::string_view name;  // the spelling used, for messages
  std::size_t line = 0;
};

class parser {
 public:
  explicit parser(input_file& in) : in_(in), file_(in.path()) {}

  nrrd_header run() {
    read_lines();
    nrrd_header h;
    h.format = "MetaImage";
    if (const value* v = get(key::object_type); v != nullptr && v->text != "Image") {
      fail(*v, "is " + detail::quoted(v->text) + ": only Image objects are volumes");
    }
    const unsigned n = parse_ndims();
    ndims_ = n;
    const std::vector<std::int64_t> sizes = parse_dim_size(n);
    for (std::size_t a = 0; a < 3; ++a) h.dims[a] = sizes[a];
    if (n >= 4) h.volumes = sizes[3];
    h.type = parse_type();
    parse_channels();
    const bool binary = parse_bool(key::binary_data).value_or(true);
    const bool compressed = parse_bool(key::compressed).value_or(false);
    if (compressed && !binary) {
      fail(*get(key::compressed), "is True with BinaryData = False (ASCII data is not compressed)");
    }
    h.encoding =
        !binary ? nrrd_encoding::ascii : (compressed ? nrrd_encoding::zlib : nrrd_encoding::raw);
    h.big_endian = parse_bool(key::byte_order).value_or(false);
    parse_geometry(h, n);
    parse_data(h);
    return h;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw error(file_.string() + ": " + what);
  }
  [[noreturn]] void fail(const value& v, const std::string& what) const {
    fail("MetaImage " + std::string(v.name) + " (header line " + std::to_string(v.line) + ") " +
         what);
  }
  [[nodiscard]] const value* get(key k) const {
    const auto& slot = values_[static_cast<std::size_t>(k)];
    return slot ? &*slot : nullptr;
  }
  [[nodiscard]] const value& require(key k, std::string_view name) const {
    const value* v = get(k);
    if (v == nullptr) {
      fail("no MetaImage " + std::string(name) + " field before ElementDataFile (expected " +
           "NDims, DimSize, ElementType and ElementDataFile)");
    }
    return *v;
  }

  // ------------------------------------------------------------------------------------------
  // Lines: "Key = Value" up to ElementDataFile, then LIST names or the data.

  void read_lines() {
    line_reader lines(in_, "MetaImage");
    std::string line;
    bool first = true;
    while (lines.next(line)) {
      const std::string_view text = trim(line);
      if (text.empty()) continue;
      const std::size_t eq = text.find('=');
      if (eq == std::string_view::npos) {
        if (first) {
          fail("not a MetaImage header (expected \"Key = Value\" lines, found " +
               detail::quoted(text) + " on line 1)");
        }
        fail("expected \"Key = Value\" on MetaImage header line " + std::to_string(lines.number()) +
             ", found " + detail::quoted(text));
      }
      first = false;
      const std::string_view name = trim(text.substr(0, eq));
      const std::string_view rest = trim(text.substr(eq + 1));
      if (name == data_file_key) {
        data_file_ = value{std::string(rest), data_file_key, lines.number()};
        data_offset_ = lines.offset();
        const std::vector<std::string_view> w = words(rest);
        if (!w.empty() && w[0] == "LIST") read_list(lines, line);
        return;
      }
      const auto s = std::find_if(spellings.begin(), spellings.end(),
                                  [&](const key_spelling& k) { return k.name == name; });
      if (s == spellings.end()) continue;  // a key progiso does not read
      auto& slot = values_[static_cast<std::size_t>(s->id)];
      if (slot) {
        fail("MetaImage " + std::string(s->name) + " on header line " +
             std::to_string(lines.number()) + " repeats " + std::string(slot->name) + " of line " +
             std::to_string(slot->line));
      }
      slot = value{std::string(rest), s->name, lines.number()};
    }
    fail(
        "the MetaImage header ends without an ElementDataFile field (expected LOCAL or the "
        "data file's name as its last field)");
  }

  void read_list(line_reader& lines, std::string& line) {
    std::size_t name_bytes = 0;
    while (lines.next(line)) {
      const std::string_view name = trim(line);
      if (name.empty()) continue;
      if (list_.size() == nrrd_max_data_files) {
        fail("the MetaImage ElementDataFile LIST names more than " +
             std::to_string(nrrd_max_data_files) + " data files");
      }
      name_bytes += name.size();
      if (name_bytes > nrrd_max_name_bytes) {
        fail("the MetaImage ElementDataFile LIST names take more than " +
             std::to_string(nrrd_max_name_bytes) + " bytes");
      }
      list_.emplace_back(name);
    }
  }

  // ------------------------------------------------------------------------------------------
  // Fields.

  unsigned parse_ndims() const {
    const value& v = require(key::ndims, "NDims");
    const auto n = to_integer<unsigned>(v.text);
    if (!n || *n < 1 || *n > metaimage_max_dimensions) {
      fail(v, "is " + detail::quoted(v.text) + ", expected 3 (at most " +
                  std::to_string(metaimage_max_dimensions) + ")");
    }
    if (*n < 3) {
      fail(v, "is " + std::to_string(*n) + ": a " + std::to_string(*n) +
                  "-D image, expected a 3-D volume");
    }
    return *n;
  }

  std::vector<std::int64_t> parse_dim_size(unsigned n) const {
    const value& v = require(key::dim_size, "DimSize");
    const std::vector<std::string_view> w = words(v.text);
    if (w.size() != n) {
      fail(v, "has " + std::to_string(w.size()) + " sizes, expected NDims = " + std::to_string(n));
    }
    std::vector<std::int64_t> sizes;
    for (std::size_t a = 0; a < n; ++a) {
      const auto s = to_integer<std::int64_t>(w[a]);
      if (!s || *s < 1) fail(v, "holds " + detail::quoted(w[a]) + ", expected a positive size");
      if (a < 3 && (*s < 2 || *s > max_axis_size)) {
        fail(v, "gives axis " + std::to_string(a) + " " + std::to_string(*s) +
                    " samples, expected 2 to " + std::to_string(max_axis_size));
      }
      if (a == 3 && *s > max_volumes) {
        fail(v, "gives axis 3 " + std::to_string(*s) + " volumes, expected at most " +
                    std::to_string(max_volumes));
      }
      if (a >= 4 && *s != 1) {
        fail(v, "gives axis " + std::to_string(a) + " " + std::to_string(*s) +
                    " samples: expected a 3-D volume or a series of them (sizes above the "
                    "fourth of 1)");
      }
      sizes.push_back(*s);
    }
    return sizes;
  }

  sample_type parse_type() const {
    const value& v = require(key::element_type, "ElementType");
    const auto t = std::find_if(types.begin(), types.end(),
                                [&](const type_spelling& s) { return s.name == v.text; });
    if (t == types.end()) {
      fail(v, "is " + detail::quoted(v.text) +
                  ", not supported (expected MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, "
                  "MET_UINT, MET_INT, MET_ULONG, MET_LONG, MET_FLOAT or MET_DOUBLE)");
    }
    return t->type;
  }

  void parse_channels() const {
    const value* v = get(key::channels);
    if (v == nullptr) return;
    const auto c = to_integer<unsigned>(v->text);
    if (!c || *c != 1) {
      fail(*v, "is " + detail::quoted(v->text) + ": expected 1 (a scalar volume)");
    }
  }

  /// True, T, 1 / False, F, 0 (any case), as MetaIO reads a boolean by its first letter.
  std::optional<bool> parse_bool(key k) const {
    const value* v = get(k);
    if (v == nullptr) return std::nullopt;
    const std::string t = lower(v->text);
    if (t == "true" || t == "t" || t == "1") return true;
    if (t == "false" || t == "f" || t == "0") return false;
    fail(*v, "is " + detail::quoted(v->text) + ", expected True or False");
  }

  /// `count` finite numbers, or nullopt when the field is absent.
  std::optional<std::vector<double>> parse_reals(key k, std::size_t count) const {
    const value* v = get(k);
    if (v == nullptr) return std::nullopt;
    const std::vector<std::string_view> w = words(v->text);
    if (w.size() != count) {
      fail(*v, "has " + std::to_string(w.size()) + " numbers, expected " + std::to_string(count));
    }
    std::vector<double> out;
    for (const std::string_view s : w) {
      const auto x = to_real<double>(s);
      if (!x || !std::isfinite(*x))
        fail(*v, "holds " + detail::quoted(s) + ", expected a finite number");
      out.push_back(*x);
    }
    return out;
  }

  void parse_geometry(nrrd_header& h, unsigned n) const {
    std::optional<std::vector<double>> spacing = parse_reals(key::spacing, n);
    if (!spacing) spacing = parse_reals(key::element_size, n);
    const std::optional<std::vector<double>> offset = parse_reals(key::offset, n);
    const std::optional<std::vector<double>> matrix =
        parse_reals(key::transform, static_cast<std::size_t>(n) * n);
    std::array<double, 3> step{1.0, 1.0, 1.0};
    for (std::size_t a = 0; a < 3; ++a) {
      if (spacing && (*spacing)[a] != 0.0) step[a] = (*spacing)[a];
      h.spacing[a] = std::abs(step[a]);
      h.origin[a] = offset ? (*offset)[a] : 0.0;
    }
    // Row i of the matrix is the direction of index axis i (ITK's reading): a column here.
    index_to_world w;
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t i = 0; i < 3; ++i) {
        const double d = matrix ? (*matrix)[i * n + r] : (i == r ? 1.0 : 0.0);
        w.m[r][i] = d * step[i];
      }
      w.m[r][3] = h.origin[r];
    }
    if (w.determinant() != 0.0) h.world = w;
  }

  // ------------------------------------------------------------------------------------------
  // The data: where it lies and how much to skip.

  void parse_data(nrrd_header& h) const {
    std::int64_t header_size = 0;
    if (const value* v = get(key::header_size); v != nullptr) {
      const auto s = to_integer<std::int64_t>(v->text);
      if (!s || *s < -1)
        fail(*v, "is " + detail::quoted(v->text) + ", expected -1 or a byte count");
      header_size = *s;
      if (header_size != 0 && deflated(h.encoding)) {
        fail(*v, "is " + std::to_string(header_size) +
                     " with CompressedData = True: not supported (MetaIO's compressed data "
                     "starts at the field's end)");
      }
    }
    const std::vector<std::string_view> w = words(data_file_.text);
    if (w.empty()) fail(data_file_, "names no file (expected LOCAL or a file name)");
    if (lower(data_file_.text) == "local") {
      h.data_offset = data_offset_;
      if (header_size > 0) {
        h.data_offset = static_cast<std::uint64_t>(header_size);  // from the file's start
      } else {
        h.byte_skip = header_size;  // -1: the data ends the file
      }
      return;
    }
    h.byte_skip = header_size;
    if (w[0] == "LIST") {
      if (w.size() > 2)
        fail(data_file_, "is " + detail::quoted(data_file_.text) + ", expected LIST [kD]");
      const unsigned subdim = w.size() == 2 ? parse_subdimension(w[1]) : default_subdimension();
      if (list_.empty()) fail(data_file_, "is LIST, followed by no file names");
      check_pieces(list_.size(), subdim, h);
      for (const std::string& name : list_) h.data_files.push_back(resolve(name));
      return;
    }
    // A pattern is a name with a conversion and three or four numbers; anything else is one
    // name, blanks and '%' included.
    std::string problem;
    const std::optional<name_pattern> pattern =
        w.size() == 4 || w.size() == 5 ? parse_name_pattern(w[0], problem) : std::nullopt;
    if (!problem.empty()) fail(data_file_, problem);
    if (!pattern) {
      h.data_files.push_back(resolve(data_file_.text));
      return;
    }
    std::array<std::int64_t, 3> numbers{};
    for (std::size_t k = 0; k < 3; ++k) {
      const auto x = to_integer<std::int64_t>(w[k + 1]);
      if (!x || *x < -max_pattern_number - 1 || *x > max_pattern_number) {
        fail(data_file_, "holds " + detail::quoted(w[k + 1]) + ", expected a 32-bit integer");
      }
      numbers[k] = *x;
    }
    const auto [first, last, step] = numbers;
    if (step == 0 || (last > first && step < 0) || (last < first && step > 0)) {
      fail(data_file_, "numbers files from " + std::to_string(first) + " to " +
                           std::to_string(last) + " by step " + std::to_string(step) +
                           ", which does not reach the last");
    }
    const auto count = static_cast<std::uint64_t>((last - first) / step + 1);
    const unsigned subdim = w.size() == 5 ? parse_subdimension(w[4]) : default_subdimension();
    check_pieces(count, subdim, h);  // bounds count by the slices
    for (std::int64_t i = first; step > 0 ? i <= last : i >= last; i += step) {
      h.data_files.push_back(resolve(
          pattern->prefix + format_number(i, pattern->zero_pad, pattern->width) + pattern->suffix));
    }
  }

  /// "2D" / "3D" (or 2 / 3): the dimension of each file's piece.
  unsigned parse_subdimension(std::string_view text) const {
    std::string_view t = text;
    if (!t.empty() && (t.back() == 'D' || t.back() == 'd')) t.remove_suffix(1);
    const auto d = to_integer<unsigned>(t);
    if (!d || *d < 2 || *d > 3) {
      fail(data_file_, "gives the file dimension " + detail::quoted(text) + ", expected 2D or 3D");
    }
    return *d;
  }

  /// MetaIO's default dimension of a file's piece: NDims − 1 (a slice of a volume, a volume of
  /// a series).
  [[nodiscard]] unsigned default_subdimension() const { return std::min(ndims_ - 1, 3u); }

  /// `count` files of `subdim`-D pieces must make up the data: one slice each, or an equal
  /// share of the slices (of every volume of a series, one after the other).
  void check_pieces(std::uint64_t count, unsigned subdim, const nrrd_header& h) const {
    const std::uint64_t slices =
        static_cast<std::uint64_t>(h.dims[2]) * static_cast<std::uint64_t>(h.volumes);
    if (subdim == 2 && count != slices) {
      fail(data_file_, "names " + std::to_string(count) + " files of one slice each, but DimSize " +
                           "has " + std::to_string(slices) + " slices");
    }
    if (subdim == 3 && (count > slices || slices % count != 0)) {
      fail(data_file_, "names " + std::to_string(count) +
                           " files of 3-D pieces, which do not divide the " +
                           std::to_string(slices) + " slices");
    }
  }

  fs::path resolve(std::string_view name) const {
    const fs::path p{std::string(name)};
    return p.is_absolute() ? p : file_.parent_path() / p;
  }

  input_file& in_;
  const fs::path& file_;
  std::array<std::optional<value>, key_count> values_;
  value data_file_;
  std::uint64_t data_offset_ = 0;
  std::vector<std::string> list_;
  unsigned ndims_ = 3;
};

}  // namespace

nrrd_header parse_metaimage_header(input_file& header_file) { return parser(header_file).run(); }

bool has_metaimage_name(const std::filesystem::path& file) {
  const std::string ext = lower_extension(file);
  return ext == ".mha" || ext == ".mhd";
}

}  // namespace progiso::detail
