// Tests for progiso's own VTK XML image data reader (io/detail/vti_reader.hpp, through
// read_vti(), read_volume(), read_volume_world() and volume_input_files()).
//
// Every sample read must equal the sample written: files of every data type in every data mode
// VTK's writer has (ascii, inline base64, appended raw, appended base64), uncompressed and in
// zlib blocks (a last block full or partial), with UInt32 and UInt64 headers, in either byte
// order, the array chosen by PointData's Scalars attribute or first. Geometry: an extent that
// does not start at 0 moves the origin, Direction turns the world map. The comparison with
// VTK's own writer and reader is readers_vs_vtk_test.cpp, built where VTK is installed.
//
// Hostile: files that are not VTK XML image data, XML that does not nest, several pieces,
// 2-D images, vectors, 64-bit integers, other compressors, base64 that is not, headers whose
// counts do not match the extent, blocks that do not inflate to their size, and declarations
// far beyond the file (refused before allocating). Each fails with one line naming the file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"
#include "support/vti_files.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::vti_file;
using progiso::test::write_pvti;
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-vti-reader-test-") {}
};

vti_file file_of(const progiso::test::vti_type& t, unsigned seed) {
  vti_file f;
  f.type_name = t.name;
  f.type = t.type;
  f.samples = progiso::test::random_samples(t.type, f.count(), seed);
  return f;
}

void expect_samples(const fs::path& file, const vti_file& f) {
  const progiso::volume v = progiso::read_vti(file);
  EXPECT_EQ(v.dims(), (progiso::index3{5, 4, 3})) << file;
  EXPECT_EQ(v.type(), f.type) << file;
  ASSERT_EQ(v.byte_size(), f.samples.size()) << file;
  EXPECT_EQ(std::memcmp(v.bytes(), f.samples.data(), f.samples.size()), 0) << file;
}

void expect_samples_in(const fs::path& file, const vti_file& f) {
  const progiso::volume v = progiso::read_volume(file, std::nullopt, std::nullopt);
  ASSERT_EQ(v.byte_size(), f.samples.size()) << file;
  EXPECT_EQ(std::memcmp(v.bytes(), f.samples.data(), f.samples.size()), 0) << file;
}

TEST(VtiReader, reads_every_type_in_every_mode_compression_header_and_byte_order) {
  scratch_dir dir;
  unsigned seed = 1;
  int files = 0;
  for (const auto& t : progiso::test::vti_types) {
    for (int m = 0; m < 4; ++m) {
      for (int variant = 0; variant < 8; ++variant) {
        vti_file f = file_of(t, seed);
        f.how = static_cast<vti_file::mode>(m);
        f.zlib = (variant & 1) != 0;
        f.uint64_headers = (variant & 2) != 0;
        f.big_endian = (variant & 4) != 0;
        f.decoy_first = variant != 5;
        // 60 samples: blocks of 16 bytes leave a partial last block except for 4- and 8-byte
        // samples, whose last block is full (written as a last size of 0, as VTK does).
        f.block_bytes = variant == 3 ? 7 : 16;
        if (f.how == vti_file::mode::ascii && variant > 1) continue;  // no binary header
        expect_samples(f.write(dir.path(), "v" + std::to_string(seed++)), f);
        ++files;
      }
    }
  }
  EXPECT_EQ(files, 8 * (2 + 3 * 8));
}

