// The mesh checks pass on good meshes and fail, with a useful message, on each kind of bad one:
// they are proven able to fail before other tests rely on them passing.
#include <support/mesh_checks.hpp>

#include <cmath>
#include <string>
#include <utility>

#include <gtest/gtest.h>

namespace progiso::test {
namespace {

// The octahedron with vertices ±e_x, ±e_y, ±e_z (indices 0..5 = +x, −x, +y, −y, +z, −z),
// offset by `shift`, one triangle per octant, normals outward.
triangle_mesh octahedron(const vec3& shift = {0, 0, 0}) {
  triangle_mesh m;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    for (const double sign : {1.0, -1.0}) {
      vec3 p = shift;
      p[axis] += sign;
      m.vertices.push_back(p);
    }
  }
  for (std::uint32_t sx = 0; sx < 2; ++sx) {
    for (std::uint32_t sy = 0; sy < 2; ++sy) {
      for (std::uint32_t sz = 0; sz < 2; ++sz) {
        const std::uint32_t x = sx;
        const std::uint32_t y = 2 + sy;
        const std::uint32_t z = 4 + sz;
        // An odd number of negative axes mirrors the octant, which flips the orientation.
        if ((sx + sy + sz) % 2 == 0) {
          m.triangles.push_back({x, y, z});
        } else {
          m.triangles.push_back({x, z, y});
        }
      }
    }
  }
  return m;
}

triangle_mesh two_octahedra() {
  triangle_mesh m = octahedron();
  const triangle_mesh other = octahedron({5, 0, 0});
  const auto offset = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (auto t : other.triangles)
    m.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  return m;
}

bool mentions(const check_result& r, const std::string& text) {
  return r.message.find(text) != std::string::npos;
}

constexpr vec3 big_lo{-2, -2, -2};
constexpr vec3 big_hi{2, 2, 2};

TEST(MeshChecks, octahedron_passes_every_check) {
  const triangle_mesh m = octahedron();
  EXPECT_TRUE(edge_manifold(m)) << edge_manifold(m).message;
  EXPECT_TRUE(watertight(m));
  EXPECT_TRUE(boundary_on_box(m, big_lo, big_hi));
  EXPECT_TRUE(consistently_oriented(m));
  EXPECT_TRUE(no_degenerate_triangles(m));
  EXPECT_TRUE(no_self_intersections(m)) << no_self_intersections(m).message;
  EXPECT_EQ(self_intersection_count(m), std::optional<std::size_t>{0});
  EXPECT_EQ(euler_characteristic(m), 2);
  EXPECT_EQ(connected_components(m), 1u);
  EXPECT_EQ(boundary_edge_count(m), 0u);
  EXPECT_DOUBLE_EQ(signed_volume(m), 4.0 / 3.0);
  EXPECT_TRUE(check_valid_cut(m, big_lo, big_hi));
  const mesh_report r = make_report(m, big_lo, big_hi);
  EXPECT_TRUE(r.valid());
  EXPECT_EQ(r.euler, 2);
}

TEST(MeshChecks, euler_characteristic_and_components_count_each_part) {
  const triangle_mesh m = two_octahedra();
  EXPECT_EQ(euler_characteristic(m), 4);
  EXPECT_EQ(connected_components(m), 2u);
  EXPECT_TRUE(check_valid_cut(m, {-2, -2, -2}, {7, 2, 2}));

  triangle_mesh with_unused = octahedron();
  with_unused.vertices.push_back({9, 9, 9});  // referenced by no triangle: not counted
  EXPECT_EQ(euler_characteristic(with_unused), 2);
  EXPECT_EQ(connected_components(with_unused), 1u);
}

TEST(MeshChecks, edge_manifold_fails_on_an_edge_of_three_triangles) {
  triangle_mesh m = octahedron();
  m.vertices.push_back({0.5, 0.5, 0.0});
  m.triangles.push_back({0, 2, 6});  // a fin on edge +x +y
  const check_result r = edge_manifold(m);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "3 triangles")) << r.message;
  const check_result x = no_self_intersections(m);  // CGAL cannot even take it
  EXPECT_FALSE(x);
  EXPECT_TRUE(mentions(x, "not a valid polygon mesh") && mentions(x, "3 triangles")) << x.message;
  EXPECT_FALSE(check_valid_cut(m, big_lo, big_hi));
}

