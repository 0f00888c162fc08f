// JPEG 2000 DICOM (1.2.840.10008.1.2.4.90 lossless only, .91 lossy allowed), decoded through
// OpenJPEG: enhanced multi-frame files and classic series whose frames OpenJPEG encoded
// (support/jpeg2000_encode.hpp) — 8, 12 and 16 bits, signed and not, bare codestreams and JP2
// files, tiles and resolutions, a frame in one fragment or several — read back as the samples
// encoded (lossless) or near them (lossy); and every refusal as one line naming the file and
// frame: a frame whose size, components, precision or sign differ from the DICOM header, a
// codestream cut short, fewer frames than NumberOfFrames, ratios beyond 4096, and
// High-Throughput JPEG 2000 by name.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/jpeg2000_encode.hpp"
#include "support/scratch_dir.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;
using test::contains;

constexpr const char* j2k_lossless = "1.2.840.10008.1.2.4.90";
constexpr const char* j2k_lossy = "1.2.840.10008.1.2.4.91";

struct depth {
  int bits_allocated;
  int bits_stored;
  bool is_signed;
};

// Random stored values of a depth.
std::vector<std::int32_t> random_frame(std::size_t count, const depth& d, std::mt19937& rng) {
  std::vector<std::int32_t> v(count);
  const std::int64_t span = std::int64_t{1} << d.bits_stored;
  for (std::int32_t& x : v) {
    const auto u = static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(span));
    x = static_cast<std::int32_t>(d.is_signed ? u - span / 2 : u);
  }
  return v;
}

// An enhanced image of `frames.size()` frames of columns × rows, one per position along z,
// each frame's codestream split into `pieces` fragments.
test::dicom_slice_file enhanced(const std::vector<std::string>& codestreams, int columns, int rows,
                                const depth& d, int pieces, const char* syntax) {
  test::dicom_slice_file f;
  f.transfer_syntax = syntax;
  f.rows = rows;
  f.columns = columns;
  f.bits_allocated = d.bits_allocated;
  f.bits_stored = d.bits_stored;
  f.pixel_representation = d.is_signed ? 1 : 0;
  f.intercept = "0";
  for (std::size_t k = 0; k < codestreams.size(); ++k) {
    f.frame_positions.push_back({0.0, 0.0, 2.0 * static_cast<double>(k)});
    const std::string& c = codestreams[k];
    std::size_t at = 0;
    for (int p = 0; p < pieces; ++p) {
      std::size_t end = p + 1 == pieces ? c.size()
                                        : (c.size() * static_cast<std::size_t>(p + 1)) /
                                              static_cast<std::size_t>(pieces);
      // A later piece must not look like the start of a frame.
      while (end + 1 < c.size() && static_cast<unsigned char>(c[end]) == 0xff) ++end;
      std::string piece = c.substr(at, end - at);
      if (piece.size() % 2 != 0 && p + 1 < pieces) piece += c[end++];  // items are even
      if (piece.size() % 2 != 0) piece += '\0';                        // DICOM pads the last one
      f.fragments.push_back(piece);
      at = end;
    }
  }
  return f;
}

