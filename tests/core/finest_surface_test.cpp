// finest_surface() (core/surface/finest_surface.hpp): the finest cut's surface by two passes
// over the samples. It must be the surface full refinement ends at — the independent reference
// (plain marching tetrahedra, tests/support) and the refiner's full cut, triangle for triangle
// and vertex for vertex, orientation included — on analytic fields of every parity of size,
// integer samples equal to the isovalue, smoothed fields and every shared volume; every vertex
// used, none twice; and the same bytes for every piece count and order of pieces.
#include <progiso/core/surface/finest_surface.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/field/smoothing.hpp>
#include <progiso/core/refine/refiner.hpp>

#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

/// Runs the pieces last to first, on as many threads as pieces (at most 8): the passes must
/// not depend on the order or the interleaving of their pieces. The first exception a piece
/// throws is thrown again once every thread is done, as a parallel_loop must.
void scrambled_loop(std::size_t n, const std::function<void(std::size_t)>& body) {
  std::vector<std::thread> threads;
  std::mutex mutex;
  std::exception_ptr failure;
  const std::size_t lanes = std::min<std::size_t>(n, 8);
  for (std::size_t l = 0; l < lanes; ++l) {
    threads.emplace_back([&, l] {
      try {
        for (std::size_t k = l; k < n; k += lanes) body(n - 1 - k);
      } catch (...) {
        const std::lock_guard lock(mutex);
        if (!failure) failure = std::current_exception();
      }
    });
  }
  for (std::thread& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
}

bool same_bytes(const triangle_mesh& a, const triangle_mesh& b) {
  return a.vertices.size() == b.vertices.size() && a.triangles.size() == b.triangles.size() &&
         std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(vec3)) == 0 &&
         std::memcmp(a.triangles.data(), b.triangles.data(),
                     a.triangles.size() * sizeof(a.triangles[0])) == 0;
}

void expect_finest_equals_full_refinement(const volume& v, double w) {
  const triangle_mesh mine = finest_surface(v, w);
  const test::reference_surface ref = test::reference_marching_tetrahedra(v, w);
  EXPECT_EQ(mine.triangles.size(), ref.mesh.triangles.size());
  EXPECT_EQ(mine.vertices.size(), ref.mesh.vertices.size());
  EXPECT_TRUE(test::same_surface(mine, ref.mesh));
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  refiner r(v, h, ranges, w, refine_order::depth_first);
  r.refine_full();
  const triangle_mesh full = r.extract();
  EXPECT_EQ(mine.vertices.size(), full.vertices.size());
  EXPECT_TRUE(test::same_surface(mine, full));
  // Every vertex used by a triangle (each crossed edge of the finest mesh lies in a tetrahedron
  // of the data box), and no position twice (each crossed edge is one owner's).
  std::vector<bool> used(mine.vertices.size(), false);
  for (const auto& t : mine.triangles) {
    for (const std::uint32_t i : t) {
      ASSERT_LT(i, mine.vertices.size());
      used[i] = true;
    }
  }
  EXPECT_EQ(std::count(used.begin(), used.end(), false), 0);
  const std::set<vec3> distinct(mine.vertices.begin(), mine.vertices.end());
  EXPECT_EQ(distinct.size(), mine.vertices.size());
  // The same bytes in 1, 7 and 64 pieces, run in any order.
  EXPECT_TRUE(same_bytes(mine, finest_surface(v, w, scrambled_loop, 7)));
  EXPECT_TRUE(same_bytes(mine, finest_surface(v, w, scrambled_loop, 64)));
}

TEST(FinestSurface, equals_full_refinement_on_grids_of_every_parity_of_size) {
  // Sizes odd and even on each axis (the cube classes of both parities at every face of the
  // box), a power of two plus one, and a surface cut open by the box.
  expect_finest_equals_full_refinement(make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}), 11.0);
  expect_finest_equals_full_refinement(make_sphere_field({30, 37, 23}, {14.2, 18.7, 11.1}), 9.5);
  expect_finest_equals_full_refinement(make_sphere_field({26, 21, 19}, {24.0, 2.0, 17.5}), 12.0);
  expect_finest_equals_full_refinement(make_torus_field({40, 40, 24}, {19.5, 20.2, 11.7}, 12.0),
                                       4.0);
  expect_finest_equals_full_refinement(make_gyroid_field({35, 29, 33}, 11.0), 0.2);
  expect_finest_equals_full_refinement(make_marschner_lobb({41, 41, 41}), 0.5);
  expect_finest_equals_full_refinement(make_gaussian_blobs({2, 17, 9}, 3, 5), 0.4);
}

