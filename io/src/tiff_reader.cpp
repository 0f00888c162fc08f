#include <progiso/io/detail/tiff_reader.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include <tiffio.h>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t max_side = 32769;      // samples per axis, as every reader
constexpr std::size_t max_entries = 1u << 20;  // a directory's entries listed at most
// Pages of a stack at most: an ImageJ hyperstack's frames may hold more than 32769 slices in
// all, each volume at most 32769 (16 bytes a page kept).
constexpr std::size_t max_pages = 1u << 20;

// ---------------------------------------------------------------------------------------------
// libtiff reading through input_file.

struct client {
  input_file in;
  std::uint64_t position = 0;
  std::string first_error;  // libtiff's first error message, for ours

  client(const fs::path& file) : in(file, "TIFF") {}
};

tmsize_t read_proc(thandle_t h, void* data, tmsize_t n) {
  auto* c = static_cast<client*>(h);
  if (n < 0) return -1;
  try {
    c->in.seek(c->position);
    const std::size_t got = c->in.read(data, static_cast<std::size_t>(n));
    c->position += got;
    return static_cast<tmsize_t>(got);
  } catch (const error& e) {
    if (c->first_error.empty()) c->first_error = e.what();
    return -1;
  }
}

tmsize_t write_proc(thandle_t, void*, tmsize_t) { return -1; }

toff_t seek_proc(thandle_t h, toff_t offset, int whence) {
  auto* c = static_cast<client*>(h);
  switch (whence) {
    case SEEK_SET:
      c->position = offset;
      break;
    case SEEK_CUR:
      c->position += offset;
      break;
    case SEEK_END:
      c->position = c->in.size() + offset;
      break;
    default:
      return static_cast<toff_t>(-1);
  }
  return c->position;
}

int close_proc(thandle_t) { return 0; }
toff_t size_proc(thandle_t h) { return static_cast<client*>(h)->in.size(); }
int map_proc(thandle_t, void**, toff_t*) { return 0; }
void unmap_proc(thandle_t, void*, toff_t) {}

int error_handler(TIFF*, void* user, const char* module, const char* format, va_list args) {
  auto* c = static_cast<client*>(user);
  if (c->first_error.empty()) {
    char text[256];
    std::vsnprintf(text, sizeof text, format, args);
    c->first_error = quoted(text, 160);
    if (module != nullptr && *module != '\0') c->first_error += " in " + quoted(module, 40);
  }
  return 1;  // handled: nothing is printed
}

int warning_handler(TIFF*, void*, const char*, const char*, va_list) { return 1; }

/// One TIFF file open in libtiff, read through input_file.
class tiff_file {
 public:
  explicit tiff_file(const fs::path& file) : client_(std::make_unique<client>(file)) {
    TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
    // libtiff's own buffers (directories, one strip's compressed bytes) never need more than
    // the file holds.
    TIFFOpenOptionsSetMaxSingleMemAlloc(
        options, static_cast<tmsize_t>(std::min<std::uint64_t>(
                     client_->in.size() + (std::uint64_t{1} << 20),
                     static_cast<std::uint64_t>(std::numeric_limits<tmsize_t>::max()))));
    TIFFOpenOptionsSetErrorHandlerExtR(options, error_handler, client_.get());
    TIFFOpenOptionsSetWarningHandlerExtR(options, warning_handler, client_.get());
    const std::string name = file.string();
    // "m": no memory mapping (map_proc declines anyway); "h" is not given: the first
    // directory is read here.
    tif_ = TIFFClientOpenExt(name.c_str(), "rm", client_.get(), read_proc, write_proc, seek_proc,
                             close_proc, size_proc, map_proc, unmap_proc, options);
    TIFFOpenOptionsFree(options);
    if (tif_ == nullptr) {
      throw error(name + ": cannot be read as TIFF (" + why("no TIFF header") + ")");
    }
  }
  tiff_file(const tiff_file&) = delete;
  tiff_file& operator=(const tiff_file&) = delete;
  ~tiff_file() {
    if (tif_ != nullptr) TIFFClose(tif_);
  }

