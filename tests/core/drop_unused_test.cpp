// drop_unused: a mesh whose suspects are all used keeps its vertices and their order; one whose
// suspects include an unused vertex loses exactly the unused ones, renumbered in order of first
// use, with every triangle naming the same positions as before. The scan in parts (a parallel
// loop's pieces, run here in reverse order) decides as the scan on one thread does.
#include <progiso/core/surface/detail/mesh_clip.hpp>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <gtest/gtest.h>

namespace progiso::detail {
namespace {

// Vertex v at (v, 0, 0): a triangle's positions say which vertices it names.
triangle_mesh strip(std::uint32_t vertices, const std::vector<std::array<std::uint32_t, 3>>& tris) {
  triangle_mesh m;
  for (std::uint32_t v = 0; v < vertices; ++v) m.vertices.push_back({static_cast<double>(v), 0, 0});
  m.triangles = tris;
  return m;
}

std::vector<std::array<double, 3>> corner_xs(const triangle_mesh& m) {
  std::vector<std::array<double, 3>> out;
  for (const auto& t : m.triangles) {
    out.push_back({m.vertices[t[0]][0], m.vertices[t[1]][0], m.vertices[t[2]][0]});
  }
  return out;
}

// The pieces in reverse order: a scan that depended on the order of its pieces would show it.
const parallel_loop reversed = [](std::size_t n, const std::function<void(std::size_t)>& body) {
  for (std::size_t i = n; i-- > 0;) body(i);
};

TEST(DropUnused, keeps_every_vertex_in_place_when_every_suspect_is_used) {
  // Not in order of first use (2, 1, 0, 3, 4): a renumbering would show.
  const std::vector<std::array<std::uint32_t, 3>> tris{{2, 1, 0}, {0, 1, 3}, {3, 4, 0}};
  for (const std::size_t parts : {std::size_t{1}, std::size_t{2}, std::size_t{3}, std::size_t{7}}) {
    triangle_mesh m = strip(5, tris);
    drop_unused(m, {4, 0}, parts == 1 ? parallel_loop{} : reversed, parts);
    EXPECT_EQ(m.vertices.size(), 5u) << parts;
    EXPECT_EQ(m.triangles, tris) << parts;
    EXPECT_EQ(m.vertices[4][0], 4.0) << parts;
  }
}

TEST(DropUnused, drops_exactly_the_unused_vertices_when_a_suspect_is_unused) {
  // Vertices 1 and 5 are unused; 5 is a suspect, so both go.
  const std::vector<std::array<std::uint32_t, 3>> tris{{4, 0, 2}, {2, 3, 4}, {6, 3, 0}};
  for (const std::size_t parts : {std::size_t{1}, std::size_t{2}, std::size_t{3}, std::size_t{7}}) {
    triangle_mesh m = strip(7, tris);
    const auto before = corner_xs(m);
    drop_unused(m, {3, 5}, parts == 1 ? parallel_loop{} : reversed, parts);
    ASSERT_EQ(m.vertices.size(), 5u) << parts;
    EXPECT_EQ(corner_xs(m), before) << parts;
    // Renumbered in order of first use: 4, 0, 2, 3, 6.
    const std::vector<std::array<std::uint32_t, 3>> renumbered{{0, 1, 2}, {2, 3, 0}, {4, 3, 1}};
    EXPECT_EQ(m.triangles, renumbered) << parts;
  }
}

}  // namespace
}  // namespace progiso::detail
