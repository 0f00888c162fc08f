// 2D range data: equal to the definition (nested min/max over every vertex of every triangle of
// the diamond's subtree, nested split error, rounded up only where stored), nested, empty beyond
// the subtree reach, and never larger than the image itself.
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/hierarchy2d.hpp>
#include <progiso/core/contour/range_data2d.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

template <class T, class F>
volume make_image(std::int64_t w, std::int64_t h, F&& f) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(w * h) * sizeof(T));
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      const T v = static_cast<T>(f(x, y));
      std::memcpy(&bytes[static_cast<std::size_t>(x + w * y) * sizeof(T)], &v, sizeof(T));
    }
  }
  sample_type type = sample_type::u8;
  if constexpr (std::is_same_v<T, std::uint16_t>) type = sample_type::u16;
  if constexpr (std::is_same_v<T, std::int16_t>) type = sample_type::i16;
  if constexpr (std::is_same_v<T, std::int8_t>) type = sample_type::i8;
  if constexpr (std::is_same_v<T, std::uint32_t>) type = sample_type::u32;
  if constexpr (std::is_same_v<T, std::int32_t>) type = sample_type::i32;
  if constexpr (std::is_same_v<T, float>) type = sample_type::f32;
  if constexpr (std::is_same_v<T, double>) type = sample_type::f64;
  return volume({w, h, 1}, type, std::move(bytes));
}

// Hashed noise in [0, 1).
double noise(std::int64_t x, std::int64_t y) {
  std::uint64_t s = static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15u ^
                    static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4Fu;
  s ^= s >> 29;
  s *= 0xBF58476D1CE4E5B9u;
  s ^= s >> 32;
  return static_cast<double>(s % 1000003u) / 1000003.0;
}

// A deterministic mix of smooth waves and noise, in [0, amplitude).
template <class T>
volume noisy_image(std::int64_t w, std::int64_t h, double amplitude) {
  return make_image<T>(w, h, [&](std::int64_t x, std::int64_t y) {
    return amplitude * (0.5 * noise(x, y) + 0.125 * (1.0 + std::sin(0.3 * static_cast<double>(x))) +
                        0.125 * (1.0 + std::cos(0.2 * static_cast<double>(y))));
  });
}

// Nested (lo, hi, error) from the definition, memoised over the DAG: no storage, no stencils.
struct nested {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  double err = 0.0;
  [[nodiscard]] bool empty() const { return lo > hi; }
};

nested own_values(const hierarchy2d& h, const volume& v, const diamond2& d) {
  nested r;
  // Wholly beyond the data box: contributes nothing.
  if (d.centre[0] - d.scale >= h.data_max()[0] || d.centre[1] - d.scale >= h.data_max()[1]) {
    return r;
  }
  const auto f = [&](const ipoint2& p) { return v.value(p[0], p[1], 0); };
  std::vector<ipoint2> points{d.centre, d.spine[0], d.spine[1]};
  for (std::size_t m = 0; m < 2; ++m) {
    if (h.in_grid(d.ring[m])) points.push_back(d.ring[m]);
  }
  for (const ipoint2& p : points) {
    r.lo = std::min(r.lo, f(p));
    r.hi = std::max(r.hi, f(p));
  }
  r.err = std::abs(f(d.centre) - 0.5 * (f(d.spine[0]) + f(d.spine[1])));
  return r;
}

nested subtree_values(const hierarchy2d& h, const volume& v, const ipoint2& c,
                      std::map<ipoint2, nested>& memo) {
  if (const auto it = memo.find(c); it != memo.end()) return it->second;
  const diamond2 d = h.make_diamond(c);
  nested r = own_values(h, v, d);
  std::array<ipoint2, 4> ch{};
  const int n = h.children(d, ch);
  for (int i = 0; i < n; ++i) {
    const nested x = subtree_values(h, v, ch[static_cast<std::size_t>(i)], memo);
    r.lo = std::min(r.lo, x.lo);
    r.hi = std::max(r.hi, x.hi);
    r.err = std::max(r.err, x.err);
  }
  memo[c] = r;
  return r;
}