  [[nodiscard]] TIFF* get() const noexcept { return tif_; }
  /// libtiff's first error, or `otherwise`.
  [[nodiscard]] std::string why(std::string_view otherwise) const {
    return client_->first_error.empty() ? std::string(otherwise) : client_->first_error;
  }
  void clear_error() { client_->first_error.clear(); }
  [[nodiscard]] std::uint64_t size() const noexcept { return client_->in.size(); }

 private:
  std::unique_ptr<client> client_;
  TIFF* tif_ = nullptr;
};

// ---------------------------------------------------------------------------------------------
// Pages.

/// The largest expansion of a codec progiso reads, or 0 for one it does not.
std::uint64_t largest_expansion(std::uint16_t compression) {
  switch (compression) {
    case COMPRESSION_NONE:
      return 1;
    case COMPRESSION_PACKBITS:
      return 64;  // a run of 128 bytes from 2
    case COMPRESSION_ADOBE_DEFLATE:
    case COMPRESSION_DEFLATE:
      return 1032;  // deflate's limit
    case COMPRESSION_LZW:
      return 4096;  // a 9-bit code names a string of up to 4096 bytes: below 4096 × its bytes
    default:
      return 0;
  }
}

std::string compression_name(std::uint16_t compression) {
  const TIFFCodec* codec = TIFFFindCODEC(compression);
  const std::string n = std::to_string(compression);
  return codec != nullptr && codec->name != nullptr ? n + " (" + codec->name + ")" : n;
}

struct page_header {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  sample_type type = sample_type::u8;
  bool reduced = false;  // a thumbnail or a pyramid level: not a slice
  std::string description;
  float x_resolution = 0.0f;
  float y_resolution = 0.0f;
};

/// "FILE (page K)", for messages.
std::string page_name(const fs::path& file, std::uint32_t page) {
  return file.string() + " (page " + std::to_string(page) + ")";
}

