// The 2D diamond hierarchy's arithmetic against a brute-force longest-edge bisection written here:
// uniformly bisect the root squares, group the triangles split at each step by the midpoint of
// their longest edge, and compare with what hierarchy2d computes from the centre alone.
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

using triangle = std::array<ipoint2, 3>;

triangle sorted(triangle t) {
  std::sort(t.begin(), t.end());
  return t;
}

std::int64_t len2(const ipoint2& a, const ipoint2& b) {
  const std::int64_t dx = a[0] - b[0];
  const std::int64_t dy = a[1] - b[1];
  return dx * dx + dy * dy;
}

struct brute_force {
  std::map<ipoint2, std::set<triangle>> diamond_triangles;  // centre -> triangles split there
  std::map<ipoint2, std::set<ipoint2>> parents;
  std::set<triangle> roots;
  std::set<triangle> finest;
  std::set<std::pair<ipoint2, ipoint2>> edges;  // every edge of every triangle ever present
};

// Root squares of side n tiled sx × sy; each cut into 2 triangles by the diagonal from its
// corner at even multiples of n to its corner at odd multiples (written independently here).
brute_force bisect(std::int32_t n, const ipoint2& squares) {
  std::vector<std::pair<triangle, ipoint2>> tris;  // triangle, centre of the split that made it
  const ipoint2 none{-1, -1};
  for (std::int32_t j = 0; j < squares[1]; ++j) {
    for (std::int32_t i = 0; i < squares[0]; ++i) {
      const ipoint2 m{i * n, j * n};
      ipoint2 e{};
      ipoint2 o{};
      for (std::size_t q = 0; q < 2; ++q) {
        const bool even = (m[q] / n) % 2 == 0;
        e[q] = even ? m[q] : m[q] + n;
        o[q] = even ? m[q] + n : m[q];
      }
      tris.push_back({{e, o, ipoint2{o[0], e[1]}}, none});
      tris.push_back({{e, o, ipoint2{e[0], o[1]}}, none});
    }
  }
  brute_force bf;
  for (const auto& t : tris) bf.roots.insert(sorted(t.first));
  while (true) {
    std::vector<std::pair<triangle, ipoint2>> next;
    bool any = false;
    for (const auto& [t, creator] : tris) {
      for (std::size_t a = 0; a < 3; ++a) {
        for (std::size_t b = a + 1; b < 3; ++b) {
          bf.edges.insert({std::min(t[a], t[b]), std::max(t[a], t[b])});
        }
      }
      std::size_t ba = 0;
      std::size_t bb = 1;
      for (std::size_t a = 0; a < 3; ++a) {
        for (std::size_t b = a + 1; b < 3; ++b) {
          if (len2(t[a], t[b]) > len2(t[ba], t[bb])) {
            ba = a;
            bb = b;
          }
        }
      }
      const ipoint2& pa = t[ba];
      const ipoint2& pb = t[bb];
      if ((pa[0] + pb[0]) % 2 != 0 || (pa[1] + pb[1]) % 2 != 0) {
        // The longest edge is a unit-square diagonal: this triangle is finest.
        next.push_back({t, creator});
        continue;
      }
      any = true;
      const ipoint2 mid{(pa[0] + pb[0]) / 2, (pa[1] + pb[1]) / 2};
      bf.diamond_triangles[mid].insert(sorted(t));
      if (creator != none) bf.parents[mid].insert(creator);
      triangle h1 = t;
      triangle h2 = t;
      h1[bb] = mid;
      h2[ba] = mid;
      next.push_back({h1, mid});
      next.push_back({h2, mid});
    }
    if (!any) break;
    tris = std::move(next);
  }
  for (const auto& [t, creator] : tris) bf.finest.insert(sorted(t));
  return bf;
}

std::string name(const ipoint2& p) { return std::to_string(p[0]) + "," + std::to_string(p[1]); }

