// Progressive 2D contours: exact at full resolution (equal to the independent marching-triangles
// reference on the finest mesh, directed segments included), valid at every cut, equal to the
// marching-triangles contour of each cut's conforming mesh, traversable without the image, and
// the one-shot modes with several isovalues.
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/contour/contour_split.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "support/contour_checks.hpp"
#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

volume make_image(std::int64_t w, std::int64_t h, double (*f)(double, double)) {
  return test::make_test_image(w, h, f);
}

double circle(double x, double y) { return std::hypot(x - 20.3, y - 17.6); }
double waves(double x, double y) {
  return std::sin(x * 0.21) * std::cos(y * 0.17) + 0.4 * std::sin((x + 2 * y) * 0.05);
}
double edge_cut(double x, double y) { return std::hypot(x - 44.0, y + 3.0); }

struct fixture {
  volume img;
  hierarchy2d h;
  range_data2d ranges;
  explicit fixture(volume v) : img(std::move(v)), h(img.dims()[0], img.dims()[1]), ranges(img, h) {}
};

void expect_full_equals_reference(const volume& img, double w) {
  const hierarchy2d h(img.dims()[0], img.dims()[1]);
  const range_data2d ranges(img, h);
  contour_refiner r(img, h, ranges, w, contour_order::breadth_first);
  r.refine_full();
  const contour_set mine = r.extract();
  EXPECT_TRUE(test::same_segments(mine, test::reference_contours(img, w)));
  EXPECT_TRUE(test::check_valid_contour(mine, test::image_box(img)));
}

TEST(ContourRefiner, full_resolution_equals_marching_triangles_on_analytic_images) {
  expect_full_equals_reference(make_image(41, 36, circle), 9.5);     // one closed loop
  expect_full_equals_reference(make_image(33, 33, circle), 12.25);   // 2^L + 1
  expect_full_equals_reference(make_image(70, 45, waves), 0.1);      // many components
  expect_full_equals_reference(make_image(50, 29, edge_cut), 20.0);  // open chains, padding
}

TEST(ContourRefiner, full_resolution_equals_marching_triangles_on_every_small_image_size) {
  // Border-heavy grids of every parity, root squares of side 1 (whose root record holds unit
  // edges: their vertices go through the key table) to 8: a split's record names the vertices
  // on its unit edges itself (contour_assembler::begin_record), the others go through the table.
  for (std::int64_t w = 2; w <= 11; ++w) {
    for (std::int64_t h = 2; h <= 11; ++h) {
      SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
      expect_full_equals_reference(make_image(w, h, waves), 0.1);
      expect_full_equals_reference(make_image(w, h, circle), 18.0);
    }
  }
  // Two samples thick: the root record alone holds every segment, many on unit edges.
  expect_full_equals_reference(make_image(2, 64, waves), 0.1);
  expect_full_equals_reference(make_image(64, 2, waves), 0.1);
}

TEST(ContourRefiner, full_resolution_equals_marching_triangles_on_images_wider_than_compact_keys) {
  // Vertex keys go into the assembler's table of 8-byte slots while the grid's doubled
  // coordinates fit in 16 bits (grid up to 32767 a side), else into the general one: both sides
  // of the limit (a 32769-sample side has a 32768 grid), on either axis.
  expect_full_equals_reference(make_image(32767, 3, waves), 0.1);
  expect_full_equals_reference(make_image(32769, 3, waves), 0.1);
  expect_full_equals_reference(make_image(3, 32769, waves), 0.1);
}

TEST(ContourRefiner, coordinates_are_physical_with_spacing_and_origin) {
  const volume grid = make_image(37, 26, waves);
  std::vector<std::byte> copy(grid.bytes(), grid.bytes() + grid.byte_size());
  const volume img(grid.dims(), grid.type(), std::move(copy), {2.0, 0.5, 1.0}, {10.0, -3.0, 0.0});
  expect_full_equals_reference(img, 0.1);
}

TEST(ContourRefiner, full_resolution_equals_marching_triangles_on_every_shared_image) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const auto& info : test::shared_images()) {
    const volume img = test::load_pgm(*dir / info.file);
    for (const double w : info.isovalues) {
      SCOPED_TRACE(std::string(info.name) + " at " + std::to_string(w));
      expect_full_equals_reference(img, w);
    }
  }
}