/// The current directory of `t` as a slice, checked: one grey channel of a supported type and
/// codec, whose strips or tiles can hold its samples.
page_header read_page(const tiff_file& t, const fs::path& file, std::uint32_t page) {
  TIFF* tif = t.get();
  const std::string name = page_name(file, page);
  page_header h;
  std::uint32_t subfile = 0;
  TIFFGetFieldDefaulted(tif, TIFFTAG_SUBFILETYPE, &subfile);
  h.reduced = (subfile & FILETYPE_REDUCEDIMAGE) != 0;
  if (h.reduced) return h;
  if (TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &h.width) != 1 ||
      TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h.height) != 1) {
    throw error(name + ": no ImageWidth or ImageLength");
  }
  if (h.width < 2 || h.height < 2 || h.width > max_side || h.height > max_side) {
    throw error(name + ": expected 2 to 32769 samples per row and column, found " +
                std::to_string(h.width) + " × " + std::to_string(h.height));
  }
  std::uint16_t channels = 1;
  std::uint16_t bits = 1;
  std::uint16_t format = SAMPLEFORMAT_UINT;
  std::uint16_t photometric = PHOTOMETRIC_MINISBLACK;
  std::uint16_t compression = COMPRESSION_NONE;
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &channels);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
  if (TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photometric) != 1) {
    photometric = PHOTOMETRIC_MINISBLACK;
  }
  if (channels != 1 ||
      (photometric != PHOTOMETRIC_MINISBLACK && photometric != PHOTOMETRIC_MINISWHITE)) {
    throw error(name + ": expected one grey channel (SamplesPerPixel 1, photometric MinIsBlack " +
                "or MinIsWhite), found " + std::to_string(channels) +
                " samples per pixel, photometric " + std::to_string(photometric) +
                (photometric == PHOTOMETRIC_RGB || channels >= 3 ? " (a colour image)" : ""));
  }
  const bool known_type = (bits == 8 || bits == 16 || bits == 32 || bits == 64) &&
                          (format == SAMPLEFORMAT_UINT || format == SAMPLEFORMAT_INT ||
                           format == SAMPLEFORMAT_IEEEFP) &&
                          !(format == SAMPLEFORMAT_IEEEFP && bits < 32) &&
                          !(format != SAMPLEFORMAT_IEEEFP && bits == 64);
  if (!known_type) {
    throw error(name + ": expected 8, 16 or 32-bit integer or 32 or 64-bit float samples, found " +
                std::to_string(bits) + "-bit " +
                (format == SAMPLEFORMAT_UINT     ? "unsigned integers"
                 : format == SAMPLEFORMAT_INT    ? "signed integers"
                 : format == SAMPLEFORMAT_IEEEFP ? "floats"
                                                 : "samples of format " + std::to_string(format)));
  }
  if (format == SAMPLEFORMAT_IEEEFP) {
    h.type = bits == 32 ? sample_type::f32 : sample_type::f64;
  } else if (format == SAMPLEFORMAT_INT) {
    h.type = bits == 8 ? sample_type::i8 : bits == 16 ? sample_type::i16 : sample_type::i32;
  } else {
    h.type = bits == 8 ? sample_type::u8 : bits == 16 ? sample_type::u16 : sample_type::u32;
  }
  const std::uint64_t expansion = largest_expansion(compression);
  if (expansion == 0 || TIFFIsCODECConfigured(compression) == 0) {
    throw error(name + ": compression " + compression_name(compression) +
                " is not read (expected none, LZW, Deflate or PackBits)");
  }
  // What the strips (or tiles) hold, against what the page needs: no allocation follows a
  // count the data cannot back.
  const std::uint32_t striles =
      TIFFIsTiled(tif) != 0 ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
  std::uint64_t stored = 0;
  for (std::uint32_t s = 0; s < striles; ++s) {
    const std::uint64_t bytes = TIFFGetStrileByteCount(tif, s);
    if (bytes > t.size()) {
      throw error(name + ": a strip of " + std::to_string(bytes) + " bytes in a file of " +
                  std::to_string(t.size()));
    }
    stored += bytes;
  }
  const std::uint64_t needed = std::uint64_t{h.width} * h.height * (bits / 8);
  if (striles == 0 || needed > stored * expansion) {
    throw error(name + ": " + std::to_string(h.width) + " × " + std::to_string(h.height) +
                " samples of " + std::to_string(bits) + " bits need " + std::to_string(needed) +
                " bytes, more than its " + std::to_string(stored) +
                " bytes of strips can hold (compression " + compression_name(compression) +
                " expands at most " + std::to_string(expansion) + "×)");
  }
  char* text = nullptr;
  if (TIFFGetField(tif, TIFFTAG_IMAGEDESCRIPTION, &text) == 1 && text != nullptr) {
    h.description.assign(text, strnlen(text, 1u << 16));
  }
  TIFFGetField(tif, TIFFTAG_XRESOLUTION, &h.x_resolution);
  TIFFGetField(tif, TIFFTAG_YRESOLUTION, &h.y_resolution);
  return h;
}

/// Moves `t` to the next directory; false after the last. Throws on a corrupt chain.
bool next_page(tiff_file& t, const fs::path& file, std::uint32_t page) {
  t.clear_error();
  if (TIFFReadDirectory(t.get()) == 1) return true;
  const std::string why = t.why("");
  if (!why.empty()) throw error(page_name(file, page) + ": " + why);
  return false;
}

// ---------------------------------------------------------------------------------------------
// ImageJ's description.

struct imagej_layout {
  bool present = false;
  std::int64_t images = 1;
  std::int64_t channels = 1;
  std::int64_t slices = 0;
  std::int64_t frames = 1;
  double spacing = 0.0;  // z; 0 when not given
};

