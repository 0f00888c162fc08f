// Imaris and BigDataViewer pyramids through libhdf5 (see detail/hdf5_reader.hpp).

#include <progiso/io/detail/hdf5_reader.hpp>

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <memory>
#include <new>
#include <optional>
#include <span>
#include <thread>
#include <type_traits>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::detail {

namespace {

namespace fs = std::filesystem;

// An HDF5 identifier, closed by its closer.
class handle {
 public:
  handle() = default;
  handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  handle(const handle&) = delete;
  handle& operator=(const handle&) = delete;
  handle(handle&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}
  handle& operator=(handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      close_ = o.close_;
    }
    return *this;
  }
  ~handle() { reset(); }
  [[nodiscard]] hid_t get() const noexcept { return id_; }
  [[nodiscard]] bool valid() const noexcept { return id_ >= 0; }

 private:
  void reset() noexcept {
    if (id_ >= 0 && close_ != nullptr) (void)close_(id_);
    id_ = H5I_INVALID_HID;
  }
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

// The largest attribute text read (Imaris writes numbers and short names).
constexpr std::size_t max_attribute_bytes = 4096;
// The most levels, timepoints and channels (setups) a file may list.
constexpr std::int64_t max_levels = 32;
constexpr std::int64_t max_series = 100000;
// Deflate's largest ratio is about 1032: a level larger than this many times its stored bytes
// (plus a slack for tiny levels) cannot be data, only a bomb or fill values.
constexpr double max_ratio = 1100.0;
constexpr std::uint64_t ratio_slack = std::uint64_t{1} << 20;

class reader {
 public:
  explicit reader(fs::path file) : file_(std::move(file)) {
    // Silence libhdf5's own printing: every failure is reported here, once.
    (void)H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    // libhdf5 keeps freed objects on free lists without bound by default: a process that reads
    // many files (a server, a fuzzer) would hold them all. 1 MiB per kind of list.
    static const bool limited =
        H5set_free_list_limits(1 << 20, 1 << 18, 1 << 20, 1 << 18, 1 << 20, 1 << 18) >= 0;
    (void)limited;
    handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    if (!fapl.valid()) fail("", "a file access list", "none");
    // Read-only media and shared file systems often refuse locks; reading needs none.
    (void)H5Pset_file_locking(fapl.get(), false, true);
    (void)H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG);
    file_id_ = handle(H5Fopen(file_.string().c_str(), H5F_ACC_RDONLY, fapl.get()), H5Fclose);
    if (!file_id_.valid()) {
      throw error(file_.string() + ": expected an HDF5 file, found one libhdf5 cannot open");
    }
  }

  reader(const reader&) = delete;
  reader& operator=(const reader&) = delete;
  ~reader() {
    file_id_ = handle();  // closes the file (every object of it is closed by then)
    (void)H5garbage_collect();
  }

  [[noreturn]] void fail(const std::string& object, const std::string& expected,
                         const std::string& found) const {
    throw error(file_.string() + (object.empty() ? "" : ": " + object) + ": expected " + expected +
                ", found " + found);
  }

  [[nodiscard]] hid_t root() const noexcept { return file_id_.get(); }
  [[nodiscard]] const fs::path& file() const noexcept { return file_; }

  // Whether the path (components separated by '/', from the root) names an object.
  [[nodiscard]] bool exists(const std::string& path) const {
    std::string at;
    std::size_t from = path.front() == '/' ? 1 : 0;
    while (from <= path.size()) {
      const std::size_t slash = path.find('/', from);
      const std::size_t to = slash == std::string::npos ? path.size() : slash;
      at += "/" + path.substr(from, to - from);
      if (H5Lexists(root(), at.c_str(), H5P_DEFAULT) <= 0) return false;
      if (H5Oexists_by_name(root(), at.c_str(), H5P_DEFAULT) <= 0) return false;
      if (slash == std::string::npos) break;
      from = slash + 1;
    }
    return true;
  }

