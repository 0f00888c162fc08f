// The diamond hierarchy's arithmetic against a brute-force longest-edge bisection written here:
// uniformly bisect the root tetrahedra, group the tetrahedra split at each step by the midpoint
// of their longest edge, and compare with what hierarchy computes from the centre alone.
#include <progiso/core/hierarchy/hierarchy.hpp>

#include <algorithm>
#include <map>
#include <set>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

using tet = std::array<ipoint, 4>;

tet sorted(tet t) {
  std::sort(t.begin(), t.end());
  return t;
}

std::int64_t len2(const ipoint& a, const ipoint& b) {
  std::int64_t s = 0;
  for (std::size_t q = 0; q < 3; ++q) s += std::int64_t{a[q] - b[q]} * (a[q] - b[q]);
  return s;
}

struct brute_force {
  std::map<ipoint, std::set<tet>> diamond_tets;  // centre -> tets split at that centre
  std::map<ipoint, std::set<ipoint>> parents;
  std::set<tet> finest;
  std::set<std::pair<ipoint, ipoint>> edges;  // every edge of every tet ever present
};

// Root cubes of side n tiled cx × cy × cz; each cut into 6 tets around the diagonal from the
// corner at even multiples of n to the corner at odd multiples (written independently here).
brute_force bisect(std::int32_t n, ipoint cubes) {
  std::vector<std::pair<tet, ipoint>> tets;  // tet, centre of the split that created it
  const ipoint none{-1, -1, -1};
  for (std::int32_t k = 0; k < cubes[2]; ++k)
    for (std::int32_t j = 0; j < cubes[1]; ++j)
      for (std::int32_t i = 0; i < cubes[0]; ++i) {
        const ipoint m{i * n, j * n, k * n};
        ipoint e{}, o{};
        for (std::size_t q = 0; q < 3; ++q) {
          const bool even = ((m[q] / n) % 2) == 0;
          e[q] = even ? m[q] : m[q] + n;
          o[q] = even ? m[q] + n : m[q];
        }
        std::array<int, 3> perm{0, 1, 2};
        do {
          tet t{};
          ipoint p = e;
          t[0] = p;
          for (std::size_t s = 0; s < 3; ++s) {
            const auto q = static_cast<std::size_t>(perm[s]);
            p[q] = o[q];
            t[s + 1] = p;
          }
          tets.push_back({t, none});
        } while (std::next_permutation(perm.begin(), perm.end()));
      }
  brute_force bf;
  while (true) {
    std::vector<std::pair<tet, ipoint>> next;
    bool any = false;
    for (const auto& [t, creator] : tets) {
      for (std::size_t a = 0; a < 4; ++a)
        for (std::size_t b = a + 1; b < 4; ++b) {
          bf.edges.insert({std::min(t[a], t[b]), std::max(t[a], t[b])});
        }
      std::size_t ba = 0, bb = 1;
      for (std::size_t a = 0; a < 4; ++a)
        for (std::size_t b = a + 1; b < 4; ++b)
          if (len2(t[a], t[b]) > len2(t[ba], t[bb])) {
            ba = a;
            bb = b;
          }
      const ipoint& pa = t[ba];
      const ipoint& pb = t[bb];
      if ((pa[0] + pb[0]) % 2 || (pa[1] + pb[1]) % 2 || (pa[2] + pb[2]) % 2) {
        bf.finest.insert(sorted(t));
        next.push_back({t, creator});
        continue;
      }
      any = true;
      const ipoint mid{(pa[0] + pb[0]) / 2, (pa[1] + pb[1]) / 2, (pa[2] + pb[2]) / 2};
      bf.diamond_tets[mid].insert(sorted(t));
      if (creator != none) bf.parents[mid].insert(creator);
      tet h1 = t, h2 = t;
      h1[bb] = mid;
      h2[ba] = mid;
      next.push_back({h1, mid});
      next.push_back({h2, mid});
    }
    if (!any) break;
    tets = std::move(next);
    bf.finest.clear();
  }
  return bf;
}