// What a stored entry holds for an exact error e: rounded up to an integer, or to a float.
double stored_error(double e, sample_type type) {
  if (type == sample_type::f32 || type == sample_type::f64) {
    auto f = static_cast<float>(e);
    if (static_cast<double>(f) < e) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return static_cast<double>(f);
  }
  return std::ceil(e);
}

std::string name(const ipoint2& p) { return std::to_string(p[0]) + "," + std::to_string(p[1]); }

struct check_stats {
  int rounded_up = 0;  // stored errors strictly above the exact value
  int empty = 0;       // diamonds with an empty range
};

check_stats check_all_diamonds(const volume& v) {
  SCOPED_TRACE(std::to_string(v.dims()[0]) + "x" + std::to_string(v.dims()[1]) + " " +
               std::string(to_string(v.type())));
  const hierarchy2d h(v.dims()[0], v.dims()[1]);
  const range_data2d rd(v, h);
  EXPECT_LE(rd.byte_size(), v.byte_size());
  std::map<ipoint2, nested> memo;
  check_stats stats;
  for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
      const ipoint2 c{x, y};
      if (!h.is_diamond(c)) continue;
      const diamond2 d = h.make_diamond(c);
      const diamond_range r = rd.get(d);
      const nested expected = subtree_values(h, v, c, memo);
      // Same definition for own(), and the same answer by centre.
      const nested own = own_values(h, v, d);
      const diamond_range o = rd.own(d);
      EXPECT_EQ(o.empty(), own.empty()) << name(c);
      if (!own.empty()) {
        EXPECT_EQ(o.lo, own.lo) << name(c);
        EXPECT_EQ(o.hi, own.hi) << name(c);
      }
      EXPECT_EQ(o.error, own.err) << name(c);
      const diamond_range rc = rd.get(c);
      EXPECT_EQ(rc.lo, r.lo) << name(c);
      EXPECT_EQ(rc.hi, r.hi) << name(c);
      EXPECT_EQ(rc.error, r.error) << name(c);
      // Equal to the definition: exact ranges; errors exact where computed on demand, rounded
      // up where stored.
      EXPECT_EQ(r.empty(), expected.empty()) << name(c);
      if (!expected.empty()) {
        EXPECT_EQ(r.lo, expected.lo) << name(c);
        EXPECT_EQ(r.hi, expected.hi) << name(c);
      } else {
        ++stats.empty;
        // Beyond the subtree reach on some axis ⇒ empty (the converse need not hold).
      }
      if (d.scale < rd.finest_stored_scale()) {
        EXPECT_EQ(r.error, expected.err) << name(c);
      } else {
        EXPECT_EQ(r.error, stored_error(expected.err, v.type())) << name(c);
        stats.rounded_up += r.error > expected.err ? 1 : 0;
      }
      for (std::size_t q = 0; q < 2; ++q) {
        if (c[q] >= h.data_max()[q] + range_data2d::subtree_reach(d.type, d.scale)) {
          EXPECT_TRUE(expected.empty()) << name(c);
          EXPECT_EQ(expected.err, 0.0) << name(c);
        }
      }
      // Nested: children never leave the parent's range or exceed its error.
      std::array<ipoint2, 4> ch{};
      const int n = h.children(d, ch);
      for (int i = 0; i < n; ++i) {
        const ipoint2& cc = ch[static_cast<std::size_t>(i)];
        const diamond_range cr = rd.get(cc);
        EXPECT_LE(cr.error, r.error) << "child " << name(cc) << " of " << name(c);
        if (!cr.empty()) {
          EXPECT_FALSE(r.empty()) << "child " << name(cc) << " of " << name(c);
          EXPECT_LE(r.lo, cr.lo) << "child " << name(cc) << " of " << name(c);
          EXPECT_GE(r.hi, cr.hi) << "child " << name(cc) << " of " << name(c);
        }
      }
    }
  }
  return stats;
}

