// The extraction without vertex hashing (core/surface/detail/cut_mesher.hpp): its rank index,
// and its meshes against an extraction that names vertices by a hash of edge keys
// (tests/support/hashed_mesh.hpp).
#include <progiso/core/surface/detail/cut_mesher.hpp>

#include <progiso/core/field/analytic.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <functional>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "support/hashed_mesh.hpp"
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

TEST(CutIndex, a_walk_from_any_rank_gives_the_members_in_order) {
  std::mt19937 rng(5);
  // Densities down to one member in a few hundred, so the dense walk crosses empty words, and
  // members at both ends of the grid.
  for (const double density : {0.003, 0.3, 1.0}) {
    constexpr std::uint64_t n = 4099;
    std::bernoulli_distribution pick(density);
    std::vector<std::uint64_t> members{0};
    for (std::uint64_t v = 1; v + 1 < n; ++v) {
      if (pick(rng)) members.push_back(v);
    }
    members.push_back(n - 1);
    detail::cut_index dense = detail::cut_index::dense(n);
    for (const std::uint64_t v : members) dense.add(v);
    dense.finish({}, 3);
    const detail::cut_index sparse = detail::cut_index::sparse(members);
    for (std::uint64_t first = 0; first < members.size(); ++first) {
      detail::cut_index::walk d(dense, first);
      detail::cut_index::walk s(sparse, first);
      for (std::uint64_t r = first; r < members.size(); ++r) {
        ASSERT_EQ(d.next(), members[r]) << "dense, from rank " << first;
        ASSERT_EQ(s.next(), members[r]) << "sparse, from rank " << first;
      }
    }
  }
}

// A cut_source made from a split set directly (compute_split per diamond, compute_root per root
// cube), for cut_mesher on any number of parts.
struct split_set_cut {
  struct entry {
    std::uint64_t diamond;
    std::int32_t scale;
    const packed_group* groups;
    std::uint32_t count;
    std::uint32_t crossed;
  };
  std::vector<std::vector<packed_group>> groups;
  std::vector<entry> list;
  std::vector<owned_triangle> roots;

  split_set_cut(const hierarchy& h, const volume& v, double w,
                const std::vector<std::uint64_t>& split) {
    for (std::uint64_t r = 0; r < h.root_count(); ++r) (void)compute_root(h, v, w, r, roots);
    groups.resize(split.size());
    list.push_back({no_owner, 0, nullptr, 0, 0});
    for (std::size_t i = 0; i < split.size(); ++i) {
      const ipoint c = h.point(split[i]);
      const std::int32_t scale = h.scale_of(c);
      const split_summary s = compute_split(h, v, w, c, scale, groups[i]);
      list.push_back({split[i], scale, groups[i].data(),
                      static_cast<std::uint32_t>(groups[i].size()), s.crossed});
    }
  }
  [[nodiscard]] std::uint64_t records() const noexcept { return list.size(); }
  [[nodiscard]] const entry& record(std::uint64_t r) const noexcept { return list[r]; }
  [[nodiscard]] bool split(std::uint64_t) const noexcept { return true; }
  [[nodiscard]] const std::vector<owned_triangle>& root_triangles() const noexcept { return roots; }
};

engine_options with_threads(unsigned n) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = n;
  return o;
}

std::vector<std::uint64_t> split_set_of(const surface_snapshot& s) {
  std::vector<std::uint64_t> split;
  s.for_each_split([&split](std::uint64_t d) { split.push_back(d); });
  return split;
}