TEST(FinestSurface, integer_samples_equal_to_the_isovalue_and_every_cube_case) {
  // Samples 0..3 with the isovalue on a sample value: ties are white; and a random 0/1 field,
  // whose cubes run through the colour cases of every parity class.
  std::vector<std::byte> bytes(23 * 19 * 17);
  std::uint32_t state = 12345;
  for (std::byte& b : bytes) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<std::byte>((state >> 24) & 3u);
  }
  const volume v({23, 19, 17}, sample_type::u8, bytes);
  expect_finest_equals_full_refinement(v, 1.0);
  expect_finest_equals_full_refinement(v, 2.0);
  for (std::byte& b : bytes) b &= std::byte{1};
  const volume binary({23, 19, 17}, sample_type::u8, bytes);
  expect_finest_equals_full_refinement(binary, 0.5);
}

TEST(FinestSurface, reads_a_smoothed_field_as_refinement_does) {
  auto data = std::make_shared<const volume>(make_gaussian_blobs({13, 11, 9}, 4, 7));
  smoothing s;
  s.levels = 1;
  const volume field = smooth(data, s);
  expect_finest_equals_full_refinement(field, 0.45);
}

TEST(FinestSurface, every_shared_volume_at_its_suggested_isovalues_equals_full_refinement) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "shared data not found (set PROGISO_DATA_DIR)";
  for (const auto& info : test::shared_volumes()) {
    const volume v = test::load_shared_volume(info, *dir);
    for (const double w : info.isovalues) {
      SCOPED_TRACE(std::string(info.name) + " at " + std::to_string(w));
      expect_finest_equals_full_refinement(v, w);
    }
  }
}

TEST(FinestSurface, an_isovalue_outside_the_data_gives_nothing_and_nan_is_refused) {
  const volume v = make_sphere_field({9, 9, 9}, {4.0, 4.0, 4.0});
  EXPECT_TRUE(finest_surface(v, 100.0).empty());
  EXPECT_TRUE(finest_surface(v, 100.0).vertices.empty());
  EXPECT_THROW((void)finest_surface(v, std::nan("")), error);
}

// The progress of both passes: every row of the volume counted once per pass, reported one
// call at a time with counts that never go down, the last call on the caller's thread with
// everything done; the surface unchanged by being watched; a callback that throws ends the call.
TEST(FinestSurface, reports_the_rows_of_both_passes_one_call_at_a_time_and_stops_when_told) {
  const volume v = make_sphere_field({40, 33, 29}, {19.0, 16.0, 14.0});
  const double w = 10.0;
  const std::uint64_t rows_total = 2 * 33 * 29;
  const triangle_mesh plain = finest_surface(v, w);
  for (const std::size_t parts : {std::size_t{1}, std::size_t{7}, std::size_t{64}}) {
    SCOPED_TRACE(parts);
    std::atomic<bool> inside{false};
    std::atomic<int> overlaps{0};
    std::vector<std::uint64_t> seen;  // filled one call at a time
    std::vector<std::thread::id> callers;
    const finest_progress progress = [&](std::uint64_t done, std::uint64_t total) {
      // seq_cst: the exchange pairs with another call's store of false below; a call that
      // finds true overlaps one still running.
      if (inside.exchange(true)) ++overlaps;
      EXPECT_EQ(total, rows_total);
      seen.push_back(done);
      callers.push_back(std::this_thread::get_id());
      std::this_thread::yield();  // widen the window another call would overlap in
      inside.store(false);        // seq_cst: pairs with the next call's exchange
    };
    const triangle_mesh watched = parts == 1
                                      ? finest_surface(v, w, {}, 1, progress)
                                      : finest_surface(v, w, scrambled_loop, parts, progress);
    EXPECT_TRUE(same_bytes(plain, watched));
    EXPECT_EQ(overlaps.load(), 0);  // seq_cst: after the run's threads are joined
    ASSERT_FALSE(seen.empty());
    EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
    EXPECT_GT(seen.front(), 0U);
    EXPECT_EQ(seen.back(), rows_total);
    EXPECT_EQ(callers.back(), std::this_thread::get_id());
    if (parts == 1) {
      // On one thread no call is dropped: 64 rows at a time through each pass (957 rows: 14
      // steps of 64 and one of 61), then the last report.
      EXPECT_EQ(seen.size(), 2 * 15 + 1);
      EXPECT_EQ(seen[0], 64U);
      EXPECT_EQ(seen[13], 896U);
      EXPECT_EQ(seen[14], 957U);
      EXPECT_EQ(seen[15], 957U + 64U);
      EXPECT_EQ(seen[29], rows_total);
    }
  }
  // What the callback throws leaves the call, from either pass.
  for (const std::uint64_t stop_at : {std::uint64_t{64}, rows_total / 2 + 64}) {
    const finest_progress stop = [stop_at](std::uint64_t done, std::uint64_t) {
      if (done >= stop_at) throw error("stopped at " + std::to_string(done));
    };
    EXPECT_THROW((void)finest_surface(v, w, {}, 1, stop), error);
    EXPECT_THROW((void)finest_surface(v, w, scrambled_loop, 7, stop), error);
  }
}

}  // namespace
}  // namespace progiso
