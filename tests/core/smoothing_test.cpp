// Smoothing (paper §6): the smoothed field against an independent, literal level-by-level
// materialisation of the 4-point rule (edge midpoints from 4 samples along their axis, face
// centres from 4 × 4 in their plane, cube centres from 4 × 4 × 4), interpolation of the control
// samples, cubic precision at α = 1, the full surface against marching tetrahedra over the
// materialised field, validity of cuts, and measured smoothness.
#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/refine/refiner.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <thread>
#include <vector>

#include "support/contour_checks.hpp"
#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"
#include "support/reference_mtri.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

// ---- The independent reference: a dense array per level. -------------------------------------

struct grid {
  index3 n{};
  std::vector<double> v;
  grid() = default;
  explicit grid(index3 dims) : n(dims), v(static_cast<std::size_t>(dims[0] * dims[1] * dims[2])) {}
  double& at(std::int64_t x, std::int64_t y, std::int64_t z) {
    return v[static_cast<std::size_t>(x + n[0] * (y + n[1] * z))];
  }
  [[nodiscard]] double at(std::int64_t x, std::int64_t y, std::int64_t z) const {
    return v[static_cast<std::size_t>(x + n[0] * (y + n[1] * z))];
  }
};

// g with one ghost layer on each side of every axis with more than one sample, each ghost the
// linear extrapolation 2 f(end) − f(next) of its row, axis after axis (x, then y, then z).
grid with_ghosts(const grid& g) {
  index3 pad{};
  index3 n{};
  for (std::size_t q = 0; q < 3; ++q) {
    pad[q] = g.n[q] > 1 ? 1 : 0;
    n[q] = g.n[q] + 2 * pad[q];
  }
  grid p(n);
  for (std::int64_t z = 0; z < g.n[2]; ++z)
    for (std::int64_t y = 0; y < g.n[1]; ++y)
      for (std::int64_t x = 0; x < g.n[0]; ++x)
        p.at(x + pad[0], y + pad[1], z + pad[2]) = g.at(x, y, z);
  for (std::size_t q = 0; q < 3; ++q) {
    if (pad[q] == 0) continue;
    std::array<std::int64_t, 3> i{};
    // Every row along axis q (the others over their padded extent once filled).
    const std::size_t a = (q + 1) % 3;
    const std::size_t b = (q + 2) % 3;
    for (i[b] = 0; i[b] < n[b]; ++i[b]) {
      for (i[a] = 0; i[a] < n[a]; ++i[a]) {
        const auto f = [&](std::int64_t k) -> double& {
          std::array<std::int64_t, 3> j = i;
          j[q] = k;
          return p.at(j[0], j[1], j[2]);
        };
        f(0) = 2 * f(1) - f(2);
        f(n[q] - 1) = 2 * f(n[q] - 2) - f(n[q] - 3);
      }
    }
  }
  return p;
}

// One level of the rule, point type by point type.
grid refine_level(const grid& g, double alpha) {
  const std::array<double, 4> m{-alpha / 16, (8 + alpha) / 16, (8 + alpha) / 16, -alpha / 16};
  const grid p = with_ghosts(g);
  index3 pad{};
  index3 n{};
  for (std::size_t q = 0; q < 3; ++q) {
    pad[q] = g.n[q] > 1 ? 1 : 0;
    n[q] = g.n[q] > 1 ? 2 * g.n[q] - 1 : 1;
  }
  grid out(n);
  for (std::int64_t z = 0; z < n[2]; ++z)
    for (std::int64_t y = 0; y < n[1]; ++y)
      for (std::int64_t x = 0; x < n[0]; ++x) {
        const std::array<std::int64_t, 3> X{x, y, z};
        // Per axis: the coarse indices and weights of the stencil (1 sample on an even axis, the
        // 4 along it on an odd one).
        std::array<std::vector<std::pair<std::int64_t, double>>, 3> taps;
        for (std::size_t q = 0; q < 3; ++q) {
          const std::int64_t c = X[q] / 2;
          if (X[q] % 2 == 0) {
            taps[q] = {{c + pad[q], 1.0}};
          } else {
            for (std::int64_t k = 0; k < 4; ++k)
              taps[q].push_back({c - 1 + k + pad[q], m[static_cast<std::size_t>(k)]});
          }
        }
        double s = 0.0;
        for (const auto& [iz, wz] : taps[2])
          for (const auto& [iy, wy] : taps[1])
            for (const auto& [ix, wx] : taps[0]) s += wx * wy * wz * p.at(ix, iy, iz);
        out.at(x, y, z) = s;
      }
  return out;
}

