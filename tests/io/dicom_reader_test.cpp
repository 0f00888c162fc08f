// Tests for progiso's own DICOM series reader (io/detail/dicom_reader.hpp, through
// read_dicom(), read_volume(), read_volume_world() and volume_input_files()).
//
// Differential: DCMTK (Debian's libdcmtk-dev, a test-only dependency) reads every slice file the
// tests write, and the volume must hold, slice for slice in the order of the positions along the
// normal, DCMTK's pixel values masked to BitsStored, sign-extended and rescaled by DCMTK's
// RescaleSlope and RescaleIntercept; the spacing, origin and patient map must follow DCMTK's
// PixelSpacing, ImagePositionPatient and ImageOrientationPatient. Files are written in the three
// uncompressed transfer syntaxes, with 8, 16 and 32 bits, signed and unsigned, with nested
// sequences of defined and undefined length to skip, oblique orientations and file names in
// another order than the slices.
//
// Hostile: several series, one slice, uneven and duplicate positions, tilted stacks, slices
// that differ, compressed syntaxes (lossy JPEG, JPEG 2000; RLE holding native pixel data),
// colour files, short pixel data, truncated files, sequences nested without end. Each fails with
// one line naming the file or directory.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::dicom_slice_file;
using progiso::test::plain_slice;
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-dicom-reader-test-") {}
};

struct series_spec {
  std::string syntax = progiso::test::dicom_explicit_le;
  int bits_allocated = 16;
  int bits_stored = 12;
  int pixel_representation = 1;
  std::string slope = "1";
  std::string intercept = "-1024";
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  int slices = 6;
  double step = 1.25;
};

/// Writes a series (file names in reverse order of the positions) and returns the files.
std::vector<fs::path> write_series(const fs::path& dir, const series_spec& spec, unsigned seed) {
  std::mt19937 rng(seed);
  const std::array<double, 6>& o = spec.orientation;
  const std::array<double, 3> normal{o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5],
                                     o[0] * o[4] - o[1] * o[3]};
  std::vector<fs::path> files;
  for (int k = 0; k < spec.slices; ++k) {
    dicom_slice_file f;
    f.transfer_syntax = spec.syntax;
    f.instance = k + 1;
    for (std::size_t i = 0; i < 3; ++i) {
      f.position[i] = (i == 0 ? -120.5 : i == 1 ? 33.0 : 7.0) + normal[i] * spec.step * k;
    }
    f.orientation = spec.orientation;
    f.bits_allocated = spec.bits_allocated;
    f.bits_stored = spec.bits_stored;
    f.pixel_representation = spec.pixel_representation;
    f.slope = spec.slope;
    f.intercept = spec.intercept;
    f.with_sequences = k % 2 == 0;
    const std::size_t bytes = static_cast<std::size_t>(f.rows * f.columns * f.bits_allocated / 8);
    f.pixels.resize(bytes);
    for (std::byte& b : f.pixels) b = static_cast<std::byte>(rng());  // high bits too: masked
    char name[32];
    std::snprintf(name, sizeof name, "IM%04d", spec.slices - k);
    files.push_back(f.write(dir, name));
  }
  return files;
}

