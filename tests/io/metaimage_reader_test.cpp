// Tests for progiso's own MetaImage reader (io/detail/metaimage_reader.hpp, through
// read_metaimage(), read_volume(), read_volume_world() and volume_input_files()).
//
// Every sample read must equal the sample written: generated volumes of every element type, both
// byte orders (under either key), data after the header or in other files (one, a LIST, a
// pattern), raw, zlib-compressed and ASCII, with bytes to skip before the data or the data at
// the end of the file; the shared real volumes described by .mhd headers. The comparison with
// MetaIO itself (VTK's copy) is metaimage_metaio_test.cpp, built where VTK is installed.
//
// Hostile: headers that are not text, lack a required field, repeat a key, declare 2-D, 4-D,
// vector or 64-bit data, sizes out of range, data files that do not exist, are FIFOs or hold far
// less than declared (refused before allocating), corrupt compressed data. Each fails with one
// line naming the file.
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"
#include "support/metaimage_files.hpp"
#include "support/scratch_dir.hpp"
#include "support/test_data.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::sample_type;
using progiso::test::contains;
using progiso::test::metaimage_file;
using progiso::test::random_samples;
constexpr auto error_naming = [](const fs::path& file, auto&& f) {
  return progiso::test::error_message_naming(file, f);
};

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-metaimage-reader-test-") {}
};

metaimage_file file_of(const progiso::test::metaimage_type& t, unsigned seed) {
  metaimage_file f;
  f.type_name = t.name;
  f.item = progiso::sample_size(t.type);
  f.samples = random_samples(t.type, 60, seed);
  return f;
}

void expect_samples(const fs::path& header, const metaimage_file& f, sample_type type) {
  const progiso::volume v = progiso::read_metaimage(header);
  EXPECT_EQ(v.dims(), (progiso::index3{5, 4, 3})) << header;
  EXPECT_EQ(v.type(), type) << header;
  ASSERT_EQ(v.byte_size(), f.samples.size()) << header;
  EXPECT_EQ(std::memcmp(v.bytes(), f.samples.data(), f.samples.size()), 0) << header;
}

TEST(MetaImageReader, reads_every_type_in_both_byte_orders_after_the_header_or_in_a_data_file) {
  scratch_dir dir;
  unsigned seed = 1;
  for (const auto& t : progiso::test::metaimage_types) {
    for (const bool msb : {false, true}) {
      for (const auto where : {metaimage_file::layout::local, metaimage_file::layout::detached}) {
        metaimage_file f = file_of(t, seed);
        f.msb = msb;
        f.msb_by_element_key = seed % 2 == 0;
        f.where = where;
        expect_samples(f.write(dir.path(), "v" + std::to_string(seed)), f, t.type);
        ++seed;
      }
    }
  }
}

TEST(MetaImageReader, reads_zlib_compressed_and_ascii_data) {
  scratch_dir dir;
  unsigned seed = 100;
  for (const auto& t : progiso::test::metaimage_types) {
    for (const auto where : {metaimage_file::layout::local, metaimage_file::layout::detached,
                             metaimage_file::layout::list}) {
      metaimage_file z = file_of(t, seed++);
      z.compressed = true;
      z.msb = seed % 2 == 0;
      z.where = where;
      expect_samples(z.write(dir.path(), "z" + std::to_string(seed)), z, t.type);
      metaimage_file a = file_of(t, seed++);
      a.ascii = true;
      a.where = where;
      expect_samples(a.write(dir.path(), "a" + std::to_string(seed)), a, t.type);
    }
  }
}

TEST(MetaImageReader, header_size_skips_bytes_and_minus_one_takes_the_last_bytes_of_the_file) {
  scratch_dir dir;
  const auto& t = progiso::test::metaimage_types[3];  // MET_SHORT
  metaimage_file skip = file_of(t, 7);
  skip.where = metaimage_file::layout::detached;
  skip.header_size = 17;
  skip.skipped = std::string(17, 'h');
  expect_samples(skip.write(dir.path(), "skip"), skip, t.type);
  metaimage_file last = file_of(t, 8);
  last.where = metaimage_file::layout::detached;
  last.header_size = -1;
  last.skipped = std::string(1000, 'j');
  expect_samples(last.write(dir.path(), "last"), last, t.type);
  metaimage_file last_local = file_of(t, 9);
  last_local.header_size = -1;
  expect_samples(last_local.write(dir.path(), "lastlocal"), last_local, t.type);
  // LOCAL data with a HeaderSize starts that many bytes from the start of the file.
  metaimage_file at = file_of(t, 10);
  at.header_size = 400;
  expect_samples(at.write(dir.path(), "at"), at, t.type);
  // Per slice file: each file of a LIST skips its own bytes.
  metaimage_file slices = file_of(t, 11);
  slices.where = metaimage_file::layout::list;
  slices.header_size = 5;
  slices.skipped = "hdr5:";
  expect_samples(slices.write(dir.path(), "slices"), slices, t.type);
}