void check_against_brute_force(const index3& dims) {
  const hierarchy h(dims);
  const brute_force bf = bisect(h.root_size(), h.cubes());
  std::map<ipoint, std::set<ipoint>> children;
  for (const auto& [c, ps] : bf.parents)
    for (const auto& p : ps) children[p].insert(c);

  // Every grid vertex but the root corners is a diamond centre, and only those.
  std::size_t centres = 0;
  for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
    for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
      for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
        const ipoint p{x, y, z};
        const bool corner =
            x % h.root_size() == 0 && y % h.root_size() == 0 && z % h.root_size() == 0;
        EXPECT_EQ(h.is_diamond(p), !corner);
        EXPECT_EQ(bf.diamond_tets.count(p) == 1, !corner);
        centres += corner ? 0 : 1;
      }
  EXPECT_EQ(centres, bf.diamond_tets.size());

  for (const auto& [c, tets] : bf.diamond_tets) {
    const diamond d = h.make_diamond(c);
    // Tetrahedra from spine and ring.
    std::set<tet> mine;
    for (int m = 0; m < d.ring_size; ++m) {
      const int m1 = (m + 1) % d.ring_size;
      if (((d.ring_in_grid >> m) & 1u) && ((d.ring_in_grid >> m1) & 1u)) {
        mine.insert(sorted({d.spine[0], d.spine[1], d.ring[static_cast<std::size_t>(m)],
                            d.ring[static_cast<std::size_t>(m1)]}));
      }
    }
    EXPECT_EQ(mine, tets) << "tets of diamond " << c[0] << "," << c[1] << "," << c[2];
    // Parents and children.
    std::array<ipoint, 4> ps{};
    const int np = h.parents(d, ps);
    const std::set<ipoint> pset(ps.begin(), ps.begin() + np);
    const auto it = bf.parents.find(c);
    EXPECT_EQ(pset, it == bf.parents.end() ? std::set<ipoint>{} : it->second)
        << "parents of " << c[0] << "," << c[1] << "," << c[2];
    for (const auto& p : pset) EXPECT_EQ(h.depth_of(p), d.depth - 1);
    EXPECT_EQ(h.parent_count(c), np);
    std::array<ipoint, 8> cs{};
    const int nc = h.children(d, cs);
    const std::set<ipoint> cset(cs.begin(), cs.begin() + nc);
    const auto jt = children.find(c);
    EXPECT_EQ(cset, jt == children.end() ? std::set<ipoint>{} : jt->second)
        << "children of " << c[0] << "," << c[1] << "," << c[2];
    std::array<ipoint, 8> cs2{};
    const int nc2 = h.children(c, cs2);  // from the centre alone
    EXPECT_EQ(std::set<ipoint>(cs2.begin(), cs2.begin() + nc2), cset);
    // From the parent's scale and type: the same children, in children()'s order, each with
    // its brute-force number of parents, scale and type.
    EXPECT_EQ(hierarchy::type_of(c, d.scale), d.type);
    const child_list cl = h.children_of(c, d.scale, d.type);
    ASSERT_EQ(cl.count, nc2);
    for (int i = 0; i < cl.count; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      const ipoint& x = cl.centre[ui];
      EXPECT_EQ(x, cs2[ui]);
      const auto px = bf.parents.find(x);
      ASSERT_NE(px, bf.parents.end());
      EXPECT_EQ(cl.parents[ui], px->second.size())
          << "parents of child " << x[0] << "," << x[1] << "," << x[2];
      EXPECT_EQ(cl.scale, h.scale_of(x));
      EXPECT_EQ(cl.type, h.make_diamond(x).type);
    }
    EXPECT_EQ(d.depth == 0, np == 0);
  }

  // Finest level: each unit cube cut into 6 tets around the all-even to all-odd diagonal, as
  // cube_tetrahedra() lists them (finest_surface() and the root cubes use it).
  std::set<tet> kuhn;
  for (std::int32_t z = 0; z < h.grid_max()[2]; ++z)
    for (std::int32_t y = 0; y < h.grid_max()[1]; ++y)
      for (std::int32_t x = 0; x < h.grid_max()[0]; ++x) {
        for (const tet& t : cube_tetrahedra({x, y, z}, 1)) kuhn.insert(sorted(t));
      }
  EXPECT_EQ(bf.finest, kuhn);

  // Edge keys name edges uniquely and decode back to their ends.
  std::map<std::uint64_t, std::pair<ipoint, ipoint>> by_key;
  for (const auto& [a, b] : bf.edges) {
    const std::uint64_t k = edge_key(a, b);
    const auto [it, inserted] = by_key.try_emplace(k, a, b);
    EXPECT_TRUE(inserted || it->second == std::make_pair(a, b)) << "two edges share a key";
    const auto ends = h.edge_ends(k);
    const ipoint lo = vertex_less(a, b) ? a : b;
    const ipoint hi = vertex_less(a, b) ? b : a;
    EXPECT_EQ(ends[0], lo);
    EXPECT_EQ(ends[1], hi);
  }
}