TEST(ContourRefiner, last_split_gives_the_split_just_made_with_its_vertex_keys) {
  // The summary is made again on demand. For each of the first splits (the diamond found as the
  // one point that became split): its segment counts follow the cut's, and its primitive
  // sequence turns the marching-triangles segments of the diamond's triangles into those of the
  // triangles that replace them.
  fixture f(make_image(41, 37, waves));
  const double w = 0.1;
  contour_refiner r(f.img, f.h, f.ranges, w);
  EXPECT_EQ(r.last_split().op_count, 0);  // nothing split yet
  const auto val = [&](const ipoint2& p) { return f.img.value(p[0], p[1], 0); };
  const auto segment = [&](const std::array<ipoint2, 3>& t, std::vector<key_segment>& out) {
    std::array<std::uint64_t, 2> k{};
    if (march_triangle(t, {val(t[0]), val(t[1]), val(t[2])}, w, k)) {
      out.push_back(k[0] < k[1] ? key_segment{k[0], k[1]} : key_segment{k[1], k[0]});
    }
  };
  std::vector<std::uint8_t> was_split(static_cast<std::size_t>(f.h.vertex_count()), 0);
  std::uint64_t segments = r.segment_count();
  int with_ops = 0;
  for (int i = 0; i < 300 && r.split_next(); ++i) {
    std::vector<ipoint2> fresh;
    for (std::int32_t y = 0; y <= f.h.grid_max()[1]; ++y) {
      for (std::int32_t x = 0; x <= f.h.grid_max()[0]; ++x) {
        auto& seen = was_split[static_cast<std::size_t>(f.h.index({x, y}))];
        if (r.is_split({x, y}) && seen == 0) fresh.push_back({x, y});
        seen = r.is_split({x, y}) ? 1 : 0;
      }
    }
    ASSERT_EQ(fresh.size(), 1u);
    const diamond2 d = f.h.make_diamond(fresh[0]);
    const contour_split_summary s = r.last_split();
    EXPECT_EQ(r.segment_count(), segments + static_cast<std::uint64_t>(s.added_segments) -
                                     static_cast<std::uint64_t>(s.removed_segments));
    segments = r.segment_count();
    std::vector<key_segment> before, after;
    for (std::size_t m = 0; m < 2; ++m) {
      if (!((d.ring_in_grid >> m) & 1u)) continue;
      segment({d.spine[0], d.spine[1], d.ring[m]}, before);
      segment({d.spine[0], d.centre, d.ring[m]}, after);
      segment({d.centre, d.spine[1], d.ring[m]}, after);
    }
    apply_contour_ops(before, s.ops.data(), s.op_count);
    std::sort(before.begin(), before.end());
    std::sort(after.begin(), after.end());
    EXPECT_EQ(before, after) << "split " << i;
    with_ops += s.op_count > 0 ? 1 : 0;
  }
  EXPECT_GT(with_ops, 20);
}

TEST(ContourRefiner, random_cuts_are_valid_contours) {
  std::mt19937 rng(5);
  for (const auto& [img, w] :
       {std::pair{make_image(70, 45, waves), 0.1}, std::pair{make_image(50, 29, edge_cut), 20.0}}) {
    fixture f(img);
    contour_refiner full(f.img, f.h, f.ranges, w);
    full.refine_full();
    const std::uint64_t all = full.segment_count();
    for (int i = 0; i < 8; ++i) {
      const auto k = std::uniform_int_distribution<std::uint64_t>(0, all)(rng);
      contour_refiner r(f.img, f.h, f.ranges, w);
      while (r.split_next(k)) {
      }
      EXPECT_TRUE(test::check_valid_contour(r.extract(), test::image_box(f.img))) << "budget " << k;
      const double eps = std::uniform_real_distribution<double>(0.0, 0.5)(rng);
      contour_refiner e(f.img, f.h, f.ranges, w);
      e.refine_to_error(eps);
      EXPECT_LE(e.next_error(), eps);
      const contour_set sub = full.extract_cut(eps);
      EXPECT_TRUE(test::check_valid_contour(sub, test::image_box(f.img)));
      EXPECT_TRUE(test::same_segments(sub, e.extract())) << "cut by error " << eps;
      const double x0 = std::uniform_real_distribution<double>(0.0, 40.0)(rng);
      const double y0 = std::uniform_real_distribution<double>(0.0, 20.0)(rng);
      EXPECT_TRUE(test::check_valid_contour(full.extract_region(x0, y0, x0 + 10, y0 + 8),
                                            test::image_box(f.img)));
    }
  }
}