TEST(RangeData2d, equals_the_definition_on_power_of_two_plus_one_images) {
  const check_stats s = check_all_diamonds(noisy_image<std::uint8_t>(17, 17, 255));
  EXPECT_GT(s.rounded_up, 0);  // half-integer errors at stored scales round up
  check_all_diamonds(noisy_image<std::uint8_t>(33, 33, 255));
  check_all_diamonds(noisy_image<std::uint16_t>(65, 65, 60000));
}

TEST(RangeData2d, equals_the_definition_on_padded_images) {
  for (const auto& [w, h] :
       {std::pair<int, int>{20, 14}, {35, 10}, {129, 5}, {33, 18}, {40, 40}, {7, 6}, {66, 35}}) {
    const check_stats s = check_all_diamonds(noisy_image<std::uint8_t>(w, h, 255));
    if (w == 33) {
      EXPECT_GT(s.empty, 0);  // padding beyond the reach
    }
  }
  check_all_diamonds(noisy_image<std::int16_t>(20, 14, 3000));
  check_all_diamonds(noisy_image<std::int16_t>(35, 10, -3000));
}

TEST(RangeData2d, equals_the_definition_for_every_integer_sample_type) {
  // The stored errors of integer images are rounded up in integers (the row-wise build of scale
  // 1's square centres and the own errors of stored diamonds), in 32 bits for samples below 4
  // bytes and 64 above: down to the extremes of each type, where |2 mid - a - b| needs them.
  check_all_diamonds(noisy_image<std::int8_t>(40, 37, 127));
  check_all_diamonds(noisy_image<std::int8_t>(40, 37, -128));
  check_all_diamonds(noisy_image<std::uint32_t>(40, 37, 4294967295.0));
  check_all_diamonds(noisy_image<std::int32_t>(40, 37, 2147483647.0));
  check_all_diamonds(noisy_image<std::int32_t>(40, 37, -2147483648.0));
  // Alternating extremes: split errors near the largest the error type holds.
  check_all_diamonds(make_image<std::int32_t>(37, 40, [](std::int64_t x, std::int64_t y) {
    return ((x + y) % 3 == 0) ? 2147483647.0 : -2147483648.0;
  }));
  check_all_diamonds(make_image<std::uint8_t>(
      37, 40, [](std::int64_t x, std::int64_t y) { return ((x * 7 + y) % 3 == 0) ? 255.0 : 0.0; }));
}

TEST(RangeData2d, equals_the_definition_for_floating_point_images) {
  const check_stats s = check_all_diamonds(noisy_image<float>(33, 18, 1.0));
  EXPECT_GT(s.rounded_up, 0);  // errors that are not floats round up to the next float
  check_all_diamonds(noisy_image<double>(20, 14, 1e-3));
  check_all_diamonds(noisy_image<double>(17, 17, 1e6));
}

TEST(RangeData2d, small_and_thin_padded_images_store_coarser_scales_only_and_stay_exact) {
  // Here the clip margins would outweigh the data at scale 2.
  for (const auto& [w, h] : {std::pair<int, int>{10, 10}, {11, 11}, {6, 6}, {10, 19}, {300, 19}}) {
    const volume v = noisy_image<std::uint8_t>(w, h, 255);
    const hierarchy2d hier(w, h);
    EXPECT_GT(range_data2d(v, hier).finest_stored_scale(), 2) << w << "x" << h;
    check_all_diamonds(v);
  }
}

TEST(RangeData2d, smallest_images_have_only_scale_one_diamonds_or_none) {
  check_all_diamonds(noisy_image<std::uint8_t>(2, 2, 255));
  check_all_diamonds(noisy_image<std::uint8_t>(3, 3, 255));
  check_all_diamonds(noisy_image<std::uint8_t>(3, 8, 255));
  check_all_diamonds(noisy_image<std::uint8_t>(2, 9, 255));
}

