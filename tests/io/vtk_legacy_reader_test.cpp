// Tests for progiso's own legacy VTK reader (io/detail/vtk_legacy_reader.hpp, through
// read_vtk_legacy(), read_volume(), read_volume_world() and volume_input_files()).
//
// Every sample read must equal the sample written: STRUCTURED_POINTS files of every data type,
// binary (big-endian) and ASCII, SCALARS (with their LOOKUP_TABLE line) and FIELD arrays,
// keywords in either case, SPACING or ASPECT_RATIO; the shared hipip volume as the legacy file it
// came from (VTK's ironProt.vtk layout). The comparison with VTK's own reader is
// readers_vs_vtk_test.cpp, built where VTK is installed.
//
// Hostile: files that are not legacy VTK, other datasets, 2-D images, sizes out of range, point
// counts that do not match, vectors, several components, unsupported types, data far shorter than
// declared (refused before allocating). Each fails with one line naming the file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <string>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"
#include "support/vtk_legacy_files.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::vtk_legacy_file;
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-vtk-legacy-reader-test-") {}
};

vtk_legacy_file file_of(const progiso::test::vtk_type& t, unsigned seed) {
  vtk_legacy_file f;
  f.type_name = t.name;
  f.type = t.type;
  f.samples = progiso::test::random_samples(t.type, 60, seed);
  return f;
}

void expect_samples(const fs::path& file, const vtk_legacy_file& f) {
  const progiso::volume v = progiso::read_vtk_legacy(file);
  EXPECT_EQ(v.dims(), (progiso::index3{5, 4, 3})) << file;
  EXPECT_EQ(v.type(), f.type) << file;
  ASSERT_EQ(v.byte_size(), f.samples.size()) << file;
  EXPECT_EQ(std::memcmp(v.bytes(), f.samples.data(), f.samples.size()), 0) << file;
}

TEST(VtkLegacyReader, reads_every_type_binary_and_ascii_as_scalars_or_a_field_in_either_case) {
  scratch_dir dir;
  unsigned seed = 1;
  for (const auto& t : progiso::test::vtk_types) {
    for (int variant = 0; variant < 8; ++variant) {
      vtk_legacy_file f = file_of(t, seed);
      f.ascii = (variant & 1) != 0;
      f.upper_case = (variant & 2) == 0;
      f.as_field = (variant & 4) != 0;
      // Later attributes are not read.
      f.after = variant == 3 ? "VECTORS v float\n1 2 3\n" : "";
      expect_samples(f.write(dir.path(), "v" + std::to_string(seed++)), f);
    }
  }
}

TEST(VtkLegacyReader, spacing_and_origin_give_an_axis_aligned_world_map) {
  scratch_dir dir;
  vtk_legacy_file f = file_of(progiso::test::vtk_types[4], 40);
  f.spacing = "0.5 -2 3";
  f.origin = "-10.5 20.25 3";
  const fs::path file = f.write(dir.path(), "geometry");
  const progiso::volume v = progiso::read_vtk_legacy(file);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 3.0}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{-10.5, 20.25, 3.0}));
  const auto world = progiso::read_volume_world(file, std::nullopt);
  ASSERT_TRUE(world.has_value());
  EXPECT_EQ(world->apply({1.0, 1.0, 1.0}), (std::array<double, 3>{-10.0, 18.25, 6.0}));
  f.aspect_ratio = true;
  f.spacing = "4 5 6";
  const progiso::volume w =
      progiso::read_volume(f.write(dir.path(), "ASPECT"), std::nullopt, std::nullopt);
  EXPECT_EQ(w.spacing(), (std::array<double, 3>{4.0, 5.0, 6.0}));
  // The file itself is the only input; a given spacing wins.
  EXPECT_EQ(progiso::volume_input_files(file, std::nullopt), std::vector<fs::path>{file});
  const fs::path upper = dir / "UPPER.VTK";
  fs::copy_file(file, upper);
  EXPECT_EQ(progiso::read_volume(upper, std::nullopt, std::array<double, 3>{1, 1, 1}).spacing(),
            (std::array<double, 3>{1.0, 1.0, 1.0}));
}

TEST(VtkLegacyReader, the_shared_hipip_volume_as_vtk_equals_its_raw_file) {
  // hipip is VTK's ironProt.vtk with its header taken off (../shared/data/README.md): put back,
  // the file reads as the raw bytes do.
  const auto data = progiso::test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found";
  scratch_dir dir;
  const std::string raw = progiso::test::read_whole_file(*data / "hipip_68x68x68_uint8.raw");
  ASSERT_EQ(raw.size(), 68u * 68u * 68u);
  const fs::path file = dir / "ironProt.vtk";
  progiso::test::write_file(file,
                            "# vtk DataFile Version 1.0\nHigh potential iron protein\nBINARY\n\n"
                            "DATASET STRUCTURED_POINTS\nDIMENSIONS 68 68 68\nASPECT_RATIO 1 1 1\n"
                            "ORIGIN 0 0 0\n\nPOINT_DATA 314432\nSCALARS scalars unsigned_char\n"
                            "LOOKUP_TABLE default\n" +
                                raw);
  const progiso::volume v = progiso::read_volume(file, std::nullopt, std::nullopt);
  ASSERT_EQ(v.byte_size(), raw.size());
  EXPECT_EQ(std::memcmp(v.bytes(), raw.data(), raw.size()), 0);
}

