// Invariant 2 (docs/ARCHITECTURE.md): every cut is a valid surface — edge-manifold, watertight away
// from the data box, consistently oriented, no degenerate triangle, no self-intersection (CGAL
// exact predicates) — for many random budgets and thresholds; and a cut's surface is exactly the
// marching-tetrahedra surface of the conforming bisection mesh that the cut defines.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/marching.hpp>

#include <map>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

void check_random_cuts(const volume& v, double w, unsigned seed, int cuts) {
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  const auto box = test::data_box(v);
  std::mt19937 rng(seed);
  // Triangle budgets.
  {
    refiner probe(v, h, ranges, w);
    const std::uint64_t root = probe.triangle_count();
    probe.refine_full();
    const std::uint64_t full = probe.triangle_count();
    for (int i = 0; i < cuts; ++i) {
      const std::uint64_t k = std::uniform_int_distribution<std::uint64_t>(0, full)(rng);
      refiner r(v, h, ranges, w);
      r.refine_to_triangles(k);
      EXPECT_LE(r.triangle_count(), std::max(k, root));
      const triangle_mesh m = r.extract();
      EXPECT_TRUE(test::check_valid_cut(m, box[0], box[1])) << "budget " << k;
    }
  }
  // Error thresholds, and coarser cuts taken from the records of a full refinement.
  refiner full(v, h, ranges, w);
  full.refine_full();
  for (int i = 0; i < cuts; ++i) {
    const double eps = std::uniform_real_distribution<double>(0.0, 1.0)(rng);
    const double scaled = eps * eps * (v.value_range()[1] - v.value_range()[0]) * 0.5;
    refiner r(v, h, ranges, w);
    r.refine_to_error(scaled);
    EXPECT_LE(r.next_error(), scaled);
    EXPECT_TRUE(test::check_valid_cut(r.extract(), box[0], box[1])) << "error " << scaled;
    const triangle_mesh sub = full.extract_cut(scaled);
    EXPECT_TRUE(test::check_valid_cut(sub, box[0], box[1])) << "sub-cut at error " << scaled;
    EXPECT_TRUE(test::same_surface(sub, r.extract())) << "cut by error " << scaled;
  }
}

TEST(CutValidity, random_cuts_of_analytic_fields_are_valid_surfaces) {
  check_random_cuts(make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}), 11.0, 1, 6);
  check_random_cuts(make_sphere_field({26, 21, 19}, {24.0, 2.0, 17.5}), 12.0, 2, 6);
  check_random_cuts(make_gyroid_field({27, 25, 30}, 10.0), 0.1, 3, 6);
  check_random_cuts(make_gaussian_blobs({37, 30, 33}, 9, 11u), 0.3, 4, 6);
}

TEST(CutValidity, random_cuts_of_shared_volumes_are_valid_surfaces) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const char* name : {"bucky", "nucleon", "headsq"}) {
    const auto* info = test::find_shared_volume(name);
    ASSERT_NE(info, nullptr);
    const volume v = test::load_shared_volume(*info, *dir);
    SCOPED_TRACE(name);
    check_random_cuts(v, info->isovalues[0], 7, 4);
  }
}

// Leaf tetrahedra of the cut: start from the root tetrahedra and bisect every tetrahedron whose
// owning diamond (centred at the midpoint of its longest edge) the refiner has split. Written
// here from the bisection rule alone.
std::vector<std::array<ipoint, 4>> leaf_tets(const hierarchy& h, const refiner& r) {
  std::vector<std::array<ipoint, 4>> todo, leaves;
  std::array<std::array<ipoint, 4>, 6> roots{};
  for (std::uint64_t i = 0; i < h.root_count(); ++i) {
    h.root_tets(i, roots);
    todo.insert(todo.end(), roots.begin(), roots.end());
  }
  while (!todo.empty()) {
    const auto t = todo.back();
    todo.pop_back();
    std::size_t a = 0, b = 1;
    std::int64_t best = -1;
    for (std::size_t i = 0; i < 4; ++i)
      for (std::size_t j = i + 1; j < 4; ++j) {
        std::int64_t l = 0;
        for (std::size_t q = 0; q < 3; ++q)
          l += std::int64_t{t[i][q] - t[j][q]} * (t[i][q] - t[j][q]);
        if (l > best) {
          best = l;
          a = i;
          b = j;
        }
      }
    const ipoint m{(t[a][0] + t[b][0]) / 2, (t[a][1] + t[b][1]) / 2, (t[a][2] + t[b][2]) / 2};
    const bool integral = (t[a][0] + t[b][0]) % 2 == 0 && (t[a][1] + t[b][1]) % 2 == 0 &&
                          (t[a][2] + t[b][2]) % 2 == 0;
    if (integral && r.is_split(m)) {
      auto t1 = t, t2 = t;
      t1[b] = m;
      t2[a] = m;
      todo.push_back(t1);
      todo.push_back(t2);
    } else {
      leaves.push_back(t);
    }
  }
  return leaves;
}

TEST(CutValidity, cut_surface_is_marching_tetrahedra_of_its_conforming_mesh) {
  const volume v = make_gaussian_blobs({33, 33, 33}, 10, 5u);  // 2^L + 1: no clipping
  const double w = 0.3;
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  for (const std::uint64_t budget : {0ull, 200ull, 1500ull, 6000ull}) {
    refiner r(v, h, ranges, w);
    r.refine_to_triangles(budget);
    const auto leaves = leaf_tets(h, r);
    // Conforming: every leaf face is shared by exactly two leaves or lies on the grid boundary.
    std::map<std::array<ipoint, 3>, int> faces;
    for (auto t : leaves) {
      std::sort(t.begin(), t.end());
      for (std::size_t skip = 0; skip < 4; ++skip) {
        std::array<ipoint, 3> f{};
        for (std::size_t i = 0, k = 0; i < 4; ++i)
          if (i != skip) f[k++] = t[i];
        ++faces[f];
      }
    }
    for (const auto& [f, n] : faces) {
      bool on_boundary = false;
      for (std::size_t q = 0; q < 3; ++q) {
        on_boundary = on_boundary || (f[0][q] == f[1][q] && f[1][q] == f[2][q] &&
                                      (f[0][q] == 0 || f[0][q] == h.grid_max()[q]));
      }
      EXPECT_EQ(n, on_boundary ? 1 : 2) << "non-conforming face";
    }
    // Marching tetrahedra over the leaves, as position triangles.
    triangle_mesh expected;
    std::map<std::uint64_t, std::uint32_t> ids;
    for (const auto& t : leaves) {
      std::array<double, 4> f{};
      for (std::size_t i = 0; i < 4; ++i) f[i] = v.value(t[i][0], t[i][1], t[i][2]);
      const tet_surface s = march_tet(t, f, w);
      for (int k = 0; k < s.count; ++k) {
        std::array<std::uint32_t, 3> tri{};
        for (std::size_t j = 0; j < 3; ++j) {
          const std::uint64_t key = s.triangles[static_cast<std::size_t>(k)][j];
          auto [it, inserted] =
              ids.try_emplace(key, static_cast<std::uint32_t>(expected.vertices.size()));
          if (inserted) {
            const auto e = h.edge_ends(key);
            expected.vertices.push_back(interpolate(e[0], v.value(e[0][0], e[0][1], e[0][2]), e[1],
                                                    v.value(e[1][0], e[1][1], e[1][2]), w));
          }
          tri[j] = it->second;
        }
        expected.triangles.push_back(tri);
      }
    }
    EXPECT_TRUE(test::same_surface(r.extract(), expected)) << "budget " << budget;
  }
}

}  // namespace
}  // namespace progiso