  [[nodiscard]] handle open_dataset(const std::string& path) const {
    if (!exists(path)) fail(path, "a dataset", "none");
    handle d(H5Dopen2(root(), path.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.valid()) fail(path, "a dataset", "another object, or one libhdf5 cannot open");
    return d;
  }

  // The text of attribute `name` of the object at `path` (Imaris writes every attribute as an
  // array of one-byte strings); nullopt when absent.
  [[nodiscard]] std::optional<std::string> text_attribute(const std::string& path,
                                                          const std::string& name) const {
    if (path != "/" && !exists(path)) return std::nullopt;
    if (H5Aexists_by_name(root(), path.c_str(), name.c_str(), H5P_DEFAULT) <= 0) {
      return std::nullopt;
    }
    const std::string what = path + " attribute " + name;
    handle a(H5Aopen_by_name(root(), path.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT),
             H5Aclose);
    if (!a.valid()) fail(what, "an attribute", "one libhdf5 cannot open");
    handle type(H5Aget_type(a.get()), H5Tclose);
    handle space(H5Aget_space(a.get()), H5Sclose);
    if (!type.valid() || !space.valid()) fail(what, "an attribute", "one without a type");
    if (H5Tget_class(type.get()) != H5T_STRING) fail(what, "text", "another type");
    const hssize_t points = H5Sget_simple_extent_npoints(space.get());
    if (points < 0) fail(what, "text", "an attribute without a size");
    if (H5Tis_variable_str(type.get()) > 0) {
      if (points != 1) fail(what, "one string", std::to_string(points) + " strings");
      handle mem(H5Tcopy(H5T_C_S1), H5Tclose);
      (void)H5Tset_size(mem.get(), H5T_VARIABLE);
      char* p = nullptr;
      if (H5Aread(a.get(), mem.get(), &p) < 0 || p == nullptr) fail(what, "text", "unreadable");
      std::string s(p, strnlen(p, max_attribute_bytes));
      H5free_memory(p);
      return s;
    }
    const std::size_t size = H5Tget_size(type.get());
    const auto bytes = static_cast<std::uint64_t>(size) * static_cast<std::uint64_t>(points);
    if (size == 0 || bytes > max_attribute_bytes) {
      fail(what, "text of at most " + std::to_string(max_attribute_bytes) + " bytes",
           std::to_string(bytes) + " bytes");
    }
    std::string s(static_cast<std::size_t>(bytes), '\0');
    if (H5Aread(a.get(), type.get(), s.data()) < 0) fail(what, "text", "unreadable");
    s.resize(strnlen(s.c_str(), s.size()));
    return s;
  }

  // A number written as text (an Imaris attribute).
  [[nodiscard]] double number_attribute(const std::string& path, const std::string& name) const {
    const std::optional<std::string> t = text_attribute(path, name);
    if (!t) fail(path, "an attribute " + name, "none");
    std::string s = *t;
    while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
    while (!s.empty() && s.front() == ' ') s.erase(s.begin());
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || errno != 0 || !std::isfinite(v)) {
      fail(path + " attribute " + name, "a number", "'" + s.substr(0, 64) + "'");
    }
    return v;
  }

 private:
  fs::path file_;
  handle file_id_;
};

// What a level's dataset is: its extent (z, y, x) and sample type, checked.
struct dataset_facts {
  std::array<hsize_t, 3> extent{};
  sample_type type = sample_type::u8;
  hid_t memory_type = H5T_NATIVE_UINT8;
  std::uint64_t stored = 0;
  hsize_t chunk_z = 0;  // 0: not chunked
};

