#include <progiso/io/detail/vti_reader.hpp>

#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/gzip_input.hpp>
#include <progiso/io/detail/header_text.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t buffer_bytes = std::size_t{64} << 10;
constexpr std::size_t max_depth = 32;        // the writer nests 6 deep
constexpr std::size_t max_attributes = 256;  // its tags have at most a dozen (each is searched)

struct type_spelling {
  std::string_view name;
  sample_type type;
};
constexpr std::array<type_spelling, 8> types{{
    {"Int8", sample_type::i8},
    {"UInt8", sample_type::u8},
    {"Int16", sample_type::i16},
    {"UInt16", sample_type::u16},
    {"Int32", sample_type::i32},
    {"UInt32", sample_type::u32},
    {"Float32", sample_type::f32},
    {"Float64", sample_type::f64},
}};

/// An element's name for a message: untrusted bytes escaped, without quotes (it stands in <>).
std::string name_text(std::string_view name) {
  const std::string q = detail::quoted(name, 40);
  return q.substr(1, q.size() - 2);
}

bool is_space(char c) noexcept { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

/// The whitespace-separated words of an attribute value.
std::vector<std::string_view> value_words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

/// A file read forward through one buffer, knowing the offset of every byte.
class byte_stream {
 public:
  explicit byte_stream(input_file& in) : in_(in), buf_(buffer_bytes) {}
  /// The next byte, or -1 at the end of the file.
  int get() {
    if (pos_ == end_ && !fill()) return -1;
    return static_cast<unsigned char>(buf_[pos_++]);
  }
  int peek() {
    if (pos_ == end_ && !fill()) return -1;
    return static_cast<unsigned char>(buf_[pos_]);
  }
  /// The offset of the next byte get() returns.
  [[nodiscard]] std::uint64_t offset() const noexcept { return base_ + pos_; }

 private:
  bool fill() {
    base_ += end_;
    pos_ = 0;
    end_ = in_.read(buf_.data(), buf_.size());
    return end_ > 0;
  }
  input_file& in_;
  std::vector<char> buf_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t base_ = 0;
};

struct xml_tag {
  enum class kind : std::uint8_t { open, close, empty } what = kind::open;
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::uint64_t at = 0;  ///< offset of its '<'
  [[nodiscard]] const std::string* attribute(std::string_view n) const {
    for (const auto& [k, v] : attributes) {
      if (k == n) return &v;
    }
    return nullptr;
  }
};

class parser {
 public:
  /// `parallel`: a .pvti (PImageData naming its pieces), else a .vti. `array`: the point array
  /// to read (a .pvti's piece), else the one Scalars names, else the first.
  parser(input_file& in, bool parallel, std::string_view array = {})
      : in_(in), bytes_(in), file_(in.path()), parallel_(parallel), want_(array) {}

  vti_header run() {
    vti_header h;
    read_document(h);
    finish(h);
    return h;
  }

  pvti_header run_parallel() {
    vti_header h;
    read_document(h);
    pvti_header p;
    if (!whole_extent_) fail("no <PImageData> element (expected one inside <VTKFile>)");
    p.extent = *whole_extent_;
    p.dims = grid_dims(p.extent, "WholeExtent");
    if (arrays_.empty()) {
      fail(
          "no point data array (expected a <PDataArray> in <PPointData>; progiso reads point "
          "scalars, not cell data)");
    }
    const array_entry& a = chosen_array();
    p.type = checked_type(a);
    p.array = a.name;
    geometry(p.extent, p.spacing, p.origin, p.world);
    if (sources_.empty()) fail("<PImageData> names no <Piece> (expected pieces with a Source)");
    p.pieces = std::move(sources_);
    return p;
  }

 private:
  struct array_entry {
    std::string name;
    std::string type;
    std::string components = "1";
    std::string format;
    std::optional<std::uint64_t> offset;  // appended
    std::uint64_t text_at = 0;            // inline: the element's text
    std::uint64_t tag_at = 0;
  };

  [[noreturn]] void fail(const std::string& what) const {
    throw error(file_.string() + ": " + what);
  }
  [[nodiscard]] std::string at_text(std::uint64_t offset) const {
    return " (byte " + std::to_string(offset) + ")";
  }

  // ---- Tokens. ------------------------------------------------------------------------------

  /// Skips text up to the next '<' and reads the markup there: a tag (returned), or a comment,
  /// processing instruction or declaration (skipped, and the next one read). nullopt at the end
  /// of the file.
  std::optional<xml_tag> next_tag() {
    for (;;) {
      int c = bytes_.get();
      while (c != -1 && c != '<') c = bytes_.get();
      if (c == -1) return std::nullopt;
      const std::uint64_t at = bytes_.offset() - 1;
      const int n = bytes_.peek();
      if (n == '?') {
        skip_until("?>", at, "processing instruction");
      } else if (n == '!') {
        (void)bytes_.get();
        if (bytes_.peek() == '-') {
          (void)bytes_.get();
          if (bytes_.get() != '-') fail("malformed XML comment" + at_text(at));
          skip_until("-->", at, "comment");
        } else if (bytes_.peek() == '[') {
          fail("a CDATA section" + at_text(at) +
               " is not supported (VTK writes its data as element text or appended data)");
        } else {
          skip_until(">", at, "declaration");
        }
      } else {
        return read_tag(at);
      }
    }
  }

  void skip_until(std::string_view end, std::uint64_t at, std::string_view what) {
    std::size_t matched = 0;
    for (;;) {
      const int c = bytes_.get();
      if (c == -1) fail("the file ends inside an XML " + std::string(what) + at_text(at));
      if (static_cast<char>(c) == end[matched]) {
        if (++matched == end.size()) return;
      } else {
        matched = static_cast<char>(c) == end[0] ? 1 : 0;
      }
    }
  }

  /// A tag whose '<' is at `at` (consumed). Bounded by header_max_line_bytes.
  xml_tag read_tag(std::uint64_t at) {
    std::string text;
    char quote = 0;
    for (;;) {
      const int c = bytes_.get();
      if (c == -1) fail("the file ends inside the XML tag" + at_text(at));
      if (c == 0) fail("a NUL byte inside the XML tag" + at_text(at));
      const char ch = static_cast<char>(c);
      if (quote == 0 && ch == '>') break;
      if (quote == 0 && (ch == '"' || ch == '\'')) {
        quote = ch;
      } else if (ch == quote) {
        quote = 0;
      }
      if (text.size() == header_max_line_bytes) {
        fail("an XML tag" + at_text(at) + " is longer than " +
             std::to_string(header_max_line_bytes) + " bytes");
      }
      text += ch;
    }
    return parse_tag(text, at);
  }

  xml_tag parse_tag(std::string_view t, std::uint64_t at) const {
    xml_tag tag;
    tag.at = at;
    if (!t.empty() && t[0] == '/') {
      tag.what = xml_tag::kind::close;
      t.remove_prefix(1);
    } else if (!t.empty() && t.back() == '/') {
      tag.what = xml_tag::kind::empty;
      t.remove_suffix(1);
    }
    std::size_t i = 0;
    while (i < t.size() && !is_space(t[i])) ++i;
    tag.name = std::string(t.substr(0, i));
    if (tag.name.empty()) fail("an XML tag without a name" + at_text(at));
    for (;;) {
      while (i < t.size() && is_space(t[i])) ++i;
      if (i == t.size()) break;
      if (tag.what == xml_tag::kind::close) fail("a closing XML tag with attributes" + at_text(at));
      const std::size_t k0 = i;
      while (i < t.size() && t[i] != '=' && !is_space(t[i])) ++i;
      const std::string key(t.substr(k0, i - k0));
      while (i < t.size() && is_space(t[i])) ++i;
      if (key.empty() || i == t.size() || t[i] != '=') {
        fail("malformed attribute " + detail::quoted(key) + " in the XML tag <" +
             name_text(tag.name) + ">" + at_text(at));
      }
      ++i;
      while (i < t.size() && is_space(t[i])) ++i;
      if (i == t.size() || (t[i] != '"' && t[i] != '\'')) {
        fail("attribute " + detail::quoted(key) + " of <" + name_text(tag.name) +
             "> has no quoted value" + at_text(at));
      }
      const char q = t[i++];
      const std::size_t v0 = i;
      while (i < t.size() && t[i] != q) ++i;
      if (i == t.size())
        fail("attribute " + detail::quoted(key) + " of <" + name_text(tag.name) +
             "> is not closed");
      if (tag.attributes.size() == max_attributes) {
        fail("the XML tag <" + name_text(tag.name) + ">" + at_text(at) + " has more than " +
             std::to_string(max_attributes) + " attributes");
      }
      if (tag.attribute(key) != nullptr) {
        fail("attribute " + detail::quoted(key) + " is given twice in <" + name_text(tag.name) +
             ">" + at_text(at));
      }
      tag.attributes.emplace_back(key, unescape(t.substr(v0, i - v0)));
      ++i;
    }
    return tag;
  }

  /// XML's five predefined entities and character references in an attribute value.
  std::string unescape(std::string_view v) const {
    std::string out;
    out.reserve(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (v[i] != '&') {
        out += v[i];
        continue;
      }
      const std::size_t semi = v.find(';', i);
      if (semi == std::string_view::npos) fail("an unterminated entity in " + detail::quoted(v));
      const std::string_view e = v.substr(i + 1, semi - i - 1);
      if (e == "lt") {
        out += '<';
      } else if (e == "gt") {
        out += '>';
      } else if (e == "amp") {
        out += '&';
      } else if (e == "quot") {
        out += '"';
      } else if (e == "apos") {
        out += '\'';
      } else if (e.size() > 1 && e[0] == '#') {
        const bool hex = e[1] == 'x';
        unsigned code = 0;
        const std::string_view digits = e.substr(hex ? 2 : 1);
        const auto [end, ec] =
            std::from_chars(digits.data(), digits.data() + digits.size(), code, hex ? 16 : 10);
        if (ec != std::errc{} || end != digits.data() + digits.size() || code == 0 || code > 0x7f) {
          out += '?';  // a name only, for messages: non-ASCII code points are not kept
        } else {
          out += static_cast<char>(code);
        }
      } else {
        fail("unknown XML entity " + detail::quoted(std::string("&") + std::string(e) + ";"));
      }
      i = semi;
    }
    return out;
  }

  // ---- The document. ------------------------------------------------------------------------

  void read_document(vti_header& h) {
    std::vector<std::string> open;
    bool seen_root = false;
    for (;;) {
      std::optional<xml_tag> tag = next_tag();
      if (!tag) {
        if (!seen_root) {
          fail(
              "not a VTK XML file (expected <VTKFile type=\"ImageData\" …>, found no XML "
              "element)");
        }
        if (!open.empty()) fail("the file ends inside <" + name_text(open.back()) + ">");
        return;
      }
      if (tag->what == xml_tag::kind::close) {
        if (open.empty() || open.back() != tag->name) {
          fail("</" + name_text(tag->name) + ">" + at_text(tag->at) + " closes " +
               (open.empty() ? std::string("nothing") : "<" + name_text(open.back()) + ">"));
        }
        open.pop_back();
        if (open.empty()) return;  // </VTKFile>
        continue;
      }
      const std::string parent = open.empty() ? std::string() : open.back();
      if (!seen_root) {
        if (tag->name != "VTKFile") {
          fail("not a VTK XML file (expected <VTKFile> as the root element, found <" +
               name_text(tag->name) + ">)");
        }
        seen_root = true;
        read_vtkfile(*tag, h);
      } else if (open.empty()) {
        fail("a second root element <" + name_text(tag->name) + ">" + at_text(tag->at));
      } else if (tag->name == data_element() && parent == "VTKFile") {
        read_image_data(*tag);
      } else if (parallel_ && tag->name == "PPointData" && parent == "PImageData") {
        if (const std::string* s = tag->attribute("Scalars")) scalars_ = *s;
      } else if (parallel_ && tag->name == "PDataArray" && parent == "PPointData") {
        add_array(*tag);
      } else if (parallel_ && tag->name == "Piece" && parent == "PImageData") {
        add_source(*tag);
      } else if (tag->name == "Piece" && parent == "ImageData") {
        if (++pieces_ > 1) {
          fail("the image data holds more than one <Piece>" + at_text(tag->at) +
               ": progiso reads a whole image in one piece (as VTK's serial writer makes it)");
        }
        const std::string* e = tag->attribute("Extent");
        if (e == nullptr) fail("<Piece>" + at_text(tag->at) + " has no Extent");
        piece_extent_ = parse_extent(*e, "Extent");
      } else if (tag->name == "PointData" && parent == "Piece") {
        if (const std::string* s = tag->attribute("Scalars")) scalars_ = *s;
      } else if (tag->name == "DataArray" && parent == "PointData") {
        add_array(*tag);
      } else if (tag->name == "AppendedData" && parent == "VTKFile") {
        start_appended(*tag);
        return;  // binary from here on
      }
      if (tag->what == xml_tag::kind::open) {
        if (open.size() == max_depth)
          fail("XML elements nest deeper than " + std::to_string(max_depth) + at_text(tag->at));
        open.push_back(tag->name);
      }
    }
  }

  void read_vtkfile(const xml_tag& t, vti_header& h) {
    const std::string* type = t.attribute("type");
    const std::string expected(data_element());
    if (type == nullptr) fail("<VTKFile> has no type (expected type=\"" + expected + "\")");
    if (*type != expected) {
      fail("VTK XML data of type " + detail::quoted(*type) + " is not supported (expected " +
           expected +
           (parallel_ ? ", a .pvti file: a regular grid in pieces"
                      : ", a .vti file: a regular grid of samples") +
           (*type == "PImageData" ? "; a .pvti names its pieces: give it the name .pvti" : "") +
           (*type == "ImageData" ? "; name a single image .vti" : "") + ")");
    }
    if (const std::string* v = t.attribute("version")) {
      const std::optional<double> x = to_real<double>(*v);
      if (!x || !(*x >= 0.0) || *x >= 3.0) {
        fail("VTK XML version " + detail::quoted(*v) + " is not supported (expected 0.1 to 2.x)");
      }
    }
    if (const std::string* b = t.attribute("byte_order")) {
      if (*b == "BigEndian") {
        h.big_endian = true;
      } else if (*b != "LittleEndian") {
        fail("byte_order " + detail::quoted(*b) + " (expected LittleEndian or BigEndian)");
      }
    }
    if (const std::string* ht = t.attribute("header_type")) {
      if (*ht == "UInt64") {
        h.uint64_headers = true;
      } else if (*ht != "UInt32") {
        fail("header_type " + detail::quoted(*ht) + " (expected UInt32 or UInt64)");
      }
    }
    if (const std::string* c = t.attribute("compressor")) {
      if (*c == "vtkZLibDataCompressor") {
        h.zlib = true;
      } else if (*c == "vtkLZ4DataCompressor" || *c == "vtkLZMADataCompressor") {
        fail("compressor " + *c +
             " is not supported (expected vtkZLibDataCompressor or none: write the file with "
             "zlib compression, ParaView's default)");
      } else if (!c->empty()) {
        fail("unknown compressor " + detail::quoted(*c) +
             " (expected vtkZLibDataCompressor or none)");
      }
    }
  }

  void read_image_data(const xml_tag& t) {
    const std::string* e = t.attribute("WholeExtent");
    if (e == nullptr) fail("<" + std::string(data_element()) + "> has no WholeExtent");
    whole_extent_ = parse_extent(*e, "WholeExtent");
    for (const char* key : {"Origin", "Spacing"}) {
      if (const std::string* v = t.attribute(key)) {
        std::array<double, 3> x{};
        parse_numbers(*v, key, x);
        (std::string_view(key) == "Origin" ? origin_ : spacing_) = x;
      }
    }
    if (const std::string* d = t.attribute("Direction")) parse_numbers(*d, "Direction", direction_);
  }

  std::array<std::int64_t, 6> parse_extent(const std::string& v, std::string_view key) const {
    const std::vector<std::string_view> w = value_words(v);
    std::array<std::int64_t, 6> e{};
    if (w.size() != 6) {
      fail(std::string(key) + " " + detail::quoted(v) +
           ": expected 6 integers (x0 x1 y0 y1 z0 z1)");
    }
    for (std::size_t i = 0; i < 6; ++i) {
      const auto x = to_integer<std::int32_t>(w[i]);
      if (!x) fail(std::string(key) + " holds " + detail::quoted(w[i]) + ", expected an integer");
      e[i] = *x;
    }
    return e;
  }

  template <std::size_t N>
  void parse_numbers(const std::string& v, std::string_view key, std::array<double, N>& out) const {
    const std::vector<std::string_view> w = value_words(v);
    if (w.size() != N) {
      fail(std::string(key) + " " + detail::quoted(v) + ": expected " + std::to_string(N) +
           " numbers");
    }
    for (std::size_t i = 0; i < N; ++i) {
      const auto x = to_real<double>(w[i]);
      if (!x || !std::isfinite(*x)) {
        fail(std::string(key) + " holds " + detail::quoted(w[i]) + ", expected a finite number");
      }
      out[i] = *x;
    }
  }

  void add_array(const xml_tag& t) {
    array_entry a;
    a.tag_at = t.at;
    a.text_at = bytes_.offset();
    if (const std::string* n = t.attribute("Name")) a.name = *n;
    const std::string* type = t.attribute("type");
    if (type == nullptr) fail("<DataArray>" + at_text(t.at) + " has no type");
    a.type = *type;
    if (const std::string* c = t.attribute("NumberOfComponents")) a.components = *c;
    const std::string* f = t.attribute("format");
    if (f == nullptr && !parallel_) fail("<DataArray>" + at_text(t.at) + " has no format");
    if (f != nullptr) a.format = *f;
    if (const std::string* o = t.attribute("offset")) {
      a.offset = to_integer<std::uint64_t>(*o);
      if (!a.offset) fail("<DataArray> offset " + detail::quoted(*o) + ", expected a byte offset");
    }
    arrays_.push_back(std::move(a));
  }

  void start_appended(const xml_tag& t) {
    const std::string* e = t.attribute("encoding");
    if (e == nullptr || (*e != "raw" && *e != "base64")) {
      fail("<AppendedData> encoding " +
           (e == nullptr ? std::string("missing") : detail::quoted(*e)) +
           " (expected raw or base64)");
    }
    appended_base64_ = *e == "base64";
    int c = bytes_.get();
    while (c != -1 && is_space(static_cast<char>(c))) c = bytes_.get();
    if (c != '_') {
      fail("<AppendedData>" + at_text(t.at) +
           " does not start with '_' (the appended data follows an underscore)");
    }
    appended_at_ = bytes_.offset();
  }

  // ---- The volume. --------------------------------------------------------------------------

  void finish(vti_header& h) {
    if (!whole_extent_) fail("no <ImageData> element (expected one inside <VTKFile>)");
    if (pieces_ == 0) fail("<ImageData> holds no <Piece>");
    if (*piece_extent_ != *whole_extent_) {
      fail("the piece's Extent is not the WholeExtent: progiso reads a whole image in one piece");
    }
    const std::array<std::int64_t, 6>& e = *whole_extent_;
    h.extent = e;
    h.dims = grid_dims(e, "WholeExtent");
    const array_entry& a = chosen_array();
    h.type = checked_type(a);
    h.array = a.name;
    if (a.format == "ascii") {
      h.format = vti_data_format::ascii;
      h.data_offset = a.text_at;
    } else if (a.format == "binary") {
      h.format = vti_data_format::binary;
      h.base64 = true;
      h.data_offset = a.text_at;
    } else if (a.format == "appended") {
      h.format = vti_data_format::appended;
      if (!a.offset) fail("appended point array " + detail::quoted(a.name) + " has no offset");
      if (!appended_at_) {
        fail("point array " + detail::quoted(a.name) +
             " is appended, but the file has no <AppendedData>");
      }
      h.base64 = appended_base64_;
      if (*a.offset > in_.size() - std::min(in_.size(), *appended_at_)) {
        fail("point array " + detail::quoted(a.name) + " starts at offset " +
             std::to_string(*a.offset) + " of the appended data, past the end of the file");
      }
      h.data_offset = *appended_at_ + *a.offset;
    } else {
      fail("point array " + detail::quoted(a.name) + " has format " + detail::quoted(a.format) +
           " (expected ascii, binary or appended)");
    }
    geometry(e, h.spacing, h.origin, h.world);
  }

  [[nodiscard]] std::string_view data_element() const noexcept {
    return parallel_ ? "PImageData" : "ImageData";
  }

  /// Points per axis of an extent: 2 to 32769 each.
  index3 grid_dims(const std::array<std::int64_t, 6>& e, std::string_view key) const {
    index3 d{};
    for (std::size_t a = 0; a < 3; ++a) {
      const std::int64_t n = e[2 * a + 1] - e[2 * a] + 1;
      if (n < 2 || n > nrrd_max_axis_size) {
        fail(std::string(key) + " gives axis " + std::to_string(a) + " " + std::to_string(n) +
             " points, expected 2 to " + std::to_string(nrrd_max_axis_size) +
             (n == 1 ? " (a 2-D image is not a volume)" : ""));
      }
      d[a] = n;
    }
    return d;
  }

  /// The sample type of a scalar array of a type progiso has.
  sample_type checked_type(const array_entry& a) const {
    const auto s = std::find_if(types.begin(), types.end(),
                                [&](const type_spelling& x) { return x.name == a.type; });
    if (s == types.end()) {
      fail("point array " + detail::quoted(a.name) + " has type " + detail::quoted(a.type) +
           ", not supported (expected Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32 or "
           "Float64)");
    }
    if (a.components != "1") {
      fail("point array " + detail::quoted(a.name) + " has " + detail::quoted(a.components) +
           " components: expected 1 (a scalar volume)");
    }
    return s->type;
  }

  /// Point (i, j, k) of the extent lies at Origin + Direction · (Spacing ⊙ (x0 + i, …)). A zero
  /// spacing is taken as 1, as the legacy reader takes it.
  void geometry(const std::array<std::int64_t, 6>& e, std::array<double, 3>& spacing,
                std::array<double, 3>& origin, index_to_world& world) const {
    std::array<double, 3> step{};
    for (std::size_t c = 0; c < 3; ++c) step[c] = spacing_[c] != 0.0 ? spacing_[c] : 1.0;
    for (std::size_t r = 0; r < 3; ++r) {
      double t = origin_[r];
      for (std::size_t c = 0; c < 3; ++c) {
        world.m[r][c] = direction_[3 * r + c] * step[c];
        t += world.m[r][c] * static_cast<double>(e[2 * c]);
      }
      world.m[r][3] = t;
      spacing[r] = std::abs(step[r]);
      origin[r] = origin_[r] + step[r] * static_cast<double>(e[2 * r]);
    }
  }

  /// A .pvti's <Piece Extent=… Source=…>: the file resolved against the .pvti's directory.
  void add_source(const xml_tag& t) {
    const std::string* e = t.attribute("Extent");
    const std::string* src = t.attribute("Source");
    if (e == nullptr || src == nullptr) {
      fail("<Piece>" + at_text(t.at) + " needs an Extent and a Source (the piece's .vti file)");
    }
    if (sources_.size() == vti_max_pieces) {
      fail("names more than " + std::to_string(vti_max_pieces) + " pieces");
    }
    if (src->empty() || *src == "-") {
      fail("<Piece>" + at_text(t.at) + " has Source " + detail::quoted(*src) +
           ", expected a file name");
    }
    const fs::path p{*src};
    sources_.push_back({parse_extent(*e, "Extent"), p.is_absolute() ? p : file_.parent_path() / p});
  }

  const array_entry& chosen_array() const {
    if (!want_.empty()) {
      for (const array_entry& a : arrays_) {
        if (a.name == want_) return a;
      }
      fail("holds no point array named " + detail::quoted(want_) + " (the array its .pvti reads)");
    }
    if (arrays_.empty()) {
      fail(
          "no point data array (expected a <DataArray> in <PointData>; progiso reads point "
          "scalars, not cell data)");
    }
    if (scalars_.empty()) return arrays_.front();
    for (const array_entry& a : arrays_) {
      if (a.name == scalars_) return a;
    }
    fail("<PointData> names Scalars=" + detail::quoted(scalars_) +
         ", but holds no array of that name");
  }

  input_file& in_;
  byte_stream bytes_;
  const fs::path& file_;
  std::optional<std::array<std::int64_t, 6>> whole_extent_;
  std::optional<std::array<std::int64_t, 6>> piece_extent_;
  std::array<double, 3> origin_{0.0, 0.0, 0.0};
  std::array<double, 3> spacing_{1.0, 1.0, 1.0};
  std::array<double, 9> direction_{1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  int pieces_ = 0;
  std::string scalars_;
  std::vector<array_entry> arrays_;
  std::optional<std::uint64_t> appended_at_;
  bool appended_base64_ = false;
  bool parallel_ = false;
  std::string want_;
  std::vector<pvti_piece> sources_;
};

// ---- Data. ----------------------------------------------------------------------------------

/// The bytes of an array from its offset: as they are (raw appended data), or decoded from
/// base64 (inline binary data and base64 appended data), which ends at the next '<'. VTK writes
/// a block's header and its data as separate base64 runs, each padded; a run's padding ends it
/// and the next starts afresh. Whitespace is skipped.
class array_bytes {
 public:
  array_bytes(input_file& in, std::uint64_t offset, bool base64, std::string label)
      : in_(in), base64_(base64), label_(std::move(label)), buf_(buffer_bytes) {
    in_.seek(offset);
    offset_ = offset;
  }

  /// Bytes the rest of the file can give at most.
  [[nodiscard]] std::uint64_t capacity() const noexcept {
    const std::uint64_t left = in_.size() - std::min(in_.size(), offset_);
    return base64_ ? left / 4 * 3 + 3 : left;
  }

  /// Fills out; returns how many bytes (fewer only when the data ends).
  std::size_t read(std::byte* out, std::size_t n) {
    if (!base64_) {
      const std::size_t got = in_.read(out, n);
      offset_ += got;
      return got;
    }
    std::size_t done = 0;
    while (done < n) {
      if (pending_count_ > pending_used_) {
        out[done++] = pending_[pending_used_++];
        continue;
      }
      if (!decode_quad()) break;
    }
    return done;
  }

 private:
  int next_char() {
    if (pos_ == end_) {
      pos_ = 0;
      end_ = in_.read(buf_.data(), buf_.size());
      if (end_ == 0) return -1;
    }
    ++offset_;
    return static_cast<unsigned char>(buf_[pos_++]);
  }

  static int value_of(int c) noexcept {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  }

  /// Decodes the next four characters into pending_; false at the end of the data.
  bool decode_quad() {
    if (ended_) return false;
    std::array<int, 4> q{};
    int got = 0;
    int pads = 0;
    while (got < 4) {
      const int c = next_char();
      if (c == -1 || c == '<') {
        ended_ = true;
        if (got == 0) return false;
        throw error(in_.path().string() + ": " + label_ + " ends inside a base64 group");
      }
      if (is_space(static_cast<char>(c))) continue;
      if (c == '=') {
        if (got < 2) {
          throw error(in_.path().string() + ": " + label_ + " has '=' inside a base64 group");
        }
        q[static_cast<std::size_t>(got++)] = 0;
        ++pads;
        continue;
      }
      const int v = value_of(c);
      if (v < 0 || pads > 0) {
        throw error(in_.path().string() + ": " + label_ + " holds " +
                    detail::quoted(std::string(1, static_cast<char>(c))) + " at byte " +
                    std::to_string(offset_ - 1) + ", not base64");
      }
      q[static_cast<std::size_t>(got++)] = v;
    }
    const std::uint32_t bits =
        (static_cast<std::uint32_t>(q[0]) << 18) | (static_cast<std::uint32_t>(q[1]) << 12) |
        (static_cast<std::uint32_t>(q[2]) << 6) | static_cast<std::uint32_t>(q[3]);
    pending_[0] = static_cast<std::byte>(bits >> 16);
    pending_[1] = static_cast<std::byte>((bits >> 8) & 0xff);
    pending_[2] = static_cast<std::byte>(bits & 0xff);
    pending_count_ = static_cast<std::size_t>(3 - pads);
    pending_used_ = 0;
    return true;
  }

  input_file& in_;
  bool base64_;
  std::string label_;
  std::vector<char> buf_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t offset_ = 0;
  std::array<std::byte, 3> pending_{};
  std::size_t pending_count_ = 0;
  std::size_t pending_used_ = 0;
  bool ended_ = false;
};

class data_reader {
 public:
  data_reader(const vti_header& h, input_file& in)
      : h_(h),
        in_(in),
        label_("point array " + detail::quoted(h.array)),
        src_(in, h.data_offset, h.base64, label_) {
    bytes_ = sample_size(h.type);
    for (std::int64_t d : h.dims) bytes_ *= static_cast<std::uint64_t>(d);
  }

  std::vector<std::byte> run() {
    std::vector<std::byte> out = h_.zlib ? read_blocks() : read_plain();
    const bool host_big = std::endian::native == std::endian::big;
    if (sample_size(h_.type) > 1 && h_.big_endian != host_big) {
      swap_sample_bytes(out, sample_size(h_.type));
    }
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw error(in_.path().string() + ": " + label_ + " " + what);
  }

  std::string shape() const {
    return std::to_string(h_.dims[0]) + "," + std::to_string(h_.dims[1]) + "," +
           std::to_string(h_.dims[2]) + " of " + std::string(to_string(h_.type));
  }

  std::uint64_t header_word(std::string_view what) {
    const std::size_t n = h_.uint64_headers ? 8 : 4;
    std::array<std::byte, 8> b{};
    if (src_.read(b.data(), n) != n)
      fail("ends inside its header (expected its " + std::string(what) + ")");
    const bool host_big = std::endian::native == std::endian::big;
    if (h_.big_endian != host_big) std::reverse(b.begin(), b.begin() + static_cast<long>(n));
    if (n == 4) {
      std::uint32_t v = 0;
      std::memcpy(&v, b.data(), 4);
      return v;
    }
    std::uint64_t v = 0;
    std::memcpy(&v, b.data(), 8);
    return v;
  }

  std::vector<std::byte> allocate() const {
    if (bytes_ > std::numeric_limits<std::size_t>::max()) {
      fail("declares " + std::to_string(bytes_) + " bytes, more than fit in memory");
    }
    return std::vector<std::byte>(static_cast<std::size_t>(bytes_));
  }

  std::vector<std::byte> read_plain() {
    const std::uint64_t declared = header_word("byte count");
    if (declared != bytes_) {
      fail("holds " + std::to_string(declared) + " bytes by its header, expected " +
           std::to_string(bytes_) + " (WholeExtent " + shape() + ")");
    }
    if (src_.capacity() < bytes_) {
      fail("cannot hold the declared " + std::to_string(bytes_) + " bytes (" + shape() +
           "): the file has room for at most " + std::to_string(src_.capacity()));
    }
    std::vector<std::byte> out = allocate();
    const std::size_t got = src_.read(out.data(), out.size());
    if (got != out.size()) {
      fail("ends after " + std::to_string(got) + " of " + std::to_string(out.size()) + " bytes");
    }
    return out;
  }

  std::vector<std::byte> read_blocks() {
    const std::uint64_t count = header_word("block count");
    const std::uint64_t block = header_word("block size");
    const std::uint64_t last = header_word("last block's size");
    const std::uint64_t word = h_.uint64_headers ? 8 : 4;
    const std::uint64_t last_size = last == 0 ? block : last;
    // The blocks must give exactly the samples: count - 1 full blocks and the last.
    const bool sizes_ok = count >= 1 && block > 0 && last_size <= block &&
                          (count - 1) <= (bytes_ / block) &&
                          (count - 1) * block + last_size == bytes_;
    if (!sizes_ok) {
      fail("has " + std::to_string(count) + " compressed blocks of " + std::to_string(block) +
           " bytes (last " + std::to_string(last) + "), which do not make the expected " +
           std::to_string(bytes_) + " bytes (" + shape() + ")");
    }
    if (count > src_.capacity() / word) {
      fail("declares " + std::to_string(count) + " compressed blocks, more than the file can list");
    }
    std::vector<std::uint64_t> sizes(static_cast<std::size_t>(count));
    std::uint64_t total = 0;
    std::uint64_t largest = 0;
    for (std::uint64_t& s : sizes) {
      s = header_word("compressed block sizes");
      total += s;
      largest = std::max(largest, s);
      if (total > src_.capacity()) {
        fail("declares compressed blocks of more bytes than the file holds after them (" +
             std::to_string(src_.capacity()) + ")");
      }
    }
    if (!gzip_can_hold(total, bytes_)) {
      fail("has " + std::to_string(total) + " bytes of zlib data, which cannot hold the declared " +
           std::to_string(bytes_) + " bytes (" + shape() + ")");
    }
    std::vector<std::byte> out = allocate();
    std::vector<std::byte> packed(static_cast<std::size_t>(largest));
    std::uint64_t at = 0;
    for (std::size_t b = 0; b < sizes.size(); ++b) {
      const std::size_t n = static_cast<std::size_t>(sizes[b]);
      if (src_.read(packed.data(), n) != n) {
        fail("ends inside compressed block " + std::to_string(b + 1) + " of " +
             std::to_string(sizes.size()));
      }
      const std::uint64_t want = b + 1 == sizes.size() ? last_size : block;
      auto got = static_cast<uLongf>(want);
      const int rc =
          uncompress(reinterpret_cast<Bytef*>(out.data() + at), &got,
                     reinterpret_cast<const Bytef*>(packed.data()), static_cast<uLong>(n));
      if (rc == Z_MEM_ERROR) throw std::bad_alloc();
      if (rc != Z_OK || got != want) {
        fail("has a corrupt compressed block " + std::to_string(b + 1) + " of " +
             std::to_string(sizes.size()) + " (zlib: " +
             (rc == Z_OK ? "inflates to " + std::to_string(got) + " bytes, expected " +
                               std::to_string(want)
              : rc == Z_BUF_ERROR ? std::string("more data than its declared size, or "
                                                "truncated")
                                  : std::string("invalid data")) +
             ")");
      }
      at += want;
    }
    return out;
  }

  const vti_header& h_;
  input_file& in_;
  std::string label_;
  array_bytes src_;
  std::uint64_t bytes_ = 0;
};

}  // namespace

vti_header parse_vti_header(input_file& file, std::string_view array) {
  return parser(file, false, array).run();
}

pvti_header parse_pvti_header(input_file& file) { return parser(file, true).run_parallel(); }

namespace {

/// Whether the bytes after a piece's array start can hold its samples, by the encoding's bound
/// (raw: the bytes; base64: 3 bytes a 4 characters; ascii: 2 bytes a value; zlib: deflate's
/// ratio), without reading them.
bool can_hold(const vti_header& h, std::uint64_t file_size, std::uint64_t bytes) {
  const std::uint64_t left = file_size - std::min(file_size, h.data_offset);
  if (h.format == vti_data_format::ascii) return left / 2 + 1 >= bytes / sample_size(h.type);
  const std::uint64_t raw = h.base64 ? left / 4 * 3 + 3 : left;
  return h.zlib ? gzip_can_hold(raw, bytes) : raw >= bytes;
}

/// Runs `f`, adding the piece's place in the .pvti to any error it throws.
template <class F>
auto in_piece(const fs::path& pvti, std::size_t k, std::size_t n, F&& f) {
  try {
    return f();
  } catch (const error& e) {
    throw error(std::string(e.what()) + " (piece " + std::to_string(k + 1) + " of " +
                std::to_string(n) + " named by " + pvti.string() + ")");
  }
}

std::string extent_text(const std::array<std::int64_t, 6>& e) {
  std::string out;
  for (std::int64_t v : e) out += (out.empty() ? "" : " ") + std::to_string(v);
  return out;
}

}  // namespace

std::vector<std::byte> read_pvti_samples(const pvti_header& h, const fs::path& pvti) {
  const std::size_t item = sample_size(h.type);
  const std::size_t n = h.pieces.size();
  std::uint64_t points = 1;
  for (std::int64_t d : h.dims) points *= static_cast<std::uint64_t>(d);
  const std::uint64_t bytes = points * item;  // ≤ 32769³ × 8 < 2^48
  // Pass 1: every piece's header, its place and its data's capacity.
  std::uint64_t present = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const pvti_piece& piece = h.pieces[k];
    in_piece(pvti, k, n, [&] {
      const auto& e = piece.extent;
      for (std::size_t a = 0; a < 3; ++a) {
        if (e[2 * a] < h.extent[2 * a] || e[2 * a + 1] > h.extent[2 * a + 1] ||
            e[2 * a] > e[2 * a + 1]) {
          throw error(pvti.string() + ": piece extent " + extent_text(e) +
                      " does not lie in the WholeExtent " + extent_text(h.extent));
        }
      }
      input_file in(piece.file, "VTK XML piece");
      const vti_header p = parse_vti_header(in, h.array);
      if (p.extent != e) {
        throw error(piece.file.string() + ": WholeExtent " + extent_text(p.extent) +
                    ", but the .pvti gives the piece the extent " + extent_text(e));
      }
      if (p.type != h.type) {
        throw error(piece.file.string() + ": point array " + detail::quoted(h.array) + " is " +
                    std::string(to_string(p.type)) + ", but the .pvti declares it " +
                    std::string(to_string(h.type)));
      }
      std::uint64_t piece_bytes = item;
      for (std::int64_t d : p.dims) piece_bytes *= static_cast<std::uint64_t>(d);
      if (!can_hold(p, in.size(), piece_bytes)) {
        throw error(piece.file.string() + ": the data after point array " +
                    detail::quoted(h.array) + " cannot hold its " + std::to_string(piece_bytes) +
                    " bytes");
      }
      // Saturating: 2^20 pieces of up to 2^48 bytes each could pass 2^64.
      present += std::min(piece_bytes, std::numeric_limits<std::uint64_t>::max() - present);
    });
  }
  if (present < bytes) {
    throw error(pvti.string() + ": its " + std::to_string(n) + " pieces hold " +
                std::to_string(present) + " bytes, fewer than the " + std::to_string(bytes) +
                " of the WholeExtent " + extent_text(h.extent) + ": points are missing");
  }
  // Pass 2: each piece decoded and copied row by row; a bit per point says it came.
  std::vector<std::byte> out(static_cast<std::size_t>(bytes));
  std::vector<std::uint64_t> seen(static_cast<std::size_t>((points + 63) / 64), 0);
  const auto nx = static_cast<std::uint64_t>(h.dims[0]);
  const auto ny = static_cast<std::uint64_t>(h.dims[1]);
  for (std::size_t k = 0; k < n; ++k) {
    const pvti_piece& piece = h.pieces[k];
    in_piece(pvti, k, n, [&] {
      input_file in(piece.file, "VTK XML piece");
      const vti_header p = parse_vti_header(in, h.array);
      const std::vector<std::byte> samples = read_vti_samples(p, in);
      const auto px = static_cast<std::uint64_t>(p.dims[0]);
      const auto x0 = static_cast<std::uint64_t>(p.extent[0] - h.extent[0]);
      std::size_t from = 0;
      for (std::int64_t z = p.extent[4]; z <= p.extent[5]; ++z) {
        for (std::int64_t y = p.extent[2]; y <= p.extent[3]; ++y) {
          const std::uint64_t at = x0 + nx * (static_cast<std::uint64_t>(y - h.extent[2]) +
                                              ny * static_cast<std::uint64_t>(z - h.extent[4]));
          std::memcpy(out.data() + at * item, samples.data() + from, px * item);
          from += px * item;
          for (std::uint64_t i = at; i < at + px; ++i) seen[i / 64] |= std::uint64_t{1} << (i % 64);
        }
      }
    });
  }
  for (std::size_t w = 0; w < seen.size(); ++w) {
    const std::uint64_t want = w + 1 < seen.size() || points % 64 == 0
                                   ? ~std::uint64_t{0}
                                   : (std::uint64_t{1} << (points % 64)) - 1;
    if (seen[w] == want) continue;
    const std::uint64_t i = w * 64 + static_cast<std::uint64_t>(std::countr_one(seen[w]));
    throw error(pvti.string() + ": point (" +
                std::to_string(static_cast<std::int64_t>(i % nx) + h.extent[0]) + ", " +
                std::to_string(static_cast<std::int64_t>(i / nx % ny) + h.extent[2]) + ", " +
                std::to_string(static_cast<std::int64_t>(i / nx / ny) + h.extent[4]) +
                ") of the WholeExtent lies in no piece");
  }
  return out;
}

std::vector<std::byte> read_vti_samples(const vti_header& header, input_file& file) {
  if (header.format == vti_data_format::ascii) {
    // Numbers in the element's text, as a NRRD ascii encoding reads them: values after the last
    // sample (the closing tag) are not read.
    nrrd_header n;
    n.dims = header.dims;
    n.type = header.type;
    n.encoding = nrrd_encoding::ascii;
    n.data_offset = header.data_offset;
    n.format = "VTK XML";
    return read_nrrd_samples(n, file);
  }
  return data_reader(header, file).run();
}

bool has_vti_name(const std::filesystem::path& file) { return lower_extension(file) == ".vti"; }

bool has_pvti_name(const std::filesystem::path& file) { return lower_extension(file) == ".pvti"; }

}  // namespace progiso::detail
