#include <progiso/io/image_io.hpp>

#include <png.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <csetjmp>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso {
namespace {

using detail::lower_extension;

/// Magic numbers and short tokens are quoted in full up to 16 bytes.
std::string quoted(std::string_view bytes) { return detail::quoted(bytes, 16); }

// Widths and heights above this are refused before any allocation: the volume's axis limit
// (grid coordinates fit in 16 bits, see hierarchy.hpp), far below PNG's 2^31 - 1.
constexpr std::uint64_t max_image_side = (std::uint64_t{1} << 15) + 1;

/// Refuses a width or height outside 2..max_image_side, naming the file.
void check_image_size(const std::string& name, std::uint64_t width, std::uint64_t height) {
  if (width < 2 || height < 2) {
    throw error(name + ": expected a width and height of at least 2, found " +
                std::to_string(width) + " x " + std::to_string(height));
  }
  if (width > max_image_side || height > max_image_side) {
    throw error(name + ": expected a width and height of at most " +
                std::to_string(max_image_side) + " (the largest image progiso contours), found " +
                std::to_string(width) + " x " + std::to_string(height));
  }
}

/// The volume of an image, with the volume's own complaints prefixed by the file name.
volume make_image(const std::string& name, std::uint64_t width, std::uint64_t height,
                  sample_type type, std::vector<std::byte> samples) {
  try {
    return volume({static_cast<std::int64_t>(width), static_cast<std::int64_t>(height), 1}, type,
                  std::move(samples));
  } catch (const error& e) {
    throw error(name + ": " + e.what());
  }
}

// =============================================================================================
// PGM.

/// What a netpbm magic number other than P5 stands for, for the error message.
std::string_view netpbm_kind(std::string_view magic) {
  if (magic == "P1") return " (plain PBM; only binary PGM is read)";
  if (magic == "P2") return " (plain PGM; only binary PGM is read)";
  if (magic == "P3") return " (plain PPM; only binary PGM is read)";
  if (magic == "P4") return " (binary PBM; only binary PGM is read)";
  if (magic == "P6") return " (binary PPM, a colour image; only binary PGM is read)";
  if (magic == "P7") return " (PAM; only binary PGM is read)";
  return "";
}

bool is_pgm_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/// Walks the PGM header: whitespace, '#' comments to the end of their line, decimal tokens.
class pgm_header_reader {
 public:
  pgm_header_reader(const std::vector<char>& data, const std::string& name)
      : data_(data), name_(name) {}