dataset_facts facts_of(const reader& r, hid_t d, const std::string& path, hdf5_layout layout) {
  dataset_facts f;
  handle space(H5Dget_space(d), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != 3) {
    r.fail(path, "a three-dimensional dataset (z, y, x)",
           std::to_string(space.valid() ? H5Sget_simple_extent_ndims(space.get()) : -1) +
               " dimensions");
  }
  (void)H5Sget_simple_extent_dims(space.get(), f.extent.data(), nullptr);
  handle type(H5Dget_type(d), H5Tclose);
  if (!type.valid()) r.fail(path, "a sample type", "none");
  const H5T_class_t cls = H5Tget_class(type.get());
  const std::size_t size = H5Tget_size(type.get());
  const bool is_signed = cls == H5T_INTEGER && H5Tget_sign(type.get()) == H5T_SGN_2;
  const std::string found = (cls == H5T_INTEGER ? std::string(is_signed ? "int" : "uint")
                             : cls == H5T_FLOAT ? std::string("float")
                                                : std::string("a non-numeric type of ")) +
                            std::to_string(8 * size);
  if (cls == H5T_INTEGER && size == 1) {
    f.type = is_signed ? sample_type::i8 : sample_type::u8;
    f.memory_type = is_signed ? H5T_NATIVE_INT8 : H5T_NATIVE_UINT8;
  } else if (cls == H5T_INTEGER && size == 2) {
    // BigDataViewer writes 16-bit data as int16 and reads it as unsigned.
    const bool as_unsigned = !is_signed || layout == hdf5_layout::bdv;
    f.type = as_unsigned ? sample_type::u16 : sample_type::i16;
    f.memory_type = is_signed ? H5T_NATIVE_INT16 : H5T_NATIVE_UINT16;
  } else if (cls == H5T_INTEGER && size == 4) {
    f.type = is_signed ? sample_type::i32 : sample_type::u32;
    f.memory_type = is_signed ? H5T_NATIVE_INT32 : H5T_NATIVE_UINT32;
  } else if (cls == H5T_FLOAT && size == 4) {
    f.type = sample_type::f32;
    f.memory_type = H5T_NATIVE_FLOAT;
  } else if (cls == H5T_FLOAT && size == 8) {
    f.type = sample_type::f64;
    f.memory_type = H5T_NATIVE_DOUBLE;
  } else {
    r.fail(path, "samples of uint8, int8, uint16, int16, uint32, int32, float32 or float64", found);
  }
  // Filters: only those libhdf5 decodes here.
  handle dcpl(H5Dget_create_plist(d), H5Pclose);
  if (!dcpl.valid()) r.fail(path, "a creation property list", "none");
  const int filters = H5Pget_nfilters(dcpl.get());
  for (int k = 0; k < filters; ++k) {
    unsigned flags = 0;
    std::size_t values = 0;
    unsigned config = 0;
    std::array<char, 64> name{};
    const H5Z_filter_t id = H5Pget_filter2(dcpl.get(), static_cast<unsigned>(k), &flags, &values,
                                           nullptr, name.size(), name.data(), &config);
    if (id < 0 || H5Zfilter_avail(id) <= 0) {
      const std::string what = id == 32004 ? std::string("LZ4 (filter 32004, a plugin)")
                                           : "filter " + std::to_string(id);
      r.fail(path, "data compressed by a filter this libhdf5 decodes (deflate, shuffle)",
             what + " '" + std::string(name.data(), strnlen(name.data(), name.size())) + "'");
    }
  }
  if (H5Pget_layout(dcpl.get()) == H5D_CHUNKED) {
    std::array<hsize_t, 3> chunk{};
    if (H5Pget_chunk(dcpl.get(), 3, chunk.data()) == 3) f.chunk_z = chunk[0];
  }
  f.stored = H5Dget_storage_size(d);
  return f;
}

std::string imaris_group(std::size_t level, std::int64_t t, std::int64_t c) {
  return "/DataSet/ResolutionLevel " + std::to_string(level) + "/TimePoint " + std::to_string(t) +
         "/Channel " + std::to_string(c);
}

// `v` in decimal, padded with zeros to `width` digits (BigDataViewer's s00 and t00000).
std::string padded(std::int64_t v, std::size_t width) {
  std::string d = std::to_string(v);
  return std::string(d.size() < width ? width - d.size() : 0, '0') + d;
}

std::string bdv_setup(std::int64_t s) { return "s" + padded(s, 2); }

std::string bdv_dataset(std::size_t level, std::int64_t t, std::int64_t s) {
  return "/t" + padded(t, 5) + "/" + bdv_setup(s) + "/" + std::to_string(level) + "/cells";
}

index3 checked_dims(const reader& r, const std::string& object, const std::array<double, 3>& xyz) {
  index3 d{};
  for (std::size_t q = 0; q < 3; ++q) {
    const double v = xyz[q];
    if (!(v >= 1 && v <= 32769) || v != std::floor(v)) {
      r.fail(object, "an image size of 1 to 32769 samples per axis",
             std::string(1, static_cast<char>('X' + q)) + " = " + std::to_string(v));
    }
    d[q] = static_cast<std::int64_t>(v);
  }
  if (d[0] < 2 || d[1] < 2) {
    r.fail(object, "at least 2 samples along x and y",
           std::to_string(d[0]) + " x " + std::to_string(d[1]));
  }
  return d;
}