// The field of `data` with K, S and α (no region): control grid, K + S levels, cropped.
grid materialise_rule(const volume& data, int levels, int from, double alpha) {
  const index3& d = data.dims();
  const std::int64_t step = std::int64_t{1} << from;
  index3 nc{};
  for (std::size_t q = 0; q < 3; ++q) nc[q] = d[q] > 1 ? (d[q] - 1 + step - 1) / step + 1 : 1;
  grid g(nc);
  // Controls past the data (the last one when 2^K does not divide n − 1) are ghosts,
  // extrapolated from the two before them, axis after axis.
  for (std::int64_t z = 0; z < nc[2]; ++z)
    for (std::int64_t y = 0; y < nc[1]; ++y)
      for (std::int64_t x = 0; x < nc[0]; ++x) {
        if (x * step < d[0] && y * step < d[1] && z * step < d[2]) {
          g.at(x, y, z) = data.value(x * step, y * step, z * step);
        }
      }
  for (std::size_t q = 0; q < 3; ++q) {
    if (nc[q] < 2 || (nc[q] - 1) * step <= d[q] - 1) continue;
    for (std::int64_t z = 0; z < nc[2]; ++z)
      for (std::int64_t y = 0; y < nc[1]; ++y)
        for (std::int64_t x = 0; x < nc[0]; ++x) {
          std::array<std::int64_t, 3> i{x, y, z};
          if (i[q] != nc[q] - 1) continue;
          // Only the axes already extrapolated (before q) or inside may be read.
          bool ok = true;
          for (std::size_t r = q + 1; r < 3; ++r) ok = ok && i[r] * step < d[r];
          if (!ok) continue;
          std::array<std::int64_t, 3> a = i;
          std::array<std::int64_t, 3> b = i;
          a[q] -= 1;
          b[q] -= 2;
          g.at(x, y, z) = 2 * g.at(a[0], a[1], a[2]) - g.at(b[0], b[1], b[2]);
        }
  }
  for (int l = 0; l < levels + from; ++l) g = refine_level(g, alpha);
  index3 fine{};
  for (std::size_t q = 0; q < 3; ++q) fine[q] = (d[q] - 1) * (std::int64_t{1} << levels) + 1;
  grid out(fine);
  for (std::int64_t z = 0; z < fine[2]; ++z)
    for (std::int64_t y = 0; y < fine[1]; ++y)
      for (std::int64_t x = 0; x < fine[0]; ++x) out.at(x, y, z) = g.at(x, y, z);
  return out;
}

// The whole smoothed field: the rule inside the region, linear interpolation (α = 0, K = 0)
// outside it.
grid materialise(const volume& data, const smoothing& s) {
  grid rule = materialise_rule(data, s.levels, s.from, s.alpha);
  if (!s.region) return rule;
  const grid lin = materialise_rule(data, s.levels, 0, 0.0);
  const std::int64_t scale = std::int64_t{1} << s.levels;
  const auto& r = *s.region;
  for (std::int64_t z = 0; z < rule.n[2]; ++z)
    for (std::int64_t y = 0; y < rule.n[1]; ++y)
      for (std::int64_t x = 0; x < rule.n[0]; ++x) {
        const bool inside = x >= r[0] * scale && x <= r[3] * scale && y >= r[1] * scale &&
                            y <= r[4] * scale && z >= r[2] * scale && z <= r[5] * scale;
        if (!inside) rule.at(x, y, z) = lin.at(x, y, z);
      }
  return rule;
}

// The materialised field as an ordinary f64 volume, with the smoothed volume's geometry.
volume as_volume(const grid& g, const volume& like) {
  std::vector<std::byte> bytes(g.v.size() * sizeof(double));
  std::memcpy(bytes.data(), g.v.data(), bytes.size());
  return volume(g.n, sample_type::f64, std::move(bytes), like.spacing(), like.origin());
}

// Integer-valued data, so that every value of the rule with a dyadic α is an exact double in both
// computations (they agree bit for bit, whatever the order of the sums).
volume quantised_sphere(index3 dims, std::array<double, 3> centre, double scale) {
  const volume f = make_sphere_field(dims, centre);
  std::vector<std::byte> bytes(f.voxel_count());
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<std::byte>(std::clamp(std::lround(f.at(i) * scale), 0L, 255L));
  }
  return volume(dims, sample_type::u8, std::move(bytes));
}