TEST(VtiReader, the_extent_start_moves_the_origin_and_direction_turns_the_world_map) {
  scratch_dir dir;
  vti_file f = file_of(progiso::test::vti_types[3], 40);
  f.extent = {2, 6, -1, 2, 10, 12};
  f.origin = "-10.5 20.25 3";
  f.spacing = "0.5 -2 3";
  const fs::path file = f.write(dir.path(), "geometry");
  expect_samples(file, f);
  const progiso::volume v = progiso::read_vti(file);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 3.0}));
  // The extent's first point: Origin + Spacing ⊙ (2, −1, 10).
  EXPECT_EQ(v.origin(), (std::array<double, 3>{-9.5, 22.25, 33.0}));
  auto world = progiso::read_volume_world(file, std::nullopt);
  ASSERT_TRUE(world.has_value());
  EXPECT_EQ(world->apply({1.0, 1.0, 1.0}), (std::array<double, 3>{-9.0, 20.25, 36.0}));
  // A rotation by 90° about z: index x runs along world y, index y along −x.
  f.direction = "0 -1 0 1 0 0 0 0 1";
  const fs::path turned = f.write(dir.path(), "turned");
  world = progiso::read_volume_world(turned, std::nullopt);
  ASSERT_TRUE(world.has_value());
  // Point index (i, j, k) = extent (2 + i, −1 + j, 10 + k): world = Origin + D (s ⊙ extent).
  EXPECT_EQ(world->apply({0.0, 0.0, 0.0}), (std::array<double, 3>{-10.5 - 2.0, 20.25 + 1.0, 33.0}));
  EXPECT_EQ(world->apply({1.0, 0.0, 0.0}), (std::array<double, 3>{-12.5, 21.75, 33.0}));
  // A rotation keeps the spacing's orientation: 0.5 × (−2) × 3.
  EXPECT_DOUBLE_EQ(world->determinant(), -3.0);
  // The file itself is the only input; any case of the extension; a given spacing wins.
  EXPECT_EQ(progiso::volume_input_files(file, std::nullopt), std::vector<fs::path>{file});
  const fs::path upper = dir / "UPPER.VTI";
  fs::copy_file(file, upper);
  EXPECT_EQ(progiso::read_volume(upper, std::nullopt, std::array<double, 3>{1, 1, 1}).spacing(),
            (std::array<double, 3>{1.0, 1.0, 1.0}));
  // One volume: --volume 0 reads it, another is refused.
  EXPECT_EQ(progiso::read_volume(file, std::nullopt, std::nullopt, {.volume = 0}).dims(),
            (progiso::index3{5, 4, 3}));
  const std::string message = error_naming(
      file, [&] { (void)progiso::read_volume(file, std::nullopt, std::nullopt, {.volume = 1}); });
  EXPECT_TRUE(contains(message, "holds one volume (0)")) << message;
}

/// Writes `text` as STEM.vti in `dir` and expects the reader to refuse it with one line that
/// names the file and contains `what`.
void expect_refused(const scratch_dir& dir, const std::string& stem, const std::string& text,
                    const std::string& what) {
  const fs::path file = dir / (stem + ".vti");
  progiso::test::write_file(file, text);
  const std::string message = error_naming(file, [&] { (void)progiso::read_vti(file); });
  EXPECT_TRUE(contains(message, what)) << stem << ": " << message;
}

