#include <progiso/io/contour_io.hpp>

#include <png.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso {
namespace {

namespace fs = std::filesystem;

using detail::errno_text;
using detail::lower_extension;

/// Shortest decimal that reads back to the same value (integers as integers).
template <class T>
std::string_view format_number(T value, std::array<char, 40>& buffer) {
  const auto r = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  PROGISO_ASSERT(r.ec == std::errc{});
  return {buffer.data(), static_cast<std::size_t>(r.ptr - buffer.data())};
}

// Stream-style formatting onto a detail::atomic_output.
class text_out {
 public:
  explicit text_out(detail::atomic_output& out) : out_(out) {}
  text_out& operator<<(std::string_view text) {
    out_.write(text);
    return *this;
  }
  text_out& operator<<(char c) { return *this << std::string_view(&c, 1); }
  text_out& operator<<(double v) {
    std::array<char, 40> b;
    return *this << format_number(v, b);
  }
  text_out& operator<<(std::uint64_t v) {
    std::array<char, 40> b;
    return *this << format_number(v, b);
  }

 private:
  detail::atomic_output& out_;
};

void check_preconditions(const contour_set& contours) {
#if defined(PROGISO_ENABLE_ASSERTS)
  for (const polyline& p : contours.polylines) {
    PROGISO_ASSERT(!p.vertices.empty());
    for (std::uint32_t v : p.vertices) PROGISO_ASSERT(v < contours.vertices.size());
    PROGISO_ASSERT(p.closed || p.vertices.size() < 2 || p.vertices.front() != p.vertices.back());
  }
#else
  (void)contours;
#endif
}

bool same_isovalue(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

// =============================================================================================
// In-memory PNG encoding for the SVG background, through libpng.
//
// libpng reports errors by calling an error function that must not return; ours records the
// message and longjmps back to the setjmp in encode_gray_png(). Skipping a C++ destructor by
// longjmp is undefined behaviour, so that frame holds only trivially destructible locals, and
// everything that owns memory lives in the caller's frame, which no longjmp leaves.

struct png_failure {
  char message[200] = {};
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  auto* failure = static_cast<png_failure*>(png_get_error_ptr(png));
  std::snprintf(failure->message, sizeof failure->message, "%s",
                message != nullptr ? message : "unknown error");
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

void on_png_write(png_structp png, png_bytep data, png_size_t size) {
  auto* out = static_cast<std::string*>(png_get_io_ptr(png));
  bool appended = true;
  try {
    out->append(reinterpret_cast<const char*>(data), size);
  } catch (...) {
    appended = false;  // png_error() must not longjmp out of the handler itself
  }
  if (!appended) png_error(png, "out of memory");
}

void on_png_flush(png_structp) {}

/// Encodes `rows` (height pointers to width bytes) as an 8-bit gray PNG appended to `out`.
/// False when libpng failed.
bool encode_gray_png(png_structp png, png_infop info, png_uint_32 width, png_uint_32 height,
                     png_bytepp rows, std::string* out) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  png_set_write_fn(png, out, on_png_write, on_png_flush);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

struct png_write_handles {
  png_structp png = nullptr;
  png_infop info = nullptr;
  png_write_handles() = default;
  png_write_handles(const png_write_handles&) = delete;
  png_write_handles& operator=(const png_write_handles&) = delete;
  ~png_write_handles() {
    if (png != nullptr) png_destroy_write_struct(&png, info != nullptr ? &info : nullptr);
  }
};

/// The image as an 8-bit gray PNG: its value range mapped linearly onto 0..255, NaN to 0.
std::string image_png(const volume& image, const std::string& file_name) {
  const auto width = static_cast<std::size_t>(image.dims()[0]);
  const auto height = static_cast<std::size_t>(image.dims()[1]);
  if (width > PNG_UINT_31_MAX || height > PNG_UINT_31_MAX) {
    throw error(file_name + ": the image is too large to embed as PNG (" + std::to_string(width) +
                " x " + std::to_string(height) + " samples)");
  }
  const auto [lo, hi] = image.value_range();
  const double scale = hi > lo ? 255.0 / (hi - lo) : 0.0;
  std::vector<unsigned char> gray(width * height);
  for (std::size_t i = 0; i < gray.size(); ++i) {
    // The clamp also sends NaN (and infinities, whose scale is 0 or the range's) to 0 or 255.
    const double t = (image.at(i) - lo) * scale;
    gray[i] = t >= 0.0 ? static_cast<unsigned char>(std::lround(std::min(t, 255.0))) : 0;
  }
  std::vector<png_bytep> rows(height);
  for (std::size_t y = 0; y < height; ++y) rows[y] = gray.data() + y * width;

  png_failure failure;
  png_write_handles h;
  h.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &failure, on_png_error, on_png_warning);
  if (h.png != nullptr) h.info = png_create_info_struct(h.png);
  if (h.png == nullptr || h.info == nullptr) {
    throw error(file_name + ": cannot set up libpng to encode the image (out of memory)");
  }
  std::string png;
  if (!encode_gray_png(h.png, h.info, static_cast<png_uint_32>(width),
                       static_cast<png_uint_32>(height), rows.data(), &png)) {
    throw error(file_name + ": cannot encode the image as PNG (libpng: " + failure.message + ")");
  }
  return png;
}

/// RFC 4648 base64 with padding.
std::string base64(std::string_view bytes) {
  constexpr std::string_view alphabet =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  const auto at = [&](std::size_t k) {
    return std::uint32_t{static_cast<unsigned char>(bytes[k])};
  };
  for (; i + 3 <= bytes.size(); i += 3) {
    const std::uint32_t group = (at(i) << 16) | (at(i + 1) << 8) | at(i + 2);
    for (int shift = 18; shift >= 0; shift -= 6) out += alphabet[(group >> shift) & 63u];
  }
  if (const std::size_t rest = bytes.size() - i; rest > 0) {
    const std::uint32_t group = (at(i) << 16) | (rest == 2 ? at(i + 1) << 8 : 0u);
    out += alphabet[group >> 18];
    out += alphabet[(group >> 12) & 63u];
    out += rest == 2 ? alphabet[(group >> 6) & 63u] : '=';
    out += '=';
  }
  return out;
}

// =============================================================================================
// OBJ reading helpers.

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

template <class T>
bool parse_whole(std::string_view word, T& value) {
  const auto r = std::from_chars(word.data(), word.data() + word.size(), value);
  return r.ec == std::errc{} && r.ptr == word.data() + word.size();
}

}  // namespace

// =============================================================================================
// Writers: one streaming implementation (contour_writer) behind the one-shot functions too.

namespace {

struct svg_frame {
  double x0 = 0.0;
  double y0 = 0.0;
  double w = 1.0;
  double h = 1.0;
};

/// The image's sample area: pixel (i, j) covers the unit square centred at origin + (i, j) × s.
svg_frame image_frame(const volume& image) {
  PROGISO_ASSERT(image.dims()[2] == 1);
  const auto& s = image.spacing();
  return {image.origin()[0] - 0.5 * s[0], image.origin()[1] - 0.5 * s[1],
          static_cast<double>(image.dims()[0]) * s[0], static_cast<double>(image.dims()[1]) * s[1]};
}

/// The contours' bounding box grown by half a unit on each side.
svg_frame bounding_frame(const contour_set& contours) {
  if (contours.vertices.empty()) return {};
  vec2 lo = contours.vertices[0];
  vec2 hi = lo;
  for (const vec2& p : contours.vertices) {
    for (std::size_t c = 0; c < 2; ++c) {
      lo[c] = std::min(lo[c], p[c]);
      hi[c] = std::max(hi[c], p[c]);
    }
  }
  return {lo[0] - 0.5, lo[1] - 0.5, hi[0] - lo[0] + 1.0, hi[1] - lo[1] + 1.0};
}

/// Distinct isovalues, ascending, NaN last.
std::vector<double> distinct_sorted(std::vector<double> values) {
  std::stable_sort(values.begin(), values.end(), [](double a, double b) {
    return std::make_pair(std::isnan(a), std::isnan(a) ? 0.0 : a) <
           std::make_pair(std::isnan(b), std::isnan(b) ? 0.0 : b);
  });
  std::vector<double> out;
  for (const double v : values) {
    if (out.empty() || !same_isovalue(out.back(), v)) out.push_back(v);
  }
  return out;
}

}  // namespace

struct contour_writer::impl {
  std::unique_ptr<detail::atomic_output> owned;
  detail::atomic_output* out = nullptr;
  bool svg = false;
  std::vector<double> isovalues;  // distinct, ascending: SVG colours by rank
  double stroke_width = 1.0;
  std::uint64_t vertices_written = 0;
  bool have_isovalue = false;
  double last_isovalue = 0.0;
  bool finished = false;

