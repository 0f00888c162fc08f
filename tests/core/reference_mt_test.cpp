// The reference extractor (test oracle): the surfaces it produces on analytic fields have the
// topology and orientation the field dictates, one vertex per crossed edge of the finest mesh,
// and pass every validity check; on the shared real volumes (when present) too.
#include <support/reference_mt.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <support/mesh_checks.hpp>
#include <support/test_data.hpp>

namespace progiso::test {
namespace {

using point = std::array<std::int64_t, 3>;

std::uint64_t doubled_midpoint_key(const point& a, const point& b) {
  return static_cast<std::uint64_t>(a[0] + b[0]) | static_cast<std::uint64_t>(a[1] + b[1]) << 21 |
         static_cast<std::uint64_t>(a[2] + b[2]) << 42;
}

// The crossed edges of the finest mesh, enumerated from its description rather than from its
// tetrahedra: every unit edge, and in every unit square and unit cube the one diagonal that
// joins the corner that is even on all of the cell's axes to the corner that is odd on them.
std::set<std::uint64_t> crossed_finest_edges(const volume& v, double w) {
  std::set<std::uint64_t> keys;
  const index3& n = v.dims();
  for (unsigned axes = 1; axes < 8; ++axes) {  // the axes the cell spans
    point hi{};
    for (std::size_t q = 0; q < 3; ++q) hi[q] = (axes >> q & 1u) != 0 ? n[q] - 1 : n[q];
    for (std::int64_t k = 0; k < hi[2]; ++k) {
      for (std::int64_t j = 0; j < hi[1]; ++j) {
        for (std::int64_t i = 0; i < hi[0]; ++i) {
          point even{i, j, k};
          point odd{i, j, k};
          for (std::size_t q = 0; q < 3; ++q) {
            if ((axes >> q & 1u) == 0) continue;
            (even[q] % 2 == 0 ? odd[q] : even[q]) += 1;
          }
          const bool be = v.value(even[0], even[1], even[2]) > w;
          const bool bo = v.value(odd[0], odd[1], odd[2]) > w;
          if (be != bo) keys.insert(doubled_midpoint_key(even, odd));
        }
      }
    }
  }
  return keys;
}

bool is_integral(double x) { return std::floor(x) == x; }

TEST(ReferenceMt, sphere_is_closed_genus_zero_and_a_valid_surface) {
  const volume v = make_sphere_field({20, 20, 20}, {9.3, 9.6, 10.1});
  const reference_surface s = reference_marching_tetrahedra(v, 6.2);
  ASSERT_FALSE(s.mesh.empty());
  const auto [lo, hi] = data_box(v);
  EXPECT_TRUE(check_valid_cut(s.mesh, lo, hi));
  EXPECT_TRUE(watertight(s.mesh)) << watertight(s.mesh).message;
  EXPECT_EQ(euler_characteristic(s.mesh), 2);
  EXPECT_EQ(connected_components(s.mesh), 1u);
}

// Normals point from black (f > w) to white (f <= w). For a distance field the inside is white,
// so a sphere's normals point inward and its signed volume is negative.
TEST(ReferenceMt, sphere_normals_point_inward_toward_decreasing_values) {
  const double r = 6.2;
  const volume v = make_sphere_field({20, 20, 20}, {9.3, 9.6, 10.1});
  const reference_surface s = reference_marching_tetrahedra(v, r);
  const double ball = 4.0 / 3.0 * std::numbers::pi * r * r * r;
  EXPECT_LT(signed_volume(s.mesh), 0.0);
  EXPECT_NEAR(-signed_volume(s.mesh), ball, 0.03 * ball);
}

TEST(ReferenceMt, one_vertex_per_crossed_edge_of_the_finest_mesh) {
  const volume fields[] = {make_sphere_field({13, 14, 15}, {6.2, 6.9, 7.3}),
                           make_gaussian_blobs({17, 12, 19}, 5, 7)};
  const double isovalues[] = {4.4, 0.35};
  for (int f = 0; f < 2; ++f) {
    const reference_surface s = reference_marching_tetrahedra(fields[f], isovalues[f]);
    const std::set<std::uint64_t> expected = crossed_finest_edges(fields[f], isovalues[f]);
    ASSERT_EQ(s.vertex_keys.size(), s.mesh.vertices.size());
    const std::set<std::uint64_t> keys(s.vertex_keys.begin(), s.vertex_keys.end());
    EXPECT_EQ(keys.size(), s.vertex_keys.size()) << "an edge has two vertices";
    EXPECT_EQ(keys, expected) << "field " << f;
    EXPECT_EQ(s.mesh.triangles.size(), reference_triangle_count(fields[f], isovalues[f]));
  }
}

// Each vertex lies on the edge its key names, at the canonical interpolation of its ends.
TEST(ReferenceMt, vertices_are_interpolated_on_their_own_edge) {
  const volume v = make_gaussian_blobs({15, 16, 17}, 4, 99);
  const double w = 0.4;
  const reference_surface s = reference_marching_tetrahedra(v, w);
  ASSERT_FALSE(s.mesh.empty());
  for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) {
    const std::uint64_t key = s.vertex_keys[i];
    constexpr std::uint64_t mask = (std::uint64_t{1} << 21) - 1;
    const point m{static_cast<std::int64_t>(key & mask),
                  static_cast<std::int64_t>((key >> 21) & mask),
                  static_cast<std::int64_t>(key >> 42)};
    // Ends: on odd (spanned) axes one end takes the even neighbour of m/2, the other the odd.
    point even{};
    point odd{};
    for (std::size_t q = 0; q < 3; ++q) {
      even[q] = odd[q] = m[q] / 2;
      if (m[q] % 2 != 0) (even[q] % 2 == 0 ? odd[q] : even[q]) += 1;
    }
    const double fe = v.value(even[0], even[1], even[2]);
    const double fo = v.value(odd[0], odd[1], odd[2]);
    ASSERT_NE(fe > w, fo > w) << "vertex " << i << " is on an uncrossed edge";
    // Exact linear interpolation of the field between the ends gives w at the vertex.
    const auto& p = s.mesh.vertices[i];
    std::size_t axis = 0;
    while (even[axis] == odd[axis]) ++axis;
    const double t =
        (p[axis] - static_cast<double>(even[axis])) / static_cast<double>(odd[axis] - even[axis]);
    EXPECT_NEAR(fe + t * (fo - fe), w, 1e-9) << "vertex " << i;
    for (std::size_t q = 0; q < 3; ++q) {
      EXPECT_NEAR(p[q], static_cast<double>(even[q]) + t * static_cast<double>(odd[q] - even[q]),
                  1e-12);
    }
  }
}

TEST(ReferenceMt, torus_has_euler_characteristic_zero) {
  const volume v = make_torus_field({28, 28, 14}, {13.6, 13.3, 6.4}, 8.0);
  const reference_surface s = reference_marching_tetrahedra(v, 3.1);
  const auto [lo, hi] = data_box(v);
  EXPECT_TRUE(check_valid_cut(s.mesh, lo, hi));
  EXPECT_TRUE(watertight(s.mesh)) << watertight(s.mesh).message;
  EXPECT_EQ(euler_characteristic(s.mesh), 0);
  EXPECT_EQ(connected_components(s.mesh), 1u);
}

TEST(ReferenceMt, gyroid_is_open_only_along_the_data_box) {
  const volume v = make_gyroid_field({21, 18, 23}, 9.0);
  const reference_surface s = reference_marching_tetrahedra(v, 0.1);
  const auto [lo, hi] = data_box(v);
  EXPECT_TRUE(check_valid_cut(s.mesh, lo, hi));
  EXPECT_GT(boundary_edge_count(s.mesh), 0u);
  EXPECT_FALSE(watertight(s.mesh));
}

TEST(ReferenceMt, marschner_lobb_and_blobs_give_valid_surfaces) {
  const volume ml = make_marschner_lobb({33, 33, 33});
  const volume blobs = make_gaussian_blobs({24, 20, 22}, 8, 2024);
  const reference_surface a = reference_marching_tetrahedra(ml, demo_isovalue);
  const auto [ml_lo, ml_hi] = data_box(ml);
  EXPECT_FALSE(a.mesh.empty());
  EXPECT_TRUE(check_valid_cut(a.mesh, ml_lo, ml_hi));

  const reference_surface b = reference_marching_tetrahedra(blobs, 0.3);
  const auto [blobs_lo, blobs_hi] = data_box(blobs);
  EXPECT_FALSE(b.mesh.empty());
  EXPECT_TRUE(check_valid_cut(b.mesh, blobs_lo, blobs_hi));
}

// Integer data often holds the isovalue exactly; such samples are white, and the clamp keeps
// every vertex strictly inside its edge, so no triangle collapses.
TEST(ReferenceMt, samples_equal_to_the_isovalue_give_no_degenerate_triangles) {
  const index3 dims{14, 15, 16};
  std::vector<std::byte> bytes;
  std::size_t at_isovalue = 0;
  for (std::int64_t z = 0; z < dims[2]; ++z) {
    for (std::int64_t y = 0; y < dims[1]; ++y) {
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        const double d = std::hypot(static_cast<double>(x) - 6.5, static_cast<double>(y) - 7.0,
                                    static_cast<double>(z) - 7.5);
        const auto value = static_cast<std::uint8_t>(std::lround(d));
        at_isovalue += value == 5 ? 1 : 0;
        bytes.push_back(static_cast<std::byte>(value));
      }
    }
  }
  ASSERT_GT(at_isovalue, 100u);
  const volume v(dims, sample_type::u8, std::move(bytes));
  const reference_surface s = reference_marching_tetrahedra(v, 5.0);
  const auto [lo, hi] = data_box(v);
  EXPECT_TRUE(check_valid_cut(s.mesh, lo, hi));
  EXPECT_TRUE(no_degenerate_triangles(s.mesh)) << no_degenerate_triangles(s.mesh).message;
  EXPECT_EQ(euler_characteristic(s.mesh), 2);
  for (const vec3& p : s.mesh.vertices) {
    EXPECT_FALSE(is_integral(p[0]) && is_integral(p[1]) && is_integral(p[2]))
        << "vertex on a grid point";
  }
}

