// Tests for progiso's own NIfTI reader (io/detail/nifti_reader.hpp, through read_nifti(),
// read_volume() and volume_input_files()).
//
// Differential: nifti_clib (Debian's libnifti2-dev, a test-only dependency) reads the same files,
// and the two must agree on dims, every sample, spacing and origin: generated volumes of every
// supported type as NIfTI-1 and NIfTI-2, both byte orders, single files and header and data
// pairs, plain and gzip, with header extensions and scaling; files that nifti_clib writes
// itself; the shared real volumes written as NIfTI.
//
// Hostile: files that end inside the header, wrong size fields and magics, dimensions and
// offsets out of range, declared arrays far beyond the data, corrupt and truncated gzip,
// missing data files, unsupported types, time series. Each fails with one line naming the file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <sys/stat.h>
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"

extern "C" {
#include <nifti2_io.h>
}

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace {

namespace fs = std::filesystem;
using progiso::index3;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::gzip;
using progiso::test::random_samples;
// The one-line message of the progiso::error a call throws, which must start with the file.
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-nifti-reader-test-") {}
};

struct type_info {
  sample_type type;
  std::int16_t code;
};
constexpr std::array<type_info, 8> types{{{sample_type::u8, 2},
                                          {sample_type::i8, 256},
                                          {sample_type::u16, 512},
                                          {sample_type::i16, 4},
                                          {sample_type::u32, 768},
                                          {sample_type::i32, 8},
                                          {sample_type::f32, 16},
                                          {sample_type::f64, 64}}};

/// A NIfTI file as this test writes it, field by field (nifti1.h / nifti2.h offsets), so that
/// every field can be set to anything, hostile values included.
struct nifti_file {
  int version = 1;
  bool big_endian = false;
  bool pair = false;  // ni1 / ni2 header with the data in the .img
  std::array<std::int64_t, 8> dim{3, 5, 4, 3, 1, 1, 1, 1};
  std::int16_t datatype = 2;
  std::int16_t bitpix = 8;
  std::array<double, 8> pixdim{1, 1.5, 2.0, 0.75, 1, 1, 1, 1};
  double vox_offset = -1;  // −1: right after the header and extensions
  double scl_slope = 0;
  double scl_inter = 0;
  std::int32_t qform_code = 0;
  std::int32_t sform_code = 1;
  std::array<double, 3> qoffset{0, 0, 0};
  std::array<double, 3> quatern{0, 0, 0};  // b, c, d
  std::array<double, 3> sform_t{-10.5, 20.25, 3.0};
  // The sform's whole rows (else diag(pixdim) with sform_t as the last column).
  std::optional<std::array<std::array<double, 4>, 3>> srow;
  std::string extension;  // bytes of header extensions (a multiple of 16, or empty)
  std::string magic;      // empty: the right one

  [[nodiscard]] std::size_t header_size() const { return version == 1 ? 348 : 540; }
  [[nodiscard]] std::uint64_t data_offset() const {
    if (vox_offset >= 0) return static_cast<std::uint64_t>(vox_offset);
    return pair ? 0 : header_size() + 4 + extension.size();
  }