TEST(ContourRefiner, cuts_by_error_are_the_contours_of_their_splits_both_sparse_and_dense) {
  // A cut asks whether a segment's owner is split in it of a bitmap of its splits when it has
  // one per 4096 grid vertices, of their sorted grid indices otherwise: cuts of a refinement,
  // each against a refiner that split exactly that set, on an image with contours everywhere
  // and one with a small circle in a corner.
  bool sparse = false;
  bool dense = false;
  for (const auto& [img, w] : {std::pair{make_image(1200, 900, waves), 0.1},
                               std::pair{make_image(1200, 900, circle), 8.0}}) {
    fixture f(img);
    contour_refiner full(f.img, f.h, f.ranges, w);
    full.refine_full();
    const std::uint64_t threshold = f.h.vertex_count() / 4096;
    for (const double eps : {0.5, 0.1, 0.0}) {
      contour_refiner e(f.img, f.h, f.ranges, w);
      e.refine_to_error(eps);
      const std::uint64_t splits = e.statistics().splits;
      sparse = sparse || (splits > 0 && splits <= threshold);
      dense = dense || splits > threshold;
      const contour_set cut = full.extract_cut(eps);
      EXPECT_TRUE(test::same_segments(cut, e.extract())) << "eps " << eps << ", " << splits;
      EXPECT_TRUE(test::check_valid_contour(cut, test::image_box(f.img))) << "eps " << eps;
    }
  }
  EXPECT_TRUE(sparse);
  EXPECT_TRUE(dense);
}