void check_against_brute_force(std::int64_t width, std::int64_t height) {
  SCOPED_TRACE(std::to_string(width) + "x" + std::to_string(height));
  const hierarchy2d h(width, height);
  const brute_force bf = bisect(h.root_size(), h.squares());
  std::map<ipoint2, std::set<ipoint2>> children;
  for (const auto& [c, ps] : bf.parents) {
    for (const auto& p : ps) children[p].insert(c);
  }

  // Every grid vertex but the root corners is a diamond centre, and only those.
  std::size_t centres = 0;
  for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
      const ipoint2 p{x, y};
      const bool corner = x % h.root_size() == 0 && y % h.root_size() == 0;
      EXPECT_EQ(h.is_diamond(p), !corner) << name(p);
      EXPECT_EQ(bf.diamond_triangles.count(p) == 1, !corner) << name(p);
      centres += corner ? 0 : 1;
    }
  }
  EXPECT_EQ(centres, bf.diamond_triangles.size());
  EXPECT_EQ(h.vertex_count(), static_cast<std::uint64_t>(h.grid_max()[0] + 1) *
                                  static_cast<std::uint64_t>(h.grid_max()[1] + 1));

  int deepest = 0;
  for (const auto& [c, tris] : bf.diamond_triangles) {
    const diamond2 d = h.make_diamond(c);
    deepest = std::max(deepest, d.depth);
    EXPECT_EQ(d.centre, c);
    EXPECT_EQ(d.scale, h.scale_of(c));
    EXPECT_EQ(d.depth, h.depth_of(c));
    // The spine is the longest edge of every triangle split at c.
    const std::pair<ipoint2, ipoint2> spine{std::min(d.spine[0], d.spine[1]),
                                            std::max(d.spine[0], d.spine[1])};
    for (const triangle& t : tris) {
      EXPECT_TRUE(std::count(t.begin(), t.end(), spine.first) == 1 &&
                  std::count(t.begin(), t.end(), spine.second) == 1)
          << "spine of " << name(c);
    }
    // Triangles from spine and ring.
    std::set<triangle> mine;
    for (std::size_t m = 0; m < 2; ++m) {
      if ((d.ring_in_grid >> m) & 1u) mine.insert(sorted({d.spine[0], d.spine[1], d.ring[m]}));
      EXPECT_EQ(((d.ring_in_grid >> m) & 1u) != 0, h.in_grid(d.ring[m]));
    }
    EXPECT_EQ(mine, tris) << "triangles of diamond " << name(c);
    // Parents, one level up, and children.
    std::array<ipoint2, 2> ps{};
    const int np = h.parents(d, ps);
    const std::set<ipoint2> pset(ps.begin(), ps.begin() + np);
    const auto it = bf.parents.find(c);
    EXPECT_EQ(pset, it == bf.parents.end() ? std::set<ipoint2>{} : it->second)
        << "parents of " << name(c);
    for (const auto& p : pset) EXPECT_EQ(h.depth_of(p), d.depth - 1) << name(p);
    EXPECT_EQ(h.parent_count(c), np);
    EXPECT_EQ(d.depth == 0, np == 0) << name(c);
    std::array<ipoint2, 4> cs{};
    const int nc = h.children(d, cs);
    const std::set<ipoint2> cset(cs.begin(), cs.begin() + nc);
    const auto jt = children.find(c);
    EXPECT_EQ(cset, jt == children.end() ? std::set<ipoint2>{} : jt->second)
        << "children of " << name(c);
  }
  if (!bf.diamond_triangles.empty()) {
    EXPECT_EQ(deepest, h.max_depth());
  }

  // Root triangles (spine first) and root centres.
  std::set<triangle> roots;
  for (std::uint64_t r = 0; r < h.root_count(); ++r) {
    std::array<triangle, 2> rt{};
    h.root_triangles(r, rt);
    for (const triangle& t : rt) {
      roots.insert(sorted(t));
      EXPECT_EQ(len2(t[0], t[1]), 2 * std::int64_t{h.root_size()} * h.root_size());
    }
    if (h.root_size() >= 2) {
      const ipoint2 c = h.root_centre(r);
      EXPECT_EQ(c, (ipoint2{(rt[0][0][0] + rt[0][1][0]) / 2, (rt[0][0][1] + rt[0][1][1]) / 2}));
      EXPECT_EQ(h.depth_of(c), 0) << name(c);
      EXPECT_EQ(h.parent_count(c), 0) << name(c);
    }
  }
  EXPECT_EQ(roots, bf.roots);

  // Finest level: each unit square cut by the diagonal from its all-even to its all-odd corner.
  std::set<triangle> alternating;
  for (std::int32_t y = 0; y < h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x < h.grid_max()[0]; ++x) {
      const ipoint2 e{x % 2 == 0 ? x : x + 1, y % 2 == 0 ? y : y + 1};
      const ipoint2 o{x % 2 == 0 ? x + 1 : x, y % 2 == 0 ? y + 1 : y};
      alternating.insert(sorted({e, o, ipoint2{o[0], e[1]}}));
      alternating.insert(sorted({e, o, ipoint2{e[0], o[1]}}));
    }
  }
  EXPECT_EQ(bf.finest, alternating);

  // Edge keys name edges uniquely and decode back to their canonically ordered ends.
  std::map<std::uint64_t, std::pair<ipoint2, ipoint2>> by_key;
  for (const auto& [a, b] : bf.edges) {
    const std::uint64_t k = edge_key2(a, b);
    EXPECT_EQ(k, edge_key2(b, a));
    const auto [it, inserted] = by_key.try_emplace(k, a, b);
    EXPECT_TRUE(inserted || it->second == std::make_pair(a, b))
        << "edges " << name(a) << "-" << name(b) << " and " << name(it->second.first) << "-"
        << name(it->second.second) << " share a key";
    const ipoint2 mid2 = edge_key2_point(k);
    EXPECT_EQ(mid2, (ipoint2{a[0] + b[0], a[1] + b[1]}));
    const auto ends = h.edge_ends(k);
    const ipoint2 lo = vertex_less2(a, b) ? a : b;
    const ipoint2 hi = vertex_less2(a, b) ? b : a;
    EXPECT_EQ(ends[0], lo) << "edge " << name(a) << "-" << name(b);
    EXPECT_EQ(ends[1], hi) << "edge " << name(a) << "-" << name(b);
  }
}

