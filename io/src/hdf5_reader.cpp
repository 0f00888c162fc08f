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
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>

namespace progiso::detail {

namespace {

namespace fs = std::filesystem;

// libhdf5's serial build is not thread-safe: every call into it holds this.
std::mutex& library_mutex() {
  static std::mutex m;
  return m;
}

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

hdf5_image read_hdf5_header(const fs::path& file) {
  const std::lock_guard<std::mutex> lock(library_mutex());
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

std::optional<std::vector<std::byte>> read_hdf5_samples(const hdf5_image& image, std::size_t level,
                                                        std::int64_t volume,
                                                        const std::function<bool()>& stop) {
  const hdf5_level& lv = image.levels.at(level);
  const std::string path = image.dataset(level, volume);
  const std::size_t sample = sample_size(image.type);
  const std::uint64_t plane =
      static_cast<std::uint64_t>(lv.dims[0]) * static_cast<std::uint64_t>(lv.dims[1]) * sample;
  const std::uint64_t bytes = plane * static_cast<std::uint64_t>(lv.dims[2]);
  std::unique_lock<std::mutex> lock(library_mutex());
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
  if (extent_bytes > max_ratio * static_cast<double>(f.stored) + static_cast<double>(ratio_slack)) {
    r.fail(path, "stored data for a dataset of " + std::to_string(extent_bytes) + " bytes",
           std::to_string(f.stored) + " bytes stored (more than " +
               std::to_string(static_cast<int>(max_ratio)) +
               " times smaller: a decompression "
               "bomb or a level of fill values)");
  }
  std::vector<std::byte> out(static_cast<std::size_t>(bytes));
  // Slabs of whole chunk layers (each chunk decoded once) of at most about 64 MiB.
  const hsize_t unit = f.chunk_z > 0 ? f.chunk_z : 1;
  const std::uint64_t per_unit = std::max<std::uint64_t>(plane * unit, 1);
  const hsize_t slab = unit * std::max<hsize_t>(1, (std::uint64_t{64} << 20) / per_unit);
  handle file_space(H5Dget_space(d.get()), H5Sclose);
  for (hsize_t z = 0; z < static_cast<hsize_t>(lv.dims[2]); z += slab) {
    if (stop) {
      lock.unlock();
      const bool stopped = stop();
      lock.lock();
      if (stopped) return std::nullopt;
    }
    const hsize_t nz = std::min<hsize_t>(slab, static_cast<hsize_t>(lv.dims[2]) - z);
    const std::array<hsize_t, 3> start{z, 0, 0};
    const std::array<hsize_t, 3> count{nz, static_cast<hsize_t>(lv.dims[1]),
                                       static_cast<hsize_t>(lv.dims[0])};
    handle memory(H5Screate_simple(3, count.data(), nullptr), H5Sclose);
    if (!memory.valid() || H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start.data(),
                                               nullptr, count.data(), nullptr) < 0) {
      r.fail(path, "a readable selection", "none");
    }
    std::byte* at = out.data() + static_cast<std::size_t>(z * plane);
    if (H5Dread(d.get(), f.memory_type, memory.get(), file_space.get(), H5P_DEFAULT, at) < 0) {
      r.fail(path, "data libhdf5 can read",
             "corrupt or truncated data in planes " + std::to_string(z) + " to " +
                 std::to_string(z + nz - 1));
    }
  }
  return out;
}

}  // namespace progiso::detail
