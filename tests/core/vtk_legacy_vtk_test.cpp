// progiso's legacy VTK reader against VTK's own (vtkStructuredPointsReader, built where
// scripts/install-deps.sh --peers installed VTK): both read the same generated files (every data
// type, binary and ASCII, SCALARS and FIELD arrays, keywords in either case, SPACING and
// ASPECT_RATIO) and must agree on the sizes, every sample, the spacing and the origin.
#include <progiso/core/io/volume_io.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

#include <progiso/core/field/volume.hpp>

#include "support/scratch_dir.hpp"
#include "support/vtk_legacy_files.hpp"
#include "support/vtk_legacy_reference.hpp"

namespace {

TEST(VtkLegacyVsVtk, agree_on_every_type_encoding_attribute_and_keyword_case) {
  progiso::test::scratch_dir dir("progiso-vtk-legacy-vtk-test-");
  unsigned seed = 1;
  for (const auto& t : progiso::test::vtk_types) {
    for (int variant = 0; variant < 8; ++variant) {
      progiso::test::vtk_legacy_file f;
      f.type_name = t.name;
      f.type = t.type;
      f.samples = progiso::test::random_samples(t.type, 60, seed);
      f.ascii = (variant & 1) != 0;
      f.upper_case = (variant & 2) == 0;
      f.as_field = (variant & 4) != 0;
      f.aspect_ratio = variant == 3;
      f.spacing = "0.5 2 1.25";
      f.origin = "-3 4.5 100";
      const std::filesystem::path file = f.write(dir.path(), "v" + std::to_string(seed++));
      SCOPED_TRACE(file.string());
      const progiso::test::vtk_reference_volume ref = progiso::test::read_with_vtk(file.string());
      ASSERT_TRUE(ref.ok);
      const progiso::volume v = progiso::read_vtk_legacy(file);
      for (std::size_t a = 0; a < 3; ++a) {
        EXPECT_EQ(ref.dims[a], v.dims()[a]);
        EXPECT_DOUBLE_EQ(std::abs(ref.spacing[a]), v.spacing()[a]);
        EXPECT_DOUBLE_EQ(ref.origin[a], v.origin()[a]);
      }
      EXPECT_EQ(ref.components, 1);
      EXPECT_EQ(ref.sample_bytes, progiso::sample_size(v.type()));
      ASSERT_EQ(ref.samples.size(), v.byte_size());
      EXPECT_EQ(std::memcmp(ref.samples.data(), v.bytes(), v.byte_size()), 0);
    }
  }
}

}  // namespace