  /// Skips whitespace and comments, then reads one decimal token that must end at whitespace,
  /// a comment or the end of the file.
  std::uint64_t number(const char* field) {
    skip_space_and_comments();
    const std::size_t start = pos_;
    while (pos_ < data_.size() && !is_pgm_space(data_[pos_]) && data_[pos_] != '#') ++pos_;
    const std::string_view token(data_.data() + start, pos_ - start);
    const auto fail = [&](std::string_view found) {
      return error(name_ + ": malformed PGM header: expected the " + field +
                   " as a decimal number, found " + std::string(found));
    };
    if (token.empty()) throw fail("the end of the file");
    // Up to 10 digits fits in 64 bits; anything longer is out of range for every field anyway.
    if (token.size() > 10 ||
        !std::all_of(token.begin(), token.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      throw fail(quoted(token));
    }
    std::uint64_t value = 0;
    for (char c : token) value = value * 10 + static_cast<std::uint64_t>(c - '0');
    return value;
  }

  /// After maxval: exactly one whitespace byte (a comment there runs up to and including its
  /// newline, which then is that byte). Returns the offset of the first raster byte.
  std::size_t raster_start() {
    if (pos_ < data_.size() && data_[pos_] == '#') {
      while (pos_ < data_.size() && data_[pos_] != '\n' && data_[pos_] != '\r') ++pos_;
    }
    if (pos_ >= data_.size()) {
      throw error(name_ +
                  ": truncated PGM file: expected one whitespace byte and the raster after "
                  "maxval, found the end of the file");
    }
    return pos_ + 1;
  }

 private:
  void skip_space_and_comments() {
    while (pos_ < data_.size()) {
      if (is_pgm_space(data_[pos_])) {
        ++pos_;
      } else if (data_[pos_] == '#') {
        while (pos_ < data_.size() && data_[pos_] != '\n' && data_[pos_] != '\r') ++pos_;
      } else {
        break;
      }
    }
  }

  const std::vector<char>& data_;
  const std::string& name_;
  std::size_t pos_ = 2;  // after the magic number
};

// =============================================================================================
// PNG through libpng.
//
// libpng reports errors by calling an error function that must not return; ours records the
// message and longjmps back to the setjmp in the function that called into libpng. A longjmp
// that skips a C++ object with a non-trivial destructor is undefined behaviour, so every
// setjmp sits in a small stage function whose frame holds only trivially destructible locals
// (and modifies none of them after the setjmp, so none can be clobbered); everything that
// owns memory — the file, libpng's structs, the raster, the row pointers — lives in
// read_png()'s frame, which no longjmp ever leaves.

/// Where the error function leaves libpng's message before it jumps back.
struct png_failure {
  char message[200] = {};
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  auto* failure = static_cast<png_failure*>(png_get_error_ptr(png));
  std::snprintf(failure->message, sizeof failure->message, "%s",
                message != nullptr ? message : "unknown error");
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {
  // Warnings (a bad ancillary chunk CRC, an unknown chunk …) do not affect the raster; libpng's
  // default would print them on stderr, which a library must not do.
}

struct png_header {
  png_uint_32 width = 0;
  png_uint_32 height = 0;
  int bit_depth = 0;
  int color_type = 0;
};

/// Stage 1: reads the chunks up to the first IDAT. False when libpng failed.
bool read_png_info(png_structp png, png_infop info, std::FILE* file, png_header& header) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  png_init_io(png, file);
  png_set_sig_bytes(png, 8);  // read_png() has checked the signature
  png_read_info(png, info);
  header.width = png_get_image_width(png, info);
  header.height = png_get_image_height(png, info);
  header.bit_depth = png_get_bit_depth(png, info);
  header.color_type = png_get_color_type(png, info);
  return true;
}

/// Stage 2: decodes the raster into `rows` (height pointers to `row_bytes` bytes each) with
/// the transformations that give plain gray samples in host order, then reads the rest of the
/// file (which checks the trailing chunks). False when libpng failed.
bool read_png_raster(png_structp png, png_infop info, const png_header& header, png_bytepp rows,
                     std::size_t row_bytes) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  if (header.bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if ((header.color_type & PNG_COLOR_MASK_ALPHA) != 0) png_set_strip_alpha(png);
  if (header.bit_depth == 16 && std::endian::native == std::endian::little) png_set_swap(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  if (png_get_rowbytes(png, info) != row_bytes || png_get_channels(png, info) != 1) {
    png_error(png, "unexpected row layout after the gray transformations");
  }
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

/// Owns libpng's read and info structs.
struct png_read_handles {
  png_structp png = nullptr;
  png_infop info = nullptr;
  png_read_handles() = default;
  png_read_handles(const png_read_handles&) = delete;
  png_read_handles& operator=(const png_read_handles&) = delete;
  ~png_read_handles() {
    if (png != nullptr) png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
  }
};

std::string_view png_color_name(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_RGB:
      return "RGB";
    case PNG_COLOR_TYPE_RGB_ALPHA:
      return "RGB with alpha";
    case PNG_COLOR_TYPE_PALETTE:
      return "a palette (indexed-colour) image";
    default:
      return "an unknown colour type";
  }
}

}  // namespace

// =============================================================================================
// Readers.

volume read_pgm(const std::filesystem::path& file) {
  const std::string name = file.string();
  const std::vector<char> data = detail::input_file(file, "PGM").read_all();

  // ---- Magic number.
  const std::string_view magic(data.data(), std::min<std::size_t>(data.size(), 2));
  if (magic != "P5") {
    throw error(name + ": expected a binary PGM file (magic number \"P5\"), found " +
                (data.empty() ? std::string("an empty file") : quoted(magic)) +
                std::string(netpbm_kind(magic)));
  }
  if (data.size() > 2 && !is_pgm_space(data[2]) && data[2] != '#') {
    throw error(name + ": malformed PGM header: expected whitespace after \"P5\", found " +
                quoted(std::string_view(&data[2], 1)));
  }

  // ---- Header tokens.
  pgm_header_reader header(data, name);
  const std::uint64_t width = header.number("width");
  const std::uint64_t height = header.number("height");
  const std::uint64_t maxval = header.number("maxval");
  check_image_size(name, width, height);
  if (maxval < 1 || maxval > 65535) {
    throw error(name + ": expected a PGM maxval from 1 to 65535, found " + std::to_string(maxval));
  }
  const std::size_t start = header.raster_start();

  // ---- Raster: exactly width × height samples.
  const std::uint64_t bytes_per_sample = maxval < 256 ? 1 : 2;
  const std::uint64_t expected = width * height * bytes_per_sample;
  const std::uint64_t found = data.size() - start;
  if (found != expected) {
    throw error(name + ": expected " + std::to_string(width) + " x " + std::to_string(height) +
                " x " + std::to_string(bytes_per_sample) + " = " + std::to_string(expected) +
                " bytes of samples after the header, found " + std::to_string(found) +
                (found < expected ? " (the file is truncated)"
                                  : " (trailing data after the image; only single-image PGM "
                                    "files are read)"));
  }

  const auto n = static_cast<std::size_t>(width * height);
  std::vector<std::byte> samples(static_cast<std::size_t>(expected));
  const auto* raster = reinterpret_cast<const unsigned char*>(data.data() + start);
  std::size_t too_large = n;  // first sample above maxval, if any
  if (bytes_per_sample == 1) {
    for (std::size_t i = 0; i < n; ++i) {
      if (raster[i] > maxval && too_large == n) too_large = i;
    }
    std::copy(data.begin() + static_cast<std::ptrdiff_t>(start), data.end(),
              reinterpret_cast<char*>(samples.data()));
  } else {
    auto* out = reinterpret_cast<std::uint16_t*>(samples.data());
    for (std::size_t i = 0; i < n; ++i) {
      // PGM stores 16-bit samples most significant byte first, whatever the host.
      const auto v = static_cast<std::uint16_t>((raster[2 * i] << 8) | raster[2 * i + 1]);
      if (v > maxval && too_large == n) too_large = i;
      out[i] = v;
    }
  }
  if (too_large != n) {
    const std::size_t x = too_large % static_cast<std::size_t>(width);
    const std::size_t y = too_large / static_cast<std::size_t>(width);
    const unsigned value = bytes_per_sample == 1
                               ? unsigned{raster[too_large]}
                               : (unsigned{raster[2 * too_large]} << 8) | raster[2 * too_large + 1];
    throw error(name + ": expected samples of at most maxval " + std::to_string(maxval) +
                ", found " + std::to_string(value) + " at column " + std::to_string(x) + ", row " +
                std::to_string(y));
  }
  return make_image(name, width, height, bytes_per_sample == 1 ? sample_type::u8 : sample_type::u16,
                    std::move(samples));
}

volume read_png(const std::filesystem::path& file) {
  const std::string name = file.string();
  detail::input_file input(file, "PNG");
  std::FILE* const f = input.stream();

  // ---- Signature, checked here so that "not a PNG" reads as such.
  unsigned char signature[8] = {};
  const std::size_t got = input.read(signature, sizeof signature);
  if (got < sizeof signature || png_sig_cmp(signature, 0, sizeof signature) != 0) {
    throw error(
        name + ": expected a PNG file (signature \"\\x89PNG\\x0d\\x0a\\x1a\\x0a\"), found " +
        (got == 0 ? std::string("an empty file")
                  : quoted(std::string_view(reinterpret_cast<const char*>(signature), got))));
  }

  png_failure failure;
  png_read_handles h;
  h.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &failure, on_png_error, on_png_warning);
  if (h.png != nullptr) h.info = png_create_info_struct(h.png);
  if (h.png == nullptr || h.info == nullptr) {
    throw error(name + ": cannot set up libpng to read the file (out of memory)");
  }
  // libpng says "Read Error" for a file that ends early; the end-of-file flag tells that apart
  // from corrupt data.
  const auto corrupt = [&]() {
    if (std::feof(f) != 0) {
      return error(name + ": truncated PNG file (it ends before the image data does; libpng: " +
                   failure.message + ")");
    }
    return error(name + ": corrupt PNG file (libpng: " + failure.message + ")");
  };

