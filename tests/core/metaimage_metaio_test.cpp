// progiso's MetaImage reader against MetaIO, the format's own library (VTK's copy, vtkmetaio:
// built where scripts/install-deps.sh --peers installed VTK). Both read the same generated files
// (every element type, both byte orders, data after the header, in one file, a LIST or a
// pattern of slices, raw, zlib and ASCII, bytes skipped before the data or the data at the end,
// spacing, offset and direction cosines) and must agree on the sizes, every sample, the spacing,
// the origin and the index-to-space map (ITK's reading of TransformMatrix).
#include <progiso/core/io/volume_io.hpp>

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
        metaimage_file f;
        f.type_name = t.name;
        f.item = progiso::sample_size(t.type);
        f.samples = progiso::test::random_samples(t.type, 60, seed);
        f.where = where;
        f.pattern_digits = "%02d";
        f.msb = seed % 2 == 0;
        f.msb_by_element_key = (seed / 3) % 2 == 0;
        f.compressed = encoding == 1;
        f.ascii = encoding == 2;
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

}  // namespace