  template <class T>
  void put(std::string& h, std::size_t at, T value) const {
    auto b = std::bit_cast<std::array<char, sizeof(T)>>(value);
    if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b.begin(), b.end());
    std::memcpy(h.data() + at, b.data(), sizeof(T));
  }

  /// The header, the extension flag and extensions (single files), then nothing else.
  [[nodiscard]] std::string header() const {
    std::string h(header_size(), '\0');
    const bool v1 = version == 1;
    put<std::int32_t>(h, 0, static_cast<std::int32_t>(header_size()));
    for (std::size_t i = 0; i < 8; ++i) {
      if (v1) {
        put<std::int16_t>(h, 40 + 2 * i, static_cast<std::int16_t>(dim[i]));
        put<float>(h, 76 + 4 * i, static_cast<float>(pixdim[i]));
      } else {
        put<std::int64_t>(h, 16 + 8 * i, dim[i]);
        put<double>(h, 104 + 8 * i, pixdim[i]);
      }
    }
    put<std::int16_t>(h, v1 ? 70 : 12, datatype);
    put<std::int16_t>(h, v1 ? 72 : 14, bitpix);
    const double off = static_cast<double>(data_offset());
    if (v1) {
      put<float>(h, 108, static_cast<float>(vox_offset >= 0 ? vox_offset : off));
      put<float>(h, 112, static_cast<float>(scl_slope));
      put<float>(h, 116, static_cast<float>(scl_inter));
      put<std::int16_t>(h, 252, static_cast<std::int16_t>(qform_code));
      put<std::int16_t>(h, 254, static_cast<std::int16_t>(sform_code));
      for (std::size_t i = 0; i < 3; ++i) {
        put<float>(h, 268 + 4 * i, static_cast<float>(qoffset[i]));
        put<float>(h, 256 + 4 * i, static_cast<float>(quatern[i]));
      }
      // sform: the diagonal is the spacing, the last column the translation.
      for (std::size_t r = 0; r < 3; ++r) {
        put<float>(h, 280 + 16 * r + 4 * r, static_cast<float>(pixdim[r + 1]));
        put<float>(h, 280 + 16 * r + 12, static_cast<float>(sform_t[r]));
        for (std::size_t c = 0; srow && c < 4; ++c) {
          put<float>(h, 280 + 16 * r + 4 * c, static_cast<float>((*srow)[r][c]));
        }
      }
      const std::string m =
          magic.empty() ? (pair ? std::string("ni1\0", 4) : std::string("n+1\0", 4)) : magic;
      std::memcpy(h.data() + 344, m.data(), std::min<std::size_t>(4, m.size()));
    } else {
      put<std::int64_t>(h, 168, static_cast<std::int64_t>(vox_offset >= 0 ? vox_offset : off));
      put<double>(h, 176, scl_slope);
      put<double>(h, 184, scl_inter);
      put<std::int32_t>(h, 344, qform_code);
      put<std::int32_t>(h, 348, sform_code);
      for (std::size_t i = 0; i < 3; ++i) {
        put<double>(h, 376 + 8 * i, qoffset[i]);
        put<double>(h, 352 + 8 * i, quatern[i]);
      }
      for (std::size_t r = 0; r < 3; ++r) {
        put<double>(h, 400 + 32 * r + 8 * r, pixdim[r + 1]);
        put<double>(h, 400 + 32 * r + 24, sform_t[r]);
        for (std::size_t c = 0; srow && c < 4; ++c) {
          put<double>(h, 400 + 32 * r + 8 * c, (*srow)[r][c]);
        }
      }
      const std::string m = magic.empty() ? (pair ? std::string("ni2\0\r\n\032\n", 8)
                                                  : std::string("n+2\0\r\n\032\n", 8))
                                          : magic;
      std::memcpy(h.data() + 4, m.data(), std::min<std::size_t>(8, m.size()));
    }
    if (!pair) {
      std::string flag(4, '\0');
      flag[0] = extension.empty() ? '\0' : '\1';
      h += flag + extension;
    }
    return h;
  }

  /// Samples (host order) in the file's byte order.
  [[nodiscard]] std::string data_bytes(const std::vector<std::byte>& samples,
                                       std::size_t item) const {
    std::string d(reinterpret_cast<const char*>(samples.data()), samples.size());
    if (item > 1 && big_endian != (std::endian::native == std::endian::big)) {
      for (std::size_t i = 0; i < d.size(); i += item)
        std::reverse(d.data() + i, d.data() + i + item);
    }
    return d;
  }

  /// Writes the file (and its .img for a pair); returns the path to read.
  fs::path write(const fs::path& dir, const std::string& stem,
                 const std::vector<std::byte>& samples, std::size_t item, bool gz) const {
    const std::string data = data_bytes(samples, item);
    if (pair) {
      const fs::path hdr = dir / (stem + (gz ? ".hdr.gz" : ".hdr"));
      progiso::test::write_file(hdr, gz ? gzip(header()) : header());
      std::string img(data_offset(), '\0');
      img += data;
      progiso::test::write_file(dir / (stem + (gz ? ".img.gz" : ".img")), gz ? gzip(img) : img);
      return hdr;
    }
    std::string all = header();
    all.resize(std::max<std::size_t>(all.size(), data_offset()), '\0');
    all += data;
    const fs::path nii = dir / (stem + (gz ? ".nii.gz" : ".nii"));
    progiso::test::write_file(nii, gz ? gzip(all) : all);
    return nii;
  }
};

/// Calls f(file, gz) for the 16 layouts of a file: NIfTI-1 and NIfTI-2, both byte orders, single
/// file and header and data pair, plain and gzip (`file` otherwise as nifti_file's defaults).
template <class F>
void for_each_layout(F&& f) {
  for (const int version : {1, 2}) {
    for (const bool big : {false, true}) {
      for (const bool pair : {false, true}) {
        for (const bool gz : {false, true}) {
          nifti_file file;
          file.version = version;
          file.big_endian = big;
          file.pair = pair;
          f(file, gz);
        }
      }
    }
  }
}

/// Random samples of `type` (finite floats), `count` of them.
struct reference_image {
  struct free_image {
    void operator()(nifti_image* p) const { nifti_image_free(p); }
  };
  std::unique_ptr<nifti_image, free_image> image;
};

reference_image reference_read(const fs::path& file) {
  nifti_set_debug_level(0);
  return {
      std::unique_ptr<nifti_image, reference_image::free_image>(nifti_image_read(file.c_str(), 1))};
}