std::shared_ptr<const volume> shared(volume v) {
  return std::make_shared<const volume>(std::move(v));
}

void expect_field_equals_reference(const std::shared_ptr<const volume>& data, const smoothing& s) {
  const volume field = smooth(data, s);
  const grid ref = materialise(*data, s);
  ASSERT_EQ(field.dims(), ref.n);
  std::size_t differ = 0;
  for (std::int64_t z = 0; z < ref.n[2]; ++z)
    for (std::int64_t y = 0; y < ref.n[1]; ++y)
      for (std::int64_t x = 0; x < ref.n[0]; ++x) {
        if (field.value(x, y, z) != ref.at(x, y, z)) {
          if (differ++ < 5) {
            ADD_FAILURE() << "S " << s.levels << " K " << s.from << " at " << x << "," << y << ","
                          << z << ": " << field.value(x, y, z) << " vs " << ref.at(x, y, z);
          }
        }
      }
  EXPECT_EQ(differ, 0u);
}

// ---- The field ----------------------------------------------------------------------------------

TEST(Smoothing, the_field_equals_a_literal_level_by_level_materialisation) {
  const auto data = shared(quantised_sphere({11, 9, 13}, {5.2, 3.9, 6.3}, 20.0));
  for (const int S : {1, 2}) {
    expect_field_equals_reference(data, {S, 0, std::nullopt, 1.0});
    expect_field_equals_reference(data, {S, 0, std::nullopt, 0.5});
  }
  // From a coarse level, with a last control point past the data on x (2^2 does not divide 10).
  expect_field_equals_reference(data, {0, 1, std::nullopt, 1.0});
  expect_field_equals_reference(data, {1, 2, std::nullopt, 1.0});
  // By region (inclusive box in data coordinates), with and without K.
  expect_field_equals_reference(data, {1, 0, std::array<std::int64_t, 6>{2, 1, 3, 7, 8, 9}, 1.0});
  expect_field_equals_reference(data, {2, 1, std::array<std::int64_t, 6>{0, 0, 0, 4, 4, 4}, 1.5});
}

// Every thread keeps recently read fine samples in a table of its own, tagged by field: reads of
// two fields of the same shape, interleaved, from several threads, and of a field made after
// another was destroyed (its memory reused), each see their own field's values; a repeated read
// is answered without a new computation.
TEST(Smoothing, the_sample_cache_answers_each_field_with_its_own_values) {
  const auto a = shared(quantised_sphere({9, 8, 7}, {4.1, 3.2, 3.3}, 20.0));
  const auto b = shared(quantised_sphere({9, 8, 7}, {2.0, 5.1, 2.7}, 30.0));
  const smoothing s{1, 0, std::nullopt, 1.0};
  const grid ra = materialise(*a, s);
  const grid rb = materialise(*b, s);
  ASSERT_NE(ra.v, rb.v);
  const auto check_interleaved = [&](const volume& fa, const volume& fb) {
    std::size_t differ = 0;
    for (int pass = 0; pass < 2; ++pass) {
      for (std::size_t i = 0; i < ra.v.size(); ++i) {
        differ += fa.at(i) != ra.v[i];
        differ += fb.at(i) != rb.v[i];
      }
    }
    return differ;
  };
  {
    const volume fa = smooth(a, s);
    const volume fb = smooth(b, s);
    EXPECT_EQ(check_interleaved(fa, fb), 0u);
    std::vector<std::thread> readers;
    std::array<std::size_t, 3> differ{};
    for (std::size_t t = 0; t < differ.size(); ++t) {
      readers.emplace_back([&, t] { differ[t] = check_interleaved(fa, fb); });
    }
    for (auto& r : readers) r.join();
    EXPECT_EQ(differ, (std::array<std::size_t, 3>{}));
  }
  // The same shapes again, the data swapped: new fields, quite possibly at the old addresses.
  const volume fb = smooth(b, s);
  const volume fa = smooth(a, s);
  EXPECT_EQ(check_interleaved(fa, fb), 0u);
  // A repeated read costs no computation; a read of a sample not read before costs one.
  const volume fresh = smooth(a, s);
  const std::uint64_t e0 = fresh.subdivided()->evaluations();
  const double v = fresh.at(std::size_t{37});
  EXPECT_EQ(fresh.subdivided()->evaluations(), e0 + 1);
  EXPECT_EQ(fresh.at(std::size_t{37}), v);
  EXPECT_EQ(fresh.subdivided()->evaluations(), e0 + 1);
}