TEST(RangeData2d, constant_image_has_point_ranges_and_no_error) {
  const volume v = make_image<std::uint16_t>(40, 23, [](auto, auto) { return 700; });
  const hierarchy2d h(40, 23);
  const range_data2d rd(v, h);
  for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
      if (!h.is_diamond({x, y})) continue;
      const diamond_range r = rd.get(ipoint2{x, y});
      EXPECT_EQ(r.error, 0.0);
      if (!r.empty()) {
        EXPECT_EQ(r.lo, 700.0);
        EXPECT_EQ(r.hi, 700.0);
        EXPECT_FALSE(r.straddles(700.0));
        EXPECT_FALSE(r.straddles(699.5));
      }
    }
  }
}

// The reach of a subtree, from the hierarchy alone: max over descendants D' (D included) of
// c_q − (c'_q − h') per axis, memoised.
std::array<std::int32_t, 2> reach_of(const hierarchy2d& h, const ipoint2& c,
                                     std::map<ipoint2, std::array<std::int32_t, 2>>& memo) {
  if (const auto it = memo.find(c); it != memo.end()) return it->second;
  const diamond2 d = h.make_diamond(c);
  std::array<std::int32_t, 2> r{d.scale, d.scale};
  std::array<ipoint2, 4> ch{};
  const int n = h.children(d, ch);
  for (int i = 0; i < n; ++i) {
    const ipoint2& x = ch[static_cast<std::size_t>(i)];
    const auto cr = reach_of(h, x, memo);
    for (std::size_t q = 0; q < 2; ++q) r[q] = std::max(r[q], c[q] - x[q] + cr[q]);
  }
  memo[c] = r;
  return r;
}

TEST(RangeData2d, subtree_reach_bounds_every_subtree_and_is_attained) {
  // Two root squares side by side, so that even the roots' subtrees have room to reach fully.
  const hierarchy2d h(257, 129);
  std::map<ipoint2, std::array<std::int32_t, 2>> memo;
  std::map<std::pair<int, std::int32_t>, std::int32_t> largest;  // (type, scale) -> reach
  for (std::int32_t y = 0; y <= h.grid_max()[1]; ++y) {
    for (std::int32_t x = 0; x <= h.grid_max()[0]; ++x) {
      const ipoint2 c{x, y};
      if (!h.is_diamond(c)) continue;
      const diamond2 d = h.make_diamond(c);
      const auto r = reach_of(h, c, memo);
      for (std::size_t q = 0; q < 2; ++q) {
        EXPECT_LE(r[q], range_data2d::subtree_reach(d.type, d.scale)) << name(c);
        auto& l = largest[{d.type, d.scale}];
        l = std::max(l, r[q]);
      }
    }
  }
  for (const auto& [key, reach] : largest) {
    EXPECT_EQ(reach, range_data2d::subtree_reach(key.first, key.second))
        << "type " << key.first << " scale " << key.second;
  }
}

TEST(RangeData2d, fits_in_the_image_bytes_for_every_small_size) {
  for (std::int64_t w = 2; w <= 48; ++w) {
    for (std::int64_t h = 2; h <= 48; ++h) {
      const volume v = make_image<std::uint8_t>(w, h, [](auto x, auto y) { return x ^ y; });
      const hierarchy2d hier(w, h);
      EXPECT_LE(range_data2d(v, hier).byte_size(), v.byte_size()) << w << "x" << h;
    }
  }
  for (const std::int64_t w : {63, 65, 100, 127, 200, 257}) {
    const volume v = noisy_image<float>(w, 70, 1.0);
    const hierarchy2d hier(w, 70);
    EXPECT_LE(range_data2d(v, hier).byte_size(), v.byte_size()) << w << "x70 f32";
    const volume d = noisy_image<double>(70, w, 1.0);
    const hierarchy2d hd(70, w);
    EXPECT_LE(range_data2d(d, hd).byte_size(), d.byte_size()) << "70x" << w << " f64";
  }
}