/// "key=value" lines after "ImageJ=".
imagej_layout parse_imagej(std::string_view d) {
  imagej_layout l;
  if (d.substr(0, 7) != "ImageJ=") return l;
  l.present = true;
  while (!d.empty()) {
    const std::size_t nl = d.find('\n');
    const std::string_view line = d.substr(0, nl);
    d = nl == std::string_view::npos ? std::string_view{} : d.substr(nl + 1);
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos) continue;
    const std::string_view key = line.substr(0, eq);
    const std::string value(line.substr(eq + 1));
    char* end = nullptr;
    if (key == "spacing") {
      const double v = std::strtod(value.c_str(), &end);
      if (end != value.c_str() && std::isfinite(v) && v > 0.0) l.spacing = v;
      continue;
    }
    std::int64_t* field = key == "images"     ? &l.images
                          : key == "channels" ? &l.channels
                          : key == "slices"   ? &l.slices
                          : key == "frames"   ? &l.frames
                                              : nullptr;
    if (field == nullptr) continue;
    const long long v = std::strtoll(value.c_str(), &end, 10);
    if (end != value.c_str() && v >= 1 && v <= (std::int64_t{1} << 40)) *field = v;
  }
  return l;
}

// ---------------------------------------------------------------------------------------------
// OME-TIFF's description (Bio-Formats, microscope software): the OME-XML's Pixels element.

struct ome_layout {
  bool present = false;
  std::int64_t size_z = 1, size_c = 1, size_t_ = 1;
  bool t_before_z = false;  // DimensionOrder names T before Z: a plane's T varies faster
  std::array<double, 3> spacing{0.0, 0.0, 0.0};  // µm; 0 when absent
};

/// Attribute `name` of the start tag `tag` (text from '<' to '>'), or empty.
std::string_view attribute(std::string_view tag, std::string_view name) {
  for (std::size_t at = tag.find(name); at != std::string_view::npos; at = tag.find(name, at + 1)) {
    const char before = at > 0 ? tag[at - 1] : ' ';
    const std::size_t eq = at + name.size();
    if ((before == ' ' || before == '\t' || before == '\n' || before == '\r') &&
        tag.substr(eq, 2) == "=\"") {
      const std::size_t end = tag.find('"', eq + 2);
      if (end == std::string_view::npos) return {};
      return tag.substr(eq + 2, end - eq - 2);
    }
  }
  return {};
}

/// Micrometres per unit of OME's length units (the ones microscopes write), 0 for others.
double micrometres_per(std::string_view unit) {
  if (unit.empty() || unit == "\xc2\xb5m" || unit == "um" || unit == "micron") return 1.0;
  if (unit == "nm") return 1e-3;
  if (unit == "mm") return 1e3;
  if (unit == "cm") return 1e4;
  if (unit == "m") return 1e6;
  return 0.0;
}

ome_layout parse_ome(std::string_view d) {
  ome_layout l;
  if (d.find("<OME") == std::string_view::npos) return l;
  std::size_t at = d.find("<Pixels");
  if (at == std::string_view::npos) at = d.find(":Pixels");
  if (at == std::string_view::npos) return l;
  const std::size_t end = d.find('>', at);
  if (end == std::string_view::npos) return l;
  const std::string_view tag = d.substr(at, end - at);
  l.present = true;
  const auto count = [&](std::string_view name, std::int64_t& out) {
    const std::string v(attribute(tag, name));
    char* stop = nullptr;
    const long long n = std::strtoll(v.c_str(), &stop, 10);
    if (!v.empty() && stop != v.c_str() && n >= 1 && n <= (std::int64_t{1} << 40)) out = n;
  };
  count("SizeZ", l.size_z);
  count("SizeC", l.size_c);
  count("SizeT", l.size_t_);
  const std::string_view order = attribute(tag, "DimensionOrder");
  const std::size_t z = order.find('Z');
  const std::size_t t = order.find('T');
  l.t_before_z = z != std::string_view::npos && t != std::string_view::npos && t < z;
  const std::array<std::string_view, 3> sizes{"PhysicalSizeX", "PhysicalSizeY", "PhysicalSizeZ"};
  for (std::size_t a = 0; a < 3; ++a) {
    const std::string v(attribute(tag, sizes[a]));
    const double per = micrometres_per(attribute(tag, std::string(sizes[a]) + "Unit"));
    char* stop = nullptr;
    const double x = std::strtod(v.c_str(), &stop);
    if (!v.empty() && stop != v.c_str() && std::isfinite(x) && x > 0.0 && per > 0.0) {
      l.spacing[a] = x * per;
    }
  }
  return l;
}