hdf5_image read_imaris(const reader& r) {
  hdf5_image im;
  im.layout = hdf5_layout::imaris;
  std::int64_t levels = 0;
  while (levels < max_levels && r.exists("/DataSet/ResolutionLevel " + std::to_string(levels))) {
    ++levels;
  }
  if (levels == 0) r.fail("/DataSet", "a group ResolutionLevel 0", "none");
  const auto count = [&r](const std::string& prefix) {
    std::int64_t n = 0;
    while (n < max_series && r.exists(prefix + std::to_string(n))) ++n;
    return n;
  };
  im.timepoints = count("/DataSet/ResolutionLevel 0/TimePoint ");
  if (im.timepoints == 0) r.fail("/DataSet/ResolutionLevel 0", "a group TimePoint 0", "none");
  im.channels = count("/DataSet/ResolutionLevel 0/TimePoint 0/Channel ");
  if (im.channels == 0) {
    r.fail("/DataSet/ResolutionLevel 0/TimePoint 0", "a group Channel 0", "none");
  }
  // The box: its corners, when the file gives them (else spacing 1, origin 0).
  std::optional<std::array<double, 6>> box;
  if (r.text_attribute("/DataSetInfo/Image", "ExtMin0")) {
    std::array<double, 6> b{};
    for (std::size_t q = 0; q < 3; ++q) {
      b[q] = r.number_attribute("/DataSetInfo/Image", "ExtMin" + std::to_string(q));
      b[3 + q] = r.number_attribute("/DataSetInfo/Image", "ExtMax" + std::to_string(q));
      if (!(b[3 + q] > b[q])) {
        r.fail("/DataSetInfo/Image",
               "ExtMax" + std::to_string(q) + " above ExtMin" + std::to_string(q),
               std::to_string(b[q]) + " and " + std::to_string(b[3 + q]));
      }
    }
    box = b;
  }
  for (std::size_t l = 0; l < static_cast<std::size_t>(levels); ++l) {
    const std::string g = imaris_group(l, 0, 0);
    if (!r.exists(g)) r.fail(g, "a group", "none");
    hdf5_level lv;
    lv.dims =
        checked_dims(r, g,
                     {r.number_attribute(g, "ImageSizeX"), r.number_attribute(g, "ImageSizeY"),
                      r.number_attribute(g, "ImageSizeZ")});
    for (std::size_t q = 0; q < 3; ++q) {
      if (box) {
        lv.spacing[q] = (box->at(3 + q) - box->at(q)) / static_cast<double>(lv.dims[q]);
        lv.origin[q] = box->at(q) + 0.5 * lv.spacing[q];
      }
      if (!(lv.spacing[q] > 0) || !std::isfinite(lv.spacing[q])) {
        r.fail("/DataSetInfo/Image", "an extent that gives a finite positive spacing",
               "spacing " + std::to_string(lv.spacing[q]));
      }
    }
    im.levels.push_back(lv);
  }
  return im;
}

hdf5_image read_bdv(const reader& r) {
  hdf5_image im;
  im.layout = hdf5_layout::bdv;
  std::int64_t setups = 0;
  while (setups < max_series && r.exists("/" + bdv_setup(setups) + "/resolutions")) ++setups;
  im.channels = setups;
  std::int64_t t = 0;
  while (t < max_series && r.exists("/t" + padded(t, 5))) ++t;
  if (t == 0) r.fail("/", "a group t00000", "none");
  im.timepoints = t;
  // Level factors, from s00's resolutions: levels × 3 (x, y, z).
  handle d = r.open_dataset("/s00/resolutions");
  handle space(H5Dget_space(d.get()), H5Sclose);
  std::array<hsize_t, 2> shape{};
  if (!space.valid() || H5Sget_simple_extent_ndims(space.get()) != 2 ||
      H5Sget_simple_extent_dims(space.get(), shape.data(), nullptr) < 0 || shape[1] != 3 ||
      shape[0] < 1 || shape[0] > static_cast<hsize_t>(max_levels)) {
    r.fail("/s00/resolutions", "a table of 1 to 32 levels by 3 factors", "another shape");
  }
  std::vector<double> factors(static_cast<std::size_t>(shape[0]) * 3);
  if (H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, factors.data()) < 0) {
    r.fail("/s00/resolutions", "numbers", "unreadable data");
  }
  for (std::size_t l = 0; l < static_cast<std::size_t>(shape[0]); ++l) {
    const std::string path = bdv_dataset(l, 0, 0);
    handle cells = r.open_dataset(path);
    const dataset_facts f = facts_of(r, cells.get(), path, hdf5_layout::bdv);
    hdf5_level lv;
    lv.dims = checked_dims(r, path,
                           {static_cast<double>(f.extent[2]), static_cast<double>(f.extent[1]),
                            static_cast<double>(f.extent[0])});
    for (std::size_t q = 0; q < 3; ++q) {
      const double s = factors[3 * l + q];
      if (!(s >= 1.0 && s <= 65536.0)) {
        r.fail("/s00/resolutions", "downsampling factors of 1 or more", std::to_string(s));
      }
      lv.spacing[q] = s;
      lv.origin[q] = (s - 1.0) / 2.0;
    }
    im.levels.push_back(lv);
  }
  return im;
}

}  // namespace