/// progiso's volume against nifti_clib's reading of the same file: dims, samples (scaled as the
/// header says), spacing and origin.
void expect_same_as_reference(const progiso::volume& v, const fs::path& file) {
  const reference_image ref = reference_read(file);
  ASSERT_NE(ref.image, nullptr) << file;
  const nifti_image& n = *ref.image;
  ASSERT_EQ(v.dims(), (index3{n.nx, n.ny, n.nz})) << file;
  ASSERT_EQ(static_cast<std::size_t>(n.nvox), v.voxel_count()) << file;
  const bool scaled = n.scl_slope != 0.0 && !(n.scl_slope == 1.0 && n.scl_inter == 0.0);
  const auto stored = [&](std::size_t i) -> double {
    const auto* p =
        static_cast<const unsigned char*>(n.data) + i * static_cast<std::size_t>(n.nbyper);
    const auto get = [p]<class T>(T) {
      T x;
      std::memcpy(&x, p, sizeof x);
      return static_cast<double>(x);
    };
    switch (n.datatype) {
      case 2:
        return get(std::uint8_t{});
      case 256:
        return get(std::int8_t{});
      case 512:
        return get(std::uint16_t{});
      case 4:
        return get(std::int16_t{});
      case 768:
        return get(std::uint32_t{});
      case 8:
        return get(std::int32_t{});
      case 16:
        return get(float{});
      default:
        return get(double{});
    }
  };
  for (std::size_t i = 0; i < v.voxel_count(); ++i) {
    double want = stored(i);
    if (scaled) {
      want = n.scl_slope * want + n.scl_inter;
      if (v.type() == sample_type::f32) want = static_cast<double>(static_cast<float>(want));
    }
    ASSERT_EQ(v.at(i), want) << file << " sample " << i;
  }
  const std::array<double, 3> spacing{std::abs(n.dx), std::abs(n.dy), std::abs(n.dz)};
  for (std::size_t a = 0; a < 3; ++a) {
    EXPECT_DOUBLE_EQ(v.spacing()[a], spacing[a] > 0 ? spacing[a] : 1.0) << file;
  }
  const auto& m = n.sform_code > 0 ? n.sto_xyz : n.qto_xyz;
  for (std::size_t a = 0; a < 3; ++a) {
    const double want = n.sform_code > 0 || n.qform_code > 0 ? m.m[a][3] : 0.0;
    EXPECT_NEAR(v.origin()[a], want, 1e-6 * (1 + std::abs(want))) << file;
  }
}

TEST(NiftiReader, agrees_with_nifti_clib_on_every_type_version_byte_order_layout_and_compression) {
  scratch_dir dir;
  int files = 0;
  for (const type_info& t : types) {
    for_each_layout([&](nifti_file& f, bool gz) {
      f.datatype = t.code;
      f.bitpix = static_cast<std::int16_t>(8 * progiso::sample_size(t.type));
      const std::size_t count = 5 * 4 * 3;
      const auto samples = random_samples(t.type, count, static_cast<unsigned>(files));
      const std::string stem = "v" + std::to_string(files++);
      const fs::path file = f.write(dir.path(), stem, samples, progiso::sample_size(t.type), gz);
      const progiso::volume v = progiso::read_nifti(file);
      EXPECT_EQ(v.type(), t.type) << file;
      EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0) << file;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{-10.5, 20.25, 3.0})) << file;
      EXPECT_EQ(v.spacing(), (std::array<double, 3>{1.5, 2.0, 0.75})) << file;
      expect_same_as_reference(v, file);
    });
  }
  EXPECT_EQ(files, 128);
}

TEST(NiftiReader, scales_samples_to_physical_values_as_nifti_clib_does) {
  scratch_dir dir;
  // CT-like: int16 with slope 1 and intercept −1024 (Hounsfield units), and a general slope on
  // every type; 32-bit integers and doubles scale into f64, the others into f32.
  int k = 0;
  for (const type_info& t : types) {
    for (const auto& [slope, inter] : {std::pair{1.0, -1024.0}, std::pair{0.25, 3.5}}) {
      nifti_file f;
      f.datatype = t.code;
      f.bitpix = static_cast<std::int16_t>(8 * progiso::sample_size(t.type));
      f.scl_slope = slope;
      f.scl_inter = inter;
      f.version = k % 2 == 0 ? 1 : 2;
      const auto samples = random_samples(t.type, 60, static_cast<unsigned>(100 + k));
      const fs::path file = f.write(dir.path(), "s" + std::to_string(k++), samples,
                                    progiso::sample_size(t.type), false);
      const progiso::volume v = progiso::read_nifti(file);
      const bool wide =
          t.type == sample_type::u32 || t.type == sample_type::i32 || t.type == sample_type::f64;
      EXPECT_EQ(v.type(), wide ? sample_type::f64 : sample_type::f32) << file;
      expect_same_as_reference(v, file);
    }
  }
  // Slope 0 means unscaled, and so does (1, 0): the stored type stays.
  for (const double slope : {0.0, 1.0}) {
    nifti_file f;
    f.scl_slope = slope;
    f.scl_inter = 0.0;
    const auto samples = random_samples(sample_type::u8, 60, 7);
    const fs::path file = f.write(dir.path(), "u" + std::to_string(slope), samples, 1, false);
    EXPECT_EQ(progiso::read_nifti(file).type(), sample_type::u8) << file;
  }
}