/// `text` with the first `from` replaced by `to` (which must be there).
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(VtiReader, refuses_hostile_documents_with_one_line_naming_the_file) {
  scratch_dir dir;
  vti_file f = file_of(progiso::test::vti_types[1], 7);
  const std::string good = f.text();
  const auto expect_error = [&](const std::string& stem, const std::string& text,
                                const std::string& what) { expect_refused(dir, stem, text, what); };
  expect_error("png", std::string("\x89PNG\r\n\x1a\n", 8), "not a VTK XML file");
  expect_error("root", "<?xml version=\"1.0\"?>\n<svg width=\"3\"/>\n", "found <svg>");
  expect_error("poly", replaced(good, "\"ImageData\" version", "\"PolyData\" version"),
               "\"PolyData\" is not supported");
  expect_error("pvti", replaced(good, "\"ImageData\" version", "\"PImageData\" version"),
               "give it the name .pvti");
  expect_error("version",
               replaced(good, "ImageData\" version=\"1.0\"", "ImageData\" version=\"7\""),
               "version");
  expect_error("order", replaced(good, "LittleEndian", "MiddleEndian"), "byte_order");
  expect_error("header", replaced(good, "UInt32\">", "UInt16\">"), "header_type");
  expect_error("lz4", replaced(good, "header_type", "compressor=\"vtkLZ4DataCompressor\" h"),
               "vtkLZ4DataCompressor is not supported");
  expect_error("twopieces",
               replaced(good, "  </ImageData>",
                        "  <Piece Extent=\"0 4 0 3 0 2\">"
                        "</Piece>\n  </ImageData>"),
               "more than one <Piece>");
  expect_error("pieceextent", replaced(good, "<Piece Extent=\"0 4", "<Piece Extent=\"1 4"),
               "not the WholeExtent");
  expect_error("image", replaced(replaced(good, "0 2\"", "0 0\""), "0 2\"", "0 0\""),
               "a 2-D image is not a volume");
  expect_error("big", replaced(replaced(good, "0 2\"", "0 40000\""), "0 2\"", "0 40000\""),
               "expected 2 to 32769");
  expect_error("extent", replaced(good, "WholeExtent=\"0 4", "WholeExtent=\"0 x"),
               "expected an integer");
  expect_error("spacing", replaced(good, "Spacing=\"0.5", "Spacing=\"nan"),
               "expected a finite number");
  expect_error("nesting", replaced(good, "    </CellData>", "    </PointData>"), "</PointData>");
  expect_error("cdata", replaced(good, "<CellData>", "<CellData><![CDATA[x]]>"), "CDATA");
  expect_error("ends", good.substr(0, good.find("<Piece") + 10), "ends inside the XML tag");
  expect_error("attr", replaced(good, "<Piece Extent=", "<Piece Extent "), "malformed attribute");
  std::string many;
  for (int k = 0; k < 300; ++k) many += " a" + std::to_string(k) + "=\"\"";
  expect_error("attributes", replaced(good, "<CellData>", "<CellData" + many + ">"),
               "has more than 256 attributes");
  expect_error("noarrays",
               replaced(replaced(good, "<DataArray type=\"Float32\"", "<Foo type=\"Float32\""),
                        "<DataArray type=\"UInt8\"", "<Foo type=\"UInt8\""),
               "no point data array");
  expect_error("scalars", replaced(good, "Scalars=\"density\"", "Scalars=\"pressure\""),
               "Scalars=\"pressure\"");
  expect_error("vector",
               replaced(good, "\"UInt8\" Name=\"density\" NumberOfComponents=\"1\"",
                        "\"UInt8\" Name=\"density\" NumberOfComponents=\"3\""),
               "expected 1 (a scalar volume)");
  expect_error("int64", replaced(good, "\"UInt8\"", "\"Int64\""), "\"Int64\", not supported");
  expect_error("format",
               replaced(good, "format=\"appended\" offset=\"244", "format=\"packed\" offset=\"244"),
               "expected ascii, binary or appended");
  expect_error("noappended", good.substr(0, good.find("  <AppendedData")) + "</VTKFile>\n",
               "has no <AppendedData>");
  expect_error("underscore", replaced(good, "   _", "   +"), "does not start with '_'");
  expect_error("offset", replaced(good, "offset=\"244\"", "offset=\"99999999\""),
               "past the end of the file");
  // A count in the header that is not the extent's (the array's data starts at byte 244 of
  // the appended data, after the decoy's 4 + 240).
  std::string count = good;
  const std::size_t appended_at = count.find("   _") + 4;
  ASSERT_EQ(count[appended_at + 244], '\x3c');
  count[appended_at + 244] = '\x3d';
  expect_error("count", count, "holds 61 bytes by its header, expected 60");
  expect_error("short", good.substr(0, good.size() - 70), "cannot hold the declared 60 bytes");

  f.how = vti_file::mode::binary;
  const std::string inline64 = f.text();
  expect_error("unclosed", inline64.substr(0, inline64.find("</VTKFile>")),
               "ends inside <VTKFile>");
  expect_error("base64", replaced(inline64, "\n        PAAAA", "\n        PA*AA"), "not base64");
  expect_error("padding", replaced(inline64, "\n        PAAAA", "\n        P=AAA"),
               "'=' inside a base64 group");
  f.zlib = true;
  const std::string packed = f.text();
  // Blocks whose sizes do not make the extent's bytes.
  expect_error("blocks",
               replaced(packed, "\n        AgAAACAAAAAcAAAA", "\n        AwAAACAAAAAcAAAA"),
               "do not make the expected 60 bytes");
  // A block that does not inflate: its compressed bytes broken.
  std::string broken = packed;
  const std::size_t data_at = broken.find("eJ", broken.find("Name=\"density\""));
  ASSERT_NE(data_at, std::string::npos);
  broken[data_at + 6] = broken[data_at + 6] == 'A' ? 'B' : 'A';
  expect_error("corrupt", broken, "corrupt compressed block");
}

