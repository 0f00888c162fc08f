// Multi-frame DICOM images: enhanced images — Enhanced CT and MR, what current scanners export:
// one file holds every frame, each placed by its functional groups
// (PerFrameFunctionalGroupsSequence, SharedFunctionalGroupsSequence) — and RT dose grids, whose
// frames GridFrameOffsetVector places and DoseGridScaling scales to dose (isodose surfaces).
// Read through read_dicom(), read_volume(), read_volume_world() and volume_input_files(), from
// the file alone or from its directory.
//
// Differential: the files are written by DCMTK's dcmdata (Debian's libdcmtk-dev, a test-only
// dependency), an encoder independent of progiso's parser, in the three uncompressed transfer
// syntaxes with sequences and items of explicit and of undefined length; the volume must hold
// the frames the test made, ordered along the normal, masked, sign-extended and rescaled by the
// shared or per-frame Pixel Value Transformation.
//
// Lossless JPEG (the compression of most archives' CT and MR): files DCMTK's dcmjpeg encodes, with
// every predictor, 8, 12 and 16 bits, one fragment per frame or many, decode to the samples given.
//
// Hostile: multi-frame files that do not place their frames, frame counts that disagree, two
// frames at one position, short pixel data, bad NumberOfFrames, frames without a position, JPEG
// streams of another process, size or table than they should. Each fails with one line naming
// the file and the frame.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcrledec.h>
#include <dcmtk/dcmdata/dcrleerg.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmjpeg/djencode.h>
#include <dcmtk/dcmjpeg/djrplol.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/io/detail/dicom_rle.hpp>

#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::test::contains;

std::string decimals(const double* v, int n) {
  std::string s;
  for (int i = 0; i < n; ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", v[i]);
    if (i > 0) s += '\\';
    s += buf;
  }
  return s;
}

/// An enhanced image as the test makes it: frames in file order, each with its place along the
/// stack (`slot`) and its stored values.
struct enhanced_image {
  E_TransferSyntax syntax = EXS_LittleEndianExplicit;  // EXS_JPEGProcess14(SV1): compressed
  int predictor = 1;                                   // of the lossless JPEG
  int point_transform = 0;
  E_EncodingType lengths = EET_UndefinedLength;
  int bits_allocated = 16;
  int bits_stored = 12;
  bool is_signed = true;
  enum class rescale { none, shared, per_frame } scaling = rescale::shared;
  int rows = 4;
  int columns = 5;
  int frames = 7;
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  std::array<double, 3> first{-120.5, 33.0, 7.0};
  std::array<double, 2> pixel_spacing{0.75, 0.5};  // row spacing, column spacing
  double step = 0.8;
  std::string series_uid = "1.2.826.0.1.3680043.2.1125.7";
  std::vector<int> slot;                     // frame f lies at first + slot[f] · step · normal
  std::vector<std::uint32_t> values;         // frames × rows × columns raw words
  bool per_frame_groups = true;              // write PerFrameFunctionalGroupsSequence
  int per_frame_items = -1;                  // items written (−1: one per frame)
  std::string number_of_frames;              // written instead of `frames` when set
  std::size_t pixel_bytes_cut = 0;           // bytes left off the pixel data
  int frame_without_position = -1;           // a frame whose groups lack Plane Position
  std::function<int(int)> position_of_slot;  // a slot's place, when not the slot itself
  std::vector<Uint32> temporal;              // each frame's TemporalPositionIndex, when not empty

