#include <progiso/io/detail/nifti_reader.hpp>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/gzip_input.hpp>
#include <progiso/io/detail/header_bytes.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

/// Where the fields lie in the two versions (nifti1.h and nifti2.h, packed).
struct layout {
  std::size_t dim;  // int16[8] or int64[8]
  std::size_t datatype;
  std::size_t pixdim;  // float[8] or double[8]
  std::size_t vox_offset;
  std::size_t scl_slope, scl_inter;
  std::size_t qform_code, sform_code;  // int16 or int32
  std::size_t quatern;                 // quatern_b, c, d
  std::size_t qoffset;                 // 3 floats or doubles
  std::array<std::size_t, 3> srow_t;   // srow_x[3], srow_y[3], srow_z[3]
};
constexpr layout v1{40, 70, 76, 108, 112, 116, 252, 254, 256, 268, {292, 308, 324}};
constexpr layout v2{16, 12, 104, 168, 176, 184, 344, 348, 352, 376, {424, 456, 488}};

struct type_code {
  std::int16_t code;
  sample_type type;
  std::string_view name;
};
constexpr std::array<type_code, 8> supported_types{{{2, sample_type::u8, "UINT8"},
                                                    {256, sample_type::i8, "INT8"},
                                                    {512, sample_type::u16, "UINT16"},
                                                    {4, sample_type::i16, "INT16"},
                                                    {768, sample_type::u32, "UINT32"},
                                                    {8, sample_type::i32, "INT32"},
                                                    {16, sample_type::f32, "FLOAT32"},
                                                    {64, sample_type::f64, "FLOAT64"}}};

std::string_view refused_type_name(std::int16_t code) noexcept {
  switch (code) {
    case 0:
      return "UNKNOWN";
    case 1:
      return "BINARY";
    case 32:
      return "COMPLEX64";
    case 128:
      return "RGB24";
    case 1024:
      return "INT64";
    case 1280:
      return "UINT64";
    case 1536:
      return "FLOAT128";
    case 1792:
      return "COMPLEX128";
    case 2048:
      return "COMPLEX256";
    case 2304:
      return "RGBA32";
    default:
      return "an unknown code";
  }
}

std::string number(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// The data file of a header and data pair: the name without .gz and its last extension, then
/// .img if it exists, else .img.gz (named in the error when neither does).
fs::path pair_data_file(const fs::path& header) {
  fs::path stem = header;
  if (lower_extension(stem) == ".gz") stem.replace_extension();
  stem.replace_extension();
  fs::path img = stem;
  img += ".img";
  fs::path img_gz = img;
  img_gz += ".gz";
  std::error_code ec;
  if (fs::exists(img, ec)) return img;
  if (fs::exists(img_gz, ec)) return img_gz;
  throw error(header.string() + ": the header's data file " + img.string() + " (or " +
              img_gz.string() + ") does not exist");
}

}  // namespace

sample_type nifti_header::volume_type() const noexcept {
  if (!scaled) return stored;
  const bool wide =
      stored == sample_type::u32 || stored == sample_type::i32 || stored == sample_type::f64;
  return wide ? sample_type::f64 : sample_type::f32;
}

bool has_nifti_name(const fs::path& file) {
  std::string ext = lower_extension(file);
  if (ext == ".gz") ext = lower_extension(file.stem());
  return ext == ".nii" || ext == ".hdr";
}

