// mesh_builder::join: builders fed consecutive parts of one triangle sequence, each on its own
// thread, joined, give exactly the mesh of one builder fed the whole sequence (vertex order,
// positions, triangles), whatever the number of parts and however far apart the parts' shared
// vertices lie. Covers clipped (padded) coarse cuts, whose clip vertices are shared by position.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/surface/detail/mesh_builder.hpp>
#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

namespace progiso {
namespace {

using keys = std::array<std::uint64_t, 3>;

std::vector<keys> cut_triangles(const surface_snapshot& s) {
  std::vector<keys> out;
  s.for_each_triangle([&out](const owned_triangle& t) { out.push_back(t.keys); });
  return out;
}

triangle_mesh one_builder(const engine& e, const std::vector<keys>& tris) {
  detail::mesh_builder b(e.hierarchy_of(), e.field(), e.isovalue(), tris.size() / 2 + 16);
  for (const keys& k : tris) b.add(k);
  return b.finish();
}

triangle_mesh in_parts(const engine& e, const std::vector<keys>& tris, std::size_t parts) {
  std::vector<detail::mesh_builder> builders;
  for (std::size_t k = 0; k < parts; ++k) {
    builders.emplace_back(e.hierarchy_of(), e.field(), e.isovalue(), 16);
  }
  const parallel_loop run = [](std::size_t n, const std::function<void(std::size_t)>& body) {
    tbb::parallel_for(std::size_t{0}, n, [&body](std::size_t i) { body(i); });
  };
  run(parts, [&](std::size_t k) {
    const std::size_t first = tris.size() * k / parts;
    const std::size_t last = tris.size() * (k + 1) / parts;
    for (std::size_t i = first; i < last; ++i) builders[k].add(tris[i]);
  });
  return detail::mesh_builder::join(builders, run);
}

void expect_joins_equal(const engine& e, const std::vector<keys>& tris, const char* what) {
  const triangle_mesh whole = one_builder(e, tris);
  ASSERT_GT(whole.triangles.size(), 20u) << what;
  for (const std::size_t parts : {1u, 2u, 3u, 7u, 16u}) {
    const triangle_mesh joined = in_parts(e, tris, parts);
    EXPECT_EQ(joined.vertices, whole.vertices) << what << ", " << parts << " parts";
    EXPECT_EQ(joined.triangles, whole.triangles) << what << ", " << parts << " parts";
  }
}

TEST(MeshJoin, parts_joined_equal_one_builder_vertex_for_vertex) {
  // 41 × 37 × 39: the hierarchy is padded to 65³, so coarse cuts are clipped at the data box.
  const volume v = make_gaussian_blobs({41, 37, 39}, 7, 19u);
  engine e(v, 0.45);
  std::mt19937 rng(3);
  for (const double error : {0.2, 0.05, 0.0}) {
    if (error > 0.0) {
      e.refine_until(error);
    } else {
      e.refine_full();
    }
    std::vector<keys> tris = cut_triangles(e.snapshot());
    expect_joins_equal(e, tris, "publication order");
    // Shuffled: parts share vertices anywhere in the volume, not only at their borders.
    std::shuffle(tris.begin(), tris.end(), rng);
    expect_joins_equal(e, tris, "shuffled");
  }
}

TEST(MeshJoin, clipped_cut_has_clip_vertices_and_joins_exactly) {
  // The root cut of a padded grid reaches past the data box: every part clips, and clip
  // vertices are shared between parts by position.
  const volume v = make_marschner_lobb({19, 23, 21});
  engine e(v, 0.5);
  const std::vector<keys> tris = cut_triangles(e.snapshot());
  const triangle_mesh whole = one_builder(e, tris);
  const auto& box = e.hierarchy_of().data_max();
  const bool on_box_face = std::any_of(
      whole.vertices.begin(), whole.vertices.end(),
      [&](const vec3& p) { return p[0] == box[0] || p[1] == box[1] || p[2] == box[2]; });
  ASSERT_TRUE(on_box_face) << "the cut is not clipped: the test checks nothing about clip vertices";
  expect_joins_equal(e, tris, "root cut");
}

// The engine's snapshots build large meshes in parts (one per 16 K records): the mesh is the
// one-thread mesh, vertex for vertex.
TEST(MeshJoin, engine_mesh_in_parts_equals_the_one_thread_mesh) {
  const volume v = make_gaussian_blobs({81, 77, 79}, 12, 8u);
  engine one(v, 0.4, [] {
    engine_options o;
    o.threads = 1;
    return o;
  }());
  engine all(v, 0.4);
  one.refine_full();
  all.refine_full();
  if (all.threads() < 2) GTEST_SKIP() << "one core: no parts";
  ASSERT_GE(all.statistics().published, 2u * 16384u) << "too few records for two parts";
  const triangle_mesh a = one.snapshot().mesh();
  const triangle_mesh b = all.snapshot().mesh();
  EXPECT_EQ(b.vertices, a.vertices);
  EXPECT_EQ(b.triangles, a.triangles);
  const triangle_mesh ca = one.snapshot().mesh_cut(0.05);
  const triangle_mesh cb = all.snapshot().mesh_cut(0.05);
  EXPECT_EQ(cb.vertices, ca.vertices);
  EXPECT_EQ(cb.triangles, ca.triangles);
}

}  // namespace
}  // namespace progiso
