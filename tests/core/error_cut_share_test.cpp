// Error cuts made in shares of planes (what MPI ranks do): the shares' splits are the one
// process's split set, each range data built from its own pieces plus copies of the others'
// bytes is the one process's, and the merged stream meshes to the one process's cut.
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/error_cut_share.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

// An integer field of noise, smoothed a little: many small components, ties at integer
// isovalues, quantised errors.
volume make_noise_u8(index3 dims, std::uint32_t seed) {
  std::mt19937 gen(seed);
  std::vector<std::uint8_t> v(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]));
  for (auto& x : v) x = static_cast<std::uint8_t>(gen() % 200);
  std::vector<std::uint8_t> s(v.size());
  const auto at = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
    x = std::clamp<std::int64_t>(x, 0, dims[0] - 1);
    y = std::clamp<std::int64_t>(y, 0, dims[1] - 1);
    z = std::clamp<std::int64_t>(z, 0, dims[2] - 1);
    return static_cast<int>(v[static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z))]);
  };
  for (std::int64_t z = 0; z < dims[2]; ++z) {
    for (std::int64_t y = 0; y < dims[1]; ++y) {
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        const int sum = at(x, y, z) * 2 + at(x - 1, y, z) + at(x + 1, y, z) + at(x, y - 1, z) +
                        at(x, y + 1, z) + at(x, y, z - 1) + at(x, y, z + 1);
        s[static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z))] =
            static_cast<std::uint8_t>(sum / 8);
      }
    }
  }
  std::vector<std::byte> bytes(s.size());
  std::memcpy(bytes.data(), s.data(), s.size());
  return volume(dims, sample_type::u8, std::move(bytes));
}

struct cut_case {
  const char* name;
  volume vol;
  double iso;
  std::vector<double> errors;
};

std::vector<cut_case> cases() {
  std::vector<cut_case> c;
  c.push_back(
      {"marschner-lobb 41x37x29", make_marschner_lobb({41, 37, 29}), 0.5, {0.2, 0.05, 0.0}});
  c.push_back(
      {"sphere 33^3", make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}), 11.0, {1.0, 0.1, 0.0}});
  c.push_back({"noise u8 30x26x47", make_noise_u8({30, 26, 47}, 7), 100.0, {20.0, 6.0, 0.0}});
  c.push_back({"blobs 50x20x64", make_gaussian_blobs({50, 20, 64}, 9, 3), 0.4, {0.1, 0.01}});
  return c;
}

// The shares as the mesher and the stream writer take them.
std::vector<const detail::share_splits*> pointers(const std::vector<detail::share_splits>& shares) {
  std::vector<const detail::share_splits*> p;
  for (const detail::share_splits& s : shares) p.push_back(&s);
  return p;
}

// Range data for each of `n` shares, each building its own pieces and copying the others'.
std::vector<std::unique_ptr<range_data>> shared_ranges(const volume& v, const hierarchy& h,
                                                       std::size_t n) {
  std::vector<std::unique_ptr<range_data>> rd;
  std::vector<detail::cut_share> share;
  for (std::size_t k = 0; k < n; ++k) {
    rd.push_back(std::make_unique<range_data>(v, h, range_data::staged));
    share.push_back(detail::error_cut_share(h, rd[k]->piece_count(), k, n));
    rd[k]->build_pieces_with_errors(share[k].piece_begin, share[k].piece_end);
  }
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < n; ++j) {
      if (j == k) continue;
      const std::span<std::byte> from =
          rd[j]->piece_bytes(share[j].piece_begin, share[j].piece_end);
      const std::span<std::byte> to = rd[k]->piece_bytes(share[j].piece_begin, share[j].piece_end);
      EXPECT_EQ(from.size(), to.size());
      if (!from.empty()) std::memcpy(to.data(), from.data(), from.size());
    }
  }
  for (auto& r : rd) {
    r->finish();
    r->finish_errors();
  }
  return rd;
}