TEST(Hierarchy, single_cube_level_2_matches_brute_force_bisection) {
  check_against_brute_force({5, 5, 5});
}
TEST(Hierarchy, single_cube_level_3_matches_brute_force_bisection) {
  check_against_brute_force({9, 9, 9});
}
TEST(Hierarchy, forest_of_reflected_cubes_matches_brute_force_bisection) {
  check_against_brute_force({9, 5, 5});
  check_against_brute_force({6, 7, 5});
  // Roots of 8 chosen over 16 (a 24³ grid instead of 32³): a forest of 3 × 3 × 3 cubes.
  ASSERT_EQ(hierarchy({20, 20, 20}).root_size(), 8);
  check_against_brute_force({20, 20, 20});
}

TEST(Hierarchy, interior_diamonds_have_the_documented_sizes) {
  const hierarchy h({17, 17, 17});
  const std::array<std::array<int, 3>, 3> expected{{{6, 3, 6}, {4, 2, 4}, {8, 4, 8}}};
  for (std::int32_t z = 2; z <= 14; ++z)
    for (std::int32_t y = 2; y <= 14; ++y)
      for (std::int32_t x = 2; x <= 14; ++x) {
        const ipoint c{x, y, z};
        const diamond d = h.make_diamond(c);
        if (d.depth == 0 || d.scale > 2 || (d.type == 2 && d.scale == 1)) continue;
        std::array<ipoint, 4> ps{};
        std::array<ipoint, 8> cs{};
        const auto t = static_cast<std::size_t>(d.type);
        EXPECT_EQ(d.ring_size, expected[t][0]);
        EXPECT_EQ(h.parents(d, ps), expected[t][1]);
        EXPECT_EQ(h.children(d, cs), expected[t][2]);
      }
}

TEST(Hierarchy, root_size_is_the_largest_power_of_two_with_little_padding) {
  // Samples 2^L + 1 per axis: N = 2^L, no padding.
  EXPECT_EQ(hierarchy({257, 257, 257}).root_size(), 256);
  EXPECT_EQ(hierarchy({257, 257, 257}).grid_max(), (ipoint{256, 256, 256}));
  EXPECT_EQ(hierarchy({64, 64, 93}).root_size(), 32);
  const hierarchy h({64, 64, 93});
  EXPECT_EQ(h.cubes(), (ipoint{2, 2, 3}));
  EXPECT_EQ(hierarchy({32, 32, 32}).cubes(), (ipoint{2, 2, 2}));
  EXPECT_EQ(hierarchy({2, 9, 9}).root_size(), 1);
  // 68³ (hipip): roots of 64 would pad to 128³; roots of 8 pad to 72³.
  EXPECT_EQ(hierarchy({68, 68, 68}).root_size(), 8);
  EXPECT_EQ(hierarchy({68, 68, 68}).grid_max(), (ipoint{72, 72, 72}));
  // 41³ (nucleon): roots of 8 fit exactly; 32 would pad to 64³.
  EXPECT_EQ(hierarchy({41, 41, 41}).grid_max(), (ipoint{40, 40, 40}));

  // The rule, checked by enumeration: among N = 2^l with min(8, Nmax) ≤ N ≤ Nmax (Nmax the
  // largest power of two within the smallest extent), the largest whose padded grid has at
  // most 1.25 times the vertices of the smallest padded grid in that range.
  const auto padded = [](const index3& d, std::int64_t n) {
    double v = 1.0;
    for (std::size_t q = 0; q < 3; ++q) v *= static_cast<double>((d[q] - 1 + n - 1) / n * n + 1);
    return v;
  };
  for (std::int64_t x = 2; x <= 140; x += 7)
    for (std::int64_t y = 2; y <= 140; y += 11)
      for (std::int64_t z = 2; z <= 300; z += 13) {
        const index3 d{x, y, z};
        std::int64_t nmax = 1;
        while (2 * nmax <= std::min({x, y, z}) - 1) nmax *= 2;
        const std::int64_t nmin = std::min<std::int64_t>(8, nmax);
        double fewest = padded(d, nmax);
        for (std::int64_t n = nmin; n < nmax; n *= 2) fewest = std::min(fewest, padded(d, n));
        std::int64_t expected = nmax;
        while (expected > nmin && padded(d, expected) > 1.25 * fewest) expected /= 2;
        const hierarchy hx(d);
        EXPECT_EQ(hx.root_size(), expected) << x << "," << y << "," << z;
        for (std::size_t q = 0; q < 3; ++q) {
          EXPECT_GE(hx.grid_max()[q], d[q] - 1);
          EXPECT_LT(hx.grid_max()[q] - (d[q] - 1), hx.root_size());  // less than one root cube
        }
      }
}