/// Writes `text` as STEM.vtk in `dir` and expects the reader to refuse it with one line that
/// names the file and contains `what`.
void expect_refused(const scratch_dir& dir, const std::string& stem, const std::string& text,
                    const std::string& what) {
  const fs::path file = dir / (stem + ".vtk");
  progiso::test::write_file(file, text);
  const std::string message = error_naming(file, [&] { (void)progiso::read_vtk_legacy(file); });
  EXPECT_TRUE(contains(message, what)) << stem << ": " << message;
}

TEST(VtkLegacyReader, refuses_hostile_headers_with_one_line_naming_the_file) {
  scratch_dir dir;
  const std::string magic = "# vtk DataFile Version 3.0\ntitle\n";
  const std::string head = magic + "BINARY\nDATASET STRUCTURED_POINTS\n";
  const std::string points = "DIMENSIONS 5 4 3\nPOINT_DATA 60\n";
  const std::string data(61, '\x07');
  const auto expect_error = [&](const std::string& stem, const std::string& text,
                                const std::string& what) { expect_refused(dir, stem, text, what); };
  expect_error("png", std::string("\x89PNG\r\n\x1a\n", 8) + data, "not a legacy VTK file");
  expect_error("notitle", "# vtk DataFile Version 3.0\n", "expected a title line");
  expect_error("mode", magic + "TEXT\n", "expected ASCII or BINARY");
  expect_error("dataset", magic + "BINARY\nDATASET RECTILINEAR_GRID\n", "RECTILINEAR_GRID");
  expect_error("nodataset", magic + "BINARY\nDIMENSIONS 5 4 3\n", "DATASET STRUCTURED_POINTS");
  expect_error("image", head + "DIMENSIONS 5 4 1\nPOINT_DATA 20\n", "a 2-D image is not a volume");
  expect_error("big", head + "DIMENSIONS 5 4 40000\n", "expected 2 to 32769");
  expect_error("number", head + "DIMENSIONS 5 x 3\n", "DIMENSIONS on line 5 holds \"x\"");
  expect_error("count", head + "DIMENSIONS 5 4 3\nPOINT_DATA 61\n", "expected 60 points");
  expect_error("early", head + "POINT_DATA 60\n", "POINT_DATA before DIMENSIONS");
  expect_error("twice", head + "DIMENSIONS 5 4 3\nDIMENSIONS 5 4 3\n", "given twice");
  expect_error("cells", head + "DIMENSIONS 5 4 3\nCELL_DATA 24\n", "CELL_DATA");
  expect_error("fielddata", head + "FIELD FieldData 1\n", "dataset FIELD data");
  expect_error("keyword", head + "COLORS 5\n", "unknown VTK keyword \"COLORS\"");
  expect_error("spacing", head + "SPACING 1 nan 1\n", "expected a finite number");
  expect_error("ends", head + "DIMENSIONS 5 4 3\n", "ends before POINT_DATA");
  expect_error("vectors", head + points + "VECTORS v float\n", "expected SCALARS");
  expect_error("components", head + points + "SCALARS s float 3\n", "expected 1");
  expect_error("lookup", head + points + "SCALARS s float\n" + data, "expected LOOKUP_TABLE");
  expect_error("bit", head + points + "SCALARS s bit\n", "\"bit\"");
  expect_error("long", head + points + "SCALARS s long\n", "not supported");
  expect_error("idtype", head + points + "SCALARS s vtkIdType\n", "not supported");
  expect_error("fieldcomp", head + points + "FIELD FieldData 1\nv 3 60 float\n", "expected 1");
  expect_error("fieldtuples", head + points + "FIELD FieldData 1\nv 1 59 float\n",
               "expected 60 (one per point)");
  expect_error("nul", head + std::string("DIMENSIONS 5 4\0 3\n", 18), "NUL byte");
}

TEST(VtkLegacyReader, refuses_short_data_without_allocating_the_declared_size) {
  scratch_dir dir;
  const auto expect_error = [&](const std::string& stem, const std::string& text,
                                const std::string& what) { expect_refused(dir, stem, text, what); };
  const std::string huge =
      "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_POINTS\n"
      "DIMENSIONS 32769 32769 32769\nPOINT_DATA 35187593412609\nSCALARS s double\n"
      "LOOKUP_TABLE default\n";
  expect_error("huge", huge + "12345678", "cannot hold");
  vtk_legacy_file f = file_of(progiso::test::vtk_types[7], 50);
  const std::string whole = f.text();
  expect_error("short", whole.substr(0, whole.size() - 3), "cannot hold");
  f.ascii = true;
  const std::string text = f.text();
  expect_error("shortascii", text.substr(0, text.size() / 2), "VTK ascii data ends");
}

}  // namespace