std::string message_of(const fs::path& file) {
  try {
    (void)read_dicom(file);
  } catch (const error& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected progiso::error for " << file;
  return {};
}

TEST(DicomJpeg2000, decodes_every_depth_sign_wrapper_tiling_and_fragmenting_as_encoded) {
  const test::scratch_dir dir("progiso-dicom-j2k-test-");
  const std::vector<depth> depths{{8, 8, false}, {16, 12, false}, {16, 16, true}, {16, 12, true}};
  std::mt19937 rng(5);
  int files = 0;
  for (const depth& d : depths) {
    for (int variant = 0; variant < 4; ++variant) {
      constexpr int columns = 37;
      constexpr int rows = 29;
      test::jpeg2000_options o;
      o.precision = static_cast<unsigned>(d.bits_stored);
      o.is_signed = d.is_signed;
      o.jp2 = (variant & 1) != 0;
      o.tile = (variant & 2) != 0 ? 16 : 0;
      o.resolutions = (variant & 2) != 0 ? 3 : 5;
      std::vector<std::vector<std::int32_t>> samples;
      std::vector<std::string> codestreams;
      for (int k = 0; k < 3; ++k) {
        samples.push_back(random_frame(columns * rows, d, rng));
        codestreams.push_back(test::encode_jpeg2000(samples.back(), columns, rows, o));
        ASSERT_FALSE(codestreams.back().empty());
      }
      const int pieces = 1 + variant % 3;
      const test::dicom_slice_file f =
          enhanced(codestreams, columns, rows, d, pieces, j2k_lossless);
      const fs::path file = f.write(dir.path(), "j" + std::to_string(files++) + ".dcm");
      SCOPED_TRACE(file.string() + " variant " + std::to_string(variant));
      const volume v = read_volume(file, std::nullopt, std::nullopt);
      ASSERT_EQ(v.dims(), (index3{columns, rows, 3}));
      const sample_type want = d.bits_allocated == 8 ? sample_type::u8
                               : d.is_signed         ? sample_type::i16
                                                     : sample_type::u16;
      EXPECT_EQ(v.type(), want);
      for (std::size_t k = 0; k < 3; ++k) {
        for (std::size_t i = 0; i < samples[k].size(); ++i) {
          ASSERT_EQ(v.at(k * samples[k].size() + i), static_cast<double>(samples[k][i]))
              << "frame " << k << " sample " << i;
        }
      }
    }
  }
  EXPECT_EQ(files, 16);
}

TEST(DicomJpeg2000, a_classic_series_reads_as_its_uncompressed_self_and_lossy_frames_near_it) {
  // The same 6 CT slices (12 bits stored, rescaled to HU), uncompressed, lossless JPEG 2000 and
  // lossy JPEG 2000 at 8:1, one file per slice.
  const test::scratch_dir dir("progiso-dicom-j2k-test-");
  for (const char* sub : {"plain", "lossless", "lossy"}) fs::create_directory(dir.path() / sub);
  std::mt19937 rng(8);
  const depth d{16, 12, false};
  for (int k = 0; k < 6; ++k) {
    test::dicom_slice_file f = test::plain_slice(k, 32, 40, 16, 1.5);
    f.bits_stored = 12;
    f.pixel_representation = 0;
    f.slope = "1";
    f.intercept = "-1024";
    // A smooth ramp with noise, as a CT slice is: lossy coding stays near it.
    std::vector<std::int32_t> px(40 * 32);
    for (std::size_t i = 0; i < px.size(); ++i) {
      px[i] = static_cast<std::int32_t>(1000 + 20 * (i % 40) + 10 * (i / 40) + rng() % 16);
    }
    f.pixels.resize(px.size() * 2);
    for (std::size_t i = 0; i < px.size(); ++i) {
      const auto u = static_cast<std::uint16_t>(px[i]);
      std::memcpy(f.pixels.data() + 2 * i, &u, 2);
    }
    (void)f.write(dir.path() / "plain", "IM" + std::to_string(k));
    test::jpeg2000_options o;
    o.precision = 12;
    f.transfer_syntax = j2k_lossless;
    f.fragments = {test::encode_jpeg2000(px, 40, 32, o)};
    (void)f.write(dir.path() / "lossless", "IM" + std::to_string(k));
    o.lossless = false;
    o.ratio = 8.0f;
    f.transfer_syntax = j2k_lossy;
    f.fragments = {test::encode_jpeg2000(px, 40, 32, o)};
    if (f.fragments[0].size() % 2 != 0) f.fragments[0] += '\0';
    (void)f.write(dir.path() / "lossy", "IM" + std::to_string(k));
  }
  (void)d;
  const volume a = read_dicom(dir.path() / "plain");
  const volume b = read_dicom(dir.path() / "lossless");
  const volume c = read_dicom(dir.path() / "lossy");
  ASSERT_EQ(a.dims(), b.dims());
  ASSERT_EQ(a.type(), b.type());
  ASSERT_EQ(a.byte_size(), b.byte_size());
  EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.byte_size()), 0);
  ASSERT_EQ(a.dims(), c.dims());
  double worst = 0.0;
  for (std::size_t i = 0; i < a.voxel_count(); ++i)
    worst = std::max(worst, std::abs(a.at(i) - c.at(i)));
  EXPECT_GT(worst, 0.0);   // lossy
  EXPECT_LT(worst, 64.0);  // but near: the values span about 1900 HU
}