/// Natural order: digit runs compare as numbers (slice2 before slice10), the rest bytewise.
bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0;
  std::size_t j = 0;
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {
      std::size_t ie = i;
      std::size_t je = j;
      while (ie < a.size() && digit(a[ie])) ++ie;
      while (je < b.size() && digit(b[je])) ++je;
      std::size_t iz = i;
      std::size_t jz = j;
      while (iz + 1 < ie && a[iz] == '0') ++iz;
      while (jz + 1 < je && b[jz] == '0') ++jz;
      const std::string_view x(a.data() + iz, ie - iz);
      const std::string_view y(b.data() + jz, je - jz);
      if (x.size() != y.size()) return x.size() < y.size();
      if (x != y) return x < y;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
      ++i;
      ++j;
    }
  }
  if ((a.size() - i) != (b.size() - j)) return a.size() - i < b.size() - j;
  return a < b;  // equal by number (slice01, slice1): bytewise, so the order is total
}

std::vector<fs::path> list_tiff_files(const fs::path& directory) {
  std::vector<fs::path> names;
  std::error_code ec;
  std::size_t entries = 0;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    if (++entries > max_entries) {
      throw error(directory.string() + ": holds more than " + std::to_string(max_entries) +
                  " entries, expected a stack of TIFF slices");
    }
    std::error_code type_ec;
    if (it->is_regular_file(type_ec) && has_tiff_name(it->path())) names.push_back(it->path());
  }
  if (ec) throw error(directory.string() + ": cannot list the directory (" + ec.message() + ")");
  std::sort(names.begin(), names.end(), [](const fs::path& x, const fs::path& y) {
    return natural_less(x.filename().string(), y.filename().string());
  });
  return names;
}

}  // namespace

bool has_tiff_name(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".tif" || ext == ".tiff";
}

bool is_tiff_directory(const fs::path& directory) {
  std::error_code ec;
  std::size_t entries = 0;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    if (++entries > max_entries) return false;
    std::error_code type_ec;
    if (it->is_regular_file(type_ec) && has_tiff_name(it->path())) return true;
  }
  return false;
}

