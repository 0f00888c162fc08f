// Invariant 1 (docs/ARCHITECTURE.md): the fully refined progressive surface equals plain marching
// tetrahedra on the finest mesh (the independent reference in tests/support), triangle for triangle
// and vertex for vertex, on analytic fields and on every shared volume at its suggested isovalues.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

void expect_full_equals_reference(const volume& v, double w, refine_order order) {
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  refiner r(v, h, ranges, w, order);
  r.refine_full();
  EXPECT_TRUE(r.done());
  const triangle_mesh mine = r.extract();
  const test::reference_surface ref = test::reference_marching_tetrahedra(v, w);
  EXPECT_EQ(mine.triangles.size(), ref.mesh.triangles.size());
  EXPECT_EQ(mine.vertices.size(), ref.mesh.vertices.size());
  EXPECT_EQ(test::euler_characteristic(mine), test::euler_characteristic(ref.mesh));
  EXPECT_TRUE(test::same_surface(mine, ref.mesh));
}

TEST(FullResolution, sphere_in_power_of_two_plus_one_grid_equals_reference) {
  const volume v = make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1});
  expect_full_equals_reference(v, 11.0, refine_order::breadth_first);
}

TEST(FullResolution, sphere_in_odd_sized_grid_equals_reference_in_both_orders) {
  const volume v = make_sphere_field({30, 37, 23}, {14.2, 18.7, 11.1});
  expect_full_equals_reference(v, 9.5, refine_order::breadth_first);
  expect_full_equals_reference(v, 9.5, refine_order::largest_error_first);
}

TEST(FullResolution, surface_cut_by_the_data_box_equals_reference) {
  // The sphere leaves the box on three sides: open surface, clipped pieces at coarse levels.
  const volume v = make_sphere_field({26, 21, 19}, {24.0, 2.0, 17.5});
  expect_full_equals_reference(v, 12.0, refine_order::breadth_first);
}

TEST(FullResolution, torus_gyroid_marschner_lobb_and_blobs_equal_reference) {
  expect_full_equals_reference(make_torus_field({40, 40, 24}, {19.5, 20.2, 11.7}, 12.0), 4.0,
                               refine_order::breadth_first);
  expect_full_equals_reference(make_gyroid_field({35, 29, 33}, 11.0), 0.2,
                               refine_order::largest_error_first);
  expect_full_equals_reference(make_marschner_lobb({41, 41, 41}), 0.5, refine_order::breadth_first);
  expect_full_equals_reference(make_gaussian_blobs({45, 38, 52}, 12, 7u), 0.35,
                               refine_order::breadth_first);
}

TEST(FullResolution, integer_samples_equal_to_the_isovalue_equal_reference) {
  // u8 data with many samples exactly at w: the clamped interpolation keeps vertices apart.
  const index3 dims{19, 17, 21};
  std::vector<std::byte> bytes(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]));
  for (std::int64_t z = 0; z < dims[2]; ++z)
    for (std::int64_t y = 0; y < dims[1]; ++y)
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        bytes[static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z))] =
            static_cast<std::byte>(((x * 7 + y * 3 + z * 5) % 11) * 10);
      }
  const volume v(dims, sample_type::u8, std::move(bytes));
  expect_full_equals_reference(v, 50.0, refine_order::breadth_first);
  EXPECT_TRUE(test::no_degenerate_triangles(test::reference_marching_tetrahedra(v, 50.0).mesh));
}

TEST(FullResolution, every_shared_volume_at_its_suggested_isovalues_equals_reference) {
  const auto dir = test::shared_data_dir();
  if (!dir)
    GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR); analytic tests still ran";
  for (const auto& info : test::shared_volumes()) {
    const volume v = test::load_shared_volume(info, *dir);
    for (const double w : info.isovalues) {
      SCOPED_TRACE(std::string(info.name) + " at " + std::to_string(w));
      expect_full_equals_reference(v, w, refine_order::breadth_first);
    }
  }
}

}  // namespace
}  // namespace progiso
