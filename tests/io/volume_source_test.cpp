// volume_source: an input opened once gives the files, the orientation and the volume that
// volume_input_files(), read_volume_world() and read_volume() give, for every format; and it
// reads the data of the file it opened.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "support/dicom_files.hpp"
#include "support/io_test_helpers.hpp"
#include "support/metaimage_files.hpp"
#include "support/scratch_dir.hpp"
#include "support/vti_files.hpp"
#include "support/vtk_legacy_files.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;

constexpr index3 dims{5, 4, 3};
constexpr std::size_t count = 60;

std::string as_string(const std::vector<std::byte>& b) {
  return {reinterpret_cast<const char*>(b.data()), b.size()};
}

std::string volume_bytes(const volume& v) {
  return {reinterpret_cast<const char*>(v.bytes()), v.byte_size()};
}

/// One input of every format reading `samples` (u16, host order, 5 × 4 × 3); .nhdr, .mhd and
/// .pvti with their data files, DICOM as a directory of three slices.
struct input {
  fs::path file;
  std::optional<raw_layout> raw;
};

std::string nrrd_header(const std::string& data_line) {
  return "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: raw\n"
         "space: left-posterior-superior\nspace directions: (0.5,0,0) (0,0,2) (0,-1.25,0)\n"
         "space origin: (-3,4.5,100)\n" +
         data_line + "\n";
}

std::string metaimage_header(const std::string& data_file) {
  return "ObjectType = Image\nNDims = 3\nDimSize = 5 4 3\nElementType = MET_USHORT\n"
         "ElementSpacing = 0.5 2 1.25\nOffset = -3 4.5 100\nElementDataFile = " +
         data_file + "\n";
}

std::vector<input> every_format(const fs::path& dir, const std::vector<std::byte>& samples) {
  static_assert(std::endian::native == std::endian::little);
  const std::string bytes = as_string(samples);
  std::vector<input> out;
  test::write_file(dir / "cube.raw", bytes);
  out.push_back({dir / "cube.raw", raw_layout{dims, sample_type::u16, false}});
  test::write_file(dir / "cube.nrrd", nrrd_header("") + bytes);
  out.push_back({dir / "cube.nrrd", std::nullopt});
  test::write_file(dir / "cube.nhdr", nrrd_header("data file: cube.raw\n"));
  out.push_back({dir / "cube.nhdr", std::nullopt});
  test::write_file(dir / "cube.nii",
                   test::nifti1_file({5, 4, 3}, 512, 16, {0.5f, 2.0f, 1.25f}, bytes));
  out.push_back({dir / "cube.nii", std::nullopt});
  test::write_file(dir / "cube.mha", metaimage_header("LOCAL") + bytes);
  out.push_back({dir / "cube.mha", std::nullopt});
  test::write_file(dir / "cube.mhd", metaimage_header("cube.raw"));
  out.push_back({dir / "cube.mhd", std::nullopt});
  test::vtk_legacy_file legacy;
  legacy.type_name = "unsigned_short";
  legacy.type = sample_type::u16;
  legacy.samples = samples;
  out.push_back({legacy.write(dir, "cube"), std::nullopt});
  test::vti_file vti;
  vti.type_name = "UInt16";
  vti.type = sample_type::u16;
  vti.samples = samples;
  vti.direction = "0 1 0 1 0 0 0 0 1";
  out.push_back({vti.write(dir, "cube"), std::nullopt});
  out.push_back({test::write_pvti(dir, "pieces", vti, {{0, 4, 0, 3, 0, 1}, {0, 4, 0, 3, 1, 2}},
                                  test::vti_file::mode::appended_base64),
                 std::nullopt});
  const fs::path series = dir / "series";
  fs::create_directory(series);
  for (int k = 0; k < 3; ++k) {
    test::dicom_slice_file f = test::plain_slice(k, 4, 5, 16, 1.25);
    f.pixels.assign(samples.begin() + 40 * k, samples.begin() + 40 * (k + 1));
    f.write(series, "IM" + std::to_string(k));
  }
  out.push_back({series, std::nullopt});
  return out;
}