  [[nodiscard]] std::array<double, 3> normal() const {
    const auto& o = orientation;
    return {o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5], o[0] * o[4] - o[1] * o[3]};
  }
  [[nodiscard]] std::array<double, 3> position(int f) const {
    const int place = position_of_slot ? position_of_slot(slot[static_cast<std::size_t>(f)])
                                       : slot[static_cast<std::size_t>(f)];
    const std::array<double, 3> n = normal();
    return {first[0] + n[0] * step * place, first[1] + n[1] * step * place,
            first[2] + n[2] * step * place};
  }
  [[nodiscard]] double slope(int f) const {
    return scaling == rescale::per_frame ? 0.5 + 0.25 * f : scaling == rescale::shared ? 2.0 : 1.0;
  }
  [[nodiscard]] double intercept(int f) const {
    return scaling == rescale::per_frame ? -100.0 + 3.0 * f
           : scaling == rescale::shared  ? -1024.0
                                         : 0.0;
  }

  /// Random values (bits above BitsStored set too: they must be masked) and shuffled slots.
  void fill(unsigned seed) {
    std::mt19937 rng(seed);
    slot.resize(static_cast<std::size_t>(frames));
    std::iota(slot.begin(), slot.end(), 0);
    std::shuffle(slot.begin(), slot.end(), rng);
    values.resize(static_cast<std::size_t>(frames * rows * columns));
    const std::uint32_t mask =
        bits_allocated == 32 ? ~std::uint32_t{0} : (std::uint32_t{1} << bits_allocated) - 1;
    for (std::uint32_t& v : values) v = static_cast<std::uint32_t>(rng()) & mask;
  }

  /// The value progiso must give for raw word `raw` of frame f.
  [[nodiscard]] double expected(std::uint32_t raw, int f) const {
    const std::uint64_t mask = (std::uint64_t{1} << bits_stored) - 1;
    const std::uint64_t v = raw & mask;
    std::int64_t x = static_cast<std::int64_t>(v);
    if (is_signed && ((v >> (bits_stored - 1)) & 1u) != 0) {
      x -= static_cast<std::int64_t>(std::uint64_t{1} << bits_stored);
    }
    if (scaling == rescale::none) return static_cast<double>(x);
    return static_cast<double>(
        static_cast<float>(slope(f) * static_cast<double>(x) + intercept(f)));
  }

  /// Writes the file with DCMTK.
  fs::path write(const fs::path& file) const {
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    const auto ok = [&](OFCondition c) { EXPECT_TRUE(c.good()) << c.text(); };
    ok(d->putAndInsertString(DCM_SOPClassUID, UID_EnhancedCTImageStorage));
    ok(d->putAndInsertString(DCM_SOPInstanceUID, (series_uid + ".1").c_str()));
    ok(d->putAndInsertString(DCM_Modality, "CT"));
    ok(d->putAndInsertString(DCM_SeriesInstanceUID, series_uid.c_str()));
    ok(d->putAndInsertUint16(DCM_SamplesPerPixel, 1));
    ok(d->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2"));
    ok(d->putAndInsertString(DCM_NumberOfFrames, number_of_frames.empty()
                                                     ? std::to_string(frames).c_str()
                                                     : number_of_frames.c_str()));
    ok(d->putAndInsertUint16(DCM_Rows, static_cast<Uint16>(rows)));
    ok(d->putAndInsertUint16(DCM_Columns, static_cast<Uint16>(columns)));
    ok(d->putAndInsertUint16(DCM_BitsAllocated, static_cast<Uint16>(bits_allocated)));
    ok(d->putAndInsertUint16(DCM_BitsStored, static_cast<Uint16>(bits_stored)));
    ok(d->putAndInsertUint16(DCM_HighBit, static_cast<Uint16>(bits_stored - 1)));
    ok(d->putAndInsertUint16(DCM_PixelRepresentation, is_signed ? 1 : 0));
    // Shared groups: pixel measures, orientation, and the rescale when it is shared.
    DcmItem* shared = nullptr;
    ok(d->findOrCreateSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0));
    DcmItem* g = nullptr;
    ok(shared->findOrCreateSequenceItem(DCM_PixelMeasuresSequence, g, 0));
    ok(g->putAndInsertString(DCM_PixelSpacing, decimals(pixel_spacing.data(), 2).c_str()));
    ok(g->putAndInsertString(DCM_SliceThickness, "0.8"));
    ok(shared->findOrCreateSequenceItem(DCM_PlaneOrientationSequence, g, 0));
    ok(g->putAndInsertString(DCM_ImageOrientationPatient, decimals(orientation.data(), 6).c_str()));
    if (scaling == rescale::shared) {
      ok(shared->findOrCreateSequenceItem(DCM_PixelValueTransformationSequence, g, 0));
      ok(g->putAndInsertString(DCM_RescaleIntercept, "-1024"));
      ok(g->putAndInsertString(DCM_RescaleSlope, "2"));
      ok(g->putAndInsertString(DCM_RescaleType, "HU"));
    }
    // Per frame: a Frame Content group (skipped), the position, and the rescale per frame.
    const int items = per_frame_items >= 0 ? per_frame_items : frames;
    for (int item_index = 0; per_frame_groups && item_index < items; ++item_index) {
      const int f = item_index % frames;  // an item past the frames repeats an earlier one
      DcmItem* item = nullptr;
      ok(d->findOrCreateSequenceItem(DCM_PerFrameFunctionalGroupsSequence, item, -2));
      ok(item->findOrCreateSequenceItem(DCM_FrameContentSequence, g, 0));
      ok(g->putAndInsertUint32(DCM_InStackPositionNumber,
                               static_cast<Uint32>(slot[static_cast<std::size_t>(f)] + 1)));
      ok(g->putAndInsertString(DCM_StackID, "1"));
      if (!temporal.empty()) {
        ok(g->putAndInsertUint32(DCM_TemporalPositionIndex, temporal[static_cast<std::size_t>(f)]));
      }
      if (f != frame_without_position) {
        ok(item->findOrCreateSequenceItem(DCM_PlanePositionSequence, g, 0));
        const std::array<double, 3> p = position(f);
        ok(g->putAndInsertString(DCM_ImagePositionPatient, decimals(p.data(), 3).c_str()));
      }
      if (scaling == rescale::per_frame) {
        ok(item->findOrCreateSequenceItem(DCM_PixelValueTransformationSequence, g, 0));
        const double b = intercept(f);
        const double m = slope(f);
        ok(g->putAndInsertString(DCM_RescaleIntercept, decimals(&b, 1).c_str()));
        ok(g->putAndInsertString(DCM_RescaleSlope, decimals(&m, 1).c_str()));
      }
    }
    // Pixel data: OB for 8 bits, OW for 16.
    if (bits_allocated == 8) {
      std::vector<Uint8> px(values.begin(), values.end());
      px.resize(px.size() - pixel_bytes_cut);
      ok(d->putAndInsertUint8Array(DCM_PixelData, px.data(),
                                   static_cast<unsigned long>(px.size())));
    } else {
      std::vector<Uint16> px(values.begin(), values.end());
      px.resize(px.size() - pixel_bytes_cut / 2);
      ok(d->putAndInsertUint16Array(DCM_PixelData, px.data(),
                                    static_cast<unsigned long>(px.size())));
    }
    if (syntax == EXS_JPEGProcess14 || syntax == EXS_JPEGProcess14SV1) {
      const DJ_RPLossless lossless(predictor, point_transform);
      ok(d->chooseRepresentation(syntax, &lossless));
      EXPECT_TRUE(d->canWriteXfer(syntax));
    } else if (syntax == EXS_RLELossless) {
      ok(d->chooseRepresentation(syntax, nullptr));
      EXPECT_TRUE(d->canWriteXfer(syntax));
    }
    ok(ff.saveFile(file.c_str(), syntax, lengths));
    return file;
  }
};

using progiso::test::stored_sample;