TEST(Smoothing, the_data_samples_used_as_control_points_are_unchanged) {
  const auto data = shared(make_gaussian_blobs({17, 13, 19}, 6, 3u));
  for (const smoothing& s :
       {smoothing{1, 0, std::nullopt, 1.0}, smoothing{2, 0, std::nullopt, 0.7},
        smoothing{1, 1, std::nullopt, 1.0}, smoothing{0, 2, std::nullopt, 1.0}}) {
    const volume field = smooth(data, s);
    const std::int64_t fine = std::int64_t{1} << s.levels;
    const std::int64_t step = std::int64_t{1} << s.from;
    std::size_t checked = 0;
    for (std::int64_t z = 0; z < 19; z += step)
      for (std::int64_t y = 0; y < 13; y += step)
        for (std::int64_t x = 0; x < 17; x += step) {
          ASSERT_EQ(field.value(x * fine, y * fine, z * fine), data->value(x, y, z))
              << "S " << s.levels << " K " << s.from << " at " << x << "," << y << "," << z;
          ++checked;
        }
    EXPECT_GE(checked, 100u);
  }
}

// A tensor-product cubic (plus a second product term), in data coordinates.
double cubic(double x, double y, double z) {
  return (0.5 * x * x * x - 3 * x * x + 2 * x - 7) * (y * y * y - y + 4) *
             (2 * z * z - z * z * z + 1) +
         3 * x * y * z - z * z * z;
}

TEST(Smoothing, alpha_one_reproduces_a_tensor_product_cubic_wherever_no_ghost_enters) {
  const index3 dims{9, 8, 10};
  std::vector<double> samples;
  for (std::int64_t z = 0; z < dims[2]; ++z)
    for (std::int64_t y = 0; y < dims[1]; ++y)
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        samples.push_back(
            cubic(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
      }
  std::vector<std::byte> bytes(samples.size() * sizeof(double));
  std::memcpy(bytes.data(), samples.data(), bytes.size());
  const auto data = shared(volume(dims, sample_type::f64, std::move(bytes)));
  for (const int S : {1, 2}) {
    double worst_exact = 0.0;
    double worst_other = 0.0;
    std::size_t inside = 0;
    const volume one = smooth(data, {S, 0, std::nullopt, 1.0});
    const volume other = smooth(data, {S, 0, std::nullopt, 0.5});
    const detail::subdivision& sub = *one.subdivided();
    const double h = 1.0 / static_cast<double>(std::int64_t{1} << S);
    for (std::int64_t z = 0; z < one.dims()[2]; ++z)
      for (std::int64_t y = 0; y < one.dims()[1]; ++y)
        for (std::int64_t x = 0; x < one.dims()[0]; ++x) {
          if (!sub.ghost_free(x, y, z)) continue;
          ++inside;
          const double p = cubic(static_cast<double>(x) * h, static_cast<double>(y) * h,
                                 static_cast<double>(z) * h);
          const double scale = std::max(1.0, std::fabs(p));
          worst_exact = std::max(worst_exact, std::fabs(one.value(x, y, z) - p) / scale);
          worst_other = std::max(worst_other, std::fabs(other.value(x, y, z) - p) / scale);
        }
    EXPECT_GT(inside, 200u) << "S " << S;
    EXPECT_LT(worst_exact, 1e-12) << "S " << S;
    EXPECT_GT(worst_other, 1e-4) << "S " << S << ": alpha 0.5 must not reproduce cubics";
  }
}

TEST(Smoothing, overshoot_bound_holds_for_every_fine_sample_of_a_noisy_volume) {
  // Values within [m − λ(M − m), M + λ(M − m)] over the data their rows reach: checked at
  // every fine sample, against its own rows' reach (the tightest box the bound may use).
  std::vector<std::byte> bytes(12 * 11 * 10);
  std::uint32_t state = 12345u;
  for (std::byte& b : bytes) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<std::byte>((state >> 24) & 0xFFu);
  }
  const auto data = shared(volume({12, 11, 10}, sample_type::u8, std::move(bytes)));
  for (const smoothing& s : {smoothing{1, 0, std::nullopt, 1.0}, smoothing{2, 1, std::nullopt, 2.4},
                             smoothing{1, 2, std::nullopt, 1.0}}) {
    const volume field = smooth(data, s);
    const detail::subdivision& sub = *field.subdivided();
    double tightest = 0.0;  // the largest overshoot seen, as a fraction of the local range
    for (std::int64_t z = 0; z < field.dims()[2]; ++z)
      for (std::int64_t y = 0; y < field.dims()[1]; ++y)
        for (std::int64_t x = 0; x < field.dims()[0]; ++x) {
          const ipoint p{static_cast<std::int32_t>(x), static_cast<std::int32_t>(y),
                         static_cast<std::int32_t>(z)};
          const auto box = sub.reach(p, p);
          double m = 1e300;
          double M = -1e300;
          for (std::int64_t k = box.lo[2]; k <= box.hi[2]; ++k)
            for (std::int64_t j = box.lo[1]; j <= box.hi[1]; ++j)
              for (std::int64_t i = box.lo[0]; i <= box.hi[0]; ++i) {
                m = std::min(m, data->value(i, j, k));
                M = std::max(M, data->value(i, j, k));
              }
          const double v = field.value(x, y, z);
          ASSERT_GE(v, m - sub.overshoot() * (M - m)) << x << "," << y << "," << z;
          ASSERT_LE(v, M + sub.overshoot() * (M - m)) << x << "," << y << "," << z;
          if (M > m) tightest = std::max(tightest, std::max(m - v, v - M) / (M - m));
        }
    // The rule does overshoot (negative weights), and by less than the bound.
    EXPECT_GT(tightest, 0.0);
    EXPECT_LE(tightest, sub.overshoot());
  }
}