std::string hdf5_image::dataset(std::size_t level, std::int64_t volume) const {
  const std::int64_t t = volume / channels;
  const std::int64_t c = volume % channels;
  return layout == hdf5_layout::imaris ? imaris_group(level, t, c) + "/Data"
                                       : bdv_dataset(level, t, c);
}

bool has_hdf5_name(const fs::path& file) {
  const std::string ext = lower_extension(file);
  return ext == ".ims" || ext == ".h5" || ext == ".hdf5" || ext == ".hdf";
}

bool has_hdf5_signature(const fs::path& file) {
  static constexpr char signature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  if (ec) return false;
  for (std::uint64_t at = 0; at + 8 <= size; at = at == 0 ? 512 : 2 * at) {
    char b[8];
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(b, 8)) return false;
    if (std::memcmp(b, signature, 8) == 0) return true;
  }
  return false;
}

namespace {

// ---- In the child process (below): libhdf5's work, on one thread.

hdf5_image header_here(const fs::path& file) {
  const reader r(file);
  hdf5_image im;
  if (r.exists("/DataSet/ResolutionLevel 0")) {
    im = read_imaris(r);
  } else if (r.exists("/s00/resolutions")) {
    im = read_bdv(r);
  } else {
    r.fail("",
           "an Imaris file (/DataSet/ResolutionLevel 0) or a BigDataViewer file "
           "(/s00/resolutions)",
           "neither");
  }
  im.file = file;
  // The sample type, from level 0's first volume (every dataset read is checked against it).
  const std::string path = im.dataset(0, 0);
  handle d = r.open_dataset(path);
  im.type = facts_of(r, d.get(), path, im.layout).type;
  return im;
}

// The level's samples into `out` (its bytes), calling `progress` after each slab; with a null
// `out`, the dataset's checks alone (before the caller allocates its bytes).
hsize_t samples_here(const hdf5_image& image, std::size_t level, std::int64_t volume,
                     std::byte* out, const std::function<void()>& progress,
                     std::int64_t z_begin = 0, std::int64_t z_end = -1) {
  const hdf5_level& lv = image.levels.at(level);
  const std::string path = image.dataset(level, volume);
  const std::size_t sample = sample_size(image.type);
  const std::uint64_t plane =
      static_cast<std::uint64_t>(lv.dims[0]) * static_cast<std::uint64_t>(lv.dims[1]) * sample;
  const reader r(image.file);
  handle d = r.open_dataset(path);
  const dataset_facts f = facts_of(r, d.get(), path, image.layout);
  if (f.type != image.type) {
    r.fail(path, "samples of " + std::string(to_string(image.type)) + " (as level 0's)",
           std::string(to_string(f.type)));
  }
  if (f.extent[2] < static_cast<hsize_t>(lv.dims[0]) ||
      f.extent[1] < static_cast<hsize_t>(lv.dims[1]) ||
      f.extent[0] < static_cast<hsize_t>(lv.dims[2])) {
    r.fail(path,
           "a dataset at least " + std::to_string(lv.dims[0]) + " x " + std::to_string(lv.dims[1]) +
               " x " + std::to_string(lv.dims[2]) + " (x, y, z)",
           std::to_string(f.extent[2]) + " x " + std::to_string(f.extent[1]) + " x " +
               std::to_string(f.extent[0]));
  }
  const double extent_bytes = static_cast<double>(f.extent[0]) * static_cast<double>(f.extent[1]) *
                              static_cast<double>(f.extent[2]) * static_cast<double>(sample);
  // The stored bytes a file's metadata claims, at most the file's own size.
  std::error_code ec;
  const std::uint64_t file_bytes = fs::file_size(image.file, ec);
  const std::uint64_t stored = ec ? f.stored : std::min<std::uint64_t>(f.stored, file_bytes);
  if (extent_bytes > max_ratio * static_cast<double>(stored) + static_cast<double>(ratio_slack)) {
    r.fail(path, "stored data for a dataset of " + std::to_string(extent_bytes) + " bytes",
           std::to_string(stored) + " bytes stored (more than " +
               std::to_string(static_cast<int>(max_ratio)) +
               " times smaller: a decompression bomb or a level of fill values)");
  }
  // Slabs of whole chunk layers (each chunk decoded once) of at most about 64 MiB.
  const hsize_t unit = f.chunk_z > 0 ? f.chunk_z : 1;
  if (out == nullptr) return unit;
  const std::uint64_t per_unit = std::max<std::uint64_t>(plane * unit, 1);
  const hsize_t slab = unit * std::max<hsize_t>(1, (std::uint64_t{64} << 20) / per_unit);
  handle file_space(H5Dget_space(d.get()), H5Sclose);
  const auto first = static_cast<hsize_t>(z_begin);
  const auto end = static_cast<hsize_t>(z_end < 0 ? lv.dims[2] : z_end);
  for (hsize_t z = first; z < end; z += slab) {
    const hsize_t nz = std::min<hsize_t>(slab, end - z);
    const std::array<hsize_t, 3> start{z, 0, 0};
    const std::array<hsize_t, 3> count{nz, static_cast<hsize_t>(lv.dims[1]),
                                       static_cast<hsize_t>(lv.dims[0])};
    handle memory(H5Screate_simple(3, count.data(), nullptr), H5Sclose);
    if (!memory.valid() || H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(),
                                               nullptr, count.data(), nullptr) < 0) {
      r.fail(path, "a readable selection", "none");
    }
    if (H5Dread(d.get(), f.memory_type, memory.get(), file_space.get(), H5P_DEFAULT,
                out + static_cast<std::size_t>((z - first) * plane)) < 0) {
      r.fail(path, "data libhdf5 can read",
             "corrupt or truncated data in planes " + std::to_string(z) + " to " +
                 std::to_string(z + nz - 1));
    }
    progress();
  }
  return unit;
}

