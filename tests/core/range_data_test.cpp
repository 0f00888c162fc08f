// Range data: nested (never grows toward children), covering (contains every value of every
// tetrahedron in the diamond's subtree), sound for culling, and within the volume's own bytes.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/ranges/detail/range_entry.hpp>
#include <progiso/core/ranges/range_data.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/test_data.hpp"

namespace progiso {
namespace {

// Nested (lo, hi, error) of d from the definition: own vertex set plus descendants', with a memo
// over the DAG; no stencils, no storage bounds.
struct nested {
  double lo = 1e300, hi = -1e300, err = 0.0;
};

nested subtree_values(const hierarchy& h, const volume& v, const diamond& d,
                      std::map<ipoint, nested>& memo) {
  if (const auto it = memo.find(d.centre); it != memo.end()) return it->second;
  nested r;
  if (!h.outside_data(d.centre, d.scale)) {
    const auto f = [&](const ipoint& p) { return v.value(p[0], p[1], p[2]); };
    for (const ipoint& p : {d.centre, d.spine[0], d.spine[1]}) {
      r.lo = std::min(r.lo, f(p));
      r.hi = std::max(r.hi, f(p));
    }
    for (int m = 0; m < d.ring_size; ++m) {
      if ((d.ring_in_grid >> m) & 1u) {
        r.lo = std::min(r.lo, f(d.ring[static_cast<std::size_t>(m)]));
        r.hi = std::max(r.hi, f(d.ring[static_cast<std::size_t>(m)]));
      }
    }
    r.err = std::abs(f(d.centre) - 0.5 * (f(d.spine[0]) + f(d.spine[1])));
  }
  std::array<ipoint, 8> ch{};
  const int n = h.children(d, ch);
  for (int i = 0; i < n; ++i) {
    const nested c = subtree_values(h, v, h.make_diamond(ch[static_cast<std::size_t>(i)]), memo);
    r.lo = std::min(r.lo, c.lo);
    r.hi = std::max(r.hi, c.hi);
    r.err = std::max(r.err, c.err);
  }
  memo[d.centre] = r;
  return r;
}

// With `exact_errors` false the data stops after the min/max pass (errors of scale ≥ 2 are then
// the bound hi − lo): the same checks hold. Returns how many get_upto() calls stopped early (an
// error below get()'s).
std::uint64_t check_all_diamonds(const volume& v, bool exact_errors = true) {
  const hierarchy h(v.dims());
  range_data rd(v, h, range_data::staged);
  rd.build_pieces(0, rd.piece_count());
  rd.finish();
  if (exact_errors) {
    rd.build_error_pieces(0, rd.error_piece_count());
    rd.finish_errors();
  }
  EXPECT_EQ(rd.errors_exact(), exact_errors);
  std::uint64_t stopped_early = 0;
  std::map<ipoint, nested> memo;
  for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
    for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
      for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
        const ipoint c{x, y, z};
        if (!h.is_diamond(c)) continue;
        const diamond d = h.make_diamond(c);
        const diamond_range r = rd.get(d);
        // The other ways in: by centre and scale, bounds only, emptiness only.
        const diamond_range by_scale = rd.get(c, d.scale);
        EXPECT_EQ(by_scale.lo, r.lo);
        EXPECT_EQ(by_scale.hi, r.hi);
        EXPECT_EQ(by_scale.error, r.error);
        if (!r.empty()) {
          // The error alone (split samples only at scale 1) is the same double.
          EXPECT_EQ(rd.error(c, d.scale), r.error) << x << "," << y << "," << z;
        }
        for (const double w : {r.lo, r.hi, 0.5 * (r.lo + r.hi), r.lo - 0.5, r.hi + 0.5,
                               std::nextafter(r.hi, -1e300), 0.1, 0.3, 0.55, 100.5}) {
          EXPECT_EQ(rd.straddles(c, d.scale, detail::sample_threshold(w)), r.straddles(w))
              << x << "," << y << "," << z << " at " << w;
          // Errors needed only up to a bound: get()'s below it, above it otherwise, and the
          // same straddle test (a visit may stop early).
          for (const double bound : {0.0, 0.5 * r.error, std::nextafter(r.error, -1e300), r.error,
                                     std::numeric_limits<double>::infinity()}) {
            const straddle_and_error u =
                rd.test_upto(c, d.scale, bound, detail::sample_threshold(w));
            EXPECT_EQ(u.straddles, r.straddles(w)) << x << "," << y << "," << z;
            const double e = rd.error_upto(c, d.scale, bound);
            if (r.error <= bound) {
              EXPECT_EQ(u.error, r.error);
              if (!r.empty()) {
                EXPECT_EQ(e, r.error);
              }
            } else {
              EXPECT_GT(u.error, bound) << x << "," << y << "," << z;
              EXPECT_GT(e, bound) << x << "," << y << "," << z;
              EXPECT_LE(u.error, r.error);
              stopped_early += u.error < r.error ? 1U : 0U;
            }
          }
        }
        EXPECT_EQ(rd.empty(c, d.scale), r.empty()) << x << "," << y << "," << z;
        const nested expected = subtree_values(h, v, d, memo);
        if (expected.lo <= expected.hi) {
          EXPECT_LE(r.lo, expected.lo) << x << "," << y << "," << z;
          EXPECT_GE(r.hi, expected.hi) << x << "," << y << "," << z;
        }
        EXPECT_GE(r.error, expected.err - 1e-6) << x << "," << y << "," << z;
        std::array<ipoint, 8> ch{};
        const int n = h.children(d, ch);
        for (int i = 0; i < n; ++i) {
          const diamond_range cr = rd.get(h.make_diamond(ch[static_cast<std::size_t>(i)]));
          EXPECT_LE(cr.error, r.error)
              << "child " << ch[static_cast<std::size_t>(i)][0] << ","
              << ch[static_cast<std::size_t>(i)][1] << "," << ch[static_cast<std::size_t>(i)][2]
              << " of " << x << "," << y << "," << z << " scale " << d.scale << " type " << d.type;
          if (!cr.empty()) {
            EXPECT_LE(r.lo, cr.lo);
            EXPECT_GE(r.hi, cr.hi);
          }
        }
      }
  return stopped_early;
}

TEST(RangeData, stored_integer_errors_are_rounded_up_and_saturated) {
  // Errors of integer samples are halves of integers, stored as the unsigned type of the
  // samples' width: rounded up (never below the error, so the bound stays sound) and saturated.
  using detail::quantize_error;
  EXPECT_EQ(quantize_error<std::uint8_t>(0.0), 0);
  EXPECT_EQ(quantize_error<std::uint8_t>(0.5), 1);
  EXPECT_EQ(quantize_error<std::uint8_t>(1.0), 1);
  EXPECT_EQ(quantize_error<std::uint8_t>(1e-300), 1);
  EXPECT_EQ(quantize_error<std::uint8_t>(127.5), 128);
  EXPECT_EQ(quantize_error<std::uint8_t>(254.5), 255);
  EXPECT_EQ(quantize_error<std::uint8_t>(255.0), 255);
  EXPECT_EQ(quantize_error<std::uint8_t>(300.0), 255);
  EXPECT_EQ(quantize_error<std::uint16_t>(65534.5), 65535);
  EXPECT_EQ(quantize_error<std::uint16_t>(1e30), 65535);
  EXPECT_EQ(quantize_error<std::uint32_t>(4294967294.5), 4294967295u);
  EXPECT_EQ(quantize_error<std::uint32_t>(3000000000.25), 3000000001u);
  EXPECT_EQ(quantize_error<std::uint32_t>(std::nan("")), 4294967295u);
  EXPECT_EQ(quantize_error<float>(0.7), std::nextafter(0.7f, 1.0f));  // 0.7f lies below 0.7
  EXPECT_GE(static_cast<double>(quantize_error<float>(0.7)), 0.7);
  EXPECT_EQ(quantize_error<float>(0.5), 0.5f);
}

TEST(RangeData, ranges_cover_every_subtree_and_are_nested_on_a_power_of_two_grid) {
  // With exact errors a coarse diamond's visit stops once its error passes the bound.
  EXPECT_GT(check_all_diamonds(make_gaussian_blobs({17, 17, 17}, 5, 1u)), 0u);
}

TEST(RangeData, ranges_cover_every_subtree_and_are_nested_on_a_padded_grid) {
  check_all_diamonds(make_gaussian_blobs({20, 14, 23}, 5, 2u));
}

TEST(RangeData, ranges_cover_every_subtree_with_padding_of_many_small_scales) {
  check_all_diamonds(make_gaussian_blobs({26, 21, 19}, 6, 3u));
  check_all_diamonds(make_gaussian_blobs({35, 10, 12}, 6, 4u));
}

// Before the error pass (what a deadline run refines by while it saves the pass for later).
TEST(RangeData, before_the_error_pass_ranges_and_error_bounds_cover_every_subtree_and_nest) {
  check_all_diamonds(make_gaussian_blobs({17, 17, 17}, 5, 1u), false);
  check_all_diamonds(make_gaussian_blobs({20, 14, 23}, 5, 2u), false);
  check_all_diamonds(make_gaussian_blobs({35, 10, 12}, 6, 4u), false);
}

TEST(RangeData, ranges_of_smoothed_fields_cover_every_subtree_and_are_nested) {
  // The derived field's ranges are bounds from the data (smoothing.hpp): checked against its
  // fine samples by brute force, below the data, from a coarse level, by region, padded.
  const auto blobs = std::make_shared<const volume>(make_gaussian_blobs({9, 9, 9}, 4, 2u));
  check_all_diamonds(smooth(blobs, {1, 0, std::nullopt, 1.0}));
  check_all_diamonds(smooth(blobs, {0, 2, std::nullopt, 2.2}));
  const auto odd = std::make_shared<const volume>(make_gaussian_blobs({7, 10, 6}, 3, 5u));
  check_all_diamonds(smooth(odd, {1, 1, std::nullopt, 1.0}));
  check_all_diamonds(smooth(odd, {1, 0, std::array<std::int64_t, 6>{1, 2, 0, 4, 9, 3}, 1.0}));
}

TEST(RangeData, integer_volume_errors_are_rounded_up_not_down) {
  std::vector<std::byte> b(9 * 9 * 9);
  for (std::size_t i = 0; i < b.size(); ++i) b[i] = static_cast<std::byte>((i * 37) % 251);
  check_all_diamonds(volume({9, 9, 9}, sample_type::u8, std::move(b)));
}

TEST(RangeData, memory_stays_below_the_volume_bytes) {
  const volume big = make_gaussian_blobs({129, 129, 129}, 4, 1u);
  const hierarchy h(big.dims());
  // The brick pyramid: 3 samples per 4 x 4 x 4 vertices and 1/7 more (plus a margin of bricks).
  EXPECT_LE(range_data(big, h).byte_size(), big.byte_size() / 10);
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found";
  for (const auto& info : test::shared_volumes()) {
    const volume v = test::load_shared_volume(info, *dir);
    const hierarchy hv(v.dims());
    EXPECT_LE(range_data(v, hv).byte_size(), v.byte_size()) << info.name;
  }
}

// A parallel loop on three threads, each running its items in reverse order.
void on_three_threads(std::size_t n, const std::function<void(std::size_t)>& f) {
  std::vector<std::thread> pool;
  for (std::size_t t = 0; t < 3; ++t) {
    pool.emplace_back([&f, n, t] {
      for (std::size_t i = n; i-- > 0;) {
        if (i % 3 == t) f(i);
      }
    });
  }
  for (auto& th : pool) th.join();
}

// The build's slabs run in any order and on any threads: every range and error is the same.
TEST(RangeData, built_in_parallel_slabs_it_equals_the_sequential_build) {
  for (const volume& v :
       {make_gaussian_blobs({37, 29, 45}, 6, 5u), make_marschner_lobb({33, 33, 33})}) {
    const hierarchy h(v.dims());
    const range_data seq(v, h);
    std::size_t slabs = 0;
    // The most items of one loop: the slabs (the coarser levels' loops have fewer).
    const range_data par(v, h, [&slabs](std::size_t n, const std::function<void(std::size_t)>& f) {
      slabs = std::max(slabs, n);
      on_three_threads(n, f);
    });
    EXPECT_GT(slabs, 1u);
    for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
      for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
        for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
          const ipoint c{x, y, z};
          if (!h.is_diamond(c)) continue;
          const diamond_range a = seq.get(c);
          const diamond_range b = par.get(c);
          ASSERT_EQ(a.lo, b.lo);
          ASSERT_EQ(a.hi, b.hi);
          ASSERT_EQ(a.error, b.error);
        }
  }
}