/// `input` (the file or its directory) read by progiso holds `img`'s frames in slot order.
void expect_frames(const fs::path& input, const enhanced_image& img) {
  const progiso::volume v = progiso::read_volume(input, std::nullopt, std::nullopt);
  ASSERT_EQ(v.dims(), (progiso::index3{img.columns, img.rows, img.frames}));
  const bool scaled = img.scaling != enhanced_image::rescale::none;
  EXPECT_EQ(v.type(), scaled ? sample_type::f32
                      : img.bits_allocated == 8
                          ? (img.is_signed ? sample_type::i8 : sample_type::u8)
                          : (img.is_signed ? sample_type::i16 : sample_type::u16));
  const auto frame = static_cast<std::size_t>(img.rows * img.columns);
  for (int f = 0; f < img.frames; ++f) {
    const auto at = static_cast<std::size_t>(img.slot[static_cast<std::size_t>(f)]) * frame;
    for (std::size_t i = 0; i < frame; ++i) {
      ASSERT_EQ(stored_sample(v, at + i),
                img.expected(img.values[static_cast<std::size_t>(f) * frame + i], f))
          << "frame " << f << " sample " << i;
    }
  }
  EXPECT_NEAR(v.spacing()[0], img.pixel_spacing[1], 1e-12);
  EXPECT_NEAR(v.spacing()[1], img.pixel_spacing[0], 1e-12);
  EXPECT_NEAR(v.spacing()[2], img.step, 1e-6);
  const int lowest =
      static_cast<int>(std::find(img.slot.begin(), img.slot.end(), 0) - img.slot.begin());
  const std::array<double, 3> origin = img.position(lowest);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(v.origin()[i], origin[i], 1e-9);
  // The patient map puts every frame's first pixel on its position.
  const auto world = progiso::read_volume_world(input, std::nullopt);
  ASSERT_TRUE(world.has_value());
  for (int f = 0; f < img.frames; ++f) {
    const std::array<double, 3> p =
        world->apply({0.0, 0.0, static_cast<double>(img.slot[static_cast<std::size_t>(f)])});
    const std::array<double, 3> want = img.position(f);
    for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(p[i], want[i], 1e-6);
  }
}

std::string message_of(const fs::path& input) {
  try {
    (void)progiso::read_volume(input, std::nullopt, std::nullopt);
  } catch (const progiso::error& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    return m;
  }
  return "no error";
}

TEST(DicomEnhanced, reads_every_frame_dcmtk_writes_in_every_syntax_length_encoding_and_rescale) {
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  unsigned seed = 1;
  int files = 0;
  for (const E_TransferSyntax syntax :
       {EXS_LittleEndianImplicit, EXS_LittleEndianExplicit, EXS_BigEndianExplicit}) {
    for (const E_EncodingType lengths : {EET_UndefinedLength, EET_ExplicitLength}) {
      struct depth {
        int allocated, stored;
        bool is_signed;
      };
      for (const depth b :
           {depth{8, 8, false}, depth{8, 6, true}, depth{16, 12, true}, depth{16, 16, false}}) {
        for (const auto scaling : {enhanced_image::rescale::none, enhanced_image::rescale::shared,
                                   enhanced_image::rescale::per_frame}) {
          enhanced_image img;
          img.syntax = syntax;
          img.lengths = lengths;
          img.bits_allocated = b.allocated;
          img.bits_stored = b.stored;
          img.is_signed = b.is_signed;
          img.scaling = scaling;
          img.fill(seed++);
          const fs::path sub = dir.path() / ("s" + std::to_string(files++));
          fs::create_directory(sub);
          const fs::path file = img.write(sub / "enhanced.dcm");
          SCOPED_TRACE(file.string());
          expect_frames(file, img);
          expect_frames(sub, img);  // its directory: the same volume
          // One file for every frame: listed once.
          EXPECT_EQ(progiso::volume_input_files(file, std::nullopt), (std::vector<fs::path>{file}));
          EXPECT_EQ(progiso::volume_input_files(sub, std::nullopt),
                    (std::vector<fs::path>{sub, file}));
        }
      }
    }
  }
  EXPECT_EQ(files, 72);
}

TEST(DicomEnhanced, an_oblique_stack_and_a_file_without_extension_are_read_and_placed) {
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  enhanced_image img;
  const double c = std::cos(0.4);
  const double s = std::sin(0.4);
  img.orientation = {c, 0.0, s, 0.0, 1.0, 0.0};  // rotated about y
  img.frames = 11;
  img.step = 2.5;
  img.fill(99);
  // Scanners and archives name files by number or UID, without an extension.
  const fs::path file = img.write(dir.path() / "1.2.826.0.1.3680043.2.1125.7.1");
  expect_frames(file, img);
}