tiff_stack read_tiff_stack(const fs::path& input) {
  tiff_stack s;
  s.input = input;
  std::error_code ec;
  const bool directory = fs::is_directory(input, ec);
  s.files = directory ? list_tiff_files(input) : std::vector<fs::path>{input};
  if (s.files.empty()) throw error(input.string() + ": holds no .tif or .tiff file");
  std::optional<page_header> first;
  fs::path first_file;
  std::uint32_t first_page = 0;
  for (std::size_t f = 0; f < s.files.size(); ++f) {
    tiff_file t(s.files[f]);
    std::uint32_t page = 0;
    do {
      const page_header h = read_page(t, s.files[f], page);
      if (!h.reduced) {
        if (!first) {
          first = h;
          first_file = s.files[f];
          first_page = page;
        } else if (h.width != first->width || h.height != first->height || h.type != first->type) {
          throw error(page_name(s.files[f], page) + ": " + std::to_string(h.width) + " × " +
                      std::to_string(h.height) + " " + std::string(to_string(h.type)) +
                      " samples, where " + page_name(first_file, first_page) + " has " +
                      std::to_string(first->width) + " × " + std::to_string(first->height) + " " +
                      std::string(to_string(first->type)) + " (expected one size and type)");
        }
        if (s.pages.size() == max_pages) {
          throw error(page_name(s.files[f], page) + ": more than " + std::to_string(max_pages) +
                      " pages");
        }
        s.pages.push_back({f, page});
      }
      if (page == std::numeric_limits<std::uint32_t>::max()) break;
      ++page;
    } while (next_page(t, s.files[f], page));
  }
  if (!first) throw error(input.string() + ": holds no full-resolution TIFF page");
  const auto pages = static_cast<std::int64_t>(s.pages.size());
  s.dims = {first->width, first->height, pages};
  s.type = first->type;
  const imagej_layout ij = parse_imagej(first->description);
  const ome_layout ome = ij.present ? ome_layout{} : parse_ome(first->description);
  if (ome.present) {
    if (ome.size_c > 1) {
      throw error(first_file.string() + ": an OME-TIFF of " + std::to_string(ome.size_c) +
                  " channels (progiso reads one; export one channel)");
    }
    if (!directory) {
      if (ome.size_z * ome.size_t_ != pages) {
        throw error(first_file.string() + ": its OME-XML describes " + std::to_string(ome.size_z) +
                    " × " + std::to_string(ome.size_t_) + " planes (SizeZ × SizeT), the file has " +
                    std::to_string(pages) +
                    " pages (an OME-TIFF split over several files is not read)");
      }
      if (ome.size_t_ > 1) {
        // Volumes made contiguous: with T before Z in DimensionOrder, plane (z, t) is page
        // t + SizeT · z.
        if (ome.t_before_z) {
          std::vector<tiff_page> ordered(s.pages.size());
          for (std::int64_t t = 0; t < ome.size_t_; ++t) {
            for (std::int64_t z = 0; z < ome.size_z; ++z) {
              ordered[static_cast<std::size_t>(t * ome.size_z + z)] =
                  s.pages[static_cast<std::size_t>(t + ome.size_t_ * z)];
            }
          }
          s.pages = std::move(ordered);
        }
        s.volumes = ome.size_t_;
        s.dims[2] = ome.size_z;
      }
    }
    for (std::size_t a = 0; a < 3; ++a) {
      if (ome.spacing[a] > 0.0) s.spacing[a] = ome.spacing[a];
    }
  }
  if (ij.present) {
    if (ij.channels > 1) {
      throw error(first_file.string() + ": an ImageJ stack of " + std::to_string(ij.channels) +
                  " channels (progiso reads one; split the channels first)");
    }
    if (!directory) {
      if (ij.images != pages) {
        throw error(first_file.string() + ": its ImageJ description counts " +
                    std::to_string(ij.images) + " images, the file has " + std::to_string(pages) +
                    " pages (ImageJ keeps the images of stacks over 4 GB outside TIFF's "
                    "directories; save it as an image sequence)");
      }
      if (ij.frames > 1) {
        if (pages % ij.frames != 0) {
          throw error(first_file.string() + ": " + std::to_string(pages) +
                      " pages do not split into " + std::to_string(ij.frames) + " frames");
        }
        s.volumes = ij.frames;
        s.dims[2] = pages / ij.frames;
      }
    }
    const auto step = [](float resolution) {
      const double r = static_cast<double>(resolution);
      return std::isfinite(r) && r > 0.0 && std::isfinite(1.0 / r) ? 1.0 / r : 1.0;
    };
    s.spacing = {step(first->x_resolution), step(first->y_resolution),
                 ij.spacing > 0.0 ? ij.spacing : 1.0};
  }
  if (s.dims[2] < 2) {
    throw error(input.string() + ": one slice (expected a stack of at least 2 pages)");
  }
  if (s.dims[2] > max_side) {
    throw error(input.string() + ": " + std::to_string(s.dims[2]) +
                " slices (expected at most 32769 per volume)");
  }
  return s;
}