/// What DCMTK reads in `file`: the slice's values masked, sign-extended and rescaled, and its
/// position.
struct dcmtk_slice {
  std::array<double, 3> position{};
  std::array<double, 6> orientation{};
  std::array<double, 2> spacing{};
  std::vector<double> values;
};
dcmtk_slice read_with_dcmtk(const fs::path& file) {
  DcmFileFormat ff;
  EXPECT_TRUE(ff.loadFile(file.c_str()).good()) << file;
  DcmDataset* d = ff.getDataset();
  dcmtk_slice s;
  for (unsigned long i = 0; i < 3; ++i)
    d->findAndGetFloat64(DCM_ImagePositionPatient, s.position[i], i);
  for (unsigned long i = 0; i < 6; ++i)
    d->findAndGetFloat64(DCM_ImageOrientationPatient, s.orientation[i], i);
  for (unsigned long i = 0; i < 2; ++i) d->findAndGetFloat64(DCM_PixelSpacing, s.spacing[i], i);
  Uint16 rows = 0, columns = 0, allocated = 0, stored = 0, representation = 0;
  d->findAndGetUint16(DCM_Rows, rows);
  d->findAndGetUint16(DCM_Columns, columns);
  d->findAndGetUint16(DCM_BitsAllocated, allocated);
  d->findAndGetUint16(DCM_BitsStored, stored);
  d->findAndGetUint16(DCM_PixelRepresentation, representation);
  Float64 slope = 1.0, intercept = 0.0;
  d->findAndGetFloat64(DCM_RescaleSlope, slope);
  d->findAndGetFloat64(DCM_RescaleIntercept, intercept);
  const std::size_t n = std::size_t{rows} * columns;
  std::vector<std::uint32_t> raw(n);
  if (allocated == 8) {
    const Uint8* p = nullptr;
    EXPECT_TRUE(d->findAndGetUint8Array(DCM_PixelData, p).good());
    for (std::size_t i = 0; i < n; ++i) raw[i] = p[i];
  } else if (allocated == 16) {
    const Uint16* p = nullptr;
    EXPECT_TRUE(d->findAndGetUint16Array(DCM_PixelData, p).good());
    for (std::size_t i = 0; i < n; ++i) raw[i] = p[i];
  } else {
    // 32-bit samples in OW: DCMTK gives 16-bit words in host order (little-endian files only).
    const Uint16* p = nullptr;
    EXPECT_TRUE(d->findAndGetUint16Array(DCM_PixelData, p).good());
    for (std::size_t i = 0; i < n; ++i) raw[i] = p[2 * i] | (std::uint32_t{p[2 * i + 1]} << 16);
  }
  const std::uint64_t mask = (std::uint64_t{1} << stored) - 1;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t v = raw[i] & mask;
    std::int64_t x = static_cast<std::int64_t>(v);
    if (representation == 1 && ((v >> (stored - 1)) & 1u) != 0) {
      x = static_cast<std::int64_t>(v) - static_cast<std::int64_t>(std::uint64_t{1} << stored);
    }
    s.values.push_back(
        slope == 1.0 && intercept == 0.0
            ? static_cast<double>(x)
            : static_cast<double>(static_cast<float>(slope * static_cast<double>(x) + intercept)));
  }
  return s;
}

using progiso::test::stored_sample;

/// The series in `dir` read by progiso equals DCMTK's slices ordered along the normal.
void expect_agreement(const fs::path& dir, const std::vector<fs::path>& files) {
  const progiso::volume v = progiso::read_dicom(dir);
  std::vector<dcmtk_slice> ref;
  for (const fs::path& f : files) ref.push_back(read_with_dcmtk(f));
  ASSERT_GE(ref.size(), 2u);
  const std::array<double, 6> o = ref.front().orientation;
  std::array<double, 3> normal{o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5],
                               o[0] * o[4] - o[1] * o[3]};
  const double len =
      std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
  for (double& x : normal) x /= len;
  const auto along = [&](const dcmtk_slice& s) {
    return s.position[0] * normal[0] + s.position[1] * normal[1] + s.position[2] * normal[2];
  };
  std::sort(ref.begin(), ref.end(),
            [&](const dcmtk_slice& a, const dcmtk_slice& b) { return along(a) < along(b); });
  ASSERT_EQ(v.dims(), (progiso::index3{5, 4, static_cast<std::int64_t>(ref.size())}));
  const std::size_t frame = 20;
  for (std::size_t k = 0; k < ref.size(); ++k) {
    for (std::size_t i = 0; i < frame; ++i) {
      ASSERT_EQ(stored_sample(v, k * frame + i), ref[k].values[i])
          << "slice " << k << " sample " << i;
    }
  }
  const double step =
      (along(ref.back()) - along(ref.front())) / static_cast<double>(ref.size() - 1);
  EXPECT_NEAR(v.spacing()[0], ref[0].spacing[1], 1e-12);
  EXPECT_NEAR(v.spacing()[1], ref[0].spacing[0], 1e-12);
  EXPECT_NEAR(v.spacing()[2], step, 1e-6);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(v.origin()[i], ref[0].position[i]);
  // The map: index (i, j, k) → first position + i · row dir · column spacing + j · column dir ·
  // row spacing + k · normal · step; it puts every slice's first pixel on its position.
  const auto world = progiso::read_volume_world(dir, std::nullopt);
  ASSERT_TRUE(world.has_value());
  for (std::size_t k = 0; k < ref.size(); ++k) {
    const std::array<double, 3> p = world->apply({0.0, 0.0, static_cast<double>(k)});
    // Within the rounding of the positions' decimal strings (6 digits here).
    for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(p[i], ref[k].position[i], 1e-3);
    const std::array<double, 3> q = world->apply({1.0, 0.0, static_cast<double>(k)});
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_NEAR(q[i] - p[i], o[i] * ref[0].spacing[1], 1e-9);
    }
  }
}