// ---- The child process. libhdf5 is not memory-safe on every corrupt file (use after free in
// its object-header code, found by fuzzing): it runs in a child, so a file that crashes or hangs
// it gives the caller one error, never a crash or a hang, and no libhdf5 state is shared between
// threads (the serial build is not thread-safe).

// The pipe's messages: a kind byte, then for 'E' and 'R' a length and that many bytes.
constexpr char progress_mark = 'P';
constexpr char error_mark = 'E';
constexpr char result_mark = 'R';
// A child silent this long (no slab read, no answer) is taken to hang.
constexpr auto quiet_limit = std::chrono::seconds(120);

bool write_all(int fd, const void* p, std::size_t n) noexcept {
  const auto* b = static_cast<const char*>(p);
  while (n > 0) {
    const ssize_t w = ::write(fd, b, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    b += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

void send(int fd, char kind, const std::string& payload) noexcept {
  const std::uint64_t n = payload.size();
  (void)(write_all(fd, &kind, 1) && write_all(fd, &n, sizeof n) &&
         write_all(fd, payload.data(), payload.size()));
}

// A crash in the child ends the child alone: default handlers (a fuzzer's or a sanitizer's
// would report the parent's input as crashing), and no sanitizer death callback.
extern "C" void __sanitizer_set_death_callback(void (*)()) __attribute__((weak));

void reset_crash_handling() noexcept {
  for (const int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGTRAP}) {
    (void)std::signal(sig, SIG_DFL);
  }
  if (&__sanitizer_set_death_callback != nullptr) __sanitizer_set_death_callback(nullptr);
}

// libhdf5's own memory in the child beyond what it inherits (the samples' shared mapping is not
// counted): enough for its caches and any real file's metadata, and a bound on what a hostile
// one can make it allocate.
// Not under AddressSanitizer, whose shadow memory already exceeds any such limit.
constexpr rlim_t child_data_bytes = rlim_t{2} << 30;

void limit_child_memory() noexcept {
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
  return;
#endif
#endif
  // On top of what the child holds already (the parent's data, copied on write).
  rlim_t held = 0;
  if (std::FILE* f = std::fopen("/proc/self/status", "r")) {
    char line[256];
    while (std::fgets(line, sizeof line, f) != nullptr) {
      unsigned long long kb = 0;
      if (std::sscanf(line, "VmData: %llu kB", &kb) == 1) held = static_cast<rlim_t>(kb) * 1024;
    }
    std::fclose(f);
  }
  rlimit r{};
  const rlim_t want = held + child_data_bytes;
  if (::getrlimit(RLIMIT_DATA, &r) == 0 && (r.rlim_cur == RLIM_INFINITY || r.rlim_cur > want)) {
    r.rlim_cur = want;
    (void)::setrlimit(RLIMIT_DATA, &r);
  }
#endif
}

// Whether this process runs under a sanitizer whose runtime does not lock its own allocator
// around fork(): ThreadSanitizer's before LLVM 19 (llvm-project pull request 96600) and
// AddressSanitizer's before LLVM 18. A child forked while another thread (a oneTBB worker, the
// sanitizer's background thread) holds that lock can then block forever in its first malloc.
constexpr bool fork_may_deadlock_the_child() {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  return true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
  return true;
#else
  return false;
#endif
#else
  return false;
#endif
}

// fork(), tried again a few times when the kernel is short of processes or memory for a moment.
pid_t fork_patiently() {
  for (int attempt = 0;; ++attempt) {
    const pid_t pid = ::fork();
    if (pid >= 0 || (errno != EAGAIN && errno != ENOMEM) || attempt == 4) return pid;
    std::this_thread::sleep_for(std::chrono::milliseconds(50 << attempt));
  }
}

// Runs `work(fd)` in a child, which writes its answer to fd ('R' payload, or 'E' message);
// returns the payload. `stop`, when given, is asked first and while waiting: true ends the
// child and returns nullopt. Throws progiso::error for an error the child reports, or when it dies
// or falls silent. Under a sanitizer whose fork can deadlock the child (above), a silent child
// is given one more try before the file is called hanging.
template <class Work>
std::optional<std::string> in_child(const fs::path& file, const Work& work,
                                    const std::function<bool()>& stop) {
  if (stop && stop()) return std::nullopt;
  const int tries = fork_may_deadlock_the_child() ? 2 : 1;
  std::string got;
  int status = 0;
  for (int attempt = 1;; ++attempt) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) {
      throw error(file.string() + ": cannot start the HDF5 reader (pipe: " + std::strerror(errno) +
                  ")");
    }
    const pid_t pid = fork_patiently();
    if (pid < 0) {
      const int e = errno;
      ::close(fds[0]);
      ::close(fds[1]);
      throw error(file.string() + ": cannot start the HDF5 reader (fork: " + std::strerror(e) +
                  ")");
    }
    if (pid == 0) {
      ::close(fds[0]);
      reset_crash_handling();
      limit_child_memory();
      try {
        send(fds[1], result_mark, work(fds[1]));
      } catch (const error& e) {
        send(fds[1], error_mark, e.what());
      } catch (const std::bad_alloc&) {
        send(fds[1], error_mark, file.string() + ": out of memory reading the HDF5 file");
      } catch (...) {
        send(fds[1], error_mark, file.string() + ": the HDF5 reader failed");
      }
      ::_exit(0);  // no atexit handlers, no destructors of the parent's objects
    }
    ::close(fds[1]);
    const int fd = fds[0];
    got.clear();
    bool stopped = false;
    bool silent = false;
    auto heard = std::chrono::steady_clock::now();
    for (;;) {
      pollfd p{fd, POLLIN, 0};
      const int ready = ::poll(&p, 1, 50);
      if (ready < 0 && errno != EINTR) break;
      if (ready > 0) {
        char buf[65536];
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;  // the child closed its end: done or dead
        got.append(buf, static_cast<std::size_t>(n));
        heard = std::chrono::steady_clock::now();
        continue;
      }
      if (stop && stop()) {
        stopped = true;
        break;
      }
      if (std::chrono::steady_clock::now() - heard > quiet_limit) {
        silent = true;
        break;
      }
    }
    ::close(fd);
    if (stopped || silent) (void)::kill(pid, SIGKILL);
    status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (stopped) return std::nullopt;
    if (!silent) break;
    if (attempt == tries) {
      throw error(file.string() + ": expected an HDF5 file libhdf5 reads, found one on which it " +
                  "hangs (no progress in " + std::to_string(quiet_limit.count()) + " s)");
    }
  }
  // The answer: progress marks, then one 'E' or 'R' message.
  std::size_t at = 0;
  while (at < got.size() && got[at] == progress_mark) ++at;
  std::uint64_t n = 0;
  if (at + 1 + sizeof n <= got.size()) std::memcpy(&n, got.data() + at + 1, sizeof n);
  const bool whole = at + 1 + sizeof n <= got.size() && got.size() - at - 1 - sizeof n == n;
  if (whole && got[at] == error_mark) throw error(got.substr(at + 1 + sizeof n));
  if (whole && got[at] == result_mark && WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    return got.substr(at + 1 + sizeof n);
  }
  const std::string how = WIFSIGNALED(status)
                              ? std::string("signal ") + std::to_string(WTERMSIG(status)) + " (" +
                                    strsignal(WTERMSIG(status)) + ")"
                              : "exit status " + std::to_string(WEXITSTATUS(status));
  throw error(file.string() + ": expected an HDF5 file libhdf5 reads, found one that ends it (" +
              how + ")");
}