std::vector<std::byte> read_tiff_samples(const tiff_stack& s, std::size_t first) {
  const std::size_t item = sample_size(s.type);
  const auto width = static_cast<std::size_t>(s.dims[0]);
  const auto height = static_cast<std::size_t>(s.dims[1]);
  const std::size_t slices = static_cast<std::size_t>(s.dims[2]);
  const std::size_t row = width * item;
  const std::size_t slice = row * height;
  std::vector<std::byte> samples(slice * slices);
  std::unique_ptr<tiff_file> open;
  std::size_t open_file = 0;
  std::uint32_t at_page = 0;
  for (std::size_t z = 0; z < slices; ++z) {
    const tiff_page& p = s.pages[first + z];
    const fs::path& file = s.files[p.file];
    const std::string name = page_name(file, p.directory);
    if (!open || open_file != p.file || at_page > p.directory) {
      open = std::make_unique<tiff_file>(file);
      open_file = p.file;
      at_page = 0;
    }
    while (at_page < p.directory) {
      if (!next_page(*open, file, at_page + 1)) throw error(name + ": the page is gone");
      ++at_page;
    }
    // The file may have changed since its header was read: check the page again.
    const page_header h = read_page(*open, file, p.directory);
    if (h.reduced || h.width != s.dims[0] || h.height != s.dims[1] || h.type != s.type) {
      throw error(name + ": the page changed since the stack's headers were read");
    }
    TIFF* tif = open->get();
    std::byte* out = samples.data() + z * slice;
    open->clear_error();
    const auto fail = [&](const std::string& what) { return error(name + ": " + open->why(what)); };
    if (TIFFIsTiled(tif) != 0) {
      std::uint32_t tw = 0;
      std::uint32_t th = 0;
      TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
      TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
      const tmsize_t tile_bytes = TIFFTileSize(tif);
      if (tw == 0 || th == 0 || tile_bytes <= 0 ||
          static_cast<std::uint64_t>(tile_bytes) != std::uint64_t{tw} * th * item ||
          tw > max_side || th > max_side) {
        throw fail("malformed tiles");
      }
      std::vector<std::byte> tile(static_cast<std::size_t>(tile_bytes));
      for (std::uint32_t y0 = 0; y0 < height; y0 += th) {
        for (std::uint32_t x0 = 0; x0 < width; x0 += tw) {
          if (TIFFReadTile(tif, tile.data(), x0, y0, 0, 0) != tile_bytes) {
            throw fail("tile at (" + std::to_string(x0) + ", " + std::to_string(y0) +
                       ") could not be decoded");
          }
          const std::size_t w = std::min<std::size_t>(tw, width - x0) * item;
          for (std::uint32_t y = y0; y < std::min<std::size_t>(y0 + th, height); ++y) {
            std::memcpy(out + y * row + x0 * item, tile.data() + (y - y0) * tw * item, w);
          }
        }
      }
    } else {
      std::uint32_t rows_per_strip = 0;
      TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
      rows_per_strip =
          std::clamp<std::uint32_t>(rows_per_strip, 1, static_cast<std::uint32_t>(height));
      const std::uint32_t strips = TIFFNumberOfStrips(tif);
      const std::size_t expected_strips = (height + rows_per_strip - 1) / rows_per_strip;
      if (strips < expected_strips) throw fail("fewer strips than its rows need");
      for (std::size_t k = 0; k < expected_strips; ++k) {
        const std::size_t rows = std::min<std::size_t>(rows_per_strip, height - k * rows_per_strip);
        const auto bytes = static_cast<tmsize_t>(rows * row);
        const tmsize_t got = TIFFReadEncodedStrip(tif, static_cast<std::uint32_t>(k),
                                                  out + k * rows_per_strip * row, bytes);
        if (got != bytes) {
          throw fail("strip " + std::to_string(k) + " decoded to " +
                     std::to_string(got < 0 ? 0 : got) + " of its " + std::to_string(bytes) +
                     " bytes");
        }
      }
    }
  }
  return samples;
}

}  // namespace progiso::detail