TEST(DicomReader, agrees_with_dcmtk_on_every_transfer_syntax_bit_depth_and_rescale) {
  unsigned seed = 1;
  for (const char* syntax : {progiso::test::dicom_implicit_le, progiso::test::dicom_explicit_le,
                             progiso::test::dicom_explicit_be}) {
    struct depth {
      int allocated, stored, representation;
    };
    for (const depth b : {depth{8, 8, 0}, depth{8, 7, 1}, depth{16, 12, 1}, depth{16, 16, 0},
                          depth{16, 10, 0}, depth{32, 32, 1}, depth{32, 20, 0}}) {
      if (b.allocated == 32 && std::string(syntax) == progiso::test::dicom_explicit_be) continue;
      for (const bool rescaled : {false, true}) {
        scratch_dir dir;
        series_spec spec;
        spec.syntax = syntax;
        spec.bits_allocated = b.allocated;
        spec.bits_stored = b.stored;
        spec.pixel_representation = b.representation;
        spec.slope = rescaled ? "0.5" : "1";
        spec.intercept = rescaled ? "-1024" : "0";
        SCOPED_TRACE(std::string(syntax) + " " + std::to_string(b.allocated) + "/" +
                     std::to_string(b.stored) + (rescaled ? " rescaled" : ""));
        expect_agreement(dir.path(), write_series(dir.path(), spec, seed++));
        const progiso::volume v = progiso::read_dicom(dir.path());
        EXPECT_EQ(v.type() == sample_type::f32, rescaled);
      }
    }
  }
}

TEST(DicomReader, orders_oblique_slices_along_their_normal_and_maps_them_to_patient_space) {
  scratch_dir dir;
  series_spec spec;
  const double c = std::cos(0.3);
  const double s = std::sin(0.3);
  spec.orientation = {c, s, 0.0, 0.0, 0.0, -1.0};  // a rotated coronal stack
  spec.step = 2.5;
  spec.slices = 9;
  const std::vector<fs::path> files = write_series(dir.path(), spec, 77);
  expect_agreement(dir.path(), files);
  // Non-DICOM files and DICOM files without pixel data are skipped.
  progiso::test::write_file(dir / "README.txt", "not a DICOM file");
  dicom_slice_file no_pixels;
  no_pixels.pixels.resize(40);
  std::string bytes = no_pixels.bytes();
  bytes.resize(bytes.find(std::string("\xe0\x7f\x10\x00", 4)));  // up to the pixel data
  progiso::test::write_file(dir / "DICOMDIR", bytes);
  const progiso::volume v = progiso::read_dicom(dir.path());
  EXPECT_EQ(v.dims()[2], 9);
  const std::vector<fs::path> inputs = progiso::volume_input_files(dir.path(), std::nullopt);
  ASSERT_EQ(inputs.size(), 10u);
  EXPECT_EQ(inputs[0], dir.path());
  // The inputs come in slice order: IM0009 holds the first position.
  EXPECT_EQ(inputs[1].filename(), "IM0009");
  EXPECT_EQ(
      progiso::read_volume(dir.path(), std::nullopt, std::array<double, 3>{1, 2, 3}).spacing(),
      (std::array<double, 3>{1.0, 2.0, 3.0}));
}