TEST(Smoothing, bad_parameters_are_refused_with_the_parameter_named) {
  const auto data = shared(make_sphere_field({9, 9, 9}, {4, 4, 4}));
  const auto message = [&](const smoothing& s) -> std::string {
    try {
      (void)smooth(data, s);
    } catch (const error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message({4, 0, std::nullopt, 1.0}).find("S (levels"), std::string::npos);
  EXPECT_NE(message({1, 4, std::nullopt, 1.0}).find("K = 4"), std::string::npos);
  EXPECT_NE(message({1, 0, std::nullopt, 0.0}).find("alpha"), std::string::npos);
  EXPECT_NE(message({1, 0, std::nullopt, 2.5}).find("alpha"), std::string::npos);
  EXPECT_NE(message({1, 0, std::array<std::int64_t, 6>{0, 0, 0, 9, 8, 8}, 1.0}).find("region"),
            std::string::npos);
  EXPECT_NE(message({1, 0, std::array<std::int64_t, 6>{5, 0, 0, 4, 8, 8}, 1.0}).find("region"),
            std::string::npos);
  EXPECT_EQ(message({3, 3, std::nullopt, 1.0}), "");
  const volume field = smooth(data, {1, 0, std::nullopt, 1.0});
  EXPECT_THROW((void)smooth(std::make_shared<const volume>(field), {1, 0, std::nullopt, 1.0}),
               error);
}

// ---- Surfaces -----------------------------------------------------------------------------------

triangle_mesh full_surface(const volume& v, double w) {
  return extract_isosurface(v, w, extract_options{}).mesh;
}

void expect_full_equals_reference_mt(const std::shared_ptr<const volume>& data, double w,
                                     const smoothing& s) {
  const volume field = smooth(data, s);
  const volume dense = as_volume(materialise(*data, s), field);
  const triangle_mesh mine = full_surface(field, w);
  const test::reference_surface ref = test::reference_marching_tetrahedra(dense, w);
  EXPECT_GT(mine.triangles.size(), 0u);
  EXPECT_EQ(mine.triangles.size(), ref.mesh.triangles.size());
  EXPECT_EQ(mine.vertices.size(), ref.mesh.vertices.size());
  EXPECT_TRUE(test::same_surface(mine, ref.mesh)) << "S " << s.levels << " K " << s.from;
}

TEST(Smoothing, full_smoothed_surface_equals_marching_tetrahedra_on_the_materialised_field) {
  const auto sphere = shared(quantised_sphere({12, 11, 13}, {5.6, 5.3, 6.1}, 10.0));
  expect_full_equals_reference_mt(sphere, 37.5, {1, 0, std::nullopt, 1.0});
  expect_full_equals_reference_mt(sphere, 37.5, {2, 0, std::nullopt, 1.0});
  expect_full_equals_reference_mt(sphere, 37.5, {1, 1, std::nullopt, 1.0});
  expect_full_equals_reference_mt(sphere, 37.5,
                                  {1, 0, std::array<std::int64_t, 6>{0, 0, 0, 5, 10, 7}, 1.0});
  expect_full_equals_reference_mt(sphere, 37.5,
                                  {2, 1, std::array<std::int64_t, 6>{3, 2, 0, 11, 10, 12}, 0.5});
}

TEST(Smoothing, full_smoothed_surface_of_shared_volumes_equals_marching_tetrahedra) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found";
  const auto bucky = shared(test::load_shared_volume(*test::find_shared_volume("bucky"), *dir));
  expect_full_equals_reference_mt(bucky, 51.0, {1, 0, std::nullopt, 1.0});
  expect_full_equals_reference_mt(bucky, 128.0, {0, 1, std::nullopt, 1.0});
  const auto nucleon = shared(test::load_shared_volume(*test::find_shared_volume("nucleon"), *dir));
  expect_full_equals_reference_mt(nucleon, 60.0,
                                  {1, 1, std::array<std::int64_t, 6>{10, 0, 0, 40, 40, 25}, 1.0});
}