TEST(MetaImageReader, reads_one_slice_per_file_from_a_list_or_a_numbered_pattern) {
  scratch_dir dir;
  const auto& t = progiso::test::metaimage_types[8];  // MET_FLOAT
  for (const char* digits : {"%d", "%03d", "%1d"}) {
    metaimage_file f = file_of(t, 20);
    f.where = metaimage_file::layout::pattern;
    f.pattern_digits = digits;
    const fs::path header = f.write(dir.path(), std::string("p") + (digits + 1));
    expect_samples(header, f, t.type);
    const std::vector<fs::path> files = progiso::volume_input_files(header, std::nullopt);
    ASSERT_EQ(files.size(), 4u);
    EXPECT_EQ(files[0], header);
    EXPECT_TRUE(fs::exists(files[3])) << files[3];
  }
  metaimage_file list = file_of(t, 21);
  list.where = metaimage_file::layout::list;
  const fs::path header = list.write(dir.path(), "list");
  expect_samples(header, list, t.type);
  EXPECT_EQ(progiso::volume_input_files(header, std::nullopt).size(), 4u);

  // A pattern counting down reads the files in that order, and "LIST 3D" splits the volume
  // into equal slabs.
  const std::string slice_bytes = list.payload_bytes(0, 20);
  const std::string slice2 = list.payload_bytes(20, 20);
  const std::string slice3 = list.payload_bytes(40, 20);
  progiso::test::write_file(dir / "down_3.raw", slice_bytes);
  progiso::test::write_file(dir / "down_2.raw", slice2);
  progiso::test::write_file(dir / "down_1.raw", slice3);
  progiso::test::write_file(dir / "down.mhd",
                            "NDims = 3\nDimSize = 5 4 3\nElementType = MET_FLOAT\n"
                            "ElementDataFile = down_%d.raw 3 1 -1\n");
  expect_samples(dir / "down.mhd", list, t.type);
  progiso::test::write_file(dir / "slab.raw", slice_bytes + slice2 + slice3);
  progiso::test::write_file(dir / "slab.mhd",
                            "NDims = 3\nDimSize = 5 4 3\nElementType = MET_FLOAT\n"
                            "ElementDataFile = LIST 3D\nslab.raw\n");
  expect_samples(dir / "slab.mhd", list, t.type);
}

TEST(MetaImageReader, spacing_origin_and_orientation_are_read_as_itk_reads_them) {
  scratch_dir dir;
  metaimage_file f = file_of(progiso::test::metaimage_types[0], 30);
  f.extra_fields =
      "ElementSpacing = 0.5 -2 3\nOffset = -10.5 20.25 3\n"
      "TransformMatrix = 0 1 0 -1 0 0 0 0 1\nAnatomicalOrientation = RAI\n"
      "CenterOfRotation = 0 0 0\nComment = ignored keys are ignored\n";
  const fs::path header = f.write(dir.path(), "oriented");
  const progiso::volume v = progiso::read_metaimage(header);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2.0, 3.0}));
  EXPECT_EQ(v.origin(), (std::array<double, 3>{-10.5, 20.25, 3.0}));
  // Row i of TransformMatrix is the direction of index axis i, scaled by its spacing.
  const auto world = progiso::read_volume_world(header, std::nullopt);
  ASSERT_TRUE(world.has_value());
  const std::array<double, 3> p = world->apply({1.0, 1.0, 1.0});
  // x axis: 0.5 × (0, 1, 0); y axis: -2 × (-1, 0, 0); z axis: 3 × (0, 0, 1).
  EXPECT_DOUBLE_EQ(p[0], -10.5 + 2.0);
  EXPECT_DOUBLE_EQ(p[1], 20.25 + 0.5);
  EXPECT_DOUBLE_EQ(p[2], 3.0 + 3.0);
  EXPECT_DOUBLE_EQ(world->determinant(), -3.0);  // the axes x and y swapped: a mirror

  // Position and Origin are Offset's synonyms; ElementSize stands in for a missing spacing; a
  // header without a matrix maps index to origin + index × spacing.
  for (const char* key : {"Position", "Origin"}) {
    metaimage_file g = file_of(progiso::test::metaimage_types[0], 31);
    g.extra_fields = std::string(key) + " = 1 2 3\nElementSize = 4 5 6\n";
    const fs::path h = g.write(dir.path(), key);
    const progiso::volume w = progiso::read_metaimage(h);
    EXPECT_EQ(w.origin(), (std::array<double, 3>{1.0, 2.0, 3.0})) << key;
    EXPECT_EQ(w.spacing(), (std::array<double, 3>{4.0, 5.0, 6.0})) << key;
    const auto m = progiso::read_volume_world(h, std::nullopt);
    ASSERT_TRUE(m.has_value());
    EXPECT_EQ(m->apply({1.0, 2.0, 3.0}), (std::array<double, 3>{5.0, 12.0, 21.0})) << key;
  }
}

