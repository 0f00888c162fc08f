// progiso's MetaImage reader against MetaIO, the format's own library (VTK's copy, vtkmetaio:
// built where scripts/install-deps.sh --peers installed VTK). Both read the same generated files
// (every element type, both byte orders, data after the header, in one file, a LIST or a
// pattern of slices, raw, zlib and ASCII, bytes skipped before the data or the data at the end,
// spacing, offset and direction cosines) and must agree on the sizes, every sample, the spacing,
// the origin and the index-to-space map (ITK's reading of TransformMatrix).
#include <progiso/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <vtkmetaio/metaImage.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <string>

#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"
#include "support/metaimage_files.hpp"
#include "support/scratch_dir.hpp"

namespace {

namespace fs = std::filesystem;
using progiso::test::metaimage_file;

void expect_agreement(const fs::path& header) {
  SCOPED_TRACE(header.string());
  vtkmetaio::MetaImage reference;
  ASSERT_TRUE(reference.Read(header.string().c_str(), true));
  // MetaIO reads binary data in the file's byte order; ITK then puts it in the host's, as
  // progiso does (ASCII values are read in the host's already).
  if (reference.BinaryData()) reference.ElementByteOrderFix();
  const progiso::volume v = progiso::read_metaimage(header);
  ASSERT_EQ(reference.NDims(), 3);
  for (int a = 0; a < 3; ++a)
    EXPECT_EQ(reference.DimSize(a), v.dims()[static_cast<std::size_t>(a)]);
  int bytes_per = 0;
  vtkmetaio::MET_SizeOfType(reference.ElementType(), &bytes_per);
  EXPECT_EQ(static_cast<std::size_t>(bytes_per), progiso::sample_size(v.type()));
  ASSERT_NE(reference.ElementData(), nullptr);
  EXPECT_EQ(std::memcmp(reference.ElementData(), v.bytes(), v.byte_size()), 0);
  const auto world = progiso::read_volume_world(header, std::nullopt);
  ASSERT_TRUE(world.has_value());
  const double* matrix = reference.TransformMatrix();
  for (std::size_t a = 0; a < 3; ++a) {
    const double s = reference.ElementSpacing()[a];
    EXPECT_DOUBLE_EQ(v.spacing()[a], std::abs(s));
    EXPECT_DOUBLE_EQ(v.origin()[a], reference.Position()[a]);
    EXPECT_DOUBLE_EQ(world->m[a][3], reference.Position()[a]);
    for (std::size_t i = 0; i < 3; ++i) {
      // ITK: row i of the matrix is the direction of index axis i.
      EXPECT_DOUBLE_EQ(world->m[a][i], matrix[i * 3 + a] * reference.ElementSpacing()[i]);
    }
  }
}

TEST(MetaImageVsMetaIO, agree_on_every_type_byte_order_layout_encoding_and_skip) {
  progiso::test::scratch_dir dir("progiso-metaio-test-");
  unsigned seed = 1;
  for (const auto& t : progiso::test::metaimage_types) {
    for (const auto where : {metaimage_file::layout::local, metaimage_file::layout::detached,
                             metaimage_file::layout::list, metaimage_file::layout::pattern}) {
      for (int encoding = 0; encoding < 3; ++encoding) {
        metaimage_file f = progiso::test::make_metaimage_file(t, 1, seed, where, encoding, "%02d");
        f.msb_by_element_key = (seed / 3) % 2 == 0;
        f.extra_fields =
            "ElementSpacing = 0.5 2 1.25\nOffset = -3 4.5 100\n"
            "TransformMatrix = 0 0 1 1 0 0 0 1 0\n";
        expect_agreement(f.write(dir.path(), "v" + std::to_string(seed++)));
      }
    }
  }
}

TEST(MetaImageVsMetaIO, agree_on_header_sizes_and_data_at_the_end_of_the_file) {
  progiso::test::scratch_dir dir("progiso-metaio-test-");
  const auto& t = progiso::test::metaimage_types[5];  // MET_INT
  unsigned seed = 200;
  const auto make = [&] {
    metaimage_file f;
    f.type_name = t.name;
    f.item = 4;
    f.samples = progiso::test::random_samples(t.type, 60, seed++);
    return f;
  };
  metaimage_file skip = make();
  skip.where = metaimage_file::layout::detached;
  skip.header_size = 33;
  skip.skipped = std::string(33, 's');
  expect_agreement(skip.write(dir.path(), "skip"));
  metaimage_file last = make();
  last.where = metaimage_file::layout::detached;
  last.header_size = -1;
  last.skipped = std::string(77, 'e');
  expect_agreement(last.write(dir.path(), "last"));
  metaimage_file local_last = make();
  local_last.header_size = -1;
  expect_agreement(local_last.write(dir.path(), "locallast"));
  metaimage_file local_at = make();
  local_at.header_size = 512;
  expect_agreement(local_at.write(dir.path(), "localat"));
}

TEST(MetaImageVsMetaIO, agree_on_every_volume_of_a_series_in_every_layout_and_encoding) {
  // NDims 4 (three volumes of 5 × 4 × 3): MetaIO reads the whole series, progiso one volume
  // at a time; volume k must be MetaIO's k-th block, with the same spacing and origin.
  progiso::test::scratch_dir dir("progiso-metaio-test-");
  unsigned seed = 300;
  for (const auto& t : {progiso::test::metaimage_types[2], progiso::test::metaimage_types[9]}) {
    for (const auto where : {metaimage_file::layout::local, metaimage_file::layout::detached,
                             metaimage_file::layout::list, metaimage_file::layout::pattern}) {
      for (int encoding = 0; encoding < 3; ++encoding) {
        metaimage_file f = progiso::test::make_metaimage_file(t, 3, seed, where, encoding, "%03d");
        f.extra_fields = "ElementSpacing = 0.5 2 1.25 7\nOffset = -3 4.5 100 2\n";
        const fs::path header = f.write(dir.path(), "s" + std::to_string(seed++));
        SCOPED_TRACE(header.string());
        vtkmetaio::MetaImage reference;
        ASSERT_TRUE(reference.Read(header.string().c_str(), true));
        if (reference.BinaryData()) reference.ElementByteOrderFix();
        ASSERT_EQ(reference.NDims(), 4);
        ASSERT_EQ(reference.DimSize(3), 3);
        const auto* data = static_cast<const std::byte*>(reference.ElementData());
        ASSERT_NE(data, nullptr);
        for (std::int64_t k = 0; k < 3; ++k) {
          const progiso::volume v = progiso::read_metaimage(header, {.volume = k});
          const std::size_t at = static_cast<std::size_t>(k) * v.byte_size();
          EXPECT_EQ(std::memcmp(data + at, v.bytes(), v.byte_size()), 0) << "volume " << k;
          for (std::size_t a = 0; a < 3; ++a) {
            EXPECT_DOUBLE_EQ(v.spacing()[a], reference.ElementSpacing()[a]);
            EXPECT_DOUBLE_EQ(v.origin()[a], reference.Position()[a]);
          }
        }
      }
    }
  }
}

}  // namespace