TEST(Smoothing, every_cut_of_a_smoothed_field_is_valid) {
  const auto data = shared(make_gaussian_blobs({15, 13, 14}, 5, 9u));
  for (const smoothing& s : {smoothing{1, 0, std::nullopt, 1.0}, smoothing{1, 1, std::nullopt, 2.0},
                             smoothing{2, 0, std::array<std::int64_t, 6>{2, 2, 2, 9, 9, 9}, 1.0}}) {
    const volume field = smooth(data, s);
    const hierarchy h(field.dims());
    const range_data ranges(field, h);
    refiner r(field, h, ranges, 0.4, refine_order::largest_error_first);
    const auto [lo, hi] = test::data_box(field);
    int cuts = 0;
    for (std::uint64_t budget = 200; !r.done(); budget *= 3) {
      r.refine_to_triangles(budget);
      EXPECT_TRUE(test::check_valid_cut(r.extract(), lo, hi)) << "budget " << budget;
      ++cuts;
      if (budget > 1000000) break;
    }
    EXPECT_GE(cuts, 2);
    r.refine_full();
    EXPECT_TRUE(test::check_valid_cut(r.extract(), lo, hi));
  }
}

// Mean angle (radians) between the normals of triangles that share an edge.
double mean_normal_angle(const triangle_mesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::size_t>> edges;
  std::vector<vec3> normals;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const auto& tri = m.triangles[t];
    const vec3& a = m.vertices[tri[0]];
    const vec3& b = m.vertices[tri[1]];
    const vec3& c = m.vertices[tri[2]];
    const vec3 u{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const vec3 v{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& x : n) x /= len;
    normals.push_back(n);
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t p = tri[k];
      const std::uint32_t q = tri[(k + 1) % 3];
      edges[{std::min(p, q), std::max(p, q)}].push_back(t);
    }
  }
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& [e, ts] : edges) {
    if (ts.size() != 2) continue;
    const vec3& a = normals[ts[0]];
    const vec3& b = normals[ts[1]];
    sum += std::acos(std::clamp(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], -1.0, 1.0));
    ++count;
  }
  return sum / static_cast<double>(count);
}

TEST(Smoothing, smoothing_a_coarse_sphere_brings_its_surface_closer_and_smoother) {
  const std::array<double, 3> c{5.6, 5.3, 5.9};
  const double radius = 3.7;
  const auto data = shared(make_sphere_field({12, 12, 12}, c));
  std::vector<double> distance;
  std::vector<double> angle;
  for (const int S : {0, 1, 2}) {
    const triangle_mesh m = S == 0 ? full_surface(*data, radius)
                                   : full_surface(smooth(data, {S, 0, std::nullopt, 1.0}), radius);
    double d = 0.0;
    for (const vec3& p : m.vertices) {
      d += std::fabs(std::sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                               (p[2] - c[2]) * (p[2] - c[2])) -
                     radius);
    }
    distance.push_back(d / static_cast<double>(m.vertices.size()));
    angle.push_back(mean_normal_angle(m));
  }
  EXPECT_LT(distance[1], distance[0]);
  EXPECT_LT(distance[2], distance[1]);
  EXPECT_LT(angle[1], angle[0]);
  EXPECT_LT(angle[2], angle[1]);
}