TEST(MetaImageReader, read_volume_picks_metaimage_by_name_in_any_case_and_a_given_spacing_wins) {
  scratch_dir dir;
  metaimage_file f = file_of(progiso::test::metaimage_types[2], 40);
  f.extra_fields = "ElementSpacing = 2 2 2\n";
  const fs::path mha = f.write(dir.path(), "UPPER");
  const fs::path upper = dir / "UPPER.MHA";
  fs::rename(mha, upper);
  const progiso::volume v = progiso::read_volume(upper, std::nullopt, std::nullopt);
  EXPECT_EQ(v.spacing(), (std::array<double, 3>{2.0, 2.0, 2.0}));
  const progiso::volume w =
      progiso::read_volume(upper, std::nullopt, std::array<double, 3>{1.0, 1.5, 3.0});
  EXPECT_EQ(w.spacing(), (std::array<double, 3>{1.0, 1.5, 3.0}));
  EXPECT_EQ(std::memcmp(w.bytes(), f.samples.data(), f.samples.size()), 0);
}

TEST(MetaImageReader, the_shared_volumes_described_by_mhd_headers_equal_their_raw_files) {
  const auto data = progiso::test::shared_data_dir();
  if (!data) GTEST_SKIP() << "shared data not found";
  scratch_dir dir;
  struct shared {
    const char* file;
    progiso::index3 dims;
    const char* type;
    progiso::raw_layout raw;
  };
  const std::array<shared, 2> volumes{{
      {"headsq_64x64x93_int16le.raw", {64, 64, 93}, "MET_SHORT", {{64, 64, 93}, sample_type::i16}},
      {"brainsmall_128x128x84_uint8.raw",
       {128, 128, 84},
       "MET_UCHAR",
       {{128, 128, 84}, sample_type::u8}},
  }};
  for (const shared& s : volumes) {
    const fs::path header = dir / (std::string(s.file) + ".mhd");
    progiso::test::write_file(
        header, "ObjectType = Image\nNDims = 3\nDimSize = " + std::to_string(s.dims[0]) + " " +
                    std::to_string(s.dims[1]) + " " + std::to_string(s.dims[2]) +
                    "\nElementType = " + s.type +
                    "\nElementDataFile = " + (*data / s.file).string() + "\n");
    const progiso::volume a = progiso::read_volume(header, std::nullopt, std::nullopt);
    const progiso::volume b = progiso::read_raw(*data / s.file, s.raw);
    ASSERT_EQ(a.byte_size(), b.byte_size()) << s.file;
    EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.byte_size()), 0) << s.file;
  }
}

