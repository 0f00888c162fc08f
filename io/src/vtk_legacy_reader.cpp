#include <progiso/io/detail/vtk_legacy_reader.hpp>

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

struct type_spelling {
  std::string_view name;
  sample_type type;
};
constexpr std::array<type_spelling, 9> types{{
    {"unsigned_char", sample_type::u8},
    {"char", sample_type::i8},
    {"signed_char", sample_type::i8},
    {"unsigned_short", sample_type::u16},
    {"short", sample_type::i16},
    {"unsigned_int", sample_type::u32},
    {"int", sample_type::i32},
    {"float", sample_type::f32},
    {"double", sample_type::f64},
}};

class parser {
 public:
  explicit parser(input_file& in) : lines_(in, "VTK"), file_(in.path()) {}

  nrrd_header run() {
    nrrd_header h;
    h.format = "VTK";
    read_preamble(h);
    std::optional<std::array<std::int64_t, 3>> dims;
    std::optional<std::array<double, 3>> spacing;
    std::optional<std::array<double, 3>> origin;
    // Dataset keywords up to the point data.
    for (;;) {
      const std::vector<std::string_view> w = next_words("POINT_DATA");
      const std::string key = lower(w[0]);
      if (key == "dimensions") {
        once(dims.has_value(), w[0]);
        dims = parse_dims(w);
      } else if (key == "spacing" || key == "aspect_ratio") {
        once(spacing.has_value(), "SPACING");
        spacing = parse_triple(w);
      } else if (key == "origin") {
        once(origin.has_value(), w[0]);
        origin = parse_triple(w);
      } else if (key == "point_data") {
        if (!dims) fail("POINT_DATA before DIMENSIONS on line " + line_no());
        points_ = parse_point_count(w, *dims);
        break;
      } else if (key == "cell_data") {
        fail("CELL_DATA on line " + line_no() +
             " before the point data: progiso reads point scalars (expected POINT_DATA)");
      } else if (key == "field") {
        fail("dataset FIELD data on line " + line_no() +
             " is not supported (expected DIMENSIONS, SPACING, ORIGIN and POINT_DATA)");
      } else {
        fail("unknown VTK keyword " + detail::quoted(w[0]) + " on line " + line_no() +
             " (expected DIMENSIONS, SPACING, ORIGIN or POINT_DATA)");
      }
    }
    for (std::size_t a = 0; a < 3; ++a) {
      h.dims[a] = (*dims)[a];
      const double s = spacing ? (*spacing)[a] : 1.0;
      const double step = std::isfinite(s) && s != 0.0 ? s : 1.0;
      h.spacing[a] = std::abs(step);
      h.origin[a] = origin ? (*origin)[a] : 0.0;
    }
    index_to_world w;
    for (std::size_t r = 0; r < 3; ++r) {
      const double s = spacing ? (*spacing)[r] : 1.0;
      w.m[r][r] = std::isfinite(s) && s != 0.0 ? s : 1.0;
      w.m[r][3] = h.origin[r];
    }
    h.world = w;
    h.type = parse_attribute();
    h.data_offset = data_offset_;
    return h;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw error(file_.string() + ": " + what);
  }
  [[nodiscard]] std::string line_no() const { return std::to_string(lines_.number()); }
  void once(bool seen, std::string_view key) const {
    if (seen) fail(std::string(key) + " is given twice (line " + line_no() + ")");
  }

  /// The words of the next non-blank line; fails at the end of the file, naming what was
  /// expected.
  std::vector<std::string_view> next_words(std::string_view expected) {
    while (lines_.next(line_)) {
      std::vector<std::string_view> w = words(line_);
      if (!w.empty()) return w;
    }
    fail("the VTK header ends before " + std::string(expected));
  }

  void read_preamble(nrrd_header& h) {
    const std::string_view magic = "# vtk DataFile Version";
    if (!lines_.next(line_) || lower(line_.substr(0, magic.size())) != lower(magic)) {
      fail("not a legacy VTK file (expected \"# vtk DataFile Version\" on line 1, found " +
           detail::quoted(lines_.head(40)) + ")");
    }
    if (!lines_.next(line_)) fail("the VTK header ends after line 1 (expected a title line)");
    const std::vector<std::string_view> mode = next_words("ASCII or BINARY");
    const std::string m = lower(mode[0]);
    if (mode.size() != 1 || (m != "ascii" && m != "binary")) {
      fail("expected ASCII or BINARY on line " + line_no() + ", found " + detail::quoted(line_));
    }
    h.encoding = m == "ascii" ? nrrd_encoding::ascii : nrrd_encoding::raw;
    h.big_endian = true;  // the format's binary data is big-endian
    const std::vector<std::string_view> ds = next_words("DATASET");
    if (lower(ds[0]) != "dataset" || ds.size() != 2) {
      fail("expected \"DATASET STRUCTURED_POINTS\" on line " + line_no() + ", found " +
           detail::quoted(line_));
    }
    if (lower(ds[1]) != "structured_points") {
      fail("DATASET " + detail::quoted(ds[1]) +
           " is not supported (expected STRUCTURED_POINTS, a regular grid of samples)");
    }
  }