TEST(RangeData2d, large_image_stays_within_its_bytes_and_matches_samples) {
  const volume v = noisy_image<std::uint16_t>(1025, 1025, 65000);
  const hierarchy2d h(1025, 1025);
  const range_data2d rd(v, h);
  EXPECT_EQ(rd.finest_stored_scale(), 2);
  const double ratio = static_cast<double>(rd.byte_size()) / static_cast<double>(v.byte_size());
  std::cout << "1025x1025 u16: range data " << rd.byte_size() << " bytes, " << ratio
            << " of the image\n";
  EXPECT_LE(rd.byte_size(), v.byte_size());
  const diamond_range root = rd.get(ipoint2{512, 512});
  EXPECT_EQ(root.lo, v.value_range()[0]);
  EXPECT_EQ(root.hi, v.value_range()[1]);
  // A sample of diamonds of every scale up to 32 against the definition.
  for (std::int32_t i = 0; i < 400; ++i) {
    const auto px = static_cast<std::int32_t>(noise(i, 1) * 1024.0);
    const auto py = static_cast<std::int32_t>(noise(i, 2) * 1024.0);
    const std::int32_t g = std::int32_t{1} << (i % 6);
    const ipoint2 c{px / g * g + (i % 3 == 0 ? 0 : g), py / g * g + (i % 3 == 1 ? 0 : g)};
    if (!h.is_diamond(c)) continue;
    const diamond2 d = h.make_diamond(c);
    std::map<ipoint2, nested> memo;
    const nested e = subtree_values(h, v, c, memo);
    const diamond_range r = rd.get(d);
    EXPECT_EQ(r.lo, e.lo) << name(c);
    EXPECT_EQ(r.hi, e.hi) << name(c);
    EXPECT_EQ(r.error, d.scale == 1 ? e.err : std::ceil(e.err)) << name(c);
  }
}

TEST(RangeData2d, shared_images_stay_within_their_bytes) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const test::shared_image& info : test::shared_images()) {
    const volume v = test::load_pgm(*dir / info.file);
    const hierarchy2d h(v.dims()[0], v.dims()[1]);
    const range_data2d rd(v, h);
    const double ratio = static_cast<double>(rd.byte_size()) / static_cast<double>(v.byte_size());
    std::cout << info.name << " " << v.dims()[0] << "x" << v.dims()[1] << " " << to_string(v.type())
              << ": range data " << rd.byte_size() << " bytes, image " << v.byte_size()
              << " bytes, ratio " << ratio << "\n";
    RecordProperty(std::string(info.name) + "_range_bytes", std::to_string(rd.byte_size()));
    EXPECT_LE(rd.byte_size(), v.byte_size()) << info.name;
    EXPECT_EQ(rd.finest_stored_scale(), 2) << info.name;
    std::map<ipoint2, nested> memo;
    for (std::uint64_t r = 0; r < h.root_count(); ++r) {
      const ipoint2 c = h.root_centre(r);
      const nested e = subtree_values(h, v, c, memo);
      const diamond_range got = rd.get(c);
      EXPECT_EQ(got.lo, e.lo) << info.name << " root " << r;
      EXPECT_EQ(got.hi, e.hi) << info.name << " root " << r;
      EXPECT_EQ(got.error, std::ceil(e.err)) << info.name << " root " << r;
    }
  }
}

TEST(RangeData2d, rejects_an_image_that_does_not_match_the_hierarchy) {
  const volume v = noisy_image<std::uint8_t>(10, 10, 255);
  const hierarchy2d other(10, 11);
  EXPECT_THROW(range_data2d(v, other), error);
  const volume thick({10, 10, 2}, sample_type::u8, std::vector<std::byte>(200));
  const hierarchy2d square(10, 10);
  EXPECT_THROW(range_data2d(thick, square), error);
}

}  // namespace
}  // namespace progiso