TEST(DicomJpeg2000,
     refuses_frames_that_disagree_with_the_header_with_one_line_naming_file_and_frame) {
  const test::scratch_dir dir("progiso-dicom-j2k-test-");
  std::mt19937 rng(9);
  const depth d{16, 12, false};
  const auto frame = [&](int columns, int rows, test::jpeg2000_options o) {
    return test::encode_jpeg2000(random_frame(static_cast<std::size_t>(columns * rows), d, rng),
                                 static_cast<std::uint32_t>(columns),
                                 static_cast<std::uint32_t>(rows), o);
  };
  test::jpeg2000_options good;
  good.precision = 12;
  int n = 0;
  const auto refused = [&](const test::dicom_slice_file& f, const std::string& what) {
    const fs::path file = f.write(dir.path(), "bad" + std::to_string(n++) + ".dcm");
    const std::string m = message_of(file);
    EXPECT_TRUE(contains(m, file.string())) << m;
    EXPECT_TRUE(contains(m, what)) << what << " / " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  };
  const std::string ok = frame(20, 10, good);
  // The second frame one column wider than the header says.
  refused(enhanced({ok, frame(21, 10, good)}, 20, 10, d, 1, j2k_lossless),
          "(frame 2): a JPEG 2000 frame of 21x10 samples");
  // Three components (a colour image).
  test::jpeg2000_options rgb = good;
  rgb.components = 3;
  refused(enhanced({frame(20, 10, rgb), ok}, 20, 10, d, 1, j2k_lossless),
          "(frame 1): a JPEG 2000 frame of 3 components, expected 1");
  // 16 bits of precision where 12 are stored; signed where the header says unsigned.
  test::jpeg2000_options wide = good;
  wide.precision = 16;
  refused(enhanced({ok, frame(20, 10, wide)}, 20, 10, d, 1, j2k_lossless),
          "16-bit unsigned samples, where the DICOM header says 12-bit unsigned");
  test::jpeg2000_options sign = good;
  sign.is_signed = true;
  refused(enhanced({frame(20, 10, sign), ok}, 20, 10, d, 1, j2k_lossless),
          "12-bit signed samples, where the DICOM header says 12-bit unsigned");
  // A codestream cut short (its last half gone).
  std::string cut = ok.substr(0, ok.size() / 2);
  if (cut.size() % 2 != 0) cut += '\0';
  refused(enhanced({ok, cut}, 20, 10, d, 1, j2k_lossless), "(frame 2): JPEG 2000 frame: ");
  // Two codestreams for three frames.
  test::dicom_slice_file three = enhanced({ok, ok}, 20, 10, d, 1, j2k_lossless);
  three.frame_positions.push_back({0.0, 0.0, 4.0});
  refused(three, "holds 2 frames, fewer than its NumberOfFrames");
  // High-Throughput JPEG 2000 is refused by name.
  test::dicom_slice_file ht = enhanced({ok, ok}, 20, 10, d, 1, "1.2.840.10008.1.2.4.201");
  refused(ht, "High-Throughput JPEG 2000");
  // 200 frames of 4000 x 4000 declared over 2 codestreams of 20 x 10: beyond 4096 times the
  // data, refused from the header.
  test::dicom_slice_file bomb = enhanced({ok, ok}, 4000, 4000, d, 1, j2k_lossless);
  bomb.frame_positions.clear();
  for (int k = 0; k < 200; ++k) bomb.frame_positions.push_back({0.0, 0.0, 1.0 * k});
  refused(bomb, "bytes of JPEG 2000 data, too few for 200 frames of 4000x4000");
}

}  // namespace
}  // namespace progiso