nifti_header read_nifti_header(const fs::path& file) {
  sequential_input in(file, "NIfTI", "NIfTI gzip data");
  const std::string name = file.string();
  std::array<std::byte, nifti2_header_bytes> raw{};
  const std::size_t first = in.read(std::span<std::byte>(raw.data(), 4));
  if (first < 4) {
    throw error(name + ": file ends after " + std::to_string(first) +
                " bytes, inside the NIfTI header (expected 348 or 540 bytes)");
  }
  const header_bytes native(raw.data(), false);
  const header_bytes swapped(raw.data(), true);
  nifti_header h;
  const auto size_field = native.get<std::int32_t>(0);
  const auto size_swapped = swapped.get<std::int32_t>(0);
  std::size_t header_size = 0;
  bool swap = false;
  if (size_field == 348 || size_field == 540) {
    header_size = static_cast<std::size_t>(size_field);
  } else if (size_swapped == 348 || size_swapped == 540) {
    header_size = static_cast<std::size_t>(size_swapped);
    swap = true;
  } else {
    throw error(name + ": not a NIfTI file (the header size field reads " +
                std::to_string(size_field) + ", expected 348 or 540 in either byte order)");
  }
  h.version = header_size == nifti1_header_bytes ? 1 : 2;
  h.big_endian = (std::endian::native == std::endian::big) != swap;
  const std::size_t rest = in.read(std::span<std::byte>(raw.data() + 4, header_size - 4));
  if (rest < header_size - 4) {
    throw error(name + ": file ends after " + std::to_string(4 + rest) + " of the " +
                std::to_string(header_size) + " bytes of the NIfTI-" + std::to_string(h.version) +
                " header");
  }
  const header_bytes f(raw.data(), swap);
  const layout& at = h.version == 1 ? v1 : v2;

  // Magic: n+1 / n+2 (data in this file) or ni1 / ni2 (data in the .img beside it).
  const std::string_view magic = h.version == 1 ? f.text(344, 4) : f.text(4, 8);
  bool single = false;
  if (h.version == 1) {
    if (magic == std::string_view("n+1\0", 4)) {
      single = true;
    } else if (magic != std::string_view("ni1\0", 4)) {
      throw error(name + ": no NIfTI-1 magic (\"n+1\" or \"ni1\") at byte 344, found " +
                  quoted(magic) + " (an Analyze 7.5 header?): not supported");
    }
  } else {
    if (magic == std::string_view("n+2\0\r\n\032\n", 8)) {
      single = true;
    } else if (magic != std::string_view("ni2\0\r\n\032\n", 8)) {
      throw error(name +
                  ": no NIfTI-2 magic (\"n+2\" or \"ni2\" and \\r\\n\\x1a\\n) at byte 4, found " +
                  quoted(magic));
    }
  }

  // Dimensions: 3 non-trivial, each 2..32769; trailing ones of size 1 are allowed.
  std::array<std::int64_t, 8> dim{};
  for (std::size_t i = 0; i < 8; ++i) {
    dim[i] =
        h.version == 1 ? f.get<std::int16_t>(at.dim + 2 * i) : f.get<std::int64_t>(at.dim + 8 * i);
  }
  if (dim[0] < 1 || dim[0] > 7) {
    throw error(name + ": dim[0] is " + std::to_string(dim[0]) + ", expected 1 to 7 dimensions");
  }
  if (dim[0] < 3) {
    throw error(name + ": a " + std::to_string(dim[0]) +
                "-D array (dim[0] = " + std::to_string(dim[0]) + "): expected a 3-D volume");
  }
  for (std::size_t i = 1; i <= 3; ++i) {
    if (dim[i] < 2 || dim[i] > nifti_max_axis_size) {
      throw error(name + ": dim[" + std::to_string(i) + "] is " + std::to_string(dim[i]) +
                  ", expected 2 to " + std::to_string(nifti_max_axis_size) + " samples");
    }
    h.dims[i - 1] = dim[i];
  }
  // Above the third, only sizes above 1 matter (0 and negatives read as 1, as nifti_clib
  // reads them): dim[4] counts the volumes of a time series, of which one is read; above it, a
  // vector or matrix per voxel is not a scalar volume.
  if (dim[0] >= 4 && dim[4] > 1) h.volumes = dim[4];
  for (std::size_t i = 5; i <= static_cast<std::size_t>(dim[0]); ++i) {
    if (dim[i] > 1) {
      throw error(name + ": dim[" + std::to_string(i) + "] is " + std::to_string(dim[i]) +
                  ": expected a 3-D volume or a time series of them (dimensions above 4 of "
                  "size 1)");
    }
  }

  // Sample type.
  const auto datatype = f.get<std::int16_t>(at.datatype);
  const auto type = std::find_if(supported_types.begin(), supported_types.end(),
                                 [&](const type_code& t) { return t.code == datatype; });
  if (type == supported_types.end()) {
    throw error(name + ": datatype " + std::to_string(datatype) + " (" +
                std::string(refused_type_name(datatype)) +
                ") is not supported (expected UINT8, INT8, UINT16, INT16, UINT32, INT32, "
                "FLOAT32 or FLOAT64)");
  }
  // bitpix is redundant with the datatype and ignored, as nifti_clib ignores it.
  h.stored = type->type;

  // Where the data starts.
  if (h.version == 1) {
    const auto off = static_cast<double>(f.get<float>(at.vox_offset));
    if (!std::isfinite(off) || off < 0.0 || off != std::floor(off) || off > 0x1p53) {
      throw error(name + ": vox_offset is " + number(off) + ", expected a whole number of bytes");
    }
    h.vox_offset = static_cast<std::uint64_t>(off);
  } else {
    const auto off = f.get<std::int64_t>(at.vox_offset);
    if (off < 0) {
      throw error(name + ": vox_offset is " + std::to_string(off) + ", expected at least 0");
    }
    h.vox_offset = static_cast<std::uint64_t>(off);
  }
  if (single && h.vox_offset < header_size) {
    throw error(name + ": vox_offset is " + std::to_string(h.vox_offset) +
                ", inside the header (expected at least " + std::to_string(header_size) + ")");
  }

  const auto real = [&](std::size_t offset) {
    return h.version == 1 ? static_cast<double>(f.get<float>(offset)) : f.get<double>(offset);
  };
  const auto code = [&](std::size_t offset) {
    return h.version == 1 ? std::int32_t{f.get<std::int16_t>(offset)} : f.get<std::int32_t>(offset);
  };

  // Scaling to physical values.
  const double slope = real(at.scl_slope);
  const double inter = real(at.scl_inter);
  if (std::isfinite(slope) && slope != 0.0 && !(slope == 1.0 && inter == 0.0)) {
    if (!std::isfinite(inter)) {
      throw error(name + ": scl_inter is " + number(inter) + " with scl_slope " + number(slope) +
                  ", expected a finite offset");
    }
    h.scaled = true;
    h.slope = slope;
    h.inter = inter;
  }

  // Geometry.
  for (std::size_t i = 0; i < 3; ++i) {
    const double p = std::abs(real(at.pixdim + (h.version == 1 ? 4 : 8) * (i + 1)));
    h.spacing[i] = std::isfinite(p) && p > 0.0 ? p : 1.0;
  }
  std::array<double, 3> origin{};
  if (code(at.sform_code) > 0) {
    for (std::size_t i = 0; i < 3; ++i) origin[i] = real(at.srow_t[i]);
  } else if (code(at.qform_code) > 0) {
    for (std::size_t i = 0; i < 3; ++i) origin[i] = real(at.qoffset + (h.version == 1 ? 4 : 8) * i);
  }
  for (std::size_t i = 0; i < 3; ++i) h.origin[i] = std::isfinite(origin[i]) ? origin[i] : 0.0;

  // The index-to-world map: the sform's rows, else the qform (NIfTI-1 "method 2").
  const std::size_t step = h.version == 1 ? 4 : 8;
  index_to_world w;
  bool has_world = false;
  if (code(at.sform_code) > 0) {
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t c = 0; c < 4; ++c) w.m[r][c] = real(at.srow_t[r] - 3 * step + c * step);
    }
    has_world = true;
  } else if (code(at.qform_code) > 0) {
    double b = real(at.quatern);
    double c = real(at.quatern + step);
    double d = real(at.quatern + 2 * step);
    double a = 1.0 - (b * b + c * c + d * d);
    if (a < 1e-7) {  // a 180° rotation: (b, c, d) normalised, a = 0
      const double n = std::sqrt(b * b + c * c + d * d);
      b /= n;
      c /= n;
      d /= n;
      a = 0.0;
    } else {
      a = std::sqrt(a);
    }
    const std::array<std::array<double, 3>, 3> rot{{
        {a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
        {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
        {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b},
    }};
    std::array<double, 3> scale{};
    for (std::size_t i = 0; i < 3; ++i) {
      const double p = real(at.pixdim + step * (i + 1));
      scale[i] = p > 0.0 ? p : 1.0;
    }
    if (real(at.pixdim) < 0.0) scale[2] = -scale[2];  // qfac = pixdim[0]
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t col = 0; col < 3; ++col) w.m[r][col] = rot[r][col] * scale[col];
      w.m[r][3] = real(at.qoffset + step * r);
    }
    has_world = true;
  }
  if (has_world) {
    bool finite = true;
    for (const auto& row : w.m) {
      for (const double v : row) finite = finite && std::isfinite(v);
    }
    if (finite && w.determinant() != 0.0) h.world = w;
  }

  if (!single) h.data_file = pair_data_file(file);
  return h;
}