TEST(VtiReader, a_pvti_assembles_its_pieces_in_every_mode_and_type) {
  scratch_dir dir;
  unsigned seed = 300;
  // VTK's pieces share a layer of points: x 2..4 and 4..6, then y and z cut the rest.
  const std::vector<std::array<int, 6>> pieces{
      {2, 4, -1, 2, 10, 12}, {4, 6, -1, 0, 10, 12}, {4, 6, 0, 2, 10, 11}, {4, 6, 0, 2, 11, 12}};
  for (const auto& t : progiso::test::vti_types) {
    for (int m = 0; m < 4; ++m) {
      vti_file whole = file_of(t, seed++);
      whole.extent = {2, 6, -1, 2, 10, 12};
      whole.samples = progiso::test::random_samples(t.type, whole.count(), seed);
      const fs::path file = write_pvti(dir.path(), "p" + std::to_string(seed), whole, pieces,
                                       static_cast<vti_file::mode>(m));
      SCOPED_TRACE(file.string());
      const progiso::volume v = progiso::read_volume(file, std::nullopt, std::nullopt);
      EXPECT_EQ(v.dims(), (progiso::index3{5, 4, 3}));
      EXPECT_EQ(v.type(), t.type);
      ASSERT_EQ(v.byte_size(), whole.samples.size());
      EXPECT_EQ(std::memcmp(v.bytes(), whole.samples.data(), whole.samples.size()), 0);
      // The extent's first point, as for a .vti.
      EXPECT_EQ(v.origin(), (std::array<double, 3>{-2.0, 2.5, 112.5}));
      const std::vector<fs::path> inputs = progiso::volume_input_files(file, std::nullopt);
      ASSERT_EQ(inputs.size(), 5u);
      EXPECT_EQ(inputs[0], file);
      EXPECT_EQ(inputs[4], dir / ("p" + std::to_string(seed) + "_3.vti"));
    }
  }
  EXPECT_TRUE(progiso::read_volume_world(dir / ("p" + std::to_string(seed) + ".pvti"), std::nullopt)
                  .has_value());
}