  // Yellow first (the usual contour-over-grayscale colour), then hues far from it and from
  // each other; all bright enough to read over dark and mid-gray backgrounds.
  static constexpr std::array<std::string_view, 8> palette = {
      "#ffd400", "#00d8ff", "#ff4fd8", "#6cff3c", "#ff8a1f", "#b08cff", "#ff3b3b", "#ffffff"};

  /// Writes the header. `counts` (vertices, polylines), when known in advance, go into the OBJ
  /// header comment and the SVG title.
  void begin(const std::vector<double>& all_isovalues, const volume* image, const svg_frame& frame,
             std::optional<std::pair<std::uint64_t, std::uint64_t>> counts, bool as_svg) {
    svg = as_svg;
    isovalues = distinct_sorted(all_isovalues);
    text_out o(*out);
    if (!svg) {
      o << "# generated by progiso: isocontours";
      if (counts) o << ", " << counts->first << " vertices, " << counts->second << " polylines";
      o << '\n';
      return;
    }
    // Nominal size: one unit per pixel, enlarged so that the longer side has at least 512 px;
    // the stroke width is chosen to come out at 1.5 px at that size.
    const double px_per_unit = std::max(1.0, 512.0 / std::max(frame.w, frame.h));
    stroke_width = 1.5 / px_per_unit;
    const std::string background =
        image != nullptr
            ? "data:image/png;base64," + base64(image_png(*image, out->target().string()))
            : "";
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" "
         "xmlns:xlink=\"http://www.w3.org/1999/xlink\" version=\"1.1\" width=\""
      << static_cast<double>(std::lround(frame.w * px_per_unit)) << "\" height=\""
      << static_cast<double>(std::lround(frame.h * px_per_unit)) << "\" viewBox=\"" << frame.x0
      << ' ' << frame.y0 << ' ' << frame.w << ' ' << frame.h << "\">\n";
    o << "<title>progiso isocontours";
    const char* sep = ": ";
    if (counts) {
      o << sep << counts->second << (counts->second == 1 ? " polyline" : " polylines");
      sep = ", ";
    }
    for (std::size_t k = 0; k < isovalues.size(); ++k) {
      o << (k > 0 ? ", " : sep)
        << (k > 0                   ? ""
            : isovalues.size() == 1 ? "isovalue "
                                    : "isovalues ")
        << isovalues[k];
    }
    o << "</title>\n";
    if (image != nullptr) {
      o << "<image x=\"" << frame.x0 << "\" y=\"" << frame.y0 << "\" width=\"" << frame.w
        << "\" height=\"" << frame.h
        << "\" preserveAspectRatio=\"none\" image-rendering=\"optimizeSpeed\" "
           "style=\"image-rendering:pixelated\" xlink:href=\""
        << background << "\"/>\n";
    }
  }

