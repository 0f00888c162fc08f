// The compact form of split records (packed_group) against the plain one (owned_triangle).
#include <progiso/core/surface/split_record.hpp>

#include <progiso/core/surface/detail/split_classify.hpp>

#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

// Every diamond of a padded hierarchy (non-power-of-two dims: clipped rings, boundary diamonds
// of every scale) on a random field at two isovalues: the packed groups hold the same
// triangles, in the same order, with the same owners, and the same classification.
void check_packed_against_plain(const volume& v, std::initializer_list<double> isovalues) {
  const index3& dims = v.dims();
  const hierarchy h(dims);
  std::uint64_t diamonds = 0;
  std::uint64_t triangles = 0;
  for (const double w : isovalues) {
    for (std::uint64_t i = 0; i < h.vertex_count(); ++i) {
      const ipoint c = h.point(i);
      if (!h.is_diamond(c)) continue;
      const diamond d = h.make_diamond(c);
      std::vector<owned_triangle> plain;
      std::vector<packed_group> packed;
      const split_summary a = compute_split(h, v, w, d, plain);
      const split_summary b = compute_split(h, v, w, d, packed);
      ++diamonds;
      EXPECT_EQ(a.added_triangles, b.added_triangles);
      EXPECT_EQ(a.removed_triangles, b.removed_triangles);
      EXPECT_EQ(a.cases, b.cases);
      EXPECT_EQ(a.primitives, b.primitives);
      std::size_t k = 0;
      for (const packed_group& g : packed) {
        ASSERT_TRUE(g.count() == 1 || g.count() == 2);
        for (std::size_t t = 0; t < g.count(); ++t, ++k) {
          ASSERT_LT(k, plain.size());
          EXPECT_EQ(group_owner(h, i, d.scale, g), plain[k].owner);
          EXPECT_EQ(unpack(d.centre, d.scale, g, t), plain[k].keys) << "diamond " << i;
        }
      }
      EXPECT_EQ(k, plain.size());
      triangles += k;
      // crossed: exactly the new edges (centre, spine end or ring point in the grid) whose ends
      // lie on opposite sides of w.
      std::uint32_t crossed = 0;
      const auto above = [&](const ipoint& p) { return v.value(p[0], p[1], p[2]) > w; };
      const auto mark = [&](const ipoint& x) {
        if (above(x) == above(c)) return;
        crossed |= 1u << edge_offset_code(
                       {(x[0] - c[0]) / d.scale, (x[1] - c[1]) / d.scale, (x[2] - c[2]) / d.scale});
      };
      mark(d.spine[0]);
      mark(d.spine[1]);
      for (int m = 0; m < d.ring_size; ++m) {
        if (((d.ring_in_grid >> m) & 1u) != 0) mark(d.ring[static_cast<std::size_t>(m)]);
      }
      EXPECT_EQ(b.crossed, crossed) << "diamond " << i;
      // group_edges: each edge code of a group decodes to two points of the diamond whose edge
      // key is the one unpack() gives, the centre first when it is an end.
      const group_edge_table& edges = group_edges(c, d.scale);
      for (const packed_group& g : packed) {
        for (std::size_t t = 0; t < g.count(); ++t) {
          const auto keys = unpack(c, d.scale, g, t);
          for (std::size_t q = 0; q < 3; ++q) {
            const auto& e = edges[g.edge(t, q)];
            ASSERT_NE(e[1], centre_offset_code);
            const auto end = [&](unsigned code) {
              return ipoint{c[0] + d.scale * (static_cast<std::int32_t>(code % 3) - 1),
                            c[1] + d.scale * (static_cast<std::int32_t>(code / 3 % 3) - 1),
                            c[2] + d.scale * (static_cast<std::int32_t>(code / 9) - 1)};
            };
            EXPECT_EQ(edge_key(end(e[0]), end(e[1])), keys[q]) << "diamond " << i;
            // An edge from the centre is a crossed new edge.
            if (e[0] == centre_offset_code) {
              EXPECT_NE((b.crossed >> e[1]) & 1u, 0u);
            }
          }
        }
      }
    }
  }
  EXPECT_GT(diamonds, 1000u);
  EXPECT_GT(triangles, 1000u);
}

template <class T, class Dist>
volume random_volume(const index3& dims, sample_type type, Dist dist) {
  std::mt19937 rng(7);
  std::vector<std::byte> bytes(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]) * sizeof(T));
  for (std::size_t i = 0; i < bytes.size(); i += sizeof(T)) {
    const T s = static_cast<T>(dist(rng));
    std::memcpy(&bytes[i], &s, sizeof s);
  }
  return volume(dims, type, std::move(bytes));
}

TEST(SplitRecord, packed_groups_unpack_to_the_plain_records_for_every_diamond) {
  check_packed_against_plain(random_volume<float>({19, 13, 22}, sample_type::f32,
                                                  std::uniform_real_distribution<float>(0, 1)),
                             {0.5, 0.23});
}

// Integer samples are compared with the isovalue as integers on the packed path: fractional,
// negative and whole isovalues, and one beyond every sample.
TEST(SplitRecord, packed_groups_match_the_plain_records_on_integer_samples) {
  check_packed_against_plain(random_volume<std::int16_t>({19, 13, 22}, sample_type::i16,
                                                         std::uniform_int_distribution<int>(-8, 8)),
                             {-3.5, 0.0, 2.0, 7.75, -1e300});
}