TEST(NiftiReader, reads_what_nifti_clib_writes_single_files_pairs_and_gzip) {
  scratch_dir dir;
  int k = 0;
  for (const char* ext : {".nii", ".nii.gz", ".hdr", ".hdr.gz"}) {
    for (const int version : {1, 2}) {
      const int64_t dims[8] = {3, 6, 5, 4, 1, 1, 1, 1};
      nifti_image* nim = nifti_make_new_nim(dims, DT_INT16, 1);
      ASSERT_NE(nim, nullptr);
      nim->nifti_type =
          version == 1
              ? (std::string(ext).find(".nii") != std::string::npos ? NIFTI_FTYPE_NIFTI1_1
                                                                    : NIFTI_FTYPE_NIFTI1_2)
              : (std::string(ext).find(".nii") != std::string::npos ? NIFTI_FTYPE_NIFTI2_1
                                                                    : NIFTI_FTYPE_NIFTI2_2);
      nim->dx = nim->pixdim[1] = 0.5;
      nim->dy = nim->pixdim[2] = 0.8;
      nim->dz = nim->pixdim[3] = 2.5;
      nim->qform_code = 1;
      nim->qoffset_x = 12.0;
      nim->qoffset_y = -7.5;
      nim->qoffset_z = 100.25;
      nim->quatern_b = nim->quatern_c = nim->quatern_d = 0.0;
      nim->qfac = 1.0;
      nim->scl_slope = 2.0;
      nim->scl_inter = -1024.0;
      auto* data = static_cast<std::int16_t*>(nim->data);
      for (std::int64_t i = 0; i < nim->nvox; ++i)
        data[i] = static_cast<std::int16_t>(i * 37 - 300);
      const fs::path file = dir.path() / ("w" + std::to_string(k++) + ext);
      ASSERT_EQ(nifti_set_filenames(nim, file.c_str(), 0, 1), 0);
      nifti_image_write(nim);
      nifti_image_free(nim);
      const progiso::volume v = progiso::read_nifti(file);
      EXPECT_EQ(v.dims(), (index3{6, 5, 4})) << file;
      EXPECT_EQ(v.type(), sample_type::f32) << file;
      EXPECT_EQ(v.at(1), 2.0 * (37 - 300) - 1024.0) << file;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{12.0, -7.5, 100.25})) << file;
      expect_same_as_reference(v, file);
      const std::vector<fs::path> inputs = progiso::volume_input_files(file, std::nullopt);
      EXPECT_EQ(inputs.size(), std::string(ext).find(".hdr") != std::string::npos ? 2u : 1u)
          << file;
    }
  }
}

TEST(NiftiReader, skips_header_extensions_and_reads_one_time_point_of_a_4d_file) {
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u16, 60, 3);
  nifti_file f;
  f.datatype = 512;
  f.bitpix = 16;
  // One extension of 32 bytes: esize 32, ecode 4 (AFNI), then text.
  std::string ext(32, 'x');
  ext[0] = 32;
  ext[1] = ext[2] = ext[3] = 0;
  ext[4] = 4;
  ext[5] = ext[6] = ext[7] = 0;
  f.extension = ext;
  f.dim = {4, 5, 4, 3, 1, 1, 1, 1};
  for (const bool gz : {false, true}) {
    const fs::path file = f.write(dir.path(), gz ? "e1" : "e0", samples, 2, gz);
    const progiso::volume v = progiso::read_nifti(file);
    EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0) << file;
    expect_same_as_reference(v, file);
  }
  // Origin from the qform when there is no sform; 0 when neither is set.
  nifti_file q;
  q.sform_code = 0;
  q.qform_code = 1;
  q.qoffset = {1.5, -2.5, 4.0};
  const auto bytes = random_samples(sample_type::u8, 60, 4);
  EXPECT_EQ(progiso::read_nifti(q.write(dir.path(), "q", bytes, 1, false)).origin(),
            (std::array<double, 3>{1.5, -2.5, 4.0}));
  q.qform_code = 0;
  EXPECT_EQ(progiso::read_nifti(q.write(dir.path(), "n", bytes, 1, false)).origin(),
            (std::array<double, 3>{0.0, 0.0, 0.0}));
}

/// nifti_clib's reading of volume t of a time series (nifti_read_collapsed_image with dim[4]
/// fixed), as stored bytes.
std::vector<std::byte> reference_volume(const fs::path& file, std::int64_t t) {
  nifti_set_debug_level(0);
  const reference_image ref{
      std::unique_ptr<nifti_image, reference_image::free_image>(nifti_image_read(file.c_str(), 0))};
  EXPECT_NE(ref.image, nullptr) << file;
  if (!ref.image) return {};
  const std::int64_t dims[8] = {-1, -1, -1, -1, t, -1, -1, -1};
  void* data = nullptr;
  const std::int64_t n = nifti_read_collapsed_image(ref.image.get(), dims, &data);
  EXPECT_GT(n, 0) << file << " volume " << t;
  std::vector<std::byte> out;
  if (n > 0) out.assign(static_cast<std::byte*>(data), static_cast<std::byte*>(data) + n);
  std::free(data);
  return out;
}