TEST(DicomReader, refuses_series_it_cannot_place_with_one_line_naming_the_file) {
  const auto expect_error = [](const fs::path& named, const fs::path& dir,
                               const std::string& what) {
    const std::string message = error_naming(named, [&] { (void)progiso::read_dicom(dir); });
    EXPECT_TRUE(contains(message, what)) << message;
  };
  {
    scratch_dir dir;
    expect_error(dir.path(), dir.path(), "holds no DICOM image");
  }
  {
    scratch_dir dir;
    series_spec spec;
    spec.slices = 1;
    const auto files = write_series(dir.path(), spec, 3);
    expect_error(files[0], dir.path(), "a 2-D image");
  }
  {
    scratch_dir dir;
    write_series(dir.path(), series_spec{}, 4);
    dicom_slice_file other;
    other.series_uid = "1.2.3.4";
    other.pixels.resize(40);
    other.write(dir.path(), "OTHER");
    expect_error(dir.path(), dir.path(), "holds 2 DICOM series");
  }
  {
    scratch_dir dir;
    const auto files = write_series(dir.path(), series_spec{}, 5);
    fs::remove(files[2]);  // a missing slice: a gap twice the step
    expect_error(files[1], dir.path(), "expected evenly spaced slices");
  }
  {
    scratch_dir dir;
    const auto files = write_series(dir.path(), series_spec{}, 6);
    fs::copy_file(files[1], dir / "COPY");  // a duplicated slice
    expect_error(dir / "COPY", dir.path(), "evenly spaced");
  }
  const auto one_bad = [&](const std::string& stem, auto&& change, const std::string& what) {
    scratch_dir dir;
    write_series(dir.path(), series_spec{}, 7);
    dicom_slice_file f;
    f.position = {-120.5, 33.0, 7.0 + 6 * 1.25};
    f.instance = 7;
    f.pixels.resize(40);
    change(f);
    const fs::path file = f.write(dir.path(), stem);
    expect_error(file, dir.path(), what);
  };
  one_bad(
      "tilt", [](dicom_slice_file& f) { f.position[0] += 2.0; }, "tilted gantry");
  one_bad(
      "rows",
      [](dicom_slice_file& f) {
        f.rows = 5;
        f.pixels.resize(50);
      },
      "differs from");
  one_bad(
      "jpeg", [](dicom_slice_file& f) { f.transfer_syntax = "1.2.840.10008.1.2.4.50"; }, "(JPEG)");
  one_bad(
      "htj2k", [](dicom_slice_file& f) { f.transfer_syntax = "1.2.840.10008.1.2.4.201"; },
      "High-Throughput JPEG 2000");
  one_bad(
      "jpegls", [](dicom_slice_file& f) { f.transfer_syntax = "1.2.840.10008.1.2.4.80"; },
      "JPEG-LS");
  one_bad(
      "j2k", [](dicom_slice_file& f) { f.transfer_syntax = "1.2.840.10008.1.2.4.90"; },
      "native pixel data in a compressed transfer syntax");
  one_bad(
      "rle", [](dicom_slice_file& f) { f.transfer_syntax = "1.2.840.10008.1.2.5"; },
      "native pixel data in a compressed transfer syntax");
  one_bad(
      "rgb",
      [](dicom_slice_file& f) {
        f.samples = 3;
        f.photometric = "RGB";
      },
      "3 samples per pixel");
  one_bad(
      "short", [](dicom_slice_file& f) { f.pixels.resize(30); }, "holds 30 bytes of pixel data");
  one_bad(
      "bits", [](dicom_slice_file& f) { f.bits_stored = 17; }, "stores 17 bits in 16");
  one_bad(
      "orient", [](dicom_slice_file& f) { f.orientation = {0, 1, 0, 1, 0, 0}; },
      "another ImageOrientationPatient");
  one_bad(
      "slope", [](dicom_slice_file& f) { f.slope = "0"; }, "RescaleSlope 0");
  one_bad(
      "ds", [](dicom_slice_file& f) { f.intercept = "abc"; }, "expected 1 finite number");
}