std::optional<mapped_bytes> map_nifti_samples(const nifti_header& h, const fs::path& file,
                                              std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < h.volumes);
  const std::size_t item = sample_size(h.stored);
  if (h.scaled || h.volume_type() != h.stored) return std::nullopt;
  if (item > 1 && h.big_endian != (std::endian::native == std::endian::big)) return std::nullopt;
  const std::uint64_t bytes = static_cast<std::uint64_t>(h.dims[0]) *
                              static_cast<std::uint64_t>(h.dims[1]) *
                              static_cast<std::uint64_t>(h.dims[2]) * item;
  if (bytes < map_min_bytes) return std::nullopt;
  const fs::path& source = h.data_file ? *h.data_file : file;
  const sequential_input in(source, h.data_file ? "NIfTI data" : "NIfTI", "NIfTI gzip data");
  if (in.plain() == nullptr) return std::nullopt;
  const std::uint64_t start = h.vox_offset;
  const auto volumes = static_cast<std::uint64_t>(h.volumes);
  if (start > in.size() || volumes > (in.size() - start) / bytes) return std::nullopt;
  return map_bytes(*in.plain(), start + static_cast<std::uint64_t>(volume) * bytes, bytes);
}

std::vector<std::byte> read_nifti_samples(const nifti_header& h, const fs::path& file,
                                          std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < h.volumes);
  const std::size_t item = sample_size(h.stored);
  const auto count = static_cast<std::uint64_t>(h.dims[0]) * static_cast<std::uint64_t>(h.dims[1]) *
                     static_cast<std::uint64_t>(h.dims[2]);
  const std::uint64_t bytes = count * item;  // ≤ 32769³ × 8 < 2^48
  const fs::path& source = h.data_file ? *h.data_file : file;
  sequential_input in(source, h.data_file ? "NIfTI data" : "NIfTI", "NIfTI gzip data");
  const std::string name = source.string();
  const std::string shape = std::to_string(h.dims[0]) + "x" + std::to_string(h.dims[1]) + "x" +
                            std::to_string(h.dims[2]) +
                            (h.volumes > 1 ? "x" + std::to_string(h.volumes) : std::string());
  // Every declared volume, from vox_offset; more than 2^64 bytes cannot be present.
  const std::uint64_t start = h.vox_offset;
  const auto volumes = static_cast<std::uint64_t>(h.volumes);
  const bool fits = volumes <= (std::numeric_limits<std::uint64_t>::max() - start) / bytes;
  const std::uint64_t all = fits ? bytes * volumes : 0;
  const std::string declared = (fits ? std::to_string(all) : std::string("more than 2^64")) +
                               " bytes (" + shape + " of " + std::string(to_string(h.stored)) + ")";
  // The data must be able to hold the array before anything is allocated for it.
  if (in.gzipped()) {
    if (!fits || !gzip_can_hold(in.size(), start + all)) {
      throw error(name + ": " + std::to_string(in.size()) +
                  " bytes of gzip data cannot hold the declared " + declared +
                  " after byte offset " + std::to_string(start) + " (gzip expands at most " +
                  std::to_string(gzip_max_ratio) + ":1)");
    }
  } else if (!fits || in.size() < start || in.size() - start < all) {
    throw error(name + ": NIfTI data ends: the file has " + std::to_string(in.size()) +
                " bytes, too few for the declared " + declared + " from byte offset " +
                std::to_string(start));
  }
  // The chosen volume's first byte; a gzip file inflates the volumes before it.
  const std::uint64_t first = start + static_cast<std::uint64_t>(volume) * bytes;
  if (!in.skip_to(first)) {
    throw error(name + ": NIfTI data ends before " +
                (volume == 0 ? "vox_offset " + std::to_string(start)
                             : "volume " + std::to_string(volume) + " (byte " +
                                   std::to_string(first) + ")"));
  }
  // Scaled samples are read into the tail of the output array and converted front to back in
  // place: the output is never narrower than the stored type, so element i is written only
  // over stored elements before i + 1 (out × (i + 1) ≤ count × (out − in) + in × (i + 1)).
  const sample_type out_type = h.volume_type();
  const std::size_t out_item = sample_size(out_type);
  std::vector<std::byte> out(static_cast<std::size_t>(count) * out_item);
  const std::size_t tail = out.size() - static_cast<std::size_t>(bytes);
  const std::span<std::byte> stored(out.data() + tail, static_cast<std::size_t>(bytes));
  const std::size_t got = in.read(stored);
  if (got < stored.size()) {
    throw error(name + ": NIfTI data ends after " + std::to_string(got) + " of the " +
                std::to_string(bytes) + " bytes of " +
                (h.volumes > 1 ? "volume " + std::to_string(volume) + " of the declared "
                               : std::string("the declared ")) +
                declared);
  }
  if (item > 1 && h.big_endian != (std::endian::native == std::endian::big)) {
    swap_sample_bytes(stored, item);
  }
  if (!h.scaled) return out;
  // slope × stored + inter, in f32 or f64 (nifti_header::volume_type()).
  const auto convert = [&]<class T>(T) {
    for (std::size_t i = 0; i < static_cast<std::size_t>(count); ++i) {
      T x;
      std::memcpy(&x, stored.data() + i * sizeof x, sizeof x);
      const double v = h.slope * static_cast<double>(x) + h.inter;
      if (out_type == sample_type::f32) {
        const auto f = static_cast<float>(v);
        std::memcpy(out.data() + i * sizeof f, &f, sizeof f);
      } else {
        std::memcpy(out.data() + i * sizeof v, &v, sizeof v);
      }
    }
  };
  switch (h.stored) {
    case sample_type::u8:
      convert(std::uint8_t{});
      break;
    case sample_type::i8:
      convert(std::int8_t{});
      break;
    case sample_type::u16:
      convert(std::uint16_t{});
      break;
    case sample_type::i16:
      convert(std::int16_t{});
      break;
    case sample_type::u32:
      convert(std::uint32_t{});
      break;
    case sample_type::i32:
      convert(std::int32_t{});
      break;
    case sample_type::f32:
      convert(float{});
      break;
    case sample_type::f64:
      convert(double{});
      break;
  }
  return out;
}

}  // namespace progiso::detail