// hdf5_image through the pipe: fixed fields, then the levels.
struct image_record {
  std::uint8_t layout;
  std::uint8_t type;
  std::int64_t timepoints;
  std::int64_t channels;
  std::uint64_t levels;
};

std::string encode(const hdf5_image& im) {
  const image_record h{static_cast<std::uint8_t>(im.layout), static_cast<std::uint8_t>(im.type),
                       im.timepoints, im.channels, im.levels.size()};
  std::string out(reinterpret_cast<const char*>(&h), sizeof h);
  for (const hdf5_level& l : im.levels) {
    out.append(reinterpret_cast<const char*>(&l), sizeof l);
  }
  return out;
}

hdf5_image decode(const fs::path& file, const std::string& bytes) {
  image_record h{};
  if (bytes.size() < sizeof h) throw error(file.string() + ": the HDF5 reader's answer is short");
  std::memcpy(&h, bytes.data(), sizeof h);
  if (bytes.size() != sizeof h + h.levels * sizeof(hdf5_level)) {
    throw error(file.string() + ": the HDF5 reader's answer is short");
  }
  hdf5_image im;
  im.file = file;
  im.layout = static_cast<hdf5_layout>(h.layout);
  im.type = static_cast<sample_type>(h.type);
  im.timepoints = h.timepoints;
  im.channels = h.channels;
  im.levels.resize(static_cast<std::size_t>(h.levels));
  std::memcpy(im.levels.data(), bytes.data() + sizeof h, im.levels.size() * sizeof(hdf5_level));
  return im;
}

}  // namespace