TEST(DicomReader, refuses_truncated_and_malformed_files_without_reading_past_them) {
  const auto expect_error = [](const fs::path& file, const std::string& bytes,
                               const std::string& what) {
    scratch_dir dir;
    const fs::path f = dir / file.filename();
    progiso::test::write_file(f, bytes);
    const std::string message = error_naming(f, [&] { (void)progiso::read_dicom(dir.path()); });
    EXPECT_TRUE(contains(message, what)) << message;
  };
  dicom_slice_file f;
  f.pixels.resize(40);
  const std::string whole = f.bytes();
  // Cut inside the header and inside an element.
  expect_error("cut", whole.substr(0, 300), "DICOM file");
  // An element length past the end of the file.
  std::string past = whole;
  const std::size_t at = past.find("CT");  // the Modality value; its length field before it
  ASSERT_NE(at, std::string::npos);
  past[at - 2] = '\xff';
  past[at - 1] = '\x7f';
  expect_error("past", past, "past its end");
  // Sequences nested without end.
  std::string deep = whole.substr(0, whole.find(std::string("\x08\x00\x16\x00", 4)));
  for (int i = 0; i < 40; ++i) {
    deep +=
        std::string("\x08\x00\x40\x11", 4) + "SQ" + std::string(2, '\0') + std::string(4, '\xff');
    deep += std::string("\xfe\xff\x00\xe0", 4) + std::string(4, '\xff');
  }
  expect_error("deep", deep, "nests sequences more than 16 deep");
  // An item tag where an element belongs.
  std::string item = whole;
  const std::size_t modality = item.find(std::string("\x08\x00\x60\x00", 4));
  ASSERT_NE(modality, std::string::npos);
  item[modality] = '\xfe';
  item[modality + 1] = '\xff';
  expect_error("item", item, "outside a sequence");
  // No transfer syntax in the file meta.
  std::string no_ts = whole;
  const std::size_t ts = no_ts.find("1.2.840.10008.1.2.1");
  ASSERT_NE(ts, std::string::npos);
  no_ts[ts - 8 + 2] = '\x11';  // (0002,0010) becomes (0002,0011)
  expect_error("nots", no_ts, "has no transfer syntax");
}

TEST(DicomReader, picks_one_of_several_series_by_number_or_uid) {
  scratch_dir dir;
  series_spec a;
  a.slices = 4;
  write_series(dir.path(), a, 11);  // series "1.2.826.0.1.3680043.2.1125.1", 4 slices
  // A second series of 3 slices, 8-bit, another UID ordered after the first.
  for (int k = 0; k < 3; ++k) {
    dicom_slice_file f = plain_slice(k, 4, 5, 8, 2.0);
    f.series_uid = "1.2.826.0.1.3680043.2.1125.2";
    f.pixels.assign(20, static_cast<std::byte>(k));
    f.write(dir.path(), "B" + std::to_string(k));
  }
  const std::string message =
      error_naming(dir.path(), [&] { (void)progiso::read_dicom(dir.path()); });
  EXPECT_TRUE(contains(message,
                       "holds 2 DICOM series (1: \"1.2.826.0.1.3680043.2.1125.1\" (4 "
                       "images), 2: \"1.2.826.0.1.3680043.2.1125.2\" (3 images))"))
      << message;
  const progiso::volume first = progiso::read_dicom(dir.path(), {"1"});
  EXPECT_EQ(first.dims()[2], 4);
  EXPECT_EQ(first.type(), sample_type::f32);
  for (const char* choice : {"2", "1.2.826.0.1.3680043.2.1125.2"}) {
    const progiso::volume second = progiso::read_dicom(dir.path(), {choice});
    EXPECT_EQ(second.dims()[2], 3) << choice;
    EXPECT_EQ(second.type(), sample_type::u8) << choice;
    EXPECT_EQ(second.spacing()[2], 2.0) << choice;
    EXPECT_EQ(stored_sample(second, 2 * 20), 2.0) << choice;  // the third slice's pixels
    EXPECT_EQ(progiso::volume_input_files(dir.path(), std::nullopt, {choice}).size(), 4u);
  }
  const std::string unknown =
      error_naming(dir.path(), [&] { (void)progiso::read_dicom(dir.path(), {"3"}); });
  EXPECT_TRUE(contains(unknown, "holds no DICOM series \"3\"")) << unknown;
  // A series chosen for another input is refused.
  const fs::path raw = dir / "v.nrrd";
  const std::string other = error_naming(
      raw, [&] { (void)progiso::read_volume(raw, std::nullopt, std::nullopt, {"1"}); });
  EXPECT_TRUE(contains(other, "not a DICOM directory")) << other;
}

TEST(DicomReader, a_single_dcm_file_is_refused_as_one_slice) {
  scratch_dir dir;
  dicom_slice_file f;
  f.pixels.resize(40);
  const fs::path file = f.write(dir.path(), "slice.dcm");
  const std::string message =
      error_naming(file, [&] { (void)progiso::read_volume(file, std::nullopt, std::nullopt); });
  EXPECT_TRUE(contains(message, "give the directory of its series")) << message;
}

}  // namespace