// Leaf triangles of the cut, from the bisection rule alone; marching triangles over them.
TEST(ContourRefiner, a_cut_is_the_marching_triangles_contour_of_its_conforming_mesh) {
  fixture f(make_image(33, 33, waves));
  const double w = 0.1;
  for (const std::uint64_t budget : {0ull, 40ull, 300ull, 900ull}) {
    contour_refiner r(f.img, f.h, f.ranges, w);
    while (r.split_next(budget)) {
    }
    std::vector<std::array<ipoint2, 3>> todo, leaves;
    std::array<std::array<ipoint2, 3>, 2> roots{};
    for (std::uint64_t i = 0; i < f.h.root_count(); ++i) {
      f.h.root_triangles(i, roots);
      todo.insert(todo.end(), roots.begin(), roots.end());
    }
    while (!todo.empty()) {
      const auto t = todo.back();
      todo.pop_back();
      std::size_t a = 0, b = 1;
      std::int64_t best = -1;
      for (std::size_t i = 0; i < 3; ++i)
        for (std::size_t j = i + 1; j < 3; ++j) {
          const std::int64_t dx = t[i][0] - t[j][0], dy = t[i][1] - t[j][1];
          if (dx * dx + dy * dy > best) {
            best = dx * dx + dy * dy;
            a = i;
            b = j;
          }
        }
      const bool integral = ((t[a][0] + t[b][0]) % 2 == 0) && ((t[a][1] + t[b][1]) % 2 == 0);
      const ipoint2 m{(t[a][0] + t[b][0]) / 2, (t[a][1] + t[b][1]) / 2};
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
    contour_set expected;
    std::map<std::uint64_t, std::uint32_t> ids;
    for (const auto& t : leaves) {
      std::array<double, 3> fv{};
      for (std::size_t i = 0; i < 3; ++i) fv[i] = f.img.value(t[i][0], t[i][1], 0);
      std::array<std::uint64_t, 2> k{};
      if (!march_triangle(t, fv, w, k)) continue;
      // The larger values lie on the segment's left: every black vertex of the leaf triangle
      // is strictly left of the placed segment (positions at least 1/4096 of an edge apart).
      {
        std::array<vec2, 2> pq{};
        for (std::size_t j = 0; j < 2; ++j) {
          const auto e = f.h.edge_ends(k[j]);
          pq[j] = interpolate2(e[0], f.img.value(e[0][0], e[0][1], 0), e[1],
                               f.img.value(e[1][0], e[1][1], 0), w);
        }
        for (std::size_t i = 0; i < 3; ++i) {
          if (!(fv[i] > w)) continue;
          const double cross = (pq[1][0] - pq[0][0]) * (t[i][1] - pq[0][1]) -
                               (pq[1][1] - pq[0][1]) * (t[i][0] - pq[0][0]);
          EXPECT_GT(cross, 0.0) << "black vertex right of its segment";
        }
      }
      polyline pl;
      pl.isovalue = w;
      for (const std::uint64_t key : k) {
        auto [it, inserted] =
            ids.try_emplace(key, static_cast<std::uint32_t>(expected.vertices.size()));
        if (inserted) {
          const auto e = f.h.edge_ends(key);
          expected.vertices.push_back(interpolate2(e[0], f.img.value(e[0][0], e[0][1], 0), e[1],
                                                   f.img.value(e[1][0], e[1][1], 0), w));
        }
        pl.vertices.push_back(it->second);
      }
      expected.polylines.push_back(pl);
    }
    EXPECT_TRUE(test::same_segments(r.extract(), expected)) << "budget " << budget;
  }
}

TEST(ContourRefiner, the_contour_hierarchy_is_traversed_without_the_image) {
  auto img = std::make_unique<volume>(make_image(70, 45, waves));
  const hierarchy2d h(70, 45);
  auto ranges = std::make_unique<range_data2d>(*img, h);
  contour_refiner r(*img, h, *ranges, 0.1);
  r.refine_full();
  const contour_set coarse = r.extract_cut(0.05);
  const contour_set region = r.extract_region(10, 10, 30, 25);
  const contour_set all = r.extract();
  // Free the image and the range data: the records and the vertex table are enough (an access
  // would be a use-after-free, which the sanitizer build reports).
  ranges.reset();
  img.reset();
  EXPECT_TRUE(test::same_segments(r.extract_cut(0.05), coarse));
  EXPECT_TRUE(test::same_segments(r.extract_region(10, 10, 30, 25), region));
  EXPECT_TRUE(test::same_segments(r.extract(), all));
  EXPECT_LT(coarse.segment_count(), all.segment_count());
  EXPECT_LT(region.segment_count(), all.segment_count());
  EXPECT_GT(region.segment_count(), coarse.segment_count() / 2);
}

TEST(ContourRefiner, several_isovalues_in_one_run_each_equal_their_own_contours) {
  const volume img = make_image(64, 40, waves);
  contour_options o;
  const std::vector<double> ws{-0.3, 0.1, 0.5};
  const contour_result res = extract_contours(img, ws, o);
  ASSERT_EQ(res.stats.size(), 3u);
  for (const double w : ws) {
    contour_set only;
    only.vertices = res.contours.vertices;
    for (const auto& p : res.contours.polylines) {
      if (p.isovalue == w) only.polylines.push_back(p);
    }
    EXPECT_TRUE(test::same_segments(only, test::reference_contours(img, w))) << w;
  }
}

TEST(ContourRefiner, budgets_and_deadlines_are_respected) {
  const volume img = make_image(64, 40, waves);
  contour_options o;
  o.goal = refine_goal::segments(150);
  const contour_result seg = extract_contours(img, {0.1, 0.5}, o);
  std::uint64_t total = 0;
  for (const auto& s : seg.stats) total += s.segments;
  EXPECT_LE(total, 150u);
  o.goal = refine_goal::within(std::chrono::duration<double>(0.0));
  const contour_result zero = extract_contours(img, {0.1}, o);
  EXPECT_EQ(zero.stats[0].splits, 0u);
  o.goal = refine_goal::error(0.2);
  int frames = 0;
  o.frame = [&](const contour_set& c, int stage) {
    EXPECT_EQ(stage, frames);
    EXPECT_TRUE(test::check_valid_contour(c, test::image_box(img)));
    ++frames;
  };
  const contour_result err = extract_contours(img, {0.1}, o);
  EXPECT_GT(frames, 3);
  EXPECT_GT(err.stats[0].splits, 0u);
}

TEST(ContourRefiner, untouched_regions_are_never_visited) {
  // A small bump in a flat 1025 x 1025 image: only the diamonds around it are visited.
  const std::int64_t n = 1025;
  std::vector<std::byte> b(static_cast<std::size_t>(n * n));
  for (std::int64_t y = 500; y < 510; ++y)
    for (std::int64_t x = 300; x < 312; ++x)
      b[static_cast<std::size_t>(x + n * y)] = std::byte{200};
  const volume img({n, n, 1}, sample_type::u8, std::move(b));
  fixture f(img);
  contour_refiner r(f.img, f.h, f.ranges, 100.0);
  r.refine_full();
  EXPECT_LT(r.statistics().visited * 1000, static_cast<std::uint64_t>(n * n));
  EXPECT_EQ(r.extract().polylines.size(), 1u);
}

}  // namespace
}  // namespace progiso