TEST(NiftiReader, reads_the_chosen_volume_of_a_time_series_as_nifti_clib_does) {
  // A 4-D file (dim[4] = 5 volumes of 5 × 4 × 3) as NIfTI-1 and -2, single file and pair, plain
  // and gzip, both byte orders: volume k is the k-th block of samples, and nifti_clib's
  // collapsed image of t = k; read_volume() and volume_input_files() take the same choice.
  scratch_dir dir;
  const std::int64_t volumes = 5;
  const std::size_t voxels = 5 * 4 * 3;
  int n = 0;
  for_each_layout([&](nifti_file& f, bool gz) {
    f.datatype = 4;  // INT16
    f.bitpix = 16;
    f.dim = {4, 5, 4, 3, volumes, 1, 1, 1};
    const auto samples =
        random_samples(sample_type::i16, voxels * volumes, static_cast<unsigned>(200 + n));
    const fs::path file = f.write(dir.path(), "t" + std::to_string(n++), samples, 2, gz);
    for (std::int64_t k = 0; k < volumes; ++k) {
      const progiso::volume v = progiso::read_nifti(file, {.volume = k});
      ASSERT_EQ(v.dims(), (index3{5, 4, 3})) << file;
      const std::size_t at = static_cast<std::size_t>(k) * voxels * 2;
      EXPECT_EQ(std::memcmp(v.bytes(), samples.data() + at, voxels * 2), 0)
          << file << " volume " << k;
      const std::vector<std::byte> ref = reference_volume(file, k);
      ASSERT_EQ(ref.size(), voxels * 2) << file;
      EXPECT_EQ(std::memcmp(v.bytes(), ref.data(), ref.size()), 0) << file << " " << k;
      EXPECT_EQ(v.origin(), (std::array<double, 3>{-10.5, 20.25, 3.0})) << file;
    }
    const progiso::volume last =
        progiso::read_volume(file, std::nullopt, std::nullopt, {.volume = volumes - 1});
    EXPECT_EQ(std::memcmp(last.bytes(), samples.data() + (volumes - 1) * voxels * 2, voxels * 2), 0)
        << file;
    EXPECT_EQ(progiso::volume_input_files(file, std::nullopt, {.volume = 2}).size(),
              f.pair ? 2u : 1u);
    EXPECT_TRUE(progiso::read_volume_world(file, std::nullopt, {.volume = 0}).has_value());
  });
  EXPECT_EQ(n, 16);
  // Scaled volumes are scaled as the first is.
  nifti_file s;
  s.dim = {4, 5, 4, 3, 3, 1, 1, 1};
  s.scl_slope = 0.5;
  s.scl_inter = -3.0;
  std::vector<std::byte> bytes(voxels * 3);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::byte>(i % 251);
  const fs::path scaled = s.write(dir.path(), "scaled", bytes, 1, true);
  const progiso::volume v = progiso::read_nifti(scaled, {.volume = 2});
  EXPECT_EQ(v.type(), sample_type::f32);
  for (std::size_t i = 0; i < voxels; ++i) {
    EXPECT_EQ(v.at(i), 0.5 * static_cast<double>((2 * voxels + i) % 251) - 3.0) << i;
  }
}

TEST(NiftiReader,
     a_time_series_needs_a_volume_that_exists_and_a_volume_needs_an_input_that_has_it) {
  scratch_dir dir;
  nifti_file f;
  f.dim = {4, 5, 4, 3, 20, 1, 1, 1};
  const auto samples = random_samples(sample_type::u8, 60 * 20, 21);
  const fs::path series = f.write(dir.path(), "series", samples, 1, false);
  const auto message = [&](const fs::path& file, const progiso::volume_choice& choice) {
    return error_naming(
        file, [&] { (void)progiso::read_volume(file, std::nullopt, std::nullopt, choice); });
  };
  // No choice: the error says how many there are and how to choose.
  std::string m = message(series, {});
  EXPECT_TRUE(contains(m, "time series of 20 volumes")) << m;
  EXPECT_TRUE(contains(m, "0 to 19")) << m;
  for (const std::int64_t k : {std::int64_t{20}, std::int64_t{-1}, std::int64_t{1} << 40}) {
    m = message(series, {.volume = k});
    EXPECT_TRUE(contains(m, "volume " + std::to_string(k) + " was chosen")) << m;
    EXPECT_TRUE(contains(m, "0 to 19")) << m;
    // The header-only calls refuse it the same way.
    const std::string w = error_naming(
        series, [&] { (void)progiso::read_volume_world(series, std::nullopt, {.volume = k}); });
    EXPECT_TRUE(contains(w, "was chosen")) << w;
    const std::string in = error_naming(
        series, [&] { (void)progiso::volume_input_files(series, std::nullopt, {.volume = k}); });
    EXPECT_TRUE(contains(in, "was chosen")) << in;
  }
  // A 3-D NIfTI, a NRRD or a raw file hold volume 0 only.
  nifti_file one;
  const fs::path three =
      one.write(dir.path(), "three", random_samples(sample_type::u8, 60, 22), 1, false);
  EXPECT_EQ(progiso::read_volume(three, std::nullopt, std::nullopt, {.volume = 0}).dims(),
            (index3{5, 4, 3}));
  m = message(three, {.volume = 1});
  EXPECT_TRUE(contains(m, "holds one volume (0)")) << m;
  const fs::path nrrd = dir.path() / "v.nrrd";
  progiso::test::write_file(nrrd,
                            "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                            "encoding: raw\n\n" +
                                std::string(8, '\1'));
  EXPECT_EQ(progiso::read_volume(nrrd, std::nullopt, std::nullopt, {.volume = 0}).dims(),
            (index3{2, 2, 2}));
  m = message(nrrd, {.volume = 3});
  EXPECT_TRUE(contains(m, "holds one volume (0)")) << m;
  const fs::path raw = dir.path() / "v.raw";
  progiso::test::write_file(raw, std::string(8, '\2'));
  const progiso::raw_layout layout{{2, 2, 2}, sample_type::u8, false};
  m = error_naming(raw,
                   [&] { (void)progiso::read_volume(raw, layout, std::nullopt, {.volume = 1}); });
  EXPECT_TRUE(contains(m, "holds one volume (0)")) << m;
  // Dimensions above the fourth are still refused: a vector per voxel is not a volume.
  nifti_file vec;
  vec.dim = {5, 5, 4, 3, 1, 3, 1, 1};
  const fs::path vf =
      vec.write(dir.path(), "vector", random_samples(sample_type::u8, 180, 23), 1, false);
  m = error_naming(vf, [&] { (void)progiso::read_nifti(vf, {.volume = 0}); });
  EXPECT_TRUE(contains(m, "dim[5] is 3")) << m;
}