// The rules of split_record.hpp applied one ring position and one tetrahedron at a time: the
// reference for detail::classify(), which evaluates them on bit sets.
split_summary classify_one_by_one(const detail::split_colours& k) {
  split_summary s;
  const int n = k.n;
  const auto colour = [&](int m) { return ((k.ring >> m) & 1u) != 0; };
  const auto in_grid = [&](int m) { return ((k.ring_in_grid >> m) & 1u) != 0; };
  const auto prev = [&](int m) { return m == 0 ? n - 1 : m - 1; };
  const auto add = [&](primitive p, int count = 1) {
    s.primitives[static_cast<std::size_t>(p)] =
        static_cast<std::uint16_t>(s.primitives[static_cast<std::size_t>(p)] + count);
  };
  int all_3a = 0;
  int all_4a = 0;
  for (int m = 0; m < n; ++m) {
    if (!k.tet_exists(m)) continue;
    const bool a = colour(m);
    const bool b = colour(m + 1 == n ? 0 : m + 1);
    ++s.tets;
    s.removed_triangles +=
        tet_triangle_count((k.c ? 1u : 0u) | (k.d ? 2u : 0u) | (a ? 4u : 0u) | (b ? 8u : 0u));
    tet_case tc{};
    if (k.c != k.d) {
      tc = a == b ? (k.e != a ? tet_case::c1b : tet_case::c1c)
                  : (k.e == k.c ? tet_case::c2b : tet_case::c2c);
    } else if (a == b && a == k.c) {
      tc = k.e == k.c ? tet_case::c3b : tet_case::c3c;
      ++all_3a;
    } else if (a == b) {
      tc = k.e == k.c ? tet_case::c4b : tet_case::c4c;
      ++all_4a;
    } else {
      tc = k.e == k.c ? tet_case::c5b : tet_case::c5c;
    }
    ++s.cases[static_cast<std::size_t>(tc)];
  }
  const auto ring_splits = [&] {
    for (int m = 0; m < n; ++m) {
      const bool any = k.tet_exists(m) || k.tet_exists(prev(m));
      if (!in_grid(m) || !any || colour(m) == k.e) continue;
      add(k.tet_exists(m) && k.tet_exists(prev(m)) ? primitive::vertex_split
                                                   : primitive::vertex_open);
    }
  };
  if (k.c != k.d) {
    s.configuration = split_configuration::spine_crossed;
    add(primitive::vertex_move);
    ring_splits();
  } else if (k.e == k.c) {
    s.configuration = split_configuration::no_new_crossing;
    ring_splits();
  } else if (all_3a == s.tets) {
    s.configuration = split_configuration::empty_region;
    bool closed = true;
    for (int m = 0; m < n; ++m) closed = closed && k.tet_exists(m);
    add(closed ? primitive::new_loop : primitive::new_surf);
  } else if (all_4a == s.tets) {
    s.configuration = split_configuration::cylinder;
    add(primitive::cylinder_flip);
  } else {
    int components = 0;
    for (int m = 0; m < n; ++m) {
      if (!in_grid(m) || colour(m) == k.c) continue;
      const bool continues = k.tet_exists(prev(m)) && colour(prev(m)) != k.c;
      if (!continues) ++components;
    }
    if (components == 0) components = 1;
    s.configuration = components == 1 ? split_configuration::single_component
                                      : split_configuration::multiple_components;
    add(primitive::vertex_split, components);
    ring_splits();
    add(primitive::edge_flip, all_4a);
    add(primitive::connectivity_change, components - 1);
  }
  return s;
}

// Every ring size, every clipping of the ring by the grid and every colouring of the points.
TEST(SplitRecord, classification_by_bit_sets_matches_the_rules_for_every_colouring) {
  std::uint64_t checked = 0;
  for (const int n : {4, 6, 8}) {
    for (unsigned in_grid = 0; in_grid < (1u << n); ++in_grid) {
      for (unsigned colouring = 0; colouring < (1u << (n + 3)); ++colouring) {
        detail::split_colours k;
        k.n = n;
        k.ring_in_grid = in_grid;
        k.c = (colouring & 1u) != 0;
        k.d = (colouring & 2u) != 0;
        k.e = (colouring & 4u) != 0;
        k.ring = (colouring >> 3) & in_grid;  // colours off the grid are never read
        split_summary got;
        detail::classify(k, got);
        const split_summary want = classify_one_by_one(k);
        ASSERT_EQ(got.tets, want.tets) << n << " " << in_grid << " " << colouring;
        ASSERT_EQ(got.removed_triangles, want.removed_triangles);
        ASSERT_EQ(got.cases, want.cases) << n << " " << in_grid << " " << colouring;
        ASSERT_EQ(got.configuration, want.configuration) << n << " " << in_grid << " " << colouring;
        ASSERT_EQ(got.primitives, want.primitives) << n << " " << in_grid << " " << colouring;
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 16u * 128 + 64u * 512 + 256u * 2048);
}

}  // namespace
}  // namespace progiso