  std::array<std::int64_t, 3> parse_dims(const std::vector<std::string_view>& w) const {
    if (w.size() != 4) fail("expected DIMENSIONS NX NY NZ on line " + line_no());
    std::array<std::int64_t, 3> d{};
    for (std::size_t a = 0; a < 3; ++a) {
      const auto n = to_integer<std::int64_t>(w[a + 1]);
      if (!n) fail("DIMENSIONS on line " + line_no() + " holds " + detail::quoted(w[a + 1]));
      if (*n < 2 || *n > nrrd_max_axis_size) {
        fail("DIMENSIONS gives axis " + std::to_string(a) + " " + std::to_string(*n) +
             " points, expected 2 to " + std::to_string(nrrd_max_axis_size) +
             (*n == 1 ? " (a 2-D image is not a volume)" : ""));
      }
      d[a] = *n;
    }
    return d;
  }

  std::array<double, 3> parse_triple(const std::vector<std::string_view>& w) const {
    if (w.size() != 4) {
      fail("expected " + std::string(w[0]) + " X Y Z on line " + line_no() + ", found " +
           detail::quoted(line_));
    }
    std::array<double, 3> v{};
    for (std::size_t a = 0; a < 3; ++a) {
      const auto x = to_real<double>(w[a + 1]);
      if (!x || !std::isfinite(*x)) {
        fail(std::string(w[0]) + " on line " + line_no() + " holds " + detail::quoted(w[a + 1]) +
             ", expected a finite number");
      }
      v[a] = *x;
    }
    return v;
  }

  std::uint64_t parse_point_count(const std::vector<std::string_view>& w,
                                  const std::array<std::int64_t, 3>& d) const {
    const auto n = w.size() == 2 ? to_integer<std::uint64_t>(w[1]) : std::nullopt;
    const auto want = static_cast<std::uint64_t>(d[0]) * static_cast<std::uint64_t>(d[1]) *
                      static_cast<std::uint64_t>(d[2]);
    if (!n || *n != want) {
      fail("POINT_DATA on line " + line_no() + " gives " + detail::quoted(line_) + ", expected " +
           std::to_string(want) + " points (DIMENSIONS' product)");
    }
    return want;
  }

  sample_type type_of(std::string_view name) const {
    const std::string t = lower(name);
    const auto s = std::find_if(types.begin(), types.end(),
                                [&](const type_spelling& x) { return x.name == t; });
    if (s == types.end()) {
      fail("data type " + detail::quoted(name) + " on line " + line_no() +
           " is not supported (expected unsigned_char, char, signed_char, unsigned_short, "
           "short, unsigned_int, int, float or double)");
    }
    return s->type;
  }

  /// The first point attribute: SCALARS (and its optional LOOKUP_TABLE line), or the first array
  /// of a FIELD. Leaves the reader just after the line the data follows.
  sample_type parse_attribute() {
    const std::vector<std::string_view> w = next_words("SCALARS");
    const std::string key = lower(w[0]);
    if (key == "scalars") {
      if (w.size() < 3 || w.size() > 4) {
        fail("expected SCALARS NAME TYPE [COMPONENTS] on line " + line_no() + ", found " +
             detail::quoted(line_));
      }
      if (w.size() == 4 && w[3] != "1") {
        fail("SCALARS on line " + line_no() + " has " + detail::quoted(w[3]) +
             " components: expected 1 (a scalar volume)");
      }
      const sample_type t = type_of(w[2]);
      // VTK requires the LOOKUP_TABLE line ("Lookup table must be specified with scalar"); the
      // data starts right after it.
      const std::vector<std::string_view> lt = next_words("LOOKUP_TABLE");
      if (lower(lt[0]) != "lookup_table") {
        fail("expected LOOKUP_TABLE after SCALARS on line " + line_no() + ", found " +
             detail::quoted(line_) + " (VTK requires it: LOOKUP_TABLE default)");
      }
      data_offset_ = lines_.offset();
      return t;
    }
    if (key == "field") {
      const std::vector<std::string_view> a = next_words("the FIELD's first array");
      if (a.size() != 4) {
        fail("expected NAME COMPONENTS TUPLES TYPE on line " + line_no() + ", found " +
             detail::quoted(line_));
      }
      if (to_integer<std::uint64_t>(a[2]) != points_) {
        fail("the FIELD array " + detail::quoted(a[0]) + " on line " + line_no() + " has " +
             detail::quoted(a[2]) + " tuples, expected " + std::to_string(points_) +
             " (one per point)");
      }
      if (a[1] != "1") {
        fail("the FIELD array " + detail::quoted(a[0]) + " on line " + line_no() + " has " +
             detail::quoted(a[1]) + " components: expected 1 (a scalar volume)");
      }
      const sample_type t = type_of(a[3]);
      data_offset_ = lines_.offset();
      return t;
    }
    fail("the first point attribute is " + detail::quoted(w[0]) + " on line " + line_no() +
         ": expected SCALARS (or a FIELD of scalars)");
  }

 private:
  line_reader lines_;
  const fs::path& file_;
  std::string line_;
  std::uint64_t data_offset_ = 0;
  std::uint64_t points_ = 0;
};

}  // namespace

nrrd_header parse_vtk_legacy_header(input_file& file) { return parser(file).run(); }

bool has_vtk_legacy_name(const std::filesystem::path& file) {
  return lower_extension(file) == ".vtk";
}

}  // namespace progiso::detail
