// Analytic fields: values at known points, ranges, argument checks, determinism.
#include <progiso/core/field/analytic.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include <progiso/core/base/error.hpp>

namespace progiso {
namespace {

constexpr double pi = std::numbers::pi;

// The value a field stores for an exact double: rounded once to float.
double as_stored(double exact) { return static_cast<double>(static_cast<float>(exact)); }

bool same_samples(const volume& a, const volume& b) {
  return a.dims() == b.dims() && a.type() == b.type() && a.byte_size() == b.byte_size() &&
         std::memcmp(a.bytes(), b.bytes(), a.byte_size()) == 0;
}

TEST(Analytic, sphere_field_is_distance_from_centre_in_grid_units) {
  const volume v = make_sphere_field({9, 10, 11}, {4.0, 5.0, 5.5});
  EXPECT_EQ(v.type(), sample_type::f32);
  EXPECT_EQ(v.dims(), (index3{9, 10, 11}));
  EXPECT_EQ(v.value(4, 5, 5), 0.5);
  EXPECT_EQ(v.value(4, 5, 8), 2.5);
  EXPECT_EQ(v.value(0, 0, 0), as_stored(std::sqrt(16.0 + 25.0 + 30.25)));
  EXPECT_EQ(v.value(8, 9, 10), as_stored(std::sqrt(16.0 + 16.0 + 20.25)));
}

TEST(Analytic, sphere_radius_scale_divides_the_distance) {
  const volume v = make_sphere_field({8, 8, 8}, {0.0, 0.0, 0.0}, 2.0);
  EXPECT_EQ(v.value(6, 0, 0), 3.0);
  EXPECT_EQ(v.value(3, 4, 0), 2.5);
}

TEST(Analytic, torus_field_is_distance_to_the_ring) {
  const volume v = make_torus_field({17, 17, 17}, {8.0, 8.0, 8.0}, 5.0);
  EXPECT_EQ(v.value(13, 8, 8), 0.0);  // on the ring
  EXPECT_EQ(v.value(8, 3, 8), 0.0);
  EXPECT_EQ(v.value(8, 8, 8), 5.0);    // the centre is R from every ring point
  EXPECT_EQ(v.value(8, 3, 11), 3.0);   // above the ring
  EXPECT_EQ(v.value(16, 8, 8), 3.0);   // outside, in the ring's plane
  EXPECT_EQ(v.value(11, 12, 8), 0.0);  // (3, 4) from the centre: on the ring
}

TEST(Analytic, gyroid_is_periodic_bounded_and_zero_at_the_origin) {
  const volume v = make_gyroid_field({17, 17, 17}, 8.0);
  EXPECT_EQ(v.value(0, 0, 0), 0.0);
  for (std::int64_t z = 0; z < 9; ++z) {
    for (std::int64_t y = 0; y < 9; ++y) {
      for (std::int64_t x = 0; x < 9; ++x) {
        EXPECT_NEAR(v.value(x, y, z), v.value(x + 8, y, z), 1e-6);
        EXPECT_NEAR(v.value(x, y, z), v.value(x, y + 8, z + 8), 1e-6);
      }
    }
  }
  // At (2, 0, 0) with period 8: sin(pi/2) cos 0 + sin 0 cos 0 + sin 0 cos(pi/2) = 1.
  EXPECT_NEAR(v.value(2, 0, 0), 1.0, 1e-7);
  EXPECT_GE(v.value_range()[0], -1.5);
  EXPECT_LE(v.value_range()[1], 1.5);
}

// The Marschner–Lobb formula written out independently, at a point of [-1, 1]^3.
double marschner_lobb(double x, double y, double z, double alpha, double f_m) {
  const double r = std::hypot(x, y);
  const double rho_r = std::cos(2.0 * pi * f_m * std::cos(pi * r / 2.0));
  return (1.0 - std::sin(pi * z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha));
}

TEST(Analytic, marschner_lobb_matches_the_formula_at_the_centre_and_corners) {
  const volume v = make_marschner_lobb({41, 41, 41});
  // Centre: r = 0, rho_r = cos(12 pi) = 1, so rho = (1 + 0.25 * 2) / 2.5 = 0.6.
  EXPECT_NEAR(v.value(20, 20, 20), 0.6, 1e-7);
  EXPECT_NEAR(v.value(0, 0, 0), marschner_lobb(-1, -1, -1, 0.25, 6), 1e-7);
  EXPECT_NEAR(v.value(40, 0, 40), marschner_lobb(1, -1, 1, 0.25, 6), 1e-7);
  EXPECT_NEAR(v.value(10, 30, 5), marschner_lobb(-0.5, 0.5, -0.75, 0.25, 6), 1e-7);

  const volume w = make_marschner_lobb({21, 11, 5}, 0.5, 3.0);
  EXPECT_NEAR(w.value(15, 2, 1), marschner_lobb(0.5, -0.6, -0.5, 0.5, 3.0), 1e-7);
}

TEST(Analytic, marschner_lobb_values_lie_in_the_unit_interval_around_the_isovalue) {
  const volume v = make_marschner_lobb({33, 33, 33});
  EXPECT_GE(v.value_range()[0], 0.0);
  EXPECT_LE(v.value_range()[1], 1.0);
  EXPECT_LT(v.value_range()[0], demo_isovalue);
  EXPECT_GT(v.value_range()[1], demo_isovalue);
}

TEST(Analytic, demo_volume_is_marschner_lobb_on_129_cubed) {
  const volume v = make_demo_volume();
  EXPECT_EQ(v.dims(), (index3{129, 129, 129}));
  EXPECT_EQ(v.type(), sample_type::f32);
  EXPECT_EQ(demo_isovalue, 0.5);
  EXPECT_TRUE(same_samples(make_demo_volume(17), make_marschner_lobb({17, 17, 17})));
}

TEST(Analytic, gaussian_blobs_are_deterministic_and_normalised) {
  const volume a = make_gaussian_blobs({20, 24, 28}, 6, 42);
  const volume b = make_gaussian_blobs({20, 24, 28}, 6, 42);
  const volume c = make_gaussian_blobs({20, 24, 28}, 6, 43);
  EXPECT_TRUE(same_samples(a, b));
  EXPECT_FALSE(same_samples(a, c));
  EXPECT_EQ(a.value_range()[1], 1.0);
  EXPECT_GE(a.value_range()[0], 0.0);
  EXPECT_LT(a.value_range()[0], 0.5);  // blobs, not a plateau
  EXPECT_EQ(c.value_range()[1], 1.0);
}

TEST(Analytic, invalid_arguments_throw_progiso_error) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)make_sphere_field({1, 4, 4}, {0, 0, 0}), error);
  EXPECT_THROW((void)make_sphere_field({4, 4, 4}, {0, 0, 0}, 0.0), error);
  EXPECT_THROW((void)make_sphere_field({4, 4, 4}, {nan, 0, 0}), error);
  EXPECT_THROW((void)make_torus_field({4, 4, 4}, {0, 0, 0}, -1.0), error);
  EXPECT_THROW((void)make_gyroid_field({4, 4, 4}, 0.0), error);
  EXPECT_THROW((void)make_gyroid_field({4, -4, 4}, 3.0), error);
  EXPECT_THROW((void)make_marschner_lobb({4, 4, 4}, nan), error);
  EXPECT_THROW((void)make_marschner_lobb({4, 4, 4}, 0.25, nan), error);
  EXPECT_THROW((void)make_gaussian_blobs({4, 4, 4}, 0, 1), error);
  EXPECT_THROW((void)make_demo_volume(1), error);
  EXPECT_THROW((void)make_demo_volume((std::int64_t{1} << 15) + 2), error);
}

}  // namespace
}  // namespace progiso