TEST(NiftiReader, refuses_a_time_series_whose_data_cannot_hold_every_volume_before_allocating) {
  // The chosen volume lies in the file, the declared ones after it do not: refused all the
  // same (the header is wrong), from the sizes; gzip data is measured against every volume too.
  scratch_dir dir;
  nifti_file f;
  f.dim = {4, 5, 4, 3, 4, 1, 1, 1};
  const auto samples = random_samples(sample_type::u8, 60 * 4, 24);
  std::string whole =
      f.header() + std::string(reinterpret_cast<const char*>(samples.data()), samples.size());
  const fs::path cut = dir.path() / "cut.nii";
  progiso::test::write_file(cut, whole.substr(0, whole.size() - 1));
  std::string m = error_naming(cut, [&] { (void)progiso::read_nifti(cut, {.volume = 0}); });
  EXPECT_TRUE(contains(m, "NIfTI data ends")) << m;
  EXPECT_TRUE(contains(m, "5x4x3x4")) << m;
  // gzip data that ends inside volume 2.
  const fs::path gz = dir.path() / "cut.nii.gz";
  progiso::test::write_file(gz, gzip(whole.substr(0, whole.size() - 100)));
  m = error_naming(gz, [&] { (void)progiso::read_nifti(gz, {.volume = 2}); });
  EXPECT_TRUE(contains(m, "NIfTI data ends")) << m;
  EXPECT_TRUE(contains(m, "volume 2")) << m;
  // 2^40 volumes of 281 TB each: refused from the sizes, at once (the product overflows).
  nifti_file huge;
  huge.version = 2;
  huge.dim = {4, 32769, 32769, 32769, std::int64_t{1} << 40, 1, 1, 1};
  huge.datatype = 64;
  huge.bitpix = 64;
  const fs::path hf = dir.path() / "huge.nii";
  progiso::test::write_file(hf, huge.header() + std::string(64, '\0'));
  m = error_naming(hf, [&] { (void)progiso::read_nifti(hf, {.volume = 5}); });
  EXPECT_TRUE(contains(m, "more than 2^64")) << m;
  const fs::path hgz = dir.path() / "huge.nii.gz";
  progiso::test::write_file(hgz, gzip(huge.header() + std::string(64, '\0')));
  m = error_naming(hgz, [&] { (void)progiso::read_nifti(hgz, {.volume = 5}); });
  EXPECT_TRUE(contains(m, "cannot hold")) << m;
}

TEST(NiftiReader, read_volume_picks_nifti_by_name_in_any_case_and_a_given_spacing_wins) {
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u8, 60, 5);
  nifti_file f;
  const fs::path file = f.write(dir.path(), "upper", samples, 1, true);
  const fs::path upper = dir.path() / "UPPER.NII.GZ";
  fs::rename(file, upper);
  const progiso::volume v = progiso::read_volume(upper, std::nullopt, std::nullopt);
  EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0);
  const progiso::volume w =
      progiso::read_volume(upper, std::nullopt, std::array<double, 3>{3.0, 3.0, 3.0});
  EXPECT_EQ(w.spacing(), (std::array<double, 3>{3.0, 3.0, 3.0}));
  // A gzip file named .nii and a plain one named .nii.gz are read by their contents.
  const fs::path misnamed = dir.path() / "gz_inside.nii";
  fs::copy_file(upper, misnamed);
  EXPECT_EQ(progiso::read_volume(misnamed, std::nullopt, std::nullopt).voxel_count(), 60u);
  const std::string message = error_naming(dir.path() / "x.img", [&] {
    (void)progiso::read_volume(dir.path() / "x.img", std::nullopt, std::nullopt);
  });
  EXPECT_TRUE(contains(message, ".nii.gz")) << message;
}

TEST(NiftiReader, the_shared_volumes_read_as_nifti_equal_their_raw_files) {
  const auto data = progiso::test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found";
  scratch_dir dir;
  for (const auto& info : progiso::test::shared_volumes()) {
    const progiso::volume raw = progiso::test::load_shared_volume(info, *data);
    nifti_file f;
    f.version = 2;  // pixdim in doubles: 3.2 is not a float
    f.dim = {3, info.dims[0], info.dims[1], info.dims[2], 1, 1, 1, 1};
    const auto t = std::find_if(types.begin(), types.end(),
                                [&](const type_info& x) { return x.type == info.type; });
    f.datatype = t->code;
    f.bitpix = static_cast<std::int16_t>(8 * progiso::sample_size(info.type));
    f.pixdim = {1, info.spacing[0], info.spacing[1], info.spacing[2], 1, 1, 1, 1};
    f.sform_t = {0, 0, 0};
    std::vector<std::byte> bytes(raw.bytes(), raw.bytes() + raw.byte_size());
    const fs::path file =
        f.write(dir.path(), std::string(info.name), bytes, progiso::sample_size(info.type), true);
    const progiso::volume v = progiso::read_nifti(file);
    EXPECT_EQ(v.dims(), raw.dims()) << info.name;
    EXPECT_EQ(v.spacing(), raw.spacing()) << info.name;
    EXPECT_EQ(std::memcmp(v.bytes(), raw.bytes(), raw.byte_size()), 0) << info.name;
  }
}