// piece_work() weighs a staged build's pieces by the sample planes they read, so that the
// engine's estimate of the time a build has left is not misled by the first pieces (padding
// mostly: one plane where the others read four). It adds up over ranges, reads every plane of
// the data, and each piece reads at most four planes, at least one.
TEST(RangeData, piece_work_counts_the_sample_planes_each_piece_reads) {
  for (const index3 dims : {index3{9, 7, 33}, index3{12, 12, 17}, index3{5, 6, 64}}) {
    const volume v = make_marschner_lobb(dims);
    const hierarchy h(v.dims());
    const range_data rd(v, h, range_data::staged);
    const std::size_t n = rd.piece_count();
    ASSERT_GT(n, 2u);
    std::uint64_t total = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint64_t w = rd.piece_work(k, k + 1);
      EXPECT_GE(w, 1u) << k;
      EXPECT_LE(w, 4u) << k;
      total += w;
    }
    EXPECT_EQ(rd.piece_work(0, n), total);
    EXPECT_EQ(rd.piece_work(0, n / 2) + rd.piece_work(n / 2, n), total);
    EXPECT_EQ(rd.piece_work(n / 2, n / 2), 0u);
    EXPECT_GE(total, static_cast<std::uint64_t>(dims[2])) << "a plane of the data read by none";
    EXPECT_LT(rd.piece_work(0, 1), rd.piece_work(1, 2)) << "the first piece is mostly padding";
  }
}