TEST(VolumeSource, gives_the_files_orientation_and_volume_of_the_three_readers_for_every_format) {
  const test::scratch_dir dir;
  const std::vector<std::byte> samples = test::random_samples(sample_type::u16, count, 7);
  const std::vector<input> inputs = every_format(dir.path(), samples);
  ASSERT_EQ(inputs.size(), 10U);
  for (const input& in : inputs) {
    SCOPED_TRACE(in.file.filename().string());
    volume_source source(in.file, in.raw);
    EXPECT_EQ(source.files(), volume_input_files(in.file, in.raw));
    EXPECT_GE(source.files().size(), 1U);
    EXPECT_EQ(source.files().front(), in.file);
    const std::optional<index_to_world> world = read_volume_world(in.file, in.raw);
    ASSERT_EQ(source.world().has_value(), world.has_value());
    if (world) {
      EXPECT_EQ(source.world()->m, world->m);
    }
    // Every input here declares where its samples lie but the raw file and the NIfTI, whose
    // qform_code and sform_code are 0.
    EXPECT_EQ(world.has_value(), !in.raw && in.file.extension() != ".nii");

    const volume got = source.read();
    const volume want = read_volume(in.file, in.raw, std::nullopt);
    EXPECT_EQ(got.dims(), dims);
    EXPECT_EQ(got.type(), sample_type::u16);
    EXPECT_EQ(volume_bytes(got), as_string(samples));
    EXPECT_EQ(volume_bytes(got), volume_bytes(want));
    EXPECT_EQ(got.spacing(), want.spacing());
    EXPECT_EQ(got.origin(), want.origin());

    // A given spacing replaces the header's, as read_volume()'s does; a second read reads again.
    const std::array<double, 3> spacing{2.0, 3.0, 4.0};
    const volume respaced = source.read(spacing);
    EXPECT_EQ(respaced.spacing(), spacing);
    EXPECT_EQ(respaced.spacing(), read_volume(in.file, in.raw, spacing).spacing());
    EXPECT_EQ(volume_bytes(respaced), as_string(samples));
  }
}

TEST(VolumeSource, a_moved_source_reads_what_it_opened) {
  const test::scratch_dir dir;
  const std::vector<std::byte> samples = test::random_samples(sample_type::u16, count, 11);
  for (const input& in : every_format(dir.path(), samples)) {
    SCOPED_TRACE(in.file.filename().string());
    volume_source first(in.file, in.raw);
    const std::vector<fs::path> files = first.files();
    volume_source moved(std::move(first));
    EXPECT_EQ(moved.files(), files);
    EXPECT_EQ(volume_bytes(moved.read()), as_string(samples));
  }
}

TEST(VolumeSource, reads_the_data_of_the_file_it_opened_when_the_name_is_replaced) {
  // A file holding its data (NRRD, MetaImage, legacy VTK, .vti) stays open from the header to
  // the samples: replacing the name in between (an editor saving, a pipeline rewriting it)
  // cannot pair one file's header with another's data. read_volume() afterwards reads the new one.
  const test::scratch_dir dir;
  const std::vector<std::byte> before = test::random_samples(sample_type::u16, count, 3);
  const std::vector<std::byte> after = test::random_samples(sample_type::u16, count, 4);
  ASSERT_NE(before, after);
  const fs::path old_dir = dir.path() / "old";
  const fs::path new_dir = dir.path() / "new";
  fs::create_directory(old_dir);
  fs::create_directory(new_dir);
  const std::vector<input> olds = every_format(old_dir, before);
  const std::vector<input> news = every_format(new_dir, after);
  int checked = 0;
  for (std::size_t i = 0; i < olds.size(); ++i) {
    const std::string ext = olds[i].file.extension().string();
    if (ext != ".nrrd" && ext != ".mha" && ext != ".vtk" && ext != ".vti") continue;
    SCOPED_TRACE(olds[i].file.filename().string());
    volume_source source(olds[i].file, olds[i].raw);
    fs::rename(news[i].file, olds[i].file);
    EXPECT_EQ(volume_bytes(source.read()), as_string(before));
    EXPECT_EQ(volume_bytes(read_volume(olds[i].file, olds[i].raw, std::nullopt)), as_string(after));
    ++checked;
  }
  EXPECT_EQ(checked, 4);
}

TEST(VolumeSource, refuses_on_construction_what_read_volume_refuses) {
  const test::scratch_dir dir;
  const std::vector<std::byte> samples = test::random_samples(sample_type::u16, count, 5);
  const std::vector<input> inputs = every_format(dir.path(), samples);
  // An unknown format, a series chosen for a file, a volume past the only one: each refused
  // before any data is read, with the message read_volume() gives.
  test::write_file(dir.path() / "cube.xyz", "");
  const auto message = [](const auto& f) {
    try {
      f();
    } catch (const error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const fs::path unknown = dir.path() / "cube.xyz";
  const std::string m = message([&] { volume_source s(unknown, std::nullopt); });
  EXPECT_TRUE(test::contains(m, "unknown volume format")) << m;
  EXPECT_EQ(m, message([&] { (void)read_volume(unknown, std::nullopt, std::nullopt); }));
  for (const input& in : inputs) {
    SCOPED_TRACE(in.file.filename().string());
    const volume_choice series{std::string("2"), std::nullopt};
    const volume_choice volume{std::nullopt, 1};
    for (const volume_choice& choice : {series, volume}) {
      const std::string got = message([&] { volume_source s(in.file, in.raw, choice); });
      const std::string want =
          message([&] { (void)read_volume(in.file, in.raw, std::nullopt, choice); });
      EXPECT_EQ(got, want);
      EXPECT_NE(got, "no error");
    }
  }
}

}  // namespace
}  // namespace progiso