TEST(DicomEnhanced, frames_split_over_two_files_of_one_series_make_one_volume) {
  // A concatenation: one series' frames in two files, each placing its own; beside them a
  // classic single-frame series, picked by number against the enhanced one.
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  enhanced_image all;
  all.frames = 10;
  all.fill(5);
  enhanced_image low = all;
  enhanced_image high = all;
  low.frames = 4;
  high.frames = 6;
  const auto frame = static_cast<std::size_t>(all.rows * all.columns);
  // low holds the frames that lie in slots 0-3, high the others, each in `all`'s order.
  low.slot.clear();
  low.values.clear();
  high.slot.clear();
  high.values.clear();
  for (int f = 0; f < all.frames; ++f) {
    enhanced_image& part = all.slot[static_cast<std::size_t>(f)] < 4 ? low : high;
    part.slot.push_back(all.slot[static_cast<std::size_t>(f)]);
    const auto from =
        all.values.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(f) * frame);
    part.values.insert(part.values.end(), from, from + static_cast<std::ptrdiff_t>(frame));
  }
  const fs::path a = high.write(dir.path() / "A.dcm");
  const fs::path b = low.write(dir.path() / "B.dcm");
  const progiso::volume v = progiso::read_volume(dir.path(), std::nullopt, std::nullopt);
  ASSERT_EQ(v.dims(), (progiso::index3{5, 4, 10}));
  for (const enhanced_image* part : {&low, &high}) {
    for (std::size_t f = 0; f < part->slot.size(); ++f) {
      const auto at = static_cast<std::size_t>(part->slot[f]) * frame;
      for (std::size_t i = 0; i < frame; ++i) {
        // The rescale is shared: the same for every frame.
        ASSERT_EQ(stored_sample(v, at + i), part->expected(part->values[f * frame + i], 0));
      }
    }
  }
  // Files in slice order, each once: B holds the lowest slot.
  EXPECT_EQ(progiso::volume_input_files(dir.path(), std::nullopt),
            (std::vector<fs::path>{dir.path(), b, a}));
  // A classic series beside it: the directory lists both by frames, and --series picks either.
  for (int k = 0; k < 3; ++k) {
    progiso::test::dicom_slice_file f = progiso::test::plain_slice(k, 4, 5, 8, 1.0);
    f.series_uid = "1.2.826.0.1.3680043.2.1125.9";
    f.pixels.assign(20, static_cast<std::byte>(k));
    f.write(dir.path(), "C" + std::to_string(k));
  }
  const std::string listing = message_of(dir.path());
  EXPECT_TRUE(contains(listing,
                       "1: \"1.2.826.0.1.3680043.2.1125.7\" (10 images), 2: "
                       "\"1.2.826.0.1.3680043.2.1125.9\" (3 images)"))
      << listing;
  EXPECT_EQ(progiso::read_dicom(dir.path(), {std::string("1"), std::nullopt}).dims()[2], 10);
  EXPECT_EQ(progiso::read_dicom(dir.path(), {std::string("2"), std::nullopt}).dims()[2], 3);
}

TEST(DicomEnhanced, refuses_frames_it_cannot_place_with_one_line_naming_file_and_frame) {
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  int n = 0;
  const auto refused = [&](const std::function<void(enhanced_image&)>& change,
                           const std::string& what) {
    enhanced_image img;
    img.fill(static_cast<unsigned>(100 + n));
    change(img);
    const fs::path file = img.write(dir.path() / ("bad" + std::to_string(n++) + ".dcm"));
    const std::string m = message_of(file);
    EXPECT_TRUE(contains(m, file.string() + ": ") || contains(m, file.string() + " (frame")) << m;
    EXPECT_TRUE(contains(m, what)) << m;
  };
  // A legacy multi-frame file: nothing places its frames.
  refused([](enhanced_image& i) { i.per_frame_groups = false; },
          "a multi-frame image of 7 frames with 0 items in PerFrameFunctionalGroupsSequence");
  refused([](enhanced_image& i) { i.per_frame_items = 6; }, "7 frames with 6 items");
  refused([](enhanced_image& i) { i.per_frame_items = 8; }, "7 frames with 8 items");
  // Two stacks (or two times) at the same positions.
  refused([](enhanced_image& i) { i.position_of_slot = [](int s) { return s / 2; }; },
          "evenly spaced");
  refused([](enhanced_image& i) { i.frame_without_position = 3; },
          "(frame 4): has no ImagePositionPatient");
  refused([](enhanced_image& i) { i.pixel_bytes_cut = 2; },
          "bytes of pixel data, expected 280 (7 frames of 5x4 of 16 bits)");
  refused([](enhanced_image& i) { i.number_of_frames = "0"; }, "has NumberOfFrames (0028,0008)");
  refused([](enhanced_image& i) { i.number_of_frames = "32770"; }, "expected 1 to 32769");
  refused([](enhanced_image& i) { i.number_of_frames = "2.5"; }, "\"2.5\"");
  // One frame alone is one slice.
  refused(
      [](enhanced_image& i) {
        i.frames = 1;
        i.slot = {0};
        i.values.resize(20);
      },
      "one DICOM file is one slice");
  // A .dcm file that is not DICOM.
  progiso::test::write_file(dir.path() / "text.dcm", std::string(200, 'x'));
  EXPECT_TRUE(contains(message_of(dir.path() / "text.dcm"), "not a DICOM Part 10 file"));
  EXPECT_EQ(n, 10);
}

TEST(DicomEnhanced, a_series_of_time_points_reads_the_volume_chosen_by_its_temporal_index) {
  // A 4-D file (a cine MR, a 4-D CT): 5 positions × 3 time points, frames shuffled, each
  // frame's Frame Content giving its TemporalPositionIndex (1-based). Volume K holds, at each
  // position, the frame of time point K + 1.
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  enhanced_image img;
  img.frames = 15;
  img.fill(21);
  std::vector<int> place(15);
  for (int f = 0; f < 15; ++f) {
    place[static_cast<std::size_t>(f)] = img.slot[static_cast<std::size_t>(f)] % 5;
    img.temporal.push_back(static_cast<Uint32>(img.slot[static_cast<std::size_t>(f)] / 5 + 1));
  }
  img.slot = place;
  const fs::path file = img.write(dir.path() / "cine.dcm");
  const std::string unchosen = message_of(file);
  EXPECT_TRUE(contains(unchosen, file.string() +
                                     ": a time series of 3 volumes (3 frames at each of 5 "
                                     "positions): choose one by its index, 0 to 2"))
      << unchosen;
  const auto frame = static_cast<std::size_t>(img.rows * img.columns);
  for (std::int64_t k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    const progiso::volume v = progiso::read_dicom(file, {std::nullopt, k});
    ASSERT_EQ(v.dims(), (progiso::index3{5, 4, 5}));
    for (int f = 0; f < 15; ++f) {
      if (img.temporal[static_cast<std::size_t>(f)] != static_cast<Uint32>(k + 1)) continue;
      const auto at = static_cast<std::size_t>(place[static_cast<std::size_t>(f)]) * frame;
      for (std::size_t i = 0; i < frame; ++i) {
        ASSERT_EQ(stored_sample(v, at + i),
                  img.expected(img.values[static_cast<std::size_t>(f) * frame + i], f));
      }
    }
    EXPECT_NEAR(v.spacing()[2], img.step, 1e-6);
    // The world map and the input files follow the chosen volume too.
    EXPECT_TRUE(progiso::read_volume_world(file, std::nullopt, {std::nullopt, k}).has_value());
    EXPECT_EQ(progiso::volume_input_files(file, std::nullopt, {std::nullopt, k}),
              (std::vector<fs::path>{file}));
  }
  EXPECT_TRUE(contains(
      progiso::test::error_message_naming(file,
                                          [&] {
                                            (void)progiso::read_dicom(file, {std::nullopt, 3});
                                          }),
      "volume 3 was chosen, but the input is a time series of 3 volumes (0 to "
      "2)"));
}