TEST(ReferenceMt, positions_are_origin_plus_grid_position_times_spacing) {
  const volume unit = make_gaussian_blobs({12, 13, 14}, 3, 5);
  std::vector<std::byte> copy(unit.bytes(), unit.bytes() + unit.byte_size());
  const std::array<double, 3> spacing{2.0, 0.5, 1.25};
  const std::array<double, 3> origin{-3.0, 10.0, 0.125};
  const volume scaled(unit.dims(), unit.type(), std::move(copy), spacing, origin);
  const reference_surface a = reference_marching_tetrahedra(unit, 0.3);
  const reference_surface b = reference_marching_tetrahedra(scaled, 0.3);
  ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
  EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  EXPECT_EQ(a.vertex_keys, b.vertex_keys);
  for (std::size_t i = 0; i < a.mesh.vertices.size(); ++i) {
    for (std::size_t q = 0; q < 3; ++q) {
      EXPECT_EQ(b.mesh.vertices[i][q], origin[q] + a.mesh.vertices[i][q] * spacing[q]);
    }
  }
  const auto [lo, hi] = data_box(scaled);
  EXPECT_TRUE(check_valid_cut(b.mesh, lo, hi));
}

TEST(ReferenceMt, isovalue_outside_the_range_gives_an_empty_surface) {
  const volume v = make_sphere_field({8, 8, 8}, {3.5, 3.5, 3.5});
  EXPECT_TRUE(reference_marching_tetrahedra(v, 100.0).mesh.empty());
  EXPECT_TRUE(reference_marching_tetrahedra(v, -1.0).mesh.empty());
  EXPECT_EQ(reference_triangle_count(v, 100.0), 0u);
}