// The staged build (the engine's, spread over runs): pieces built in any grouping and order,
// then finish(), then the error pass's pieces and finish_errors(), give the one-pass data
// exactly; empty() answers before any piece is built; between the passes the ranges are final
// and the errors bounds.
TEST(RangeData, a_staged_build_in_any_order_equals_the_one_pass_build) {
  const volume blobs = make_gaussian_blobs({37, 29, 45}, 6, 5u);
  const auto data = std::make_shared<const volume>(make_marschner_lobb({21, 19, 23}));
  const volume smoothed = smooth(data, {1, 0, std::nullopt, 1.0});
  for (const volume* v : {&blobs, &smoothed}) {
    const hierarchy h(v->dims());
    const range_data whole(*v, h);
    range_data staged(*v, h, range_data::staged);
    EXPECT_FALSE(staged.complete());
    const std::size_t n = staged.piece_count();
    ASSERT_GT(n, 2u);
    // empty() needs no piece: the same answers as the complete data's.
    for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
      for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
        for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
          const ipoint c{x, y, z};
          if (!h.is_diamond(c)) continue;
          ASSERT_EQ(staged.empty(c, h.scale_of(c)), whole.empty(c, h.scale_of(c)));
        }
    // The last pieces first, in groups of three, the rest one by one.
    std::size_t end = n;
    while (end > n / 2) {
      const std::size_t first = end >= 3 ? end - 3 : 0;
      staged.build_pieces(first, end);
      end = first;
    }
    for (std::size_t k = 0; k < end; ++k) staged.build_pieces(k, k + 1);
    staged.finish();
    EXPECT_TRUE(staged.complete());
    // Ranges final; errors of scale ≥ 2 the bound hi − lo until the error pass (sound and
    // nested: RangeData.before_the_error_pass_* checks them against every subtree).
    if (!staged.errors_exact()) {
      std::size_t checked = 0;
      for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
        for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
          for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
            const ipoint c{x, y, z};
            if (!h.is_diamond(c) || h.scale_of(c) < 2) continue;
            const diamond_range a = whole.get(c);
            const diamond_range b = staged.get(c);
            ASSERT_EQ(a.lo, b.lo);
            ASSERT_EQ(a.hi, b.hi);
            if (b.empty()) continue;
            ASSERT_EQ(b.error, b.hi - b.lo);
            ++checked;
          }
      EXPECT_GT(checked, 0u);
      const std::size_t m = staged.error_piece_count();
      for (std::size_t k = m; k-- > 0;) staged.build_error_pieces(k, k + 1);
      staged.finish_errors();
    }
    EXPECT_TRUE(staged.errors_exact());
    for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
      for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
        for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
          const ipoint c{x, y, z};
          if (!h.is_diamond(c)) continue;
          const diamond_range a = whole.get(c);
          const diamond_range b = staged.get(c);
          ASSERT_EQ(a.lo, b.lo);
          ASSERT_EQ(a.hi, b.hi);
          ASSERT_EQ(a.error, b.error);
        }
  }
}