TEST(DicomEnhanced, a_classic_series_of_time_points_orders_them_by_instance_number) {
  // Two time points of 4 slices in one classic series (a 4-D CT exported as one series): the
  // second's instance numbers follow the first's; file names shuffled.
  const progiso::test::scratch_dir dir("progiso-dicom-enhanced-test-");
  const std::array<int, 8> names{5, 2, 7, 0, 3, 6, 1, 4};
  for (int i = 0; i < 8; ++i) {
    const int time = i / 4;
    const int k = i % 4;
    progiso::test::dicom_slice_file f = progiso::test::plain_slice(k, 4, 5, 8, 2.0);
    f.instance = i + 1;
    f.pixels.assign(20, static_cast<std::byte>(10 * time + k));
    f.write(dir.path(), "IM" + std::to_string(names[static_cast<std::size_t>(i)]));
  }
  EXPECT_TRUE(contains(message_of(dir.path()),
                       "a time series of 2 volumes (2 frames at each of "
                       "4 positions)"));
  for (std::int64_t time = 0; time < 2; ++time) {
    const progiso::volume v = progiso::read_dicom(dir.path(), {std::nullopt, time});
    ASSERT_EQ(v.dims(), (progiso::index3{5, 4, 4}));
    for (std::size_t k = 0; k < 4; ++k) {
      EXPECT_EQ(stored_sample(v, 20 * k), static_cast<double>(10 * time) + static_cast<double>(k));
    }
    // Only the chosen time point's files are read.
    EXPECT_EQ(progiso::volume_input_files(dir.path(), std::nullopt, {std::nullopt, time}).size(),
              5U);
  }
}

/// An RT dose grid as a treatment planning system writes it: one multi-frame file whose frames
/// GridFrameOffsetVector places from ImagePositionPatient, its values in units of
/// DoseGridScaling.
struct rt_dose {
  E_TransferSyntax syntax = EXS_LittleEndianImplicit;
  E_EncodingType lengths = EET_ExplicitLength;
  int bits = 32;
  int rows = 4;
  int columns = 5;
  int frames = 6;
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  std::array<double, 3> first{-50.0, 20.0, 100.0};
  double step = 2.5;
  bool absolute = false;    // offsets as z coordinates (axial grids), else relative to the first
  bool descending = false;  // frames written from the highest position down
  std::string scaling = "1.5E-4";
  std::string offsets;  // written instead of the computed ones when set
  std::vector<std::uint32_t> values;

  void fill(unsigned seed) {
    std::mt19937 rng(seed);
    values.resize(static_cast<std::size_t>(frames * rows * columns));
    for (std::uint32_t& v : values) {
      v = static_cast<std::uint32_t>(rng()) & (bits == 32 ? 0xffffffu : 0xffffu);
    }
  }
  [[nodiscard]] int slot(int f) const { return descending ? frames - 1 - f : f; }
  [[nodiscard]] std::array<double, 3> position(int f) const {
    const auto& o = orientation;
    const std::array<double, 3> n{o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5],
                                  o[0] * o[4] - o[1] * o[3]};
    const double d = step * slot(f);
    return {first[0] + n[0] * d, first[1] + n[1] * d, first[2] + n[2] * d};
  }

  fs::path write(const fs::path& file) const {
    DcmFileFormat ff;
    DcmDataset* d = ff.getDataset();
    const auto ok = [&](OFCondition c) { EXPECT_TRUE(c.good()) << c.text(); };
    ok(d->putAndInsertString(DCM_SOPClassUID, UID_RTDoseStorage));
    ok(d->putAndInsertString(DCM_SOPInstanceUID, "1.2.826.0.1.3680043.2.1125.8.1"));
    ok(d->putAndInsertString(DCM_Modality, "RTDOSE"));
    ok(d->putAndInsertString(DCM_SeriesInstanceUID, "1.2.826.0.1.3680043.2.1125.8"));
    // The grid's first frame lies at ImagePositionPatient: the lowest, or with descending
    // offsets the highest.
    const std::array<double, 3> p0 = position(0);
    ok(d->putAndInsertString(DCM_ImagePositionPatient, decimals(p0.data(), 3).c_str()));
    ok(d->putAndInsertString(DCM_ImageOrientationPatient, decimals(orientation.data(), 6).c_str()));
    ok(d->putAndInsertUint16(DCM_SamplesPerPixel, 1));
    ok(d->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2"));
    ok(d->putAndInsertString(DCM_NumberOfFrames, std::to_string(frames).c_str()));
    ok(d->putAndInsertTagKey(DCM_FrameIncrementPointer, DCM_GridFrameOffsetVector));
    ok(d->putAndInsertUint16(DCM_Rows, static_cast<Uint16>(rows)));
    ok(d->putAndInsertUint16(DCM_Columns, static_cast<Uint16>(columns)));
    ok(d->putAndInsertString(DCM_PixelSpacing, "2.5\\3"));
    ok(d->putAndInsertUint16(DCM_BitsAllocated, static_cast<Uint16>(bits)));
    ok(d->putAndInsertUint16(DCM_BitsStored, static_cast<Uint16>(bits)));
    ok(d->putAndInsertUint16(DCM_HighBit, static_cast<Uint16>(bits - 1)));
    ok(d->putAndInsertUint16(DCM_PixelRepresentation, 0));
    ok(d->putAndInsertString(DCM_DoseUnits, "GY"));
    ok(d->putAndInsertString(DCM_DoseType, "PHYSICAL"));
    ok(d->putAndInsertString(DCM_DoseSummationType, "PLAN"));
    std::vector<double> off;
    for (int f = 0; f < frames; ++f) {
      const double rel = (descending ? -step : step) * f;
      off.push_back(absolute ? p0[2] + rel : rel);
    }
    ok(d->putAndInsertString(DCM_GridFrameOffsetVector,
                             (offsets.empty() ? decimals(off.data(), frames) : offsets).c_str()));
    ok(d->putAndInsertString(DCM_DoseGridScaling, scaling.c_str()));
    if (bits == 16) {
      std::vector<Uint16> px(values.begin(), values.end());
      ok(d->putAndInsertUint16Array(DCM_PixelData, px.data(),
                                    static_cast<unsigned long>(px.size())));
    } else {
      // 32-bit samples as OW words, low word first (little-endian syntaxes).
      std::vector<Uint16> px;
      for (const std::uint32_t v : values) {
        px.push_back(static_cast<Uint16>(v & 0xffff));
        px.push_back(static_cast<Uint16>(v >> 16));
      }
      ok(d->putAndInsertUint16Array(DCM_PixelData, px.data(),
                                    static_cast<unsigned long>(px.size())));
    }
    ok(ff.saveFile(file.c_str(), syntax, lengths));
    return file;
  }
};

