// The extraction without vertex hashing (core/surface/detail/cut_mesher.hpp): its rank index,
// and its meshes against the sequential refiner's, which names vertices by a hash of edge keys.
#include <progiso/core/surface/detail/cut_mesher.hpp>

#include <progiso/core/field/analytic.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/scheduler/engine.hpp>

#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"

namespace progiso {
namespace {

TEST(CutIndex, dense_and_sparse_agree_with_a_count_of_the_members_below) {
  std::mt19937 rng(3);
  for (const double density : {0.01, 0.3, 0.9}) {
    constexpr std::uint64_t n = 5000;
    std::bernoulli_distribution pick(density);
    std::vector<bool> member(n);
    std::vector<std::uint64_t> members;
    for (std::uint64_t v = 0; v < n; ++v) {
      member[v] = pick(rng);
      if (member[v]) members.push_back(v);
    }
    detail::cut_index dense = detail::cut_index::dense(n);
    for (auto it = members.rbegin(); it != members.rend(); ++it) dense.add(*it);
    dense.finish({}, 7);
    const detail::cut_index sparse = detail::cut_index::sparse(members);
    EXPECT_EQ(dense.size(), members.size());
    EXPECT_EQ(sparse.size(), members.size());
    std::uint32_t below = 0;
    for (std::uint64_t v = 0; v < n; ++v) {
      EXPECT_EQ(dense.contains(v), member[v]) << v;
      EXPECT_EQ(sparse.contains(v), member[v]) << v;
      if (!member[v]) continue;
      EXPECT_EQ(dense.rank(v), below) << v;
      EXPECT_EQ(sparse.rank(v), below) << v;
      ++below;
    }
  }
}

engine_options with_threads(unsigned n) {
  engine_options o;
  o.threads = n;
  return o;
}

// Each surface vertex once: as many vertices as the hashed extraction of the same cut (which
// merges vertices by edge key), the same oriented surface, every vertex used. On a grid of
// 2^k + 1 and on padded grids (clipping at the data box), for the root cut, a partial cut, cuts
// by error and the full cut, on one and two threads.
TEST(CutMesher, each_surface_vertex_once_and_the_surface_of_the_hashed_extraction) {
  const std::vector<volume> volumes{make_marschner_lobb({33, 33, 33}),
                                    make_sphere_field({29, 21, 35}, {13.3, 9.6, 17.1}),
                                    make_marschner_lobb({23, 40, 19})};
  const std::vector<double> isovalues{0.5, 7.2, 0.3};
  for (std::size_t i = 0; i < volumes.size(); ++i) {
    const volume& v = volumes[i];
    const double w = isovalues[i];
    SCOPED_TRACE(i);
    const hierarchy h(v.dims());
    const range_data ranges(v, h);
    const auto box = test::data_box(v);
    const auto check = [&](const triangle_mesh& mine, const triangle_mesh& hashed) {
      EXPECT_EQ(mine.vertices.size(), hashed.vertices.size());
      EXPECT_EQ(mine.triangles.size(), hashed.triangles.size());
      EXPECT_TRUE(test::same_surface(mine, hashed));
      EXPECT_TRUE(test::check_valid_cut(mine, box[0], box[1]));
    };
    for (const unsigned threads : {1u, 2u}) {
      SCOPED_TRACE(threads);
      engine e(v, w, with_threads(threads));
      refiner root(v, h, ranges, w);
      check(e.snapshot().mesh(), root.extract());
      // A partial cut: the engine's split set replayed by the refiner (error order).
      for (const double eps : {0.3, 0.05}) {
        refiner r(v, h, ranges, w);
        r.refine_to_error(eps);
        ASSERT_TRUE(e.refine_until(eps));
        check(e.snapshot().mesh(), r.extract());
      }
      refiner full(v, h, ranges, w);
      full.refine_full();
      ASSERT_TRUE(e.refine_full());
      const surface_snapshot s = e.snapshot();
      check(s.mesh(), full.extract());
      ASSERT_GT(s.mesh().triangles.size(), 100u);
      for (const double eps : {0.5, 0.1, 0.02}) check(s.mesh_cut(eps), full.extract_cut(eps));
    }
  }
}

}  // namespace
}  // namespace progiso
