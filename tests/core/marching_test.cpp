// The per-tetrahedron marching rules that make neighbouring pieces fit exactly.
#include <progiso/core/surface/marching.hpp>

#include <cstring>

#include <gtest/gtest.h>

namespace progiso {
namespace {

double dot(const vec3& a, const vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
vec3 sub(const vec3& a, const vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
vec3 cross(const vec3& a, const vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
vec3 to_vec(const ipoint& p) {
  return {static_cast<double>(p[0]), static_cast<double>(p[1]), static_cast<double>(p[2])};
}

TEST(Marching, interpolation_is_bit_identical_whichever_end_comes_first) {
  const ipoint a{3, 7, 2};
  const ipoint b{5, 6, 4};
  for (const double w : {0.1, 0.37, 0.999, 1.0 / 3.0}) {
    const vec3 p = interpolate(a, 0.0, b, 1.0, w);
    const vec3 q = interpolate(b, 1.0, a, 0.0, w);
    EXPECT_EQ(std::memcmp(p.data(), q.data(), sizeof p), 0);
  }
}

TEST(Marching, vertices_stay_strictly_inside_their_edge_when_a_sample_equals_the_isovalue) {
  const ipoint a{0, 0, 0};
  const ipoint b{2, 0, 0};
  EXPECT_DOUBLE_EQ(interpolate(a, 5.0, b, 9.0, 5.0)[0], 2.0 * interpolation_margin);
  EXPECT_DOUBLE_EQ(interpolate(a, 9.0, b, 5.0, 5.0)[0], 2.0 * (1.0 - interpolation_margin));
  EXPECT_DOUBLE_EQ(interpolate(a, 0.0, b, 4.0, 1.0)[0], 0.5);
}

TEST(Marching, edge_keys_are_doubled_midpoints) {
  const std::uint64_t k = edge_key({1, 2, 3}, {3, 2, 0});
  EXPECT_EQ(edge_key_point(k), (ipoint{4, 4, 3}));
  EXPECT_EQ(k, edge_key({3, 2, 0}, {1, 2, 3}));
}

TEST(Marching, every_colouring_gives_triangles_whose_normals_point_from_black_to_white) {
  const std::array<ipoint, 4> t{ipoint{0, 0, 0}, ipoint{2, 0, 0}, ipoint{2, 2, 0}, ipoint{2, 2, 2}};
  for (unsigned mask = 0; mask < 16; ++mask) {
    std::array<double, 4> f{};
    vec3 black{}, white{};
    int nb = 0, nw = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      f[i] = (mask >> i) & 1u ? 1.0 : 0.0;
      vec3& acc = f[i] > 0.5 ? black : white;
      for (std::size_t q = 0; q < 3; ++q) acc[q] += t[i][q];
      (f[i] > 0.5 ? nb : nw)++;
    }
    const tet_surface s = march_tet(t, f, 0.5);
    EXPECT_EQ(s.count, tet_triangle_count(mask));
    if (s.count == 0) continue;
    for (std::size_t q = 0; q < 3; ++q) {
      black[q] /= nb;
      white[q] /= nw;
    }
    for (int k = 0; k < s.count; ++k) {
      std::array<vec3, 3> p{};
      for (std::size_t j = 0; j < 3; ++j) {
        const ipoint m = edge_key_point(s.triangles[static_cast<std::size_t>(k)][j]);
        p[j] = {m[0] / 2.0, m[1] / 2.0, m[2] / 2.0};
      }
      const vec3 n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
      EXPECT_GT(dot(n, sub(white, black)), 0.0) << "mask " << mask;
      (void)to_vec;
    }
  }
}

TEST(Marching, quad_is_cut_along_the_diagonal_through_the_smallest_key) {
  const std::array<ipoint, 4> t{ipoint{0, 0, 0}, ipoint{2, 0, 0}, ipoint{2, 2, 0}, ipoint{2, 2, 2}};
  const tet_surface s = march_tet(t, {1.0, 1.0, 0.0, 0.0}, 0.5);
  ASSERT_EQ(s.count, 2);
  std::uint64_t smallest = ~std::uint64_t{0};
  for (const auto& tri : s.triangles)
    for (const auto k : tri) smallest = std::min(smallest, k);
  for (const auto& tri : s.triangles) {
    EXPECT_NE(std::find(tri.begin(), tri.end(), smallest), tri.end());
  }
}

}  // namespace
}  // namespace progiso