TEST(ReferenceMt, nan_isovalue_throws) {
  const volume v = make_sphere_field({4, 4, 4}, {1.5, 1.5, 1.5});
  EXPECT_THROW((void)reference_marching_tetrahedra(v, std::numeric_limits<double>::quiet_NaN()),
               error);
}

TEST(ReferenceMtOnSharedData, every_volume_loads_with_its_documented_size) {
  const auto dir = shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found: set PROGISO_DATA_DIR or provide ../shared/data";
  for (const shared_volume& info : shared_volumes()) {
    const volume v = load_shared_volume(info, *dir);
    EXPECT_EQ(v.dims(), info.dims) << info.name;
    EXPECT_LT(v.value_range()[0], v.value_range()[1]) << info.name;
    for (const double w : info.isovalues) {
      EXPECT_GT(w, v.value_range()[0]) << info.name;
      EXPECT_LT(w, v.value_range()[1]) << info.name;
    }
  }
  const volume head = load_shared_volume(*find_shared_volume("headsq"), *dir);
  EXPECT_EQ(head.value_range()[0], 0.0);  // data README: range 0..3926
  EXPECT_EQ(head.value_range()[1], 3926.0);
  EXPECT_EQ(head.spacing(), (std::array<double, 3>{3.2, 3.2, 1.5}));
}

// One case per (shared volume, suggested isovalue), so that each shows up, and runs, on its own.
struct shared_case {
  const shared_volume* info;
  double isovalue;
};

std::vector<shared_case> shared_cases() {
  std::vector<shared_case> cases;
  for (const shared_volume& info : shared_volumes()) {
    for (const double w : info.isovalues) cases.push_back({&info, w});
  }
  return cases;
}

class SharedVolume : public ::testing::TestWithParam<shared_case> {};

TEST_P(SharedVolume, reference_surface_is_a_valid_cut) {
  const auto dir = shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found: set PROGISO_DATA_DIR or provide ../shared/data";
  const shared_case c = GetParam();
  const volume v = load_shared_volume(*c.info, *dir);
  const reference_surface s = reference_marching_tetrahedra(v, c.isovalue);
  const auto [lo, hi] = data_box(v);
  EXPECT_FALSE(s.mesh.empty());
  EXPECT_EQ(s.mesh.triangles.size(), reference_triangle_count(v, c.isovalue));
  EXPECT_TRUE(check_valid_cut(s.mesh, lo, hi));
}

INSTANTIATE_TEST_SUITE_P(ReferenceMtOnSharedData, SharedVolume, ::testing::ValuesIn(shared_cases()),
                         [](const ::testing::TestParamInfo<shared_case>& p) {
                           return std::string(p.param.info->name) + "_" +
                                  std::to_string(std::lround(p.param.isovalue));
                         });

}  // namespace
}  // namespace progiso::test