TEST(VtiReader, a_pvti_refuses_pieces_that_do_not_make_its_grid) {
  scratch_dir dir;
  vti_file whole = file_of(progiso::test::vti_types[1], 77);
  const std::vector<std::array<int, 6>> halves{{0, 2, 0, 3, 0, 2}, {2, 4, 0, 3, 0, 2}};
  // The message starts with the file at fault: the .pvti, or the piece's (then it names the
  // .pvti too).
  const auto refused = [&](const fs::path& file, const std::string& what,
                           const fs::path& at_fault = {}) {
    const std::string m = progiso::test::error_message_naming(
        at_fault.empty() ? file : at_fault,
        [&] { (void)progiso::read_volume(file, std::nullopt, std::nullopt); });
    EXPECT_TRUE(contains(m, what)) << file << ": " << m;
    if (!at_fault.empty()) {
      EXPECT_TRUE(contains(m, "named by " + file.string())) << m;
    }
  };
  const fs::path good = write_pvti(dir.path(), "good", whole, halves, vti_file::mode::binary);
  expect_samples_in(good, whole);
  EXPECT_EQ(progiso::read_pvti(good).dims(), (progiso::index3{5, 4, 3}));
  // A gap: x = 2 in no piece (the pieces still hold enough bytes between them: a third piece
  // repeats the first).
  const fs::path gap =
      write_pvti(dir.path(), "gap", whole,
                 {{0, 1, 0, 3, 0, 2}, {3, 4, 0, 3, 0, 2}, {0, 1, 0, 3, 0, 2}, {0, 1, 0, 3, 0, 2}},
                 vti_file::mode::ascii);
  refused(gap, "point (2, 0, 0) of the WholeExtent lies in no piece");
  refused(write_pvti(dir.path(), "few", whole, {{0, 2, 0, 3, 0, 2}}, vti_file::mode::binary),
          "fewer than the 60 of the WholeExtent");
  // A piece outside the grid, a piece whose file says another extent, a missing file.
  refused(write_pvti(dir.path(), "outside", whole, {{0, 2, 0, 3, 0, 2}, {2, 5, 0, 3, 0, 2}},
                     vti_file::mode::binary),
          "piece extent 2 5 0 3 0 2 does not lie in the WholeExtent 0 4 0 3 0 2");
  fs::path shifted = write_pvti(dir.path(), "shifted", whole, halves, vti_file::mode::binary);
  {
    std::string t = progiso::test::read_whole_file(shifted);
    t = replaced(t, "Extent=\"2 4 0 3 0 2\"", "Extent=\"2 4 0 3 0 1\"");
    progiso::test::write_file(shifted, t);
  }
  refused(shifted, "but the .pvti gives the piece the extent 2 4 0 3 0 1", dir / "shifted_1.vti");
  refused(write_pvti(dir.path(), "missing", whole, halves, vti_file::mode::binary,
                     "    <Piece Extent=\"0 1 0 1 0 1\" Source=\"nowhere.vti\"/>\n"),
          "piece 3 of 3 named by", dir / "nowhere.vti");
  // The array the .pvti names, of another type in a piece.
  fs::path typed = write_pvti(dir.path(), "typed", whole, halves, vti_file::mode::binary);
  {
    std::string t = progiso::test::read_whole_file(typed);
    t = replaced(t, "<PDataArray type=\"UInt8\"", "<PDataArray type=\"Int16\"");
    progiso::test::write_file(typed, t);
  }
  refused(typed, "but the .pvti declares it i16", dir / "typed_0.vti");
  // A .vti named .pvti and the other way round.
  const fs::path single = dir / "single.pvti";
  fs::copy_file(whole.write(dir.path(), "single"), single);
  refused(single, "name a single image .vti");
  const fs::path parallel = dir / "parallel.vti";
  fs::copy_file(good, parallel);
  refused(parallel, "give it the name .pvti");
}

TEST(VtiReader, refuses_declarations_beyond_the_file_without_allocating_them) {
  scratch_dir dir;
  const auto expect_error = [&](const std::string& stem, const std::string& text,
                                const std::string& what) { expect_refused(dir, stem, text, what); };
  // 32769³ doubles (2.8 · 10^14 bytes) declared in files of a few hundred bytes.
  const auto head = [](bool zlib) {
    return std::string(
               "<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" "
               "header_type=\"UInt64\"") +
           (zlib ? " compressor=\"vtkZLibDataCompressor\"" : "") +
           ">\n<ImageData WholeExtent=\"0 32768 0 32768 0 32768\">\n"
           "<Piece Extent=\"0 32768 0 32768 0 32768\"><PointData>"
           "<DataArray type=\"Float64\" Name=\"d\" format=\"appended\" offset=\"0\"/>"
           "</PointData></Piece></ImageData>\n<AppendedData encoding=\"raw\">_";
  };
  vti_file f;
  f.uint64_headers = true;
  const auto word = [&](std::uint64_t v) { return f.word(v); };
  const std::uint64_t bytes = std::uint64_t{32769} * 32769 * 32769 * 8;
  expect_error("plain", head(false) + word(bytes) + std::string(64, '\0'),
               "cannot hold the declared");
  // One block of all the bytes, compressed into 64: beyond deflate's ratio.
  expect_error("ratio",
               head(true) + word(1) + word(bytes) + word(0) + word(64) + std::string(64, 'x'),
               "cannot hold the declared");
  // 2^32 − 1 blocks that do not make the extent's bytes.
  expect_error("list",
               head(true) + word(0xffffffffu) + word(65536) + word(0) + std::string(16, 'x'),
               "do not make the expected");
  // Blocks that do, listed in a file that cannot list them.
  expect_error("table",
               head(true) + word((bytes + 65535) / 65536) + word(65536) + word(bytes % 65536) +
                   std::string(16, 'x'),
               "more than the file can list");
  // Compressed sizes beyond the file.
  expect_error("sizes",
               head(true) + word(1) + word(bytes) + word(0) + word(1u << 30) + std::string(16, 'x'),
               "more bytes than the file holds");
}

}  // namespace