void expect_dose(const fs::path& file, const rt_dose& dose) {
  const progiso::volume v = progiso::read_volume(file, std::nullopt, std::nullopt);
  ASSERT_EQ(v.dims(), (progiso::index3{dose.columns, dose.rows, dose.frames}));
  ASSERT_EQ(v.type(), sample_type::f32);  // doses: stored values × DoseGridScaling
  const double scale = std::stod(dose.scaling);
  const auto frame = static_cast<std::size_t>(dose.rows * dose.columns);
  for (int f = 0; f < dose.frames; ++f) {
    const auto at = static_cast<std::size_t>(dose.slot(f)) * frame;
    for (std::size_t i = 0; i < frame; ++i) {
      const auto raw = dose.values[static_cast<std::size_t>(f) * frame + i];
      ASSERT_EQ(stored_sample(v, at + i),
                static_cast<double>(static_cast<float>(scale * static_cast<double>(raw))))
          << "frame " << f << " sample " << i;
    }
  }
  EXPECT_NEAR(v.spacing()[0], 3.0, 1e-12);
  EXPECT_NEAR(v.spacing()[1], 2.5, 1e-12);
  EXPECT_NEAR(v.spacing()[2], dose.step, 1e-6);
  const auto world = progiso::read_volume_world(file, std::nullopt);
  ASSERT_TRUE(world.has_value());
  for (int f = 0; f < dose.frames; ++f) {
    const std::array<double, 3> p = world->apply({0.0, 0.0, static_cast<double>(dose.slot(f))});
    const std::array<double, 3> want = dose.position(f);
    for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(p[i], want[i], 1e-6) << f;
  }
}

TEST(DicomRtDose, places_every_frame_by_its_grid_offset_and_scales_it_to_dose) {
  const progiso::test::scratch_dir dir("progiso-dicom-rtdose-test-");
  unsigned seed = 1;
  int files = 0;
  for (const E_TransferSyntax syntax :
       {EXS_LittleEndianImplicit, EXS_LittleEndianExplicit, EXS_BigEndianExplicit}) {
    for (const int bits : {16, 32}) {
      if (bits == 32 && syntax == EXS_BigEndianExplicit) continue;  // OW swaps 16-bit words
      for (const bool absolute : {false, true}) {
        for (const bool descending : {false, true}) {
          rt_dose dose;
          dose.syntax = syntax;
          dose.bits = bits;
          dose.absolute = absolute;
          dose.descending = descending;
          dose.fill(seed++);
          const fs::path file = dose.write(dir.path() / ("dose" + std::to_string(files++)));
          SCOPED_TRACE(file.string());
          expect_dose(file, dose);
        }
      }
    }
  }
  EXPECT_EQ(files, 20);
  // An oblique grid with relative offsets.
  rt_dose oblique;
  const double c = std::cos(0.5);
  const double s = std::sin(0.5);
  oblique.orientation = {c, 0.0, -s, 0.0, 1.0, 0.0};
  oblique.fill(77);
  expect_dose(oblique.write(dir.path() / "oblique.dcm"), oblique);
}