TEST(NiftiReader, reads_what_nifti_clib_reads_despite_a_wrong_bitpix_or_zero_upper_dims) {
  // Writers get bitpix wrong and leave dimensions above dim[0]'s third at 0; the datatype and
  // the first three dimensions say what the data is, for nifti_clib as for progiso.
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u16, 60, 21);
  nifti_file f;
  f.datatype = 512;
  f.bitpix = 8;
  f.dim = {5, 5, 4, 3, 0, -1, 1, 1};
  const fs::path file = f.write(dir.path(), "lenient", samples, 2, false);
  const progiso::volume v = progiso::read_nifti(file);
  EXPECT_EQ(v.type(), sample_type::u16);
  EXPECT_EQ(std::memcmp(v.bytes(), samples.data(), samples.size()), 0);
  expect_same_as_reference(v, file);
}

TEST(NiftiReader, declares_the_scanner_orientation_nifti_clib_reads_sform_then_qform) {
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u8, 60, 31);
  int k = 0;
  const auto check = [&](const nifti_file& f, bool expect_world) {
    const bool gz = k % 2 == 0;
    const fs::path file = f.write(dir.path(), "o" + std::to_string(k++), samples, 1, gz);
    const std::optional<progiso::index_to_world> w = progiso::read_volume_world(file, std::nullopt);
    ASSERT_EQ(w.has_value(), expect_world) << file;
    const reference_image ref = reference_read(file);
    ASSERT_NE(ref.image, nullptr);
    if (!expect_world) return;
    const nifti_image& n = *ref.image;
    const auto& m = n.sform_code > 0 ? n.sto_xyz : n.qto_xyz;
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t c = 0; c < 4; ++c) {
        EXPECT_NEAR(w->m[r][c], m.m[r][c], 1e-9 * (1 + std::abs(m.m[r][c])))
            << file << " row " << r << " column " << c;
      }
    }
    // apply() is the matrix times (i, j, k, 1).
    const std::array<double, 3> p = w->apply({2.0, 1.0, 3.0});
    for (std::size_t r = 0; r < 3; ++r) {
      EXPECT_NEAR(p[r], m.m[r][0] * 2 + m.m[r][1] + m.m[r][2] * 3 + m.m[r][3], 1e-9) << file;
    }
  };
  for (const int version : {1, 2}) {
    nifti_file f;
    f.version = version;
    // A rotated, mirrored and sheared sform (a right-to-left flip, as many MRI files have).
    f.srow = std::array<std::array<double, 4>, 3>{
        {{-0.9, 0.1, 0.0, 90.5}, {0.05, 1.1, -0.2, -126.0}, {0.0, 0.3, 1.4, -72.25}}};
    check(f, true);
    // The qform alone: a quaternion with qfac −1, then a 180° turn (a = 0).
    nifti_file q;
    q.version = version;
    q.sform_code = 0;
    q.qform_code = 1;
    q.quatern = {0.1, -0.2, 0.3};
    q.pixdim[0] = -1;
    q.qoffset = {12.0, -7.5, 100.25};
    check(q, true);
    q.quatern = {0.0, 0.0, 1.0};
    q.pixdim[0] = 1;
    check(q, true);
    nifti_file none;
    none.version = version;
    none.sform_code = 0;
    check(none, false);
  }
  // The determinant: negative for the mirrored sform above, positive without a flip.
  progiso::index_to_world mirrored{
      {{{-0.9, 0.1, 0.0, 0}, {0.05, 1.1, -0.2, 0}, {0.0, 0.3, 1.4, 0}}}};
  EXPECT_NEAR(mirrored.determinant(), -0.9 * (1.1 * 1.4 + 0.2 * 0.3) - 0.1 * (0.05 * 1.4), 1e-12);
  // A singular sform declares nothing usable.
  nifti_file flat;
  flat.srow = std::array<std::array<double, 4>, 3>{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 0, 0}}};
  const fs::path file = flat.write(dir.path(), "flat", samples, 1, false);
  EXPECT_FALSE(progiso::read_volume_world(file, std::nullopt).has_value());
  // Raw files declare none.
  EXPECT_FALSE(progiso::read_volume_world(file, progiso::raw_layout{{5, 4, 3}, sample_type::u8})
                   .has_value());
}

// ---- Hostile input: one line naming the file, no allocation for a declared size.