TEST(Smoothing, smoothing_a_ct_head_lowers_the_angle_between_adjacent_normals) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found";
  const auto head = shared(test::load_shared_volume(*test::find_shared_volume("headsq"), *dir));
  const double w = 1150.0;
  const double raw = mean_normal_angle(full_surface(*head, w));
  const double smoothed =
      mean_normal_angle(full_surface(smooth(head, {1, 0, std::nullopt, 1.0}), w));
  // From a coarse level: the data on every 2nd sample, smoothed back to its resolution.
  const double coarse = mean_normal_angle(full_surface(smooth(head, {0, 1, std::nullopt, 1.0}), w));
  EXPECT_LT(smoothed, raw);
  EXPECT_LT(coarse, raw);
}

// ---- 2D: images are volumes one sample thick; z is left alone. ---------------------------------

// A u8 image of rings and a ramp (integer samples: exact values, as for the volumes).
volume ring_image(std::int64_t w, std::int64_t h) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(w * h));
  for (std::int64_t y = 0; y < h; ++y)
    for (std::int64_t x = 0; x < w; ++x) {
      const double r = std::hypot(static_cast<double>(x) - 0.45 * static_cast<double>(w),
                                  static_cast<double>(y) - 0.55 * static_cast<double>(h));
      const double v = 120 + 90 * std::sin(r * 0.7) + 2 * static_cast<double>(x);
      bytes[static_cast<std::size_t>(x + w * y)] =
          static_cast<std::byte>(std::clamp(std::lround(v), 0L, 255L));
    }
  return volume({w, h, 1}, sample_type::u8, std::move(bytes));
}

contour_set full_contours(const volume& image, double w) {
  const hierarchy2d h(image.dims()[0], image.dims()[1]);
  const range_data2d ranges(image, h);
  contour_refiner r(image, h, ranges, w, contour_order::breadth_first);
  r.refine_full();
  return r.extract();
}

TEST(Smoothing, smoothed_images_equal_the_materialisation_and_their_contours_marching_triangles) {
  const auto image = shared(ring_image(23, 19));
  for (const smoothing& s :
       {smoothing{1, 0, std::nullopt, 1.0}, smoothing{2, 0, std::nullopt, 0.5},
        smoothing{1, 2, std::nullopt, 1.0},
        smoothing{2, 1, std::array<std::int64_t, 6>{4, 3, 0, 15, 12, 0}, 1.0}}) {
    SCOPED_TRACE(s.levels * 10 + s.from);
    expect_field_equals_reference(image, s);
    const volume field = smooth(image, s);
    EXPECT_EQ(field.dims()[2], 1);
    const volume dense = as_volume(materialise(*image, s), field);
    for (const double w : {100.5, 140.0}) {
      const contour_set mine = full_contours(field, w);
      EXPECT_GT(mine.segment_count(), 0u);
      EXPECT_TRUE(test::same_segments(mine, test::reference_contours(dense, w))) << w;
      EXPECT_TRUE(test::check_valid_contour(mine, test::image_box(field))) << w;
    }
  }
}

TEST(Smoothing, every_cut_of_a_smoothed_image_is_valid_and_the_shared_images_match_the_reference) {
  const auto image = shared(ring_image(41, 37));
  const volume field = smooth(image, {2, 1, std::nullopt, 1.0});
  const hierarchy2d h(field.dims()[0], field.dims()[1]);
  const range_data2d ranges(field, h);
  contour_refiner r(field, h, ranges, 130.0);
  for (const double eps : {60.0, 20.0, 5.0, 1.0, 0.0}) {
    r.refine_to_error(eps);
    EXPECT_TRUE(test::check_valid_contour(r.extract(), test::image_box(field))) << eps;
  }
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found";
  const auto coins = shared(test::load_pgm(*dir / "coins_384x303.pgm"));
  const smoothing s{1, 0, std::nullopt, 1.0};
  const volume smooth_coins = smooth(coins, s);
  const volume dense = as_volume(materialise(*coins, s), smooth_coins);
  EXPECT_TRUE(test::same_segments(full_contours(smooth_coins, 100.0),
                                  test::reference_contours(dense, 100.0)));
}

}  // namespace
}  // namespace progiso