TEST(ErrorCutShare, shares_partition_the_planes_and_the_pieces) {
  const hierarchy h({41, 37, 29});
  const volume v = make_marschner_lobb({41, 37, 29});
  const range_data rd(v, h, range_data::staged);
  for (std::size_t n : {1u, 2u, 3u, 7u, 40u}) {
    std::int32_t z = 0;
    std::size_t p = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const detail::cut_share s = detail::error_cut_share(h, rd.piece_count(), k, n);
      EXPECT_EQ(s.z_begin, z) << n << " shares, share " << k;
      EXPECT_EQ(s.piece_begin, p) << n << " shares, share " << k;
      EXPECT_LE(s.z_begin, s.z_end);
      z = s.z_end;
      p = s.piece_end;
    }
    EXPECT_EQ(z, h.grid_max()[2] + 1);
    EXPECT_EQ(p, rd.piece_count());
  }
}

TEST(ErrorCutShare, the_shares_splits_are_the_one_process_split_set_and_mesh_to_its_cut) {
  for (cut_case& c : cases()) {
    const hierarchy h(c.vol.dims());
    const range_data whole(c.vol, h);
    for (const double eps : c.errors) {
      refiner one(c.vol, h, whole, c.iso);
      one.refine_to_error(eps);
      const triangle_mesh expected = one.extract();
      for (const std::size_t n : {1u, 2u, 3u, 5u}) {
        SCOPED_TRACE(std::string(c.name) + ", error " + std::to_string(eps) + ", " +
                     std::to_string(n) + " shares");
        const auto rd = shared_ranges(c.vol, h, n);
        std::vector<detail::share_splits> shares;
        std::uint64_t splits = 0;
        for (std::size_t k = 0; k < n; ++k) {
          const detail::cut_share s = detail::error_cut_share(h, rd[k]->piece_count(), k, n);
          shares.push_back(
              detail::error_cut_splits(h, c.vol, *rd[k], c.iso, eps, s.z_begin, s.z_end));
          for (const detail::share_split& sp : shares.back().splits) {
            const ipoint p = h.point(sp.diamond);
            EXPECT_GE(p[2], s.z_begin);
            EXPECT_LT(p[2], s.z_end);
            EXPECT_TRUE(one.is_split(p)) << "split only by the share: " << sp.diamond;
          }
          splits += shares.back().splits.size();
        }
        // Every share's split is the process's, none twice: the counts then say the sets agree.
        EXPECT_EQ(splits, one.statistics().splits);
        std::vector<std::byte> bytes;
        detail::write_cut_stream(
            [&bytes](std::span<const std::byte> b) {
              bytes.insert(bytes.end(), b.begin(), b.end());
            },
            h, c.vol, c.iso, pointers(shares));
        const hierarchy_stream stream = hierarchy_stream::decode(bytes);
        EXPECT_EQ(stream.records(), splits);
        const triangle_mesh got = stream.mesh(stream.all());
        ASSERT_EQ(got.vertices.size(), expected.vertices.size());
        ASSERT_EQ(got.triangles.size(), expected.triangles.size());
        EXPECT_TRUE(got.vertices == expected.vertices);
        EXPECT_TRUE(got.triangles == expected.triangles);
        // The same without a stream, in one piece and in several.
        for (const std::size_t parts : {1u, 3u}) {
          const triangle_mesh direct =
              detail::mesh_of_shares(h, c.vol, c.iso, pointers(shares), {}, parts);
          EXPECT_TRUE(direct.vertices == expected.vertices) << parts << " parts";
          EXPECT_TRUE(direct.triangles == expected.triangles) << parts << " parts";
        }
      }
    }
  }
}