TEST(MeshChecks, edge_manifold_fails_on_repeated_indices_and_duplicate_triangles) {
  triangle_mesh repeated = octahedron();
  repeated.triangles[3] = {1, 1, 4};
  EXPECT_FALSE(edge_manifold(repeated));
  EXPECT_TRUE(mentions(edge_manifold(repeated), "repeats a vertex"))
      << edge_manifold(repeated).message;

  triangle_mesh duplicate = octahedron();
  const auto t = duplicate.triangles[0];
  duplicate.triangles.push_back({t[0], t[2], t[1]});  // same vertices, other orientation
  EXPECT_FALSE(edge_manifold(duplicate));
  EXPECT_TRUE(mentions(edge_manifold(duplicate), "same vertices"))
      << edge_manifold(duplicate).message;

  triangle_mesh out_of_range = octahedron();
  out_of_range.triangles[0][2] = 17;
  EXPECT_FALSE(edge_manifold(out_of_range));
  EXPECT_FALSE(consistently_oriented(out_of_range));
  EXPECT_FALSE(no_self_intersections(out_of_range));
}

TEST(MeshChecks, consistently_oriented_fails_on_a_flipped_triangle) {
  triangle_mesh m = octahedron();
  std::swap(m.triangles[5][1], m.triangles[5][2]);
  const check_result r = consistently_oriented(m);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "same direction")) << r.message;
  EXPECT_TRUE(edge_manifold(m));  // still manifold: only orientation is wrong
  EXPECT_FALSE(check_valid_cut(m, big_lo, big_hi));
}

TEST(MeshChecks, no_degenerate_triangles_fails_on_collinear_or_coincident_points) {
  triangle_mesh collinear;
  collinear.vertices = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  collinear.triangles = {{0, 1, 2}};
  EXPECT_FALSE(no_degenerate_triangles(collinear));
  EXPECT_TRUE(mentions(no_degenerate_triangles(collinear), "collinear"));

  triangle_mesh coincident;
  coincident.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 0, 0}};
  coincident.triangles = {{0, 1, 2}};
  EXPECT_FALSE(no_degenerate_triangles(coincident));
  EXPECT_TRUE(mentions(no_degenerate_triangles(coincident), "equal positions"));

  // One ulp off the line is not collinear: the predicate is exact, not a tolerance.
  triangle_mesh sliver;
  sliver.vertices = {{0, 0, 0}, {1, 1, 1}, {2, 2, std::nextafter(2.0, 3.0)}};
  sliver.triangles = {{0, 1, 2}};
  EXPECT_TRUE(no_degenerate_triangles(sliver)) << no_degenerate_triangles(sliver).message;
}

TEST(MeshChecks, no_self_intersections_fails_on_two_crossing_triangles) {
  triangle_mesh m;
  m.vertices = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0.5, 0.2, -1}, {0.5, 0.2, 1}, {0.5, 1.0, 0}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  const check_result r = no_self_intersections(m);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "1 pairs")) << r.message;
  EXPECT_EQ(self_intersection_count(m), std::optional<std::size_t>{1});

  // Moved apart, the same triangles do not touch.
  for (std::size_t i = 3; i < 6; ++i) m.vertices[i][0] += 5.0;
  EXPECT_TRUE(no_self_intersections(m)) << no_self_intersections(m).message;
}

TEST(MeshChecks, no_self_intersections_fails_on_a_closed_surface_folded_through_itself) {
  triangle_mesh m = octahedron();
  m.vertices[4] = {0.6, 0.6, -0.2};  // +z apex pulled down and out through the lower half
  EXPECT_TRUE(edge_manifold(m));
  EXPECT_TRUE(consistently_oriented(m));
  EXPECT_FALSE(no_self_intersections(m));
  EXPECT_GT(self_intersection_count(m).value_or(0), 0u);
  EXPECT_FALSE(check_valid_cut(m, {-3, -3, -3}, {3, 3, 3}));
}