TEST(Hierarchy, point_inverts_index_on_every_row_and_slab_boundary_up_to_the_largest_grid) {
  // point() divides by reciprocal multiplication; the quotient must be exact where it is an
  // integer or one below (the first and last vertex of every row and slab), up to the largest
  // grid the hierarchy accepts (32769 samples per axis: indices near 2^45).
  for (const index3 d :
       {index3{2, 2, 2}, index3{257, 257, 257}, index3{93, 64, 301}, index3{32769, 32769, 32769},
        index3{32769, 3, 32769}, index3{5, 32769, 17}}) {
    const hierarchy h(d);
    const ipoint g = h.grid_max();
    const auto check = [&](const ipoint& p) {
      ASSERT_EQ(h.point(h.index(p)), p) << d[0] << "x" << d[1] << "x" << d[2];
    };
    const int step_z = std::max(1, g[2] / 97);
    const int step_y = std::max(1, g[1] / 89);
    for (int z = 0; z <= g[2]; z += step_z)
      for (int y = 0; y <= g[1]; y += step_y) {
        for (const int x : {0, 1, g[0] - 1, g[0]}) check({std::max(x, 0), y, z});
        check({g[0], std::max(y - 1, 0), z});
      }
    check(g);
    EXPECT_EQ(h.index(g) + 1, h.vertex_count());
  }
}

// half_offset_index() names a packed group's owner: the grid index of c + (h/2)·o from c's, for
// every code of o in {-2..2}³ whose point is a grid vertex, at every scale, on padded grids up to
// the largest one (indices near 2^45, offsets of both signs).
TEST(Hierarchy, half_offset_index_is_the_index_of_the_offset_point_for_every_code_and_scale) {
  std::uint64_t checked = 0;
  for (const index3 d : {index3{19, 13, 22}, index3{257, 257, 257}, index3{32769, 3, 32769}}) {
    const hierarchy h(d);
    const ipoint g = h.grid_max();
    for (std::int32_t hs = 1; hs < h.root_size(); hs *= 2) {
      // A centre of scale hs in the middle of the grid, and one near its far corner.
      for (const ipoint c :
           {ipoint{g[0] / (2 * hs) * hs, g[1] / (2 * hs) * hs, g[2] / (2 * hs) * hs},
            ipoint{g[0] - hs, g[1] - hs, g[2] - hs}}) {
        for (unsigned code = 0; code < 125; ++code) {
          const std::array<int, 3> o{static_cast<int>(code % 5) - 2,
                                     static_cast<int>(code / 5 % 5) - 2,
                                     static_cast<int>(code / 25) - 2};
          bool whole = true;
          ipoint p{};
          for (std::size_t q = 0; q < 3; ++q) {
            whole = whole && (hs * o[q]) % 2 == 0;
            p[q] = c[q] + hs * o[q] / 2;
          }
          if (!whole || !h.in_grid(p) || !h.in_grid(c)) continue;
          ASSERT_EQ(h.half_offset_index(h.index(c), hs, code), h.index(p))
              << d[0] << "x" << d[1] << "x" << d[2] << " h " << hs << " code " << code;
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 1000u);
}

}  // namespace
}  // namespace progiso