TEST(MetaImageReader, reads_the_chosen_volume_of_a_series_in_every_layout_and_encoding) {
  // NDims 4, DimSize 5 4 3 3: three volumes after the header, in one data file, a LIST or a
  // pattern of one file per volume (MetaIO's default piece for NDims 4), raw, zlib and ASCII,
  // both byte orders: volume k is the k-th block of 60 samples; the skipped volumes are sought
  // over, inflated or parsed and dropped.
  scratch_dir dir;
  unsigned seed = 400;
  for (const auto& t : {progiso::test::metaimage_types[3], progiso::test::metaimage_types[8]}) {
    for (const auto where : {metaimage_file::layout::local, metaimage_file::layout::detached,
                             metaimage_file::layout::list, metaimage_file::layout::pattern}) {
      for (int encoding = 0; encoding < 3; ++encoding) {
        metaimage_file f = progiso::test::make_metaimage_file(t, 3, seed, where, encoding, "%d");
        f.extra_fields = "ElementSpacing = 0.5 2 1.25 10\nOffset = -3 4.5 100 0\n";
        const fs::path header = f.write(dir.path(), "s" + std::to_string(seed++));
        for (std::int64_t k = 0; k < 3; ++k) {
          const progiso::volume v = progiso::read_metaimage(header, {.volume = k});
          ASSERT_EQ(v.dims(), (progiso::index3{5, 4, 3})) << header;
          ASSERT_EQ(v.byte_size(), 60 * f.item) << header;
          EXPECT_EQ(
              std::memcmp(v.bytes(), f.samples.data() + static_cast<std::size_t>(k) * 60 * f.item,
                          v.byte_size()),
              0)
              << header << " volume " << k;
          EXPECT_EQ(v.spacing(), (std::array<double, 3>{0.5, 2, 1.25})) << header;
          EXPECT_EQ(v.origin(), (std::array<double, 3>{-3, 4.5, 100})) << header;
        }
        const std::size_t files = where == metaimage_file::layout::local
                                      ? 1
                                      : (where == metaimage_file::layout::detached ? 2 : 4);
        EXPECT_EQ(progiso::volume_input_files(header, std::nullopt, {.volume = 1}).size(), files)
            << header;
        EXPECT_TRUE(progiso::read_volume_world(header, std::nullopt, {.volume = 2}).has_value());
      }
    }
  }
  // LIST 2D: a file per slice of every volume, nine in all; volume 1 is files 3 to 5.
  std::string h =
      "NDims = 4\nDimSize = 5 4 3 3\nElementType = MET_UCHAR\nElementDataFile = LIST 2D\n";
  std::string all;
  for (int i = 0; i < 9; ++i) {
    const std::string name = "slice" + std::to_string(i) + ".raw";
    const std::string bytes(20, static_cast<char>(10 + i));
    progiso::test::write_file(dir / name, bytes);
    h += name + "\n";
    all += bytes;
  }
  progiso::test::write_file(dir / "slices.mhd", h);
  const progiso::volume v = progiso::read_metaimage(dir / "slices.mhd", {.volume = 1});
  EXPECT_EQ(std::memcmp(v.bytes(), all.data() + 60, 60), 0);
  // A LIST of one slice per file for a series must name every slice of every volume.
  progiso::test::write_file(dir / "few.mhd",
                            "NDims = 4\nDimSize = 5 4 3 3\nElementType = MET_UCHAR\n"
                            "ElementDataFile = LIST 2D\nslice0.raw\nslice1.raw\nslice2.raw\n");
  const std::string m = error_naming(
      dir / "few.mhd", [&] { (void)progiso::read_metaimage(dir / "few.mhd", {.volume = 0}); });
  EXPECT_TRUE(contains(m, "names 3 files of one slice each")) << m;
}

TEST(MetaImageReader, a_series_needs_a_volume_that_exists_and_data_that_holds_every_volume) {
  scratch_dir dir;
  metaimage_file f = file_of(progiso::test::metaimage_types[0], 500);
  f.volumes = 4;
  f.samples = random_samples(sample_type::u8, 240, 500);
  f.where = metaimage_file::layout::detached;
  const fs::path header = f.write(dir.path(), "series");
  const auto message = [&](const fs::path& named, const progiso::volume_choice& choice) {
    return error_naming(
        named, [&] { (void)progiso::read_volume(header, std::nullopt, std::nullopt, choice); });
  };
  std::string m = message(header, {});
  EXPECT_TRUE(contains(m, "a time series of 4 volumes (DimSize[3] = 4)")) << m;
  m = message(header, {.volume = 4});
  EXPECT_TRUE(contains(m, "volume 4 was chosen, but the input is a time series of 4 volumes")) << m;
  // One byte short of the fourth volume: refused whichever volume is asked for.
  const std::string whole = progiso::test::read_whole_file(dir / "series.raw");
  progiso::test::write_file(dir / "series.raw", whole.substr(0, whole.size() - 1));
  m = message(dir / "series.raw", {.volume = 0});
  EXPECT_TRUE(contains(m, "cannot hold")) << m;
  // 2^31 − 1 volumes of 32769³ doubles: refused from the sizes.
  progiso::test::write_file(dir / "huge.mha",
                            "NDims = 4\nDimSize = 32769 32769 32769 2147483647\n"
                            "ElementType = MET_DOUBLE\nElementDataFile = LOCAL\n12345678");
  m = error_naming(dir / "huge.mha",
                   [&] { (void)progiso::read_metaimage(dir / "huge.mha", {.volume = 3}); });
  EXPECT_TRUE(contains(m, "pass 2^64 bytes")) << m;
}