TEST(DicomRtDose, refuses_grids_its_offsets_do_not_place) {
  const progiso::test::scratch_dir dir("progiso-dicom-rtdose-test-");
  int n = 0;
  const auto refused = [&](const std::function<void(rt_dose&)>& change, const std::string& what) {
    rt_dose dose;
    dose.fill(static_cast<unsigned>(200 + n));
    change(dose);
    const fs::path file = dose.write(dir.path() / ("bad" + std::to_string(n++) + ".dcm"));
    const std::string m = message_of(file);
    EXPECT_TRUE(contains(m, file.string())) << m;
    EXPECT_TRUE(contains(m, what)) << m;
  };
  refused([](rt_dose& d) { d.offsets = "0\\2.5\\5"; }, "6 frames with 3 offsets");
  refused([](rt_dose& d) { d.offsets = "0\\2.5\\5\\7.5\\12.5\\15"; }, "evenly spaced");
  refused([](rt_dose& d) { d.offsets = "3\\5.5\\8\\10.5\\13\\15.5"; },
          "neither 0 (relative offsets) nor, on an axial grid, ImagePositionPatient's z");
  refused(
      [](rt_dose& d) {
        d.orientation = {1.0, 0.0, 0.0, 0.0, 0.0, -1.0};  // coronal: no absolute z offsets
        d.absolute = true;
      },
      "neither 0");
  refused([](rt_dose& d) { d.offsets = "0\\x\\5\\7.5\\10\\12.5"; }, "finite numbers");
  refused([](rt_dose& d) { d.scaling = "0"; }, "has DoseGridScaling 0");
  EXPECT_EQ(n, 6);
}

// ---- Lossless JPEG (most archives' compressed CT and MR).

/// DCMTK's JPEG encoders, registered for the tests of this file: each frame in fragments of at
/// most `fragment` bytes (0: one per frame).
void register_jpeg(Uint32 fragment) {
  DJEncoderRegistration::cleanup();
  DJEncoderRegistration::registerCodecs(ECC_lossyYCbCr, EUC_never, OFFalse, 0, 0, fragment);
}

TEST(DicomJpeg, decodes_every_predictor_depth_and_fragmenting_dcmtk_encodes) {
  const progiso::test::scratch_dir dir("progiso-dicom-jpeg-test-");
  unsigned seed = 300;
  int files = 0;
  for (const Uint32 fragment : {Uint32{0}, Uint32{64}}) {
    register_jpeg(fragment);
    for (const E_TransferSyntax syntax : {EXS_JPEGProcess14SV1, EXS_JPEGProcess14}) {
      for (int predictor = 1; predictor <= 7; ++predictor) {
        if (syntax == EXS_JPEGProcess14SV1 && predictor > 1) break;
        struct depth {
          int allocated, stored;
          bool is_signed;
        };
        for (const depth b : {depth{8, 8, false}, depth{16, 12, true}, depth{16, 16, false}}) {
          for (const auto scaling :
               {enhanced_image::rescale::none, enhanced_image::rescale::per_frame}) {
            enhanced_image img;
            img.syntax = syntax;
            img.predictor = predictor;
            img.bits_allocated = b.allocated;
            img.bits_stored = b.stored;
            img.is_signed = b.is_signed;
            img.scaling = scaling;
            img.rows = 12;
            img.columns = 9;
            img.fill(seed++);
            // The bits above BitsStored: zero, as JPEG of BitsStored precision holds them.
            for (std::uint32_t& v : img.values) v &= (std::uint32_t{1} << b.stored) - 1;
            const fs::path file = img.write(dir.path() / ("j" + std::to_string(files++) + ".dcm"));
            SCOPED_TRACE(file.string() + " predictor " + std::to_string(predictor));
            expect_frames(file, img);
          }
        }
      }
    }
  }
  EXPECT_EQ(files, 2 * (1 + 7) * 3 * 2);
  DJEncoderRegistration::cleanup();
}

TEST(DicomJpeg, a_classic_series_of_jpeg_slices_reads_as_its_uncompressed_self) {
  // The same 9 slices, uncompressed and compressed by DCMTK (one file per slice): one volume.
  const progiso::test::scratch_dir dir("progiso-dicom-jpeg-test-");
  register_jpeg(0);
  const fs::path plain = dir.path() / "plain";
  const fs::path packed = dir.path() / "packed";
  fs::create_directory(plain);
  fs::create_directory(packed);
  std::mt19937 rng(8);
  for (int k = 0; k < 9; ++k) {
    progiso::test::dicom_slice_file f = progiso::test::plain_slice(k, 7, 6, 16, 1.5);
    f.bits_stored = 12;
    f.slope = "1";
    f.intercept = "-1024";
    std::vector<std::uint16_t> px(42);
    for (std::uint16_t& v : px) v = static_cast<std::uint16_t>(rng() & 0xfff);
    f.pixels.resize(84);
    std::memcpy(f.pixels.data(), px.data(), 84);
    const fs::path file = f.write(plain, "IM" + std::to_string(k));
    DcmFileFormat ff;
    ASSERT_TRUE(ff.loadFile(file.c_str()).good());
    const DJ_RPLossless lossless(1, 0);
    ASSERT_TRUE(ff.getDataset()->chooseRepresentation(EXS_JPEGProcess14SV1, &lossless).good());
    ASSERT_TRUE(
        ff.saveFile((packed / ("IM" + std::to_string(k))).c_str(), EXS_JPEGProcess14SV1).good());
  }
  const progiso::volume a = progiso::read_dicom(plain);
  const progiso::volume b = progiso::read_dicom(packed);
  EXPECT_EQ(a.dims(), b.dims());
  EXPECT_EQ(a.type(), b.type());
  ASSERT_EQ(a.byte_size(), b.byte_size());
  EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.byte_size()), 0);
  DJEncoderRegistration::cleanup();
}