TEST(MeshChecks, boundary_on_box_fails_on_an_open_edge_inside_the_box) {
  triangle_mesh m = octahedron();
  m.triangles.erase(m.triangles.begin());  // a hole in the +x +y +z octant
  EXPECT_TRUE(edge_manifold(m));
  EXPECT_TRUE(consistently_oriented(m));
  EXPECT_FALSE(watertight(m));
  const check_result r = boundary_on_box(m, big_lo, big_hi);
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "does not lie on a face")) << r.message;
  EXPECT_EQ(boundary_edge_count(m), 3u);
  EXPECT_EQ(euler_characteristic(m), 1);
  EXPECT_FALSE(check_valid_cut(m, big_lo, big_hi));
}

TEST(MeshChecks, boundary_on_box_accepts_open_edges_on_the_box_faces_only) {
  // A square across the box [0,1]^3 at x = 0.5: its four open edges lie on the faces y = 0,
  // z = 1, y = 1 and z = 0.
  triangle_mesh m;
  m.vertices = {{0.5, 0, 0}, {0.5, 1, 0}, {0.5, 1, 1}, {0.5, 0, 1}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  EXPECT_TRUE(boundary_on_box(m, {0, 0, 0}, {1, 1, 1}))
      << boundary_on_box(m, {0, 0, 0}, {1, 1, 1}).message;
  EXPECT_TRUE(check_valid_cut(m, {0, 0, 0}, {1, 1, 1}));
  EXPECT_FALSE(watertight(m));
  // In a larger box two of those edges are inside it.
  EXPECT_FALSE(boundary_on_box(m, {0, 0, 0}, {2, 2, 2}));

  // An edge from the face x = 0 to the face y = 0 runs through the box's inside.
  triangle_mesh corner;
  corner.vertices = {{0, 0.5, 0.5}, {0.5, 0, 0.5}, {0, 0, 0}};
  corner.triangles = {{0, 1, 2}};
  const check_result r = boundary_on_box(corner, {0, 0, 0}, {1, 1, 1});
  EXPECT_FALSE(r);
  EXPECT_TRUE(mentions(r, "v0") && mentions(r, "v1")) << r.message;
}

TEST(MeshChecks, check_valid_cut_names_the_failed_check) {
  triangle_mesh m = octahedron();
  std::swap(m.triangles[2][0], m.triangles[2][1]);
  const ::testing::AssertionResult r = check_valid_cut(m, big_lo, big_hi);
  EXPECT_FALSE(r);
  EXPECT_NE(std::string(r.message()).find("consistently_oriented failed"), std::string::npos)
      << r.message();
  const mesh_report report = make_report(m, big_lo, big_hi);
  EXPECT_FALSE(report.valid());
  EXPECT_TRUE(report.manifold);
  EXPECT_FALSE(report.oriented);
}

TEST(MeshChecks, same_surface_ignores_numbering_and_order_but_not_orientation) {
  const triangle_mesh a = octahedron();
  // Same surface: vertices renumbered (reversed), triangles reordered and rotated.
  triangle_mesh b;
  b.vertices.assign(a.vertices.rbegin(), a.vertices.rend());
  const auto n = static_cast<std::uint32_t>(a.vertices.size());
  for (auto it = a.triangles.rbegin(); it != a.triangles.rend(); ++it) {
    const auto& t = *it;
    b.triangles.push_back({n - 1 - t[1], n - 1 - t[2], n - 1 - t[0]});
  }
  EXPECT_TRUE(same_surface(a, b));
  EXPECT_EQ(canonical_triangles(a), canonical_triangles(b));

  triangle_mesh flipped = b;
  std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
  const ::testing::AssertionResult r = same_surface(a, flipped);
  EXPECT_FALSE(r);
  EXPECT_NE(std::string(r.message()).find("1 only in the first"), std::string::npos) << r.message();

  triangle_mesh fewer = a;
  fewer.triangles.pop_back();
  EXPECT_FALSE(same_surface(a, fewer));
  EXPECT_NE(std::string(same_surface(a, fewer).message()).find("8 vs 7"), std::string::npos);
}

}  // namespace
}  // namespace progiso::test