hdf5_image read_hdf5_header(const fs::path& file) {
  static_assert(std::is_trivially_copyable_v<hdf5_level>);
  const std::optional<std::string> answer =
      in_child(file, [&file](int) { return encode(header_here(file)); }, {});
  return decode(file, *answer);
}

std::int64_t check_hdf5_samples(const hdf5_image& image, std::size_t level, std::int64_t volume) {
  // The dataset's type, its size against the level's and its stored bytes, in a child.
  const std::optional<std::string> unit = in_child(
      image.file,
      [&](int) { return std::to_string(samples_here(image, level, volume, nullptr, [] {})); }, {});
  const std::int64_t planes = unit ? std::strtoll(unit->c_str(), nullptr, 10) : 1;
  return std::clamp<std::int64_t>(planes, 1, image.levels.at(level).dims[2]);
}

namespace {

// Planes [z_begin, z_end) of `volume` at `level`, read by a child into memory shared with it
// (the keeper unmaps it); nullopt when `stop` answered true.
std::optional<mapped_bytes> planes_in_child(const hdf5_image& image, std::size_t level,
                                            std::int64_t volume, std::int64_t z_begin,
                                            std::int64_t z_end, const std::function<bool()>& stop) {
  const hdf5_level& lv = image.levels.at(level);
  const std::uint64_t bytes = static_cast<std::uint64_t>(lv.dims[0]) *
                              static_cast<std::uint64_t>(lv.dims[1]) *
                              static_cast<std::uint64_t>(z_end - z_begin) * sample_size(image.type);
  // Shared with the child, which writes the samples.
  void* p = ::mmap(nullptr, static_cast<std::size_t>(bytes), PROT_READ | PROT_WRITE,
                   MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  std::shared_ptr<const void> keeper(p, [bytes](const void* q) {
    ::munmap(const_cast<void*>(q), static_cast<std::size_t>(bytes));
  });
  auto* out = static_cast<std::byte*>(p);
  const std::optional<std::string> answer = in_child(
      image.file,
      [&](int fd) {
        (void)samples_here(
            image, level, volume, out,
            [fd] {
              const char mark = progress_mark;
              (void)write_all(fd, &mark, 1);
            },
            z_begin, z_end);
        return std::string();
      },
      stop);
  if (!answer) return std::nullopt;
  return mapped_bytes{std::span<const std::byte>(out, static_cast<std::size_t>(bytes)),
                      std::move(keeper)};
}

}  // namespace

std::optional<mapped_bytes> read_hdf5_samples(const hdf5_image& image, std::size_t level,
                                              std::int64_t volume,
                                              const std::function<bool()>& stop) {
  // The dataset checked first: nothing of a bomb's size is allocated.
  (void)check_hdf5_samples(image, level, volume);
  // The volume then owns the shared memory.
  return planes_in_child(image, level, volume, 0, image.levels.at(level).dims[2], stop);
}

void read_hdf5_planes(const hdf5_image& image, std::size_t level, std::int64_t volume,
                      std::int64_t z_begin, std::int64_t z_end, std::span<std::byte> out) {
  const std::optional<mapped_bytes> planes =
      planes_in_child(image, level, volume, z_begin, z_end, {});
  PROGISO_ASSERT(planes && planes->bytes.size() == out.size());
  std::memcpy(out.data(), planes->bytes.data(), out.size());
}

}  // namespace progiso::detail