TEST(DicomJpeg, refuses_streams_it_cannot_decode_with_one_line_naming_file_and_frame) {
  const progiso::test::scratch_dir dir("progiso-dicom-jpeg-test-");
  register_jpeg(0);
  enhanced_image img;
  img.syntax = EXS_JPEGProcess14SV1;
  img.fill(9);
  const fs::path good = img.write(dir.path() / "good.dcm");
  const std::string bytes = progiso::test::read_whole_file(good);
  const std::size_t sof = bytes.find("\xff\xc3");
  const std::size_t sos = bytes.find("\xff\xda");
  const std::size_t dht = bytes.find("\xff\xc4");
  ASSERT_NE(sof, std::string::npos);
  ASSERT_NE(sos, std::string::npos);
  ASSERT_NE(dht, std::string::npos);
  int n = 0;
  const auto refused = [&](std::string changed, const std::string& what) {
    const fs::path file = dir.path() / ("bad" + std::to_string(n++) + ".dcm");
    progiso::test::write_file(file, changed);
    const std::string m = message_of(file);
    EXPECT_TRUE(contains(m, file.string())) << m;
    EXPECT_TRUE(contains(m, what)) << m;
  };
  std::string baseline = bytes;
  baseline[sof + 1] = '\xc0';  // SOF0: baseline, lossy
  refused(baseline, "uses the JPEG process of marker FF C0");
  std::string wider = bytes;
  wider[sof + 8] = static_cast<char>(wider[sof + 8] + 1);  // one more sample per line
  refused(wider, "holds an image of 6x4 samples, expected 5x4");
  std::string no_table = bytes;
  no_table[sos + 6] = '\x30';  // the scan names Huffman table 3
  refused(no_table, "uses Huffman table 3, which it does not define");
  std::string predictor = bytes;
  predictor[sos + 7] = '\x00';  // predictor 0 (hierarchical only)
  refused(predictor, "uses predictor 0");
  // A scan cut short: the file ends inside the pixel data's last item.
  refused(bytes.substr(0, sos + 20), "past the file's end");
  EXPECT_EQ(n, 5);
  DJEncoderRegistration::cleanup();
}

// ---- RLE Lossless.

// PS3.5 G.3.1: the PackBits code -128 outputs nothing. progiso's RLE decoder follows it; DCMTK's
// (DcmRLEDecoder, dcmdata) reads it as a repeat run of 129 bytes, which is why RLE frames are
// decoded by progiso's own code (docs/formats.md). Should DCMTK's decoder come to agree, the
// second half fails, and DICOM RLE can move to it as lossless JPEG has.
TEST(DicomRle, the_code_minus_128_outputs_nothing_where_dcmtk_repeats_129_bytes) {
  std::vector<std::uint8_t> fragment(64, 0);
  fragment[0] = 1;   // one segment (one byte a sample)
  fragment[4] = 64;  // at byte 64
  // -128 (nothing), a literal of one byte (7), a repeat of three (9).
  fragment.insert(fragment.end(), {0x80, 0x00, 0x07, 0xfe, 0x09});
  std::vector<std::byte> out(4);
  progiso::detail::decode_dicom_rle(fragment, 1, out);
  EXPECT_EQ(out, (std::vector<std::byte>{std::byte{7}, std::byte{9}, std::byte{9}, std::byte{9}}));

  DcmRLEDecoder dcmtk(4096);
  (void)dcmtk.decompress(fragment.data() + 64, fragment.size() - 64);
  EXPECT_NE(dcmtk.size(), 4u) << "DCMTK's RLE decoder now reads -128 as PS3.5 says";
}

TEST(DicomRle, decodes_every_depth_and_frame_dcmtk_encodes) {
  const progiso::test::scratch_dir dir("progiso-dicom-rle-test-");
  DcmRLEEncoderRegistration::registerCodecs();
  unsigned seed = 500;
  int files = 0;
  struct depth {
    int allocated, stored;
    bool is_signed;
  };
  for (const depth b :
       {depth{8, 8, false}, depth{8, 6, true}, depth{16, 12, true}, depth{16, 16, false}}) {
    for (const auto scaling : {enhanced_image::rescale::none, enhanced_image::rescale::shared}) {
      for (const bool runs : {false, true}) {
        enhanced_image img;
        img.syntax = EXS_RLELossless;
        img.bits_allocated = b.allocated;
        img.bits_stored = b.stored;
        img.is_signed = b.is_signed;
        img.scaling = scaling;
        img.rows = 11;
        img.columns = 300;  // rows longer than a run (128)
        img.fill(seed++);
        // Runs: long stretches of one value (repeat runs), else noise (literal runs).
        if (runs) {
          for (std::size_t i = 0; i < img.values.size(); ++i) img.values[i] = img.values[i / 200];
        }
        const fs::path file = img.write(dir.path() / ("r" + std::to_string(files++) + ".dcm"));
        SCOPED_TRACE(file.string());
        expect_frames(file, img);
      }
    }
  }
  EXPECT_EQ(files, 16);
  // A frame header that counts other segments than the samples' bytes, and an offset outside
  // the fragment: refused naming file and frame.
  enhanced_image img;
  img.syntax = EXS_RLELossless;
  img.fill(7);
  const std::string bytes = progiso::test::read_whole_file(img.write(dir.path() / "good.dcm"));
  // The first fragment (after the empty offsets table's item) starts with its segment count, 2.
  const std::size_t header = bytes.find(std::string("\x02\0\0\0\x40\0\0\0", 8));
  ASSERT_NE(header, std::string::npos);
  std::string three = bytes;
  three[header] = '\x03';
  progiso::test::write_file(dir.path() / "three.dcm", three);
  const std::string m3 = message_of(dir.path() / "three.dcm");
  EXPECT_TRUE(contains(m3, "three.dcm (frame 1): RLE frame has 3 segments, expected 2")) << m3;
  std::string far = bytes;
  far[header + 9] = '\x7f';  // the second segment's offset beyond the fragment
  progiso::test::write_file(dir.path() / "far.dcm", far);
  const std::string mf = message_of(dir.path() / "far.dcm");
  EXPECT_TRUE(contains(mf, "far.dcm (frame 1): RLE frame has segment")) << mf;
  DcmRLEEncoderRegistration::cleanup();
}

}  // namespace
