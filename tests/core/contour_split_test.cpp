// The paper's 2D cases (a)–(h) (Figure 3) and their boundary variants: for every colouring of the
// five vertices of an interior diamond and the four of a boundary one, the split is classified as
// the paper's text says, and executing its primitive sequence on the old segments yields exactly
// the marching-triangles segments of the new triangles. Hand-built configurations pin the exact
// sequence of each case.
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/contour_split.hpp>

#include <algorithm>
#include <set>

#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/contour/detail/contour_frontier.hpp>
#include <progiso/core/contour/range_data2d.hpp>

#include <gtest/gtest.h>

namespace progiso {
namespace {

// A 3x3 image: one root square (N = 2) whose centre (1, 1) is a diamond with two triangles, and
// whose border edge midpoints, e.g. (1, 0), are diamonds with one triangle.
volume image3(const std::array<double, 9>& v) {
  std::vector<std::byte> b(9 * sizeof(float));
  auto* f = reinterpret_cast<float*>(b.data());
  for (std::size_t i = 0; i < 9; ++i) f[i] = static_cast<float>(v[i]);
  return volume({3, 3, 1}, sample_type::f32, std::move(b));
}

std::set<key_segment> undirected(const std::vector<key_segment>& s) { return {s.begin(), s.end()}; }

key_segment und(std::uint64_t a, std::uint64_t b) {
  return a < b ? key_segment{a, b} : key_segment{b, a};
}

// Old segments of the diamond's triangles, and the classification the paper's text gives.
struct expectation {
  std::vector<key_segment> old_segments;
  contour_case kind;
};

expectation expect(const diamond2& d, const volume& img, double w) {
  expectation x;
  const auto f = [&](const ipoint2& p) { return img.value(p[0], p[1], 0); };
  const auto black = [&](const ipoint2& p) { return f(p) > w; };
  std::vector<ipoint2> sides;
  for (std::size_t m = 0; m < 2; ++m) {
    if ((d.ring_in_grid >> m) & 1u) sides.push_back(d.ring[m]);
  }
  for (const ipoint2& s : sides) {
    std::array<std::uint64_t, 2> k{};
    if (march_triangle({d.spine[0], d.spine[1], s}, {f(d.spine[0]), f(d.spine[1]), f(s)}, w, k)) {
      x.old_segments.push_back(und(k[0], k[1]));
    }
  }
  const bool c = black(d.spine[0]), dd = black(d.spine[1]), e = black(d.centre);
  const bool a = black(sides[0]);
  const bool b = sides.size() == 2 ? black(sides[1]) : a;
  const bool one = sides.size() == 1;
  if (c != dd) {
    // §3.1: a = b → (a) if also = e, else (b); a ≠ b → (c). One triangle: (a) or (b).
    x.kind = (a == b) ? (a == e ? contour_case::a : contour_case::b) : contour_case::c;
  } else if (c == e) {
    x.kind = (a == b) ? (a == c ? contour_case::none : contour_case::d) : contour_case::e;
    if (one) x.kind = a == c ? contour_case::none : contour_case::d;
  } else {
    x.kind = (a == b) ? (a == c ? contour_case::g : contour_case::h) : contour_case::f;
    if (one) x.kind = a == c ? contour_case::g : contour_case::h;
  }
  return x;
}

void check_all_colourings(const ipoint2& centre, const std::vector<std::size_t>& pixel_of_vertex) {
  // pixel_of_vertex: c, d, e, A[, B] as row-major pixel indices in the 3x3 image.
  const hierarchy2d h(3, 3);
  const diamond2 d = h.make_diamond(centre);
  const std::size_t n = pixel_of_vertex.size();
  std::array<int, contour_case_count> seen{};
  for (unsigned mask = 0; mask < (1u << n); ++mask) {
    std::array<double, 9> px{};
    for (std::size_t i = 0; i < n; ++i) px[pixel_of_vertex[i]] = (mask >> i) & 1u ? 1.0 : 0.0;
    const volume img = image3(px);
    const expectation x = expect(d, img, 0.5);
    std::vector<owned_segment> out;
    const contour_split_summary s = compute_contour_split(h, img, 0.5, d, out);
    EXPECT_EQ(s.kind, x.kind) << "mask " << mask;
    EXPECT_EQ(s.boundary, n == 4);
    EXPECT_EQ(s.removed_segments, static_cast<int>(x.old_segments.size()));
    std::vector<key_segment> segs = x.old_segments;
    apply_contour_ops(segs, s.ops.data(), s.op_count);
    std::vector<key_segment> fresh;
    for (const auto& o : out) fresh.push_back(und(o.keys[0], o.keys[1]));
    EXPECT_EQ(undirected(segs), undirected(fresh))
        << "mask " << mask << " case " << to_string(s.kind);
    EXPECT_EQ(segs.size(), fresh.size()) << "mask " << mask;
    // The refiners' split takes the case and the primitives' kinds from its class's table entry
    // instead of the rules above: the same, and the class names them too.
    std::vector<detail::placed_segment> placed;
    const contour_split_summary p = detail::compute_placed_contour_split(h, img, 0.5, d, placed);
    const contour_split_class& k = contour_split_class_info(s.split_class);
    EXPECT_EQ(p.split_class, s.split_class) << "mask " << mask;
    EXPECT_EQ(p.kind, s.kind) << "mask " << mask;
    EXPECT_EQ(k.kind, s.kind) << "mask " << mask;
    ASSERT_EQ(p.op_count, s.op_count) << "mask " << mask;
    ASSERT_EQ(static_cast<int>(k.op_count), s.op_count) << "mask " << mask;
    for (std::size_t i = 0; i < static_cast<std::size_t>(s.op_count); ++i) {
      EXPECT_EQ(p.ops[i].kind, s.ops[i].kind) << "mask " << mask << " op " << i;
      EXPECT_EQ(k.ops[i], s.ops[i].kind) << "mask " << mask << " op " << i;
    }
    ++seen[static_cast<std::size_t>(s.kind)];
  }
  for (std::size_t k = 0; k < contour_case_count; ++k) {
    if (n == 5) {
      EXPECT_GT(seen[k], 0) << "case " << to_string(static_cast<contour_case>(k));
    }
  }
}

TEST(ContourSplit,
     every_colouring_of_an_interior_diamond_is_classified_and_its_primitives_are_exact) {
  const hierarchy2d h(3, 3);
  const diamond2 d = h.make_diamond({1, 1});
  ASSERT_EQ(d.ring_in_grid, 3);
  const auto pix = [](const ipoint2& p) { return static_cast<std::size_t>(p[0] + 3 * p[1]); };
  check_all_colourings(
      {1, 1}, {pix(d.spine[0]), pix(d.spine[1]), pix(d.centre), pix(d.ring[0]), pix(d.ring[1])});
}

TEST(ContourSplit,
     every_colouring_of_a_boundary_diamond_is_classified_and_its_primitives_are_exact) {
  const hierarchy2d h(3, 3);
  for (const ipoint2 c : {ipoint2{1, 0}, ipoint2{0, 1}, ipoint2{2, 1}, ipoint2{1, 2}}) {
    const diamond2 d = h.make_diamond(c);
    ASSERT_EQ(__builtin_popcount(d.ring_in_grid), 1);
    const ipoint2 apex = (d.ring_in_grid & 1u) ? d.ring[0] : d.ring[1];
    const auto pix = [](const ipoint2& p) { return static_cast<std::size_t>(p[0] + 3 * p[1]); };
    check_all_colourings(c, {pix(d.spine[0]), pix(d.spine[1]), pix(d.centre), pix(apex)});
  }
}

// Exact sequences, by case, on the interior diamond (two triangles) and a boundary one.
std::vector<contour_primitive> kinds(const contour_split_summary& s) {
  std::vector<contour_primitive> k;
  for (int i = 0; i < s.op_count; ++i) k.push_back(s.ops[static_cast<std::size_t>(i)].kind);
  return k;
}

contour_split_summary split_with(const ipoint2& centre, double c, double d, double e, double a,
                                 double b) {
  const hierarchy2d h(3, 3);
  const diamond2 dm = h.make_diamond(centre);
  std::array<double, 9> px{};
  const auto set = [&](const ipoint2& p, double v) {
    px[static_cast<std::size_t>(p[0] + 3 * p[1])] = v;
  };
  set(dm.spine[0], c);
  set(dm.spine[1], d);
  set(dm.centre, e);
  if (dm.ring_in_grid & 1u) set(dm.ring[0], a);
  if (dm.ring_in_grid & 2u) set(dm.ring[1], b);
  std::vector<owned_segment> out;
  return compute_contour_split(h, image3(px), 0.5, dm, out);
}

TEST(ContourSplit, each_case_uses_the_primitives_listed_for_it) {
  using P = contour_primitive;
  const ipoint2 in{1, 1};
  struct row {
    double c, d, e, a, b;
    contour_case kind;
    std::vector<P> ops;
  };
  const std::vector<row> rows{
      {1, 0, 1, 1, 1, contour_case::a, {P::vertex_move}},
      {1, 0, 1, 0, 0, contour_case::b, {P::vertex_move, P::vertex_split, P::vertex_split}},
      {1, 0, 1, 1, 0, contour_case::c, {P::vertex_move, P::vertex_split}},
      {1, 1, 1, 0, 0, contour_case::d, {P::vertex_split, P::vertex_split}},
      {1, 1, 1, 0, 1, contour_case::e, {P::vertex_split}},
      {1, 1, 0, 0, 1, contour_case::f, {P::vertex_split, P::vertex_split, P::vertex_split}},
      {1, 1, 0, 1, 1, contour_case::g, {P::new_loop}},
      {1, 1, 0, 0, 0, contour_case::h, {P::edge_flip, P::vertex_split, P::vertex_split}},
      {1, 1, 1, 1, 1, contour_case::none, {}},
  };
  for (const row& r : rows) {
    const contour_split_summary s = split_with(in, r.c, r.d, r.e, r.a, r.b);
    EXPECT_EQ(s.kind, r.kind) << to_string(r.kind);
    EXPECT_EQ(kinds(s), r.ops) << to_string(r.kind);
  }
  // Boundary variants: (1, 0) has its triangle on the side of ring vertex (1, 1).
  const ipoint2 bd{1, 0};
  const std::vector<row> boundary{
      {1, 0, 0, 0, 0, contour_case::a, {P::vertex_move}},
      {1, 0, 1, 0, 0, contour_case::b, {P::vertex_move, P::vertex_split}},
      {1, 1, 1, 0, 0, contour_case::d, {P::vertex_split}},
      {1, 1, 0, 1, 1, contour_case::g, {P::new_edge, P::vertex_split}},
      {1, 1, 0, 0, 0, contour_case::h, {P::vertex_split, P::vertex_open}},
  };
  for (const row& r : boundary) {
    const contour_split_summary s = split_with(bd, r.c, r.d, r.e, r.a, r.b);
    EXPECT_TRUE(s.boundary);
    EXPECT_EQ(s.kind, r.kind) << "boundary " << to_string(r.kind);
    EXPECT_EQ(kinds(s), r.ops) << "boundary " << to_string(r.kind);
  }
}

// The contour after the split, as the refiner extracts it: the root of a 3x3 image is the
// interior diamond (1, 1), so one split gives exactly the four new triangles.
struct shape {
  std::size_t polylines;
  std::size_t closed;
  std::vector<std::size_t> sizes;  // vertices per polyline, sorted
};

shape contour_after_root_split(double c, double d, double e, double a, double b) {
  const hierarchy2d h(3, 3);
  const diamond2 dm = h.make_diamond({1, 1});
  std::array<double, 9> px{};
  const auto set = [&](const ipoint2& p, double v) {
    px[static_cast<std::size_t>(p[0] + 3 * p[1])] = v;
  };
  set(dm.spine[0], c);
  set(dm.spine[1], d);
  set(dm.centre, e);
  set(dm.ring[0], a);
  set(dm.ring[1], b);
  const volume img = image3(px);
  const range_data2d ranges(img, h);
  contour_refiner r(img, h, ranges, 0.5);
  if (!r.done()) r.split_next();
  const contour_set cs = r.extract();
  shape s{cs.polylines.size(), 0, {}};
  for (const auto& p : cs.polylines) {
    s.closed += p.closed ? 1 : 0;
    s.sizes.push_back(p.vertices.size());
  }
  std::sort(s.sizes.begin(), s.sizes.end());
  return s;
}

TEST(ContourSplit, each_case_gives_the_polylines_of_figure_3) {
  struct row {
    double c, d, e, a, b;
    const char* name;
    std::size_t polylines, closed;
    std::vector<std::size_t> sizes;
  };
  const std::vector<row> rows{
      {1, 0, 1, 1, 1, "a: the spine vertex moves", 1, 0, {3}},
      {1, 0, 1, 0, 0, "b: chain CA-EA-ED-EB-CB", 1, 0, {5}},
      {1, 0, 1, 1, 0, "c: chain DA-ED-EB-CB", 1, 0, {4}},
      {1, 1, 1, 0, 0, "d: two chains CX-EX-DX", 2, 0, {3, 3}},
      {1, 1, 1, 0, 1, "e: one chain CA-EA-DA", 1, 0, {3}},
      {1, 1, 0, 0, 1, "f: chain CA-CE-BE-DE-DA", 1, 0, {5}},
      {1, 1, 0, 1, 1, "g: a new closed loop CE-AE-DE-BE", 1, 1, {4}},
      {1, 1, 0, 0, 0, "h: chains CA-CE-CB and DA-DE-DB", 2, 0, {3, 3}},
  };
  for (const row& r : rows) {
    const shape got = contour_after_root_split(r.c, r.d, r.e, r.a, r.b);
    EXPECT_EQ(got.polylines, r.polylines) << r.name;
    EXPECT_EQ(got.closed, r.closed) << r.name;
    EXPECT_EQ(got.sizes, r.sizes) << r.name;
  }
}

TEST(ContourSplit, primitives_refuse_segments_that_are_not_there) {
  std::vector<key_segment> segs{{1, 2}};
  const contour_op flip{contour_primitive::edge_flip, {1, 2, 3, 4}};
  EXPECT_THROW(apply_contour_ops(segs, &flip, 1), error);
  const contour_op move{contour_primitive::vertex_move, {7, 8, no_key, no_key}};
  EXPECT_THROW(apply_contour_ops(segs, &move, 1), error);
}

TEST(ContourSplit, segments_keep_the_larger_values_on_their_left) {
  // Triangle with one black vertex at the origin corner.
  const std::array<ipoint2, 3> t{ipoint2{0, 0}, ipoint2{2, 0}, ipoint2{0, 2}};
  std::array<std::uint64_t, 2> k{};
  ASSERT_TRUE(march_triangle(t, {1.0, 0.0, 0.0}, 0.5, k));
  const ipoint2 p = edge_key2_point(k[0]);
  const ipoint2 q = edge_key2_point(k[1]);
  // Black vertex (0,0) doubled: cross(q - p, 0 - p) > 0.
  const std::int64_t cross =
      std::int64_t{q[0] - p[0]} * (0 - p[1]) - std::int64_t{q[1] - p[1]} * (0 - p[0]);
  EXPECT_GT(cross, 0);
}

// A padded noisy image with plateaus (values equal to some isovalues): 7 levels, 40 apart.
volume noisy_image(std::int64_t width, std::int64_t height) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(width * height));
  for (std::int64_t y = 0; y < height; ++y) {
    for (std::int64_t x = 0; x < width; ++x) {
      const std::uint64_t s = (static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15u) ^
                              (static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4Fu);
      bytes[static_cast<std::size_t>(x + width * y)] = static_cast<std::byte>(((s >> 29) % 7) * 40);
    }
  }
  return volume({width, height, 1}, sample_type::u8, std::move(bytes));
}