// Each surface vertex once: as many vertices as the hashed extraction of the same cut (which
// merges vertices by edge key, tests/support/hashed_mesh.hpp), the same oriented surface, every
// vertex used. On a grid of 2^k + 1 and on padded grids (clipping at the data box), for the root
// cut, partial cuts, cuts by error and the full cut, on one and two threads. The sequential
// refiner extracts through the same cut_mesher: its meshes equal the engine's vertex for vertex.
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
    const auto check = [&](const triangle_mesh& mine, const std::vector<std::uint64_t>& split) {
      const triangle_mesh hashed = test::hashed_mesh_of(h, v, w, split);
      EXPECT_EQ(mine.vertices.size(), hashed.vertices.size());
      EXPECT_EQ(mine.triangles.size(), hashed.triangles.size());
      EXPECT_TRUE(test::same_surface(mine, hashed));
      EXPECT_TRUE(test::check_valid_cut(mine, box[0], box[1]));
    };
    const auto equal = [](const triangle_mesh& engine_mesh, const triangle_mesh& refiner_mesh) {
      EXPECT_EQ(engine_mesh.vertices, refiner_mesh.vertices);
      EXPECT_EQ(engine_mesh.triangles, refiner_mesh.triangles);
    };
    for (const unsigned threads : {1u, 2u}) {
      SCOPED_TRACE(threads);
      engine e(v, w, with_threads(threads));
      refiner root(v, h, ranges, w);
      check(e.snapshot().mesh(), split_set_of(e.snapshot()));
      equal(e.snapshot().mesh(), root.extract());
      // Partial cuts: the engine's split set replayed by the refiner (error order).
      for (const double eps : {0.3, 0.05}) {
        refiner r(v, h, ranges, w);
        r.refine_to_error(eps);
        ASSERT_TRUE(e.refine_until(eps));
        const surface_snapshot s = e.snapshot();
        check(s.mesh(), split_set_of(s));
        equal(s.mesh(), r.extract());
      }
      refiner full(v, h, ranges, w);
      full.refine_full();
      ASSERT_TRUE(e.refine_full());
      const surface_snapshot s = e.snapshot();
      const std::vector<std::uint64_t> all = split_set_of(s);
      check(s.mesh(), all);
      equal(s.mesh(), full.extract());
      ASSERT_GT(s.mesh().triangles.size(), 100u);
      for (const double eps : {0.5, 0.1, 0.02}) {
        SCOPED_TRACE(eps);
        std::vector<std::uint64_t> coarse;
        for (const std::uint64_t d : all) {
          if (ranges.get(h.make_diamond(h.point(d))).error > eps) coarse.push_back(d);
        }
        ASSERT_LT(coarse.size(), all.size());
        check(s.mesh_cut(eps), coarse);
        equal(s.mesh_cut(eps), full.extract_cut(eps));
      }
    }
  }
}

// Parts are pieces of every pass: any number of them, run in any order, gives the mesh of one,
// vertex for vertex; on a padded grid whose root cut is clipped at the data box (crossing points
// shared between parts by position) and on finer cuts.
TEST(CutMesher, any_number_of_parts_gives_the_one_part_mesh_vertex_for_vertex) {
  const volume v = make_marschner_lobb({19, 23, 21});
  const hierarchy h(v.dims());
  engine e(v, 0.5, with_threads(1));
  const parallel_loop backwards = [](std::size_t n, const std::function<void(std::size_t)>& body) {
    for (std::size_t i = n; i-- > 0;) body(i);
  };
  for (const double eps : {-1.0, 0.2, 0.02, 0.0}) {
    SCOPED_TRACE(eps);
    if (eps > 0) {
      ASSERT_TRUE(e.refine_until(eps));
    } else if (eps == 0) {
      ASSERT_TRUE(e.refine_full());
    }
    std::vector<std::uint64_t> split;
    e.snapshot().for_each_split([&](std::uint64_t d) { split.push_back(d); });
    const split_set_cut cut(h, v, 0.5, split);
    detail::cut_mesher one(cut, h, v, 0.5);
    const triangle_mesh whole = one.build({}, 1);
    ASSERT_GT(whole.triangles.size(), 20u);
    EXPECT_EQ(whole.vertices.size(), e.snapshot().mesh().vertices.size());
    EXPECT_TRUE(test::same_surface(whole, e.snapshot().mesh()));
    if (eps < 0) {
      const auto& box = h.data_max();
      ASSERT_TRUE(std::any_of(whole.vertices.begin(), whole.vertices.end(), [&](const vec3& p) {
        return p[0] == box[0] || p[1] == box[1] || p[2] == box[2];
      })) << "the root cut is not clipped: nothing is checked about crossing points";
    }
    for (const std::size_t parts : {2u, 3u, 7u, 16u}) {
      detail::cut_mesher many(cut, h, v, 0.5);
      const triangle_mesh m = many.build(backwards, parts);
      EXPECT_EQ(m.vertices, whole.vertices) << parts << " parts";
      EXPECT_EQ(m.triangles, whole.triangles) << parts << " parts";
    }
  }
}

// The engine's snapshots build large meshes in parts (one per 16 K records): the mesh is the
// one-thread mesh, vertex for vertex.
TEST(CutMesher, engine_mesh_in_parts_equals_the_one_thread_mesh) {
  const volume v = make_gaussian_blobs({81, 77, 79}, 12, 8u);
  engine one(v, 0.4, with_threads(1));
  engine all(v, 0.4, with_threads(0));  // all cores, by records
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
