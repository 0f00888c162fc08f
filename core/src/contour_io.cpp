#include <progiso/core/contour_io.hpp>

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
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/assert.hpp>
#include <progiso/core/detail/file_output.hpp>
#include <progiso/core/error.hpp>

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

// All-or-nothing text output (detail::atomic_output) with stream-style formatting.
class atomic_text_file {
 public:
  explicit atomic_text_file(const fs::path& target) : out_(target) {}
  atomic_text_file& operator<<(std::string_view text) {
    out_.write(text);
    return *this;
  }
  atomic_text_file& operator<<(char c) { return *this << std::string_view(&c, 1); }
  atomic_text_file& operator<<(double v) {
    std::array<char, 40> b;
    return *this << format_number(v, b);
  }
  atomic_text_file& operator<<(std::uint64_t v) {
    std::array<char, 40> b;
    return *this << format_number(v, b);
  }
  void commit() { out_.commit(); }

 private:
  detail::atomic_output out_;
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
// Writers.

void write_contour_obj(const std::filesystem::path& file, const contour_set& contours) {
  check_preconditions(contours);
  atomic_text_file out(file);
  out << "# generated by progiso: isocontours, " << std::uint64_t{contours.vertices.size()}
      << " vertices, " << std::uint64_t{contours.polylines.size()} << " polylines\n";
  for (const vec2& p : contours.vertices) out << "v " << p[0] << ' ' << p[1] << " 0\n";
  for (std::size_t i = 0; i < contours.polylines.size(); ++i) {
    const polyline& line = contours.polylines[i];
    if (i == 0 || !same_isovalue(line.isovalue, contours.polylines[i - 1].isovalue)) {
      out << "# isovalue " << line.isovalue << '\n';
    }
    out << 'l';
    for (std::uint32_t v : line.vertices) out << ' ' << std::uint64_t{v} + 1;
    if (line.closed && !line.vertices.empty()) out << ' ' << std::uint64_t{line.vertices[0]} + 1;
    out << '\n';
  }
  out.commit();
}

void write_contour_svg(const std::filesystem::path& file, const contour_set& contours,
                       const volume* image) {
  check_preconditions(contours);
  const std::string name = file.string();

  // ---- Frame: the image's sample area, else the contours' bounding box, half a unit wider.
  double x0 = 0.0;
  double y0 = 0.0;
  double w = 1.0;
  double h = 1.0;
  if (image != nullptr) {
    PROGISO_ASSERT(image->dims()[2] == 1);
    const auto& s = image->spacing();
    x0 = image->origin()[0] - 0.5 * s[0];
    y0 = image->origin()[1] - 0.5 * s[1];
    w = static_cast<double>(image->dims()[0]) * s[0];
    h = static_cast<double>(image->dims()[1]) * s[1];
  } else if (!contours.vertices.empty()) {
    vec2 lo = contours.vertices[0];
    vec2 hi = lo;
    for (const vec2& p : contours.vertices) {
      for (std::size_t c = 0; c < 2; ++c) {
        lo[c] = std::min(lo[c], p[c]);
        hi[c] = std::max(hi[c], p[c]);
      }
    }
    x0 = lo[0] - 0.5;
    y0 = lo[1] - 0.5;
    w = hi[0] - lo[0] + 1.0;
    h = hi[1] - lo[1] + 1.0;
  }
  // Nominal size: one unit per pixel, enlarged so that the longer side has at least 512 px;
  // the stroke width is chosen to come out at 1.5 px at that size.
  const double px_per_unit = std::max(1.0, 512.0 / std::max(w, h));
  const double stroke_width = 1.5 / px_per_unit;

  // ---- Polylines grouped by isovalue, ascending (NaN last), each group in input order.
  std::vector<std::size_t> order(contours.polylines.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  const auto key = [&](std::size_t i) {
    const double v = contours.polylines[i].isovalue;
    return std::make_pair(std::isnan(v), std::isnan(v) ? 0.0 : v);
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  std::vector<double> isovalues;
  for (std::size_t i : order) {
    const double v = contours.polylines[i].isovalue;
    if (isovalues.empty() || !same_isovalue(isovalues.back(), v)) isovalues.push_back(v);
  }

  // Yellow first (the usual contour-over-grayscale colour), then hues far from it and from
  // each other; all bright enough to read over dark and mid-gray backgrounds.
  constexpr std::array<std::string_view, 8> palette = {"#ffd400", "#00d8ff", "#ff4fd8", "#6cff3c",
                                                       "#ff8a1f", "#b08cff", "#ff3b3b", "#ffffff"};

  const std::string background =
      image != nullptr ? "data:image/png;base64," + base64(image_png(*image, name)) : "";

  atomic_text_file out(file);
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" "
         "xmlns:xlink=\"http://www.w3.org/1999/xlink\" version=\"1.1\" width=\""
      << static_cast<double>(std::lround(w * px_per_unit)) << "\" height=\""
      << static_cast<double>(std::lround(h * px_per_unit)) << "\" viewBox=\"" << x0 << ' ' << y0
      << ' ' << w << ' ' << h << "\">\n";
  out << "<title>progiso isocontours: " << std::uint64_t{contours.polylines.size()}
      << (contours.polylines.size() == 1 ? " polyline" : " polylines");
  for (std::size_t k = 0; k < isovalues.size(); ++k) {
    out << (k > 0 ? ", " : isovalues.size() == 1 ? ", isovalue " : ", isovalues ") << isovalues[k];
  }
  out << "</title>\n";
  if (image != nullptr) {
    out << "<image x=\"" << x0 << "\" y=\"" << y0 << "\" width=\"" << w << "\" height=\"" << h
        << "\" preserveAspectRatio=\"none\" image-rendering=\"optimizeSpeed\" "
           "style=\"image-rendering:pixelated\" xlink:href=\""
        << background << "\"/>\n";
  }
  std::size_t next = 0;  // position in `order`
  for (std::size_t k = 0; k < isovalues.size(); ++k) {
    out << "<g data-isovalue=\"" << isovalues[k] << "\" fill=\"none\" stroke=\""
        << palette[k % palette.size()] << "\" stroke-width=\"" << stroke_width
        << "\" stroke-linejoin=\"round\" stroke-linecap=\"round\">\n";
    for (; next < order.size() &&
           same_isovalue(contours.polylines[order[next]].isovalue, isovalues[k]);
         ++next) {
      const polyline& line = contours.polylines[order[next]];
      out << (line.closed ? "<polygon points=\"" : "<polyline points=\"");
      for (std::size_t j = 0; j < line.vertices.size(); ++j) {
        const vec2& p = contours.vertices[line.vertices[j]];
        out << (j == 0 ? "" : " ") << p[0] << ',' << p[1];
      }
      out << "\"/>\n";
    }
    out << "</g>\n";
  }
  out << "</svg>\n";
  out.commit();
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
  struct closer {
    void operator()(std::FILE* f) const noexcept { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, closer> f(std::fopen(name.c_str(), "rb"));
  if (!f) throw error(name + ": cannot open OBJ file (" + errno_text(errno) + ")");
  std::string text;
  {
    char block[1 << 16];
    std::size_t got = 0;
    while ((got = std::fread(block, 1, sizeof block, f.get())) > 0) text.append(block, got);
    if (std::ferror(f.get()) != 0) throw error(name + ": cannot read OBJ file (I/O error)");
  }

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
          throw fail("expected \"# isovalue\" and a number, found \"" + std::string(line) + "\"");
        }
      }
    } else if (words[0] == "v") {
      vec2 p{};
      double z = 0.0;
      const bool ok = (words.size() == 3 || words.size() == 4) && parse_whole(words[1], p[0]) &&
                      parse_whole(words[2], p[1]) &&
                      (words.size() == 3 || parse_whole(words[3], z));
      if (!ok) {
        throw fail("expected \"v x y 0\" with decimal numbers, found \"" + std::string(line) +
                   "\"");
      }
      if (z != 0.0) {
        throw fail("expected a 2D contour vertex with z = 0, found z = " + std::string(words[3]));
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
          throw fail("expected a positive vertex index, found \"" + std::string(words[k]) + "\"");
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
      throw fail("expected only v and l lines in a contour OBJ file, found \"" +
                 std::string(words[0]) + "\"");
    }
  }
  return contours;
}

}  // namespace progiso