TEST(ContourSplit, split_segments_are_marching_triangles_of_each_new_triangle_with_its_owner) {
  // The split marches its new triangles by a table, places each crossed edge once and takes the
  // owner from the spine end and the apex. Against the definition: for every diamond of a padded
  // image, at four isovalues, the segments are march_triangle() of (spine0, centre, apex) and then
  // (centre, spine1, apex) for each apex in the grid, in that order and direction, each owned by
  // the diamond centred on its triangle's longest edge (none when that edge is a finest one).
  const volume img = noisy_image(23, 14);
  const hierarchy2d hier(23, 14);
  const auto longest_edge_owner = [&](const std::array<ipoint2, 3>& t) {
    std::int64_t best = -1;
    ipoint2 sum{};
    for (std::size_t i = 0; i < 3; ++i) {
      const std::array<ipoint2, 2> e{t[i], t[(i + 1) % 3]};
      const std::int64_t dx = e[0][0] - e[1][0], dy = e[0][1] - e[1][1];
      if (dx * dx + dy * dy > best) {
        best = dx * dx + dy * dy;
        sum = {e[0][0] + e[1][0], e[0][1] + e[1][1]};
      }
    }
    if ((sum[0] | sum[1]) & 1) return detail::no_owner2;
    const ipoint2 m{sum[0] / 2, sum[1] / 2};
    return hier.is_diamond(m) ? hier.index(m) : detail::no_owner2;
  };
  std::size_t total = 0;
  for (const double w : {40.0, 100.0, 120.5, 200.0}) {
    for (std::int32_t y = 0; y <= hier.grid_max()[1]; ++y) {
      for (std::int32_t x = 0; x <= hier.grid_max()[0]; ++x) {
        if (!hier.is_diamond({x, y})) continue;
        const diamond2 d = hier.make_diamond({x, y});
        const auto f = [&](const ipoint2& p) { return img.value(p[0], p[1], 0); };
        std::vector<owned_segment> want;
        int removed = 0;
        for (std::size_t m = 0; m < 2; ++m) {
          if (!((d.ring_in_grid >> m) & 1u)) continue;
          const ipoint2& a = d.ring[m];
          std::array<std::uint64_t, 2> k{};
          if (march_triangle({d.spine[0], d.spine[1], a}, {f(d.spine[0]), f(d.spine[1]), f(a)}, w,
                             k)) {
            ++removed;
          }
          for (const std::array<ipoint2, 3>& t :
               {std::array<ipoint2, 3>{d.spine[0], d.centre, a},
                std::array<ipoint2, 3>{d.centre, d.spine[1], a}}) {
            if (march_triangle(t, {f(t[0]), f(t[1]), f(t[2])}, w, k)) {
              want.push_back({longest_edge_owner(t), k});
            }
          }
        }
        std::vector<owned_segment> got;
        const contour_split_summary s = compute_contour_split(hier, img, w, d, got);
        EXPECT_EQ(s.removed_segments, removed) << "diamond (" << x << ", " << y << "), w " << w;
        EXPECT_EQ(s.added_segments, static_cast<int>(want.size()));
        ASSERT_EQ(got.size(), want.size()) << "diamond (" << x << ", " << y << "), w " << w;
        for (std::size_t i = 0; i < got.size(); ++i) {
          EXPECT_EQ(got[i].owner, want[i].owner) << "diamond (" << x << ", " << y << "), w " << w;
          EXPECT_EQ(got[i].keys, want[i].keys) << "diamond (" << x << ", " << y << "), w " << w;
        }
        total += got.size();
      }
    }
  }
  EXPECT_GT(total, 300u);
}