TEST(NiftiReader, refuses_hostile_headers_with_one_line_naming_the_file) {
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u8, 60, 9);
  const auto expect_error = [&](const nifti_file& f, const std::string& stem,
                                const std::string& what, bool gz = false) {
    const fs::path file = f.write(dir.path(), stem, samples, 1, gz);
    const std::string message = error_naming(file, [&] { (void)progiso::read_nifti(file); });
    EXPECT_TRUE(contains(message, what)) << stem << ": " << message;
  };
  {
    nifti_file f;
    f.magic = std::string(4, '\0');
    expect_error(f, "analyze", "Analyze");
  }
  {
    nifti_file f;
    f.version = 2;
    f.magic = "n+1";
    expect_error(f, "badmagic2", "NIfTI-2 magic");
  }
  for (const std::int64_t d : {std::int64_t{0}, std::int64_t{-3}, std::int64_t{8}}) {
    nifti_file f;
    f.dim[0] = d;
    expect_error(f, "dim0_" + std::to_string(d), "dim[0]");
  }
  {
    nifti_file f;
    f.dim = {2, 5, 12, 1, 1, 1, 1, 1};
    expect_error(f, "two_d", "expected a 3-D volume");
  }
  {
    nifti_file f;
    f.dim = {4, 5, 4, 3, 20, 1, 1, 1};
    expect_error(f, "series", "time series of 20 volumes");  // no volume chosen
  }
  {
    nifti_file f;
    f.dim = {6, 5, 4, 3, 2, 1, 7, 1};
    expect_error(f, "dim6", "dim[6] is 7");
  }
  for (const std::int64_t d : {std::int64_t{1}, std::int64_t{-5}, std::int64_t{40000}}) {
    nifti_file f;
    f.version = 2;
    f.dim[2] = d;
    expect_error(f, "dim2_" + std::to_string(d), "dim[2]");
  }
  {
    nifti_file f;
    f.datatype = 128;
    f.bitpix = 24;
    expect_error(f, "rgb", "RGB24");
  }
  {
    nifti_file f;
    f.vox_offset = 100;
    expect_error(f, "inside", "inside the header");
  }
  {
    nifti_file f;
    f.vox_offset = 352.5;
    expect_error(f, "fraction", "whole number");
  }
  {
    nifti_file f;
    f.version = 2;
    f.vox_offset = 1e12;  // far past the end of a small file
    const fs::path file = dir.path() / "far.nii";
    progiso::test::write_file(file, f.header() + std::string(60, '\0'));
    const std::string message = error_naming(file, [&] { (void)progiso::read_nifti(file); });
    EXPECT_TRUE(contains(message, "NIfTI data ends")) << message;
  }
  {
    nifti_file f;
    f.scl_slope = 2;
    f.scl_inter = std::numeric_limits<double>::infinity();
    expect_error(f, "inter", "scl_inter");
  }
}

TEST(NiftiReader, refuses_short_truncated_and_corrupt_files_without_allocating_the_declared_size) {
  scratch_dir dir;
  const auto samples = random_samples(sample_type::u8, 60, 11);
  nifti_file f;
  const std::string whole =
      f.header() + std::string(reinterpret_cast<const char*>(samples.data()), 60);
  const auto expect_error = [&](const std::string& stem, const std::string& bytes,
                                const std::string& what) {
    const fs::path file = dir.path() / stem;
    progiso::test::write_file(file, bytes);
    const std::string message = error_naming(file, [&] { (void)progiso::read_nifti(file); });
    EXPECT_TRUE(contains(message, what)) << stem << ": " << message;
  };
  expect_error("empty.nii", "", "inside the NIfTI header");
  expect_error("short.nii", whole.substr(0, 200), "of the 348 bytes");
  expect_error("notnifti.nii", std::string(400, 'a'), "not a NIfTI file");
  expect_error("shortdata.nii", whole.substr(0, whole.size() - 1), "NIfTI data ends");
  expect_error("shortgz.nii.gz", gzip(whole.substr(0, whole.size() - 7)),
               "NIfTI data ends after 53");
  std::string corrupt = gzip(whole);
  for (std::size_t i = 20; i < corrupt.size() - 8; i += 3)
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5a);
  expect_error("corrupt.nii.gz", corrupt, "corrupt NIfTI gzip data");
  // A declared 32769 × 32769 × 32769 array of doubles (281 TB) in a file of a few hundred
  // bytes, plain and gzip: refused from the sizes, at once.
  nifti_file huge;
  huge.version = 2;
  huge.dim = {3, 32769, 32769, 32769, 1, 1, 1, 1};
  huge.datatype = 64;
  huge.bitpix = 64;
  expect_error("huge.nii", huge.header() + std::string(64, '\0'), "NIfTI data ends");
  expect_error("huge.nii.gz", gzip(huge.header() + std::string(64, '\0')), "cannot hold");
  // A pair without its data file names the file it looked for.
  nifti_file pair;
  pair.pair = true;
  const fs::path hdr = dir.path() / "lonely.hdr";
  progiso::test::write_file(hdr, pair.header());
  const std::string message = error_naming(hdr, [&] { (void)progiso::read_nifti(hdr); });
  EXPECT_TRUE(contains(message, "lonely.img")) << message;
  // A NaN sample names the data file and the sample.
  nifti_file nan;
  nan.datatype = 16;
  nan.bitpix = 32;
  nan.pair = true;
  std::vector<std::byte> floats = random_samples(sample_type::f32, 60, 12);
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(floats.data() + 4 * 17, &bad, sizeof bad);
  const fs::path nan_hdr = nan.write(dir.path(), "nan", floats, 4, false);
  const std::string nan_message =
      error_naming(dir.path() / "nan.img", [&] { (void)progiso::read_nifti(nan_hdr); });
  EXPECT_TRUE(contains(nan_message, "NaN") || contains(nan_message, "finite")) << nan_message;
}

TEST(NiftiReader, refuses_a_fifo_without_blocking) {
  scratch_dir dir;
  const fs::path fifo = dir.path() / "pipe.nii";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string message = error_naming(fifo, [&] { (void)progiso::read_nifti(fifo); });
  EXPECT_TRUE(contains(message, "FIFO")) << message;
}

}  // namespace