  // ---- Header.
  png_header header;
  if (!read_png_info(h.png, h.info, f, header)) throw corrupt();
  if ((header.color_type & PNG_COLOR_MASK_COLOR) != 0) {
    throw error(name + ": expected a grayscale PNG, found " +
                std::string(png_color_name(header.color_type)));
  }
  check_image_size(name, header.width, header.height);
  // A corrupt header can announce a huge raster in a tiny file; refuse to allocate for it.
  // Deflate cannot compress better than about 1032:1 (a 258-byte match in two bits), so the
  // filtered raster — at least height × (1 + packed row bytes) — cannot exceed ~1032 times the
  // file size. 1100 and 4 KiB leave room for the zlib and chunk framing.
  const std::uint64_t packed_row =
      (std::uint64_t{header.width} * static_cast<std::uint64_t>(header.bit_depth) *
           ((header.color_type & PNG_COLOR_MASK_ALPHA) != 0 ? 2 : 1) +
       7) /
      8;
  const std::uint64_t file_size = input.size();
  if (std::uint64_t{header.height} * (packed_row + 1) > file_size * 1100 + 4096) {
    throw error(name + ": corrupt or truncated PNG file (" + std::to_string(header.width) + " x " +
                std::to_string(header.height) + " pixels cannot fit in " +
                std::to_string(file_size) + " bytes)");
  }

  // ---- Raster, decoded straight into the volume's storage.
  const std::size_t bytes_per_sample = header.bit_depth == 16 ? 2 : 1;
  const std::size_t row_bytes = std::size_t{header.width} * bytes_per_sample;
  std::vector<std::byte> samples(row_bytes * header.height);
  std::vector<png_bytep> rows(header.height);
  for (std::size_t y = 0; y < rows.size(); ++y) {
    rows[y] = reinterpret_cast<png_bytep>(samples.data() + y * row_bytes);
  }
  if (!read_png_raster(h.png, h.info, header, rows.data(), row_bytes)) throw corrupt();

  return make_image(name, header.width, header.height,
                    bytes_per_sample == 1 ? sample_type::u8 : sample_type::u16, std::move(samples));
}

volume read_image(const std::filesystem::path& file) {
  const std::string ext = lower_extension(file);
  if (ext == ".pgm") return read_pgm(file);
  if (ext == ".png") return read_png(file);
  throw error(file.string() + ": unknown image format (expected .pgm or .png)");
}

}  // namespace progiso