TEST(ErrorCutShare, rounds_of_falling_thresholds_add_up_to_each_thresholds_split_set) {
  for (cut_case& c : cases()) {
    const hierarchy h(c.vol.dims());
    const range_data rd(c.vol, h);
    for (const std::size_t n : {1u, 3u}) {
      SCOPED_TRACE(std::string(c.name) + ", " + std::to_string(n) + " shares");
      std::vector<std::unique_ptr<detail::error_cut_walk>> walks;
      for (std::size_t k = 0; k < n; ++k) {
        const detail::cut_share s = detail::error_cut_share(h, rd.piece_count(), k, n);
        walks.push_back(
            std::make_unique<detail::error_cut_walk>(h, c.vol, rd, c.iso, s.z_begin, s.z_end));
      }
      // Thresholds as a deadline run takes them: half the largest error still waiting.
      double largest = std::numeric_limits<double>::infinity();
      int rounds = 0;
      while (largest > 0.0 && rounds < 40) {
        double waiting = 0.0;
        for (const auto& w : walks) waiting = std::max(waiting, w->largest_waiting_error());
        if (!(waiting > 0.0)) break;
        const double eps = waiting / 2;
        largest = waiting;
        std::uint64_t total = 0;
        std::vector<detail::share_splits> now;
        for (auto& w : walks) {
          ASSERT_TRUE(w->extend(eps));
          EXPECT_EQ(w->round_end(), w->splits().splits.size());
          now.push_back(w->splits());
          total += w->round_end();
        }
        refiner one(c.vol, h, rd, c.iso);
        one.refine_to_error(eps);
        EXPECT_EQ(total, one.statistics().splits) << "round " << rounds << ", error " << eps;
        for (const auto& sh : now) {
          for (const auto& sp : sh.splits) EXPECT_TRUE(one.is_split(h.point(sp.diamond)));
        }
        const triangle_mesh got = detail::mesh_of_shares(h, c.vol, c.iso, pointers(now));
        const triangle_mesh want = one.extract();
        EXPECT_TRUE(got.vertices == want.vertices && got.triangles == want.triangles)
            << "round " << rounds << ", error " << eps;
        ++rounds;
      }
      EXPECT_GT(rounds, 3);
      // The last round leaves nothing of positive error: the error-0 set.
      refiner zero(c.vol, h, rd, c.iso);
      zero.refine_to_error(0.0);
      std::uint64_t total = 0;
      for (const auto& w : walks) total += w->round_end();
      EXPECT_EQ(total, zero.statistics().splits);
    }
  }
}

TEST(ErrorCutShare, a_round_stopped_early_says_so_and_keeps_the_last_rounds_count) {
  const volume v = make_marschner_lobb({41, 37, 29});
  const hierarchy h(v.dims());
  const range_data rd(v, h);
  detail::error_cut_walk w(h, v, rd, 0.5, 0, h.grid_max()[2] + 1);
  ASSERT_TRUE(w.extend(0.2));
  const std::size_t first = w.round_end();
  EXPECT_GT(first, 0U);
  int asked = 0;
  EXPECT_FALSE(w.extend(0.01, {}, [&asked] { return ++asked > 2; }));
  EXPECT_EQ(w.round_end(), first);
}

TEST(ErrorCutShare, a_share_far_from_the_surface_makes_only_the_coarse_splits_its_ranges_ask) {
  const volume v = make_sphere_field({33, 33, 65}, {16.0, 16.0, 10.0});
  const hierarchy h(v.dims());
  const range_data rd(v, h);
  // The sphere of radius 6 lies in planes 4 … 16. Planes from 40 on hold only coarse diamonds
  // whose (superset) ranges reach it; a fine diamond there straddles nothing.
  const auto finest_scale = [&](const detail::share_splits& s) {
    std::int32_t m = 1 << 30;
    for (const detail::share_split& sp : s.splits) m = std::min(m, h.scale_of(h.point(sp.diamond)));
    return m;
  };
  const detail::share_splits far = detail::error_cut_splits(h, v, rd, 6.0, 0.0, 40, 65);
  EXPECT_GE(finest_scale(far), 4);
  const detail::share_splits near = detail::error_cut_splits(h, v, rd, 6.0, 0.0, 0, 40);
  EXPECT_EQ(finest_scale(near), 1);
  EXPECT_GT(near.splits.size(), 10 * far.splits.size());
}

}  // namespace
}  // namespace progiso