  void add(const contour_set& contours) {
    PROGISO_ASSERT(!finished);
    check_preconditions(contours);
    text_out o(*out);
    if (!svg) {
      for (const vec2& p : contours.vertices) o << "v " << p[0] << ' ' << p[1] << " 0\n";
      for (const polyline& line : contours.polylines) {
        if (!have_isovalue || !same_isovalue(line.isovalue, last_isovalue)) {
          o << "# isovalue " << line.isovalue << '\n';
          have_isovalue = true;
          last_isovalue = line.isovalue;
        }
        o << 'l';
        for (std::uint32_t v : line.vertices) o << ' ' << vertices_written + v + 1;
        if (line.closed) o << ' ' << vertices_written + line.vertices[0] + 1;
        o << '\n';
      }
      vertices_written += contours.vertices.size();
      return;
    }
    // Polylines grouped by isovalue, ascending (NaN last), each group in input order.
    std::vector<std::size_t> order(contours.polylines.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    const auto key = [&](std::size_t i) {
      const double v = contours.polylines[i].isovalue;
      return std::make_pair(std::isnan(v), std::isnan(v) ? 0.0 : v);
    };
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
    for (std::size_t next = 0; next < order.size();) {
      const double w = contours.polylines[order[next]].isovalue;
      const auto rank =
          static_cast<std::size_t>(std::find_if(isovalues.begin(), isovalues.end(),
                                                [&](double v) { return same_isovalue(v, w); }) -
                                   isovalues.begin());
      o << "<g data-isovalue=\"" << w << "\" fill=\"none\" stroke=\""
        << palette[rank % palette.size()] << "\" stroke-width=\"" << stroke_width
        << "\" stroke-linejoin=\"round\" stroke-linecap=\"round\">\n";
      for (; next < order.size() && same_isovalue(contours.polylines[order[next]].isovalue, w);
           ++next) {
        const polyline& line = contours.polylines[order[next]];
        o << (line.closed ? "<polygon points=\"" : "<polyline points=\"");
        for (std::size_t j = 0; j < line.vertices.size(); ++j) {
          const vec2& p = contours.vertices[line.vertices[j]];
          o << (j == 0 ? "" : " ") << p[0] << ',' << p[1];
        }
        o << "\"/>\n";
      }
      o << "</g>\n";
    }
  }

  void finish() {
    if (finished) return;
    if (svg) text_out(*out) << "</svg>\n";
    out->finish();
    finished = true;
  }
};

contour_writer::contour_writer(const std::filesystem::path& file,
                               const std::vector<double>& isovalues, const volume* image)
    : impl_(std::make_unique<impl>()) {
  impl_->owned = std::make_unique<detail::atomic_output>(file);
  impl_->out = impl_->owned.get();
  start(isovalues, image);
}

contour_writer::contour_writer(detail::atomic_output& out, const std::vector<double>& isovalues,
                               const volume* image)
    : impl_(std::make_unique<impl>()) {
  impl_->out = &out;
  start(isovalues, image);
}

void contour_writer::start(const std::vector<double>& isovalues, const volume* image) {
  const std::filesystem::path& file = impl_->out->target();
  const std::string ext = lower_extension(file);
  if (ext != ".obj" && ext != ".svg") {
    throw error(file.string() + ": unknown contour format \"" + file.extension().string() +
                "\" (expected .obj or .svg)");
  }
  if (ext == ".svg" && image == nullptr) {
    throw error(file.string() +
                ": streamed SVG contours are drawn over their image, and none was given");
  }
  impl_->begin(isovalues, image, image != nullptr ? image_frame(*image) : svg_frame{}, std::nullopt,
               ext == ".svg");
}

contour_writer::~contour_writer() = default;

void contour_writer::add(const contour_set& contours) { impl_->add(contours); }
void contour_writer::finish() { impl_->finish(); }
void contour_writer::commit() {
  impl_->finish();
  impl_->out->publish();
}

void contour_writer::write_whole(const std::filesystem::path& file, const contour_set& contours,
                                 const volume* image, bool svg) {
  check_preconditions(contours);
  std::vector<double> isovalues;
  for (const polyline& p : contours.polylines) isovalues.push_back(p.isovalue);
  auto i = std::make_unique<impl>();
  i->owned = std::make_unique<detail::atomic_output>(file);
  i->out = i->owned.get();
  i->begin(isovalues, image, image != nullptr ? image_frame(*image) : bounding_frame(contours),
           std::make_pair(std::uint64_t{contours.vertices.size()},
                          std::uint64_t{contours.polylines.size()}),
           svg);
  i->add(contours);
  i->finish();
  i->out->publish();
}

void write_contour_obj(const std::filesystem::path& file, const contour_set& contours) {
  contour_writer::write_whole(file, contours, nullptr, false);
}

void write_contour_svg(const std::filesystem::path& file, const contour_set& contours,
                       const volume* image) {
  contour_writer::write_whole(file, contours, image, true);
}

void write_contours(const std::filesystem::path& file, const contour_set& contours,
                    const volume* image) {
  const std::string ext = lower_extension(file);
  if (ext == ".obj") return write_contour_obj(file, contours);
  if (ext == ".svg") return write_contour_svg(file, contours, image);
  throw error(file.string() + ": unknown contour format \"" + file.extension().string() +
              "\" (expected .obj or .svg)");
}

// =============================================================================================
// Reader.

contour_set read_contour_obj(const std::filesystem::path& file) {
  const std::string name = file.string();
  const std::vector<char> data = detail::input_file(file, "OBJ").read_all();
  const std::string_view text(data.data(), data.size());

  contour_set contours;
  double isovalue = 0.0;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const auto fail = [&](const std::string& what) {
      return error(name + ":" + std::to_string(line_no) + ": " + what);
    };
    const std::vector<std::string_view> words = split_words(line);
    if (words.empty()) continue;

    if (words[0][0] == '#') {
      // "# isovalue W" (also "#isovalue W") sets the isovalue of the polylines that follow.
      const std::vector<std::string_view> rest = split_words(line.substr(line.find('#') + 1));
      if (!rest.empty() && rest[0] == "isovalue") {
        if (rest.size() != 2 || !parse_whole(rest[1], isovalue)) {
          throw fail("expected \"# isovalue\" and a number, found " + detail::quoted(line));
        }
      }
    } else if (words[0] == "v") {
      vec2 p{};
      double z = 0.0;
      const bool ok = (words.size() == 3 || words.size() == 4) && parse_whole(words[1], p[0]) &&
                      parse_whole(words[2], p[1]) &&
                      (words.size() == 3 || parse_whole(words[3], z));
      if (!ok) {
        throw fail("expected \"v x y 0\" with decimal numbers, found " + detail::quoted(line));
      }
      if (z != 0.0) {
        throw fail("expected a 2D contour vertex with z = 0, found z = " +
                   detail::quoted(words[3]));
      }
      if (contours.vertices.size() > std::numeric_limits<std::uint32_t>::max()) {
        throw fail("more vertices than 32-bit indices can address");
      }
      contours.vertices.push_back(p);
    } else if (words[0] == "l") {
      if (words.size() < 2) throw fail("expected \"l\" and at least one vertex index");
      polyline p;
      p.isovalue = isovalue;
      p.vertices.reserve(words.size() - 1);
      for (std::size_t k = 1; k < words.size(); ++k) {
        std::uint64_t index = 0;
        if (!parse_whole(words[k], index)) {
          throw fail("expected a positive vertex index, found " + detail::quoted(words[k]));
        }
        if (index < 1 || index > contours.vertices.size()) {
          throw fail("vertex index " + std::to_string(index) + " is out of range (expected 1 to " +
                     std::to_string(contours.vertices.size()) + ", the vertices defined above)");
        }
        p.vertices.push_back(static_cast<std::uint32_t>(index - 1));
      }
      if (p.vertices.size() >= 2 && p.vertices.front() == p.vertices.back()) {
        p.closed = true;
        p.vertices.pop_back();
      }
      contours.polylines.push_back(std::move(p));
    } else if (words[0] == "o" || words[0] == "g" || words[0] == "s") {
      continue;
    } else {
      throw fail("expected only v and l lines in a contour OBJ file, found " +
                 detail::quoted(words[0]));
    }
  }
  return contours;
}

}  // namespace progiso