TEST(MetaImageReader, refuses_hostile_headers_with_one_line_naming_the_file) {
  scratch_dir dir;
  const std::string good = "NDims = 3\nDimSize = 5 4 3\nElementType = MET_UCHAR\n";
  const std::string data(60, '\x07');
  const auto expect_error = [&](const std::string& stem, const std::string& text,
                                const std::string& what) {
    const fs::path file = dir / (stem + ".mha");
    progiso::test::write_file(file, text);
    const std::string message = error_naming(file, [&] { (void)progiso::read_metaimage(file); });
    EXPECT_TRUE(contains(message, what)) << stem << ": " << message;
  };
  expect_error("binary", std::string("\x89PNG\r\n\x1a\n", 8) + data, "not a MetaImage header");
  expect_error("noeq", good + "DimSize 5 4 3\nElementDataFile = LOCAL\n" + data,
               "expected \"Key = Value\" on MetaImage header line 4");
  expect_error("nodatafile", good, "without an ElementDataFile");
  expect_error("nondims", "DimSize = 5 4 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "no MetaImage NDims");
  expect_error("notype", "NDims = 3\nDimSize = 5 4 3\nElementDataFile = LOCAL\n",
               "no MetaImage ElementType");
  expect_error("twod",
               "NDims = 2\nDimSize = 5 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "a 2-D image");
  expect_error("series",
               "NDims = 4\nDimSize = 5 4 3 7\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                   std::string(420, '\1'),
               "a time series of 7 volumes (DimSize[3] = 7): choose one by its index, 0 to 6");
  expect_error("ndims5",
               "NDims = 5\nDimSize = 5 4 3 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "axis 4 2 samples");
  expect_error("volumes",
               "NDims = 4\nDimSize = 5 4 3 2147483648\nElementType = MET_UCHAR\n"
               "ElementDataFile = LOCAL\n",
               "at most 2147483647");
  expect_error("count",
               "NDims = 3\nDimSize = 5 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "has 2 sizes");
  expect_error("small",
               "NDims = 3\nDimSize = 5 1 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "axis 1 1 samples");
  expect_error("big",
               "NDims = 3\nDimSize = 5 4 40000\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
               "expected 2 to 32769");
  expect_error("vector",
               "NDims = 3\nDimSize = 5 4 3\nElementType = MET_FLOAT_ARRAY\n"
               "ElementDataFile = LOCAL\n",
               "MET_FLOAT_ARRAY");
  expect_error("long64",
               "NDims = 3\nDimSize = 5 4 3\nElementType = MET_LONG_LONG\n"
               "ElementDataFile = LOCAL\n",
               "not supported");
  expect_error("channels", good + "ElementNumberOfChannels = 3\nElementDataFile = LOCAL\n" + data,
               "a scalar volume");
  expect_error("twice", good + "Offset = 0 0 0\nPosition = 1 1 1\nElementDataFile = LOCAL\n" + data,
               "repeats Offset");
  expect_error("bool", good + "ElementByteOrderMSB = Maybe\nElementDataFile = LOCAL\n" + data,
               "expected True or False");
  expect_error("nan", good + "ElementSpacing = 1 nan 1\nElementDataFile = LOCAL\n" + data,
               "expected a finite number");
  expect_error("tube", "ObjectType = Tube\n" + good + "ElementDataFile = LOCAL\n" + data,
               "only Image objects");
  expect_error("zskip", good + "CompressedData = True\nHeaderSize = 10\nElementDataFile = LOCAL\n",
               "not supported");
  expect_error("asciiz",
               good + "BinaryData = False\nCompressedData = True\nElementDataFile = LOCAL\n",
               "ASCII data is not compressed");
  expect_error("skipneg", good + "HeaderSize = -2\nElementDataFile = LOCAL\n" + data,
               "expected -1 or a byte count");
  expect_error("listcount", good + "ElementDataFile = LIST\na.raw\nb.raw\n",
               "names 2 files of one slice each");
  expect_error("listempty", good + "ElementDataFile = LIST\n", "followed by no file names");
  expect_error("listdim", good + "ElementDataFile = LIST 4D\na.raw\n", "expected 2D or 3D");
  expect_error("conversion", good + "ElementDataFile = s%s.raw 1 3 1\n", "unsupported conversion");
  expect_error("step", good + "ElementDataFile = s%d.raw 1 3 -1\n", "does not reach the last");
  expect_error("pieces", good + "ElementDataFile = s%d.raw 1 5 1\n", "names 5 files");
  expect_error("longline", good + "Comment = " + std::string((1u << 20) + 10, 'c') + "\n",
               "longer than");
  expect_error("nul", good + std::string("Comment = a\0b\n", 14), "NUL byte");
}

TEST(MetaImageReader, refuses_short_and_corrupt_data_without_allocating_the_declared_size) {
  scratch_dir dir;
  const auto expect_error = [&](const fs::path& named, const fs::path& header,
                                const std::string& what) {
    const std::string message = error_naming(named, [&] { (void)progiso::read_metaimage(header); });
    EXPECT_TRUE(contains(message, what)) << header << ": " << message;
  };
  // 32769³ doubles (281 TB) declared over a few bytes: refused from the sizes, plain and zlib.
  const std::string huge = "NDims = 3\nDimSize = 32769 32769 32769\nElementType = MET_DOUBLE\n";
  progiso::test::write_file(dir / "huge.mha", huge + "ElementDataFile = LOCAL\n" + "12345678");
  expect_error(dir / "huge.mha", dir / "huge.mha", "cannot hold");
  progiso::test::write_file(dir / "hugez.mha", huge + "CompressedData = True\n" +
                                                   "ElementDataFile = LOCAL\n" +
                                                   progiso::test::gzip("12345678", 6, true));
  expect_error(dir / "hugez.mha", dir / "hugez.mha", "zlib expands at most");
  // One byte short, a truncated and a corrupt zlib stream, a missing data file, a FIFO.
  metaimage_file f = file_of(progiso::test::metaimage_types[4], 50);
  f.where = metaimage_file::layout::detached;
  const fs::path header = f.write(dir.path(), "short");
  const std::string whole = progiso::test::read_whole_file(dir / "short.raw");
  progiso::test::write_file(dir / "short.raw", whole.substr(0, whole.size() - 1));
  expect_error(dir / "short.raw", header, "cannot hold");
  f.compressed = true;
  const fs::path zheader = f.write(dir.path(), "cut");
  const std::string z = progiso::test::read_whole_file(dir / "cut.raw");
  progiso::test::write_file(dir / "cut.raw", z.substr(0, z.size() / 2));
  expect_error(dir / "cut.raw", zheader, "MetaImage data ends");
  std::string corrupt = z;
  for (std::size_t i = 4; i < corrupt.size() - 4; i += 3)
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5a);
  progiso::test::write_file(dir / "cut.raw", corrupt);
  expect_error(dir / "cut.raw", zheader, "corrupt MetaImage zlib data");
  progiso::test::write_file(dir / "missing.mhd",
                            "NDims = 3\nDimSize = 5 4 3\nElementType = MET_UCHAR\n"
                            "ElementDataFile = nowhere.raw\n");
  expect_error(dir / "nowhere.raw", dir / "missing.mhd", "cannot open");
  ASSERT_EQ(mkfifo((dir / "pipe.raw").c_str(), 0600), 0);
  progiso::test::write_file(dir / "pipe.mhd",
                            "NDims = 3\nDimSize = 5 4 3\nElementType = MET_UCHAR\n"
                            "ElementDataFile = pipe.raw\n");
  expect_error(dir / "pipe.raw", dir / "pipe.mhd", "FIFO");
}

}  // namespace