// The coarser levels and their errors made through a parallel loop (the engine's oneTBB loop:
// one plane of a level per item) equal the one-thread build on every diamond; with the items
// run on three threads in reverse order, and with a volume whose levels have many planes.
TEST(RangeData, coarser_levels_built_through_a_parallel_loop_equal_the_one_thread_build) {
  std::size_t items = 0;
  const parallel_loop counting = [&](std::size_t n, const std::function<void(std::size_t)>& body) {
    items += n;
    on_three_threads(n, body);
  };
  const volume v = make_gaussian_blobs({70, 61, 53}, 9, 11u);
  const hierarchy h(v.dims());
  const range_data serial(v, h);
  const range_data parallel(v, h, on_three_threads);
  range_data staged(v, h, range_data::staged);
  staged.build_pieces(0, staged.piece_count());
  items = 0;
  staged.finish(counting);
  // Level 0 has about 53 / 4 planes, so the levels above it have 8, 4, 2 and 1.
  EXPECT_GE(items, 15u);
  const auto each_diamond = [&](auto&& f) {
    for (std::int32_t z = 0; z <= h.grid_max()[2]; ++z)
      for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y)
        for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
          const ipoint c{x, y, z};
          if (h.is_diamond(c) && h.scale_of(c) >= 2) f(c);
        }
  };
  each_diamond([&](const ipoint& c) {
    const diamond_range a = serial.get(c);
    const diamond_range b = staged.get(c);
    ASSERT_EQ(a.lo, b.lo);
    ASSERT_EQ(a.hi, b.hi);
  });
  staged.build_error_pieces(0, staged.error_piece_count());
  items = 0;
  staged.finish_errors(counting);
  EXPECT_GE(items, 15u);
  std::size_t nonzero = 0;
  each_diamond([&](const ipoint& c) {
    const diamond_range a = serial.get(c);
    for (const range_data* other : {&parallel, static_cast<const range_data*>(&staged)}) {
      const diamond_range b = other->get(c);
      ASSERT_EQ(a.lo, b.lo);
      ASSERT_EQ(a.hi, b.hi);
      ASSERT_EQ(a.error, b.error);
    }
    if (a.error > 0.0) ++nonzero;
  });
  EXPECT_GT(nonzero, 0u);
}

}  // namespace
}  // namespace progiso