TEST(ContourSplit, placed_split_gives_the_segments_and_the_vertex_positions_of_their_keys) {
  // The refiners publish segments with positions computed while marching; readers and tests
  // place a key from its edge's ends (place_contour_vertex). Every diamond of a padded noisy
  // image with plateaus (values equal to w), at three isovalues: the same segments, in the same
  // order, and exactly the same positions, both ends.
  const std::int64_t width = 23;
  const std::int64_t height = 14;
  const volume img = noisy_image(width, height);
  const hierarchy2d hier(width, height);
  std::size_t placed_total = 0;
  for (const double w : {40.0, 100.0, 120.5}) {
    for (std::int32_t y = 0; y <= hier.grid_max()[1]; ++y) {
      for (std::int32_t x = 0; x <= hier.grid_max()[0]; ++x) {
        if (!hier.is_diamond({x, y})) continue;
        const diamond2 d = hier.make_diamond({x, y});
        std::vector<owned_segment> plain;
        std::vector<detail::placed_segment> placed;
        const contour_split_summary a = compute_contour_split(hier, img, w, d, plain);
        const contour_split_summary b =
            detail::compute_placed_contour_split(hier, img, w, d, placed);
        EXPECT_EQ(a.added_segments, b.added_segments);
        EXPECT_EQ(a.removed_segments, b.removed_segments);
        ASSERT_EQ(plain.size(), placed.size());
        for (std::size_t i = 0; i < plain.size(); ++i) {
          EXPECT_EQ(placed[i].seg.owner, plain[i].owner);
          EXPECT_EQ(placed[i].seg.keys, plain[i].keys);
          for (std::size_t e = 0; e < 2; ++e) {
            EXPECT_EQ(placed[i].pos[e],
                      detail::place_contour_vertex(hier, img, w, plain[i].keys[e]))
                << "diamond (" << x << ", " << y << "), w " << w << ", segment " << i;
          }
        }
        placed_total += placed.size();
      }
    }
  }
  EXPECT_GT(placed_total, 200u);
}

}  // namespace
}  // namespace progiso