TEST(Hierarchy2d, single_square_level_2_matches_brute_force_bisection) {
  check_against_brute_force(5, 5);
}
TEST(Hierarchy2d, single_square_level_3_matches_brute_force_bisection) {
  check_against_brute_force(9, 9);
}
TEST(Hierarchy2d, single_square_level_4_matches_brute_force_bisection) {
  check_against_brute_force(17, 17);
}
TEST(Hierarchy2d, smallest_hierarchies_match_brute_force_bisection) {
  check_against_brute_force(3, 3);
  check_against_brute_force(2, 2);
  check_against_brute_force(4, 3);
}
TEST(Hierarchy2d, forest_of_reflected_squares_matches_brute_force_bisection) {
  check_against_brute_force(9, 5);
  check_against_brute_force(7, 6);
  check_against_brute_force(17, 9);
  check_against_brute_force(6, 13);
  check_against_brute_force(2, 6);
}

TEST(Hierarchy2d, interior_diamonds_have_two_triangles_two_parents_four_children) {
  for (const auto& [w, hgt] : {std::pair<int, int>{33, 33}, {40, 21}}) {
    const hierarchy2d h(w, hgt);
    int interior = 0;
    for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
      for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
        const ipoint2 c{x, y};
        if (!h.is_diamond(c)) continue;
        const diamond2 d = h.make_diamond(c);
        // Interior: both triangles present, not a root, and not a finest edge midpoint.
        if (d.ring_in_grid != 3 || d.depth == 0 || (d.type == 1 && d.scale == 1)) continue;
        ++interior;
        std::array<ipoint2, 2> ps{};
        std::array<ipoint2, 4> cs{};
        EXPECT_EQ(h.parents(d, ps), 2) << name(c);
        EXPECT_EQ(h.children(d, cs), 4) << name(c);
      }
    }
    EXPECT_GT(interior, 100);
  }
}

TEST(Hierarchy2d, finest_edge_midpoints_have_no_children) {
  const hierarchy2d h(17, 17);
  std::array<ipoint2, 4> cs{};
  EXPECT_EQ(h.children(h.make_diamond({1, 2}), cs), 0);
  EXPECT_EQ(h.children(h.make_diamond({4, 7}), cs), 0);
  EXPECT_EQ(h.children(h.make_diamond({1, 1}), cs), 4);
}

TEST(Hierarchy2d, root_size_is_largest_power_of_two_within_the_smaller_side) {
  EXPECT_EQ(hierarchy2d(513, 513).root_size(), 512);
  EXPECT_EQ(hierarchy2d(512, 512).root_size(), 256);
  EXPECT_EQ(hierarchy2d(384, 303).root_size(), 256);
  EXPECT_EQ(hierarchy2d(384, 303).squares(), (ipoint2{2, 2}));
  EXPECT_EQ(hierarchy2d(403, 344).grid_max(), (ipoint2{512, 512}));
  EXPECT_EQ(hierarchy2d(403, 344).data_max(), (ipoint2{402, 343}));
  EXPECT_EQ(hierarchy2d(2, 9).root_size(), 1);
  EXPECT_EQ(hierarchy2d(129, 5).squares(), (ipoint2{32, 1}));
}

TEST(Hierarchy2d, point_inverts_index_over_the_whole_grid) {
  for (const auto& [w, h] : {std::pair{5, 9}, std::pair{17, 4}, std::pair{40, 33}}) {
    const hierarchy2d hier(w, h);
    std::uint64_t expected = 0;
    for (std::int32_t y = 0; y <= hier.grid_max()[1]; ++y) {
      for (std::int32_t x = 0; x <= hier.grid_max()[0]; ++x, ++expected) {
        const ipoint2 p{x, y};
        ASSERT_EQ(hier.index(p), expected);
        ASSERT_EQ(hier.point(expected), p) << w << "x" << h;
      }
    }
    EXPECT_EQ(expected, hier.vertex_count());
  }
}

TEST(Hierarchy2d, rejects_too_small_and_too_large_images) {
  EXPECT_THROW(hierarchy2d(1, 5), error);
  EXPECT_THROW(hierarchy2d(5, 1), error);
  EXPECT_THROW(hierarchy2d(5, (std::int64_t{1} << 20) + 2), error);
}

}  // namespace
}  // namespace progiso
