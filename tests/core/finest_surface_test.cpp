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
#include <chrono>
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
#include "support/render_checks.hpp"
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

using test::same_bytes;

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

// ---- In slabs of z planes (detail::finest_slab_planes()): what a grid larger than memory
// takes. Every slab size gives the same surface, ids and order, and the pieces join to it.

// Returns how many triangle corners named a vertex of the next piece.
std::size_t expect_slabs_give_the_same_surface(const volume& v, double w) {
  const triangle_mesh whole = finest_surface(v, w);
  const detail::float_mesh whole_floats = detail::finest_surface_floats(v, w);
  const auto plane = static_cast<std::size_t>(v.dims()[0] * v.dims()[1]);
  std::size_t forward = 0;
  for (const std::size_t planes : {std::size_t{1}, std::size_t{2}, std::size_t{5}}) {
    SCOPED_TRACE("slabs of " + std::to_string(planes) + " planes");
    EXPECT_EQ(detail::finest_slab_planes(v.dims(), planes * plane),
              std::min<std::int64_t>(static_cast<std::int64_t>(planes), v.dims()[2]));
    const detail::float_mesh floats =
        detail::finest_surface_floats(v, w, scrambled_loop, 7, {}, planes * plane);
    EXPECT_EQ(floats.vertices, whole_floats.vertices);
    EXPECT_EQ(floats.triangles, whole_floats.triangles);
    // The pieces, joined in order, are the whole surface; each piece's triangles name vertices
    // of that piece or of the next (the slab's last plane of cubes), never of an earlier one.
    triangle_mesh joined;
    std::size_t pieces = 0;
    std::uint64_t progress_total = 0, progress_last = 0;
    const finest_progress progress = [&](std::uint64_t done, std::uint64_t total) {
      progress_total = total;
      progress_last = done;
    };
    detail::finest_surface_pieces(
        v, w, scrambled_loop, 7, progress,
        [&](triangle_mesh& piece, std::uint64_t first_vertex) {
          ++pieces;
          EXPECT_EQ(first_vertex, joined.vertices.size());
          EXPECT_TRUE(piece.normals.empty());
          for (const auto& t : piece.triangles) {
            for (const std::uint32_t i : t) {
              EXPECT_GE(i, first_vertex);
              if (i >= first_vertex + piece.vertices.size()) ++forward;
            }
          }
          joined.vertices.insert(joined.vertices.end(), piece.vertices.begin(),
                                 piece.vertices.end());
          joined.triangles.insert(joined.triangles.end(), piece.triangles.begin(),
                                  piece.triangles.end());
          piece.vertices.assign(3, vec3{});  // the callee may change the piece: cleared after
        },
        planes * plane);
    const auto nz = static_cast<std::size_t>(v.dims()[2]);
    EXPECT_EQ(pieces, (nz + planes - 1) / planes);
    EXPECT_TRUE(same_bytes(whole, joined));
    // Each slab's first pass counts the plane after it too: the progress total says so.
    const std::uint64_t rows = static_cast<std::uint64_t>(v.dims()[1]) * nz;
    EXPECT_EQ(progress_total, 2 * rows + (pieces - 1) * static_cast<std::uint64_t>(v.dims()[1]));
    EXPECT_EQ(progress_last, progress_total);
  }
  return forward;
}

TEST(FinestSurface, in_slabs_of_any_plane_count_is_the_same_surface_and_its_pieces_join_to_it) {
  // A sphere crosses every slab boundary: triangles there name the next piece's vertices.
  EXPECT_GT(
      expect_slabs_give_the_same_surface(make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}), 11.0),
      0U);
  expect_slabs_give_the_same_surface(make_torus_field({40, 40, 24}, {19.5, 20.2, 11.7}, 12.0), 4.0);
  expect_slabs_give_the_same_surface(make_gyroid_field({35, 29, 33}, 11.0), 0.2);
  expect_slabs_give_the_same_surface(make_gaussian_blobs({2, 17, 9}, 3, 5), 0.4);
}

TEST(FinestSurface, shares_of_the_planes_counted_then_meshed_join_to_the_whole_surface) {
  // What MPI ranks do: each counts its planes, takes the counts before it as its first ids, and
  // meshes its planes alone; joined in rank order the pieces are finest_surface()'s mesh.
  const volume v = make_torus_field({40, 37, 29}, {19.5, 18.2, 14.7}, 12.0);
  const double w = 4.0;
  const triangle_mesh whole = finest_surface(v, w);
  const auto plane = static_cast<std::size_t>(v.dims()[0] * v.dims()[1]);
  for (const std::vector<std::int64_t>& cuts :
       {std::vector<std::int64_t>{0, 29}, {0, 10, 29}, {0, 7, 7, 16, 28, 29}, {0, 1, 2, 3, 29}}) {
    for (const std::size_t slab : {std::size_t{0}, 2 * plane}) {
      SCOPED_TRACE(testing::PrintToString(cuts) + " slab bytes " + std::to_string(slab));
      std::uint64_t first_vertex = 0, first_triangle = 0;
      triangle_mesh joined;
      for (std::size_t r = 0; r + 1 < cuts.size(); ++r) {
        detail::finest_share share{cuts[r], cuts[r + 1], first_vertex, first_triangle};
        const std::array<std::uint64_t, 2> counts =
            detail::finest_share_counts(v, w, scrambled_loop, 5, share, slab);
        const std::size_t before = joined.vertices.size(), before_t = joined.triangles.size();
        detail::finest_surface_pieces(
            v, w, scrambled_loop, 5, {},
            [&](triangle_mesh& piece, std::uint64_t first) {
              EXPECT_EQ(first, joined.vertices.size());
              joined.vertices.insert(joined.vertices.end(), piece.vertices.begin(),
                                     piece.vertices.end());
              joined.triangles.insert(joined.triangles.end(), piece.triangles.begin(),
                                      piece.triangles.end());
            },
            slab, share);
        EXPECT_EQ(joined.vertices.size() - before, counts[0]);
        EXPECT_EQ(joined.triangles.size() - before_t, counts[1]);
        first_vertex += counts[0];
        first_triangle += counts[1];
      }
      EXPECT_TRUE(same_bytes(whole, joined));
    }
  }
  EXPECT_THROW((void)detail::finest_share_counts(v, w, {}, 1, {5, 30, 0, 0}), error);
  EXPECT_THROW((void)detail::finest_share_counts(v, w, {}, 1, {6, 5, 0, 0}), error);
}

TEST(FinestSurface, slabs_are_chosen_by_the_grid_corner_bytes) {
  // Up to finest_whole_grid_bytes points: one slab; beyond: finest_slab_bytes of planes.
  EXPECT_EQ(detail::finest_slab_planes({513, 513, 513}), 513);
  EXPECT_EQ(detail::finest_slab_planes({1024, 1024, 1024}), 64);
  EXPECT_EQ(detail::finest_slab_planes({1024, 1024, 1024}, std::size_t{1} << 20), 1);
  EXPECT_EQ(detail::finest_slab_planes({1024, 1024, 1024}, 1), 1);  // at least a plane
  EXPECT_EQ(detail::finest_slab_planes({20000, 20000, 3}), 1);
  EXPECT_EQ(detail::finest_slab_planes({8, 8, 8}, std::size_t{1} << 30), 8);
  EXPECT_EQ(detail::finest_slab_planes({30000, 30000, 1}), 1);  // an image: its one plane
}

// ---- uniform_surface(): a uniform cut above the finest, by the same passes on every
// stride-th sample.

// The hierarchy's cut in which every diamond of scale ≥ stride is split (the refiner replays a
// parent-closed set), extracted as refinement extracts it.
triangle_mesh hierarchy_uniform_cut(const volume& v, double w, std::int32_t stride) {
  const hierarchy h(v.dims());
  const range_data ranges(v, h);
  refiner r(v, h, ranges, w, refine_order::depth_first);
  r.refine_set([&h, stride](std::uint64_t index) { return h.scale_of(h.point(index)) >= stride; });
  return r.extract();
}

TEST(UniformSurface, is_the_hierarchy_cut_of_every_diamond_of_the_stride_or_coarser) {
  // Boxes whose every dims − 1 the strides divide: the surface must be the hierarchy's cut,
  // triangle for triangle, vertex for vertex and orientation included (a diagonal pattern
  // around the wrong corners or a position computed another way would differ).
  struct field_case {
    volume v;
    double w;
  };
  std::vector<field_case> cases;
  cases.push_back({make_sphere_field({33, 33, 33}, {16.3, 15.8, 16.1}), 11.0});
  cases.push_back({make_gyroid_field({33, 17, 65}, 11.0), 0.2});
  cases.push_back({make_marschner_lobb({33, 33, 33}), 0.5});
  std::vector<std::byte> bytes(33 * 17 * 17);
  std::uint32_t state = 777;
  for (std::byte& b : bytes) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<std::byte>((state >> 24) & 3u);
  }
  cases.push_back({volume({33, 17, 17}, sample_type::u8, bytes), 1.0});  // ties at the isovalue
  // Stored samples are read in place with a stride; a computed (smoothed) field's are copied.
  smoothing s;
  s.levels = 1;
  cases.push_back(
      {smooth(std::make_shared<const volume>(make_gaussian_blobs({33, 17, 17}, 4, 7)), s), 0.45});
  for (const field_case& c : cases) {
    for (const std::int32_t stride : {2, 4, 8}) {
      SCOPED_TRACE(stride);
      const triangle_mesh mine = uniform_surface(c.v, c.w, stride);
      const triangle_mesh cut = hierarchy_uniform_cut(c.v, c.w, stride);
      ASSERT_FALSE(cut.empty());
      EXPECT_EQ(mine.triangles.size(), cut.triangles.size());
      EXPECT_EQ(mine.vertices.size(), cut.vertices.size());
      EXPECT_TRUE(test::same_surface(mine, cut));
      EXPECT_TRUE(same_bytes(mine, uniform_surface(c.v, c.w, stride, scrambled_loop, 7)));
    }
  }
}

TEST(UniformCut, is_the_hierarchy_cut_clipped_to_the_box_on_grids_the_stride_does_not_divide) {
  // Where a stride does not divide dims − 1 the hierarchy pads the grid with the nearest samples
  // and clips its cut to the box: uniform_cut() must give that very surface (the engine publishes
  // it as a cut of the hierarchy), valid, the same for every piece count, and the finest surface
  // at stride 1.
  struct field_case {
    volume v;
    double w;
  };
  std::vector<field_case> cases;
  cases.push_back({make_sphere_field({30, 37, 23}, {14.2, 18.7, 11.1}), 9.5});
  cases.push_back({make_sphere_field({26, 21, 19}, {24.0, 2.0, 17.5}), 12.0});  // cut by the box
  cases.push_back({make_gyroid_field({44, 20, 38}, 11.0), 0.2});
  cases.push_back({make_marschner_lobb({40, 40, 40}), 0.5});
  std::vector<std::byte> bytes(29 * 18 * 21);
  std::uint32_t state = 4242;
  for (std::byte& b : bytes) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<std::byte>((state >> 24) & 3u);
  }
  cases.push_back({volume({29, 18, 21}, sample_type::u8, bytes), 1.0});  // ties at the isovalue
  for (const field_case& c : cases) {
    SCOPED_TRACE(c.v.dims()[0]);
    const auto box = test::data_box(c.v);
    for (const std::int32_t stride : {2, 4, 8}) {
      SCOPED_TRACE(stride);
      const triangle_mesh mine = uniform_cut(c.v, c.w, stride);
      const triangle_mesh cut = hierarchy_uniform_cut(c.v, c.w, stride);
      ASSERT_FALSE(cut.empty());
      EXPECT_EQ(mine.triangles.size(), cut.triangles.size());
      EXPECT_EQ(mine.vertices.size(), cut.vertices.size());
      EXPECT_TRUE(test::same_surface(mine, cut));
      // (Random samples with ties at the isovalue pinch the hierarchy's own cut at vertices: its
      // sameness is what is asked there.)
      if (c.v.type() != sample_type::u8) {
        EXPECT_TRUE(test::check_valid_cut(mine, box[0], box[1]));
      }
      EXPECT_TRUE(same_bytes(mine, uniform_cut(c.v, c.w, stride, scrambled_loop, 7)));
    }
    EXPECT_TRUE(same_bytes(uniform_cut(c.v, c.w, 1), finest_surface(c.v, c.w)));
  }
}

TEST(UniformSurface, covers_the_whole_box_when_the_stride_does_not_divide_it) {
  // A linear field: marching tetrahedra reproduces its level set exactly, so every vertex
  // must lie on the plane, inside the box, and the surface must reach the box's last planes
  // (the thinner last cells stretched to them, not cut off or pushed past them).
  const index3 dims{30, 37, 23};
  std::vector<std::byte> bytes(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]) * 4);
  const auto f = [](double x, double y, double z) { return 0.5 * x + 0.25 * y + z; };
  for (std::int64_t z = 0; z < dims[2]; ++z) {
    for (std::int64_t y = 0; y < dims[1]; ++y) {
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        const auto v = static_cast<float>(
            f(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
        std::memcpy(bytes.data() + 4 * static_cast<std::size_t>(x + dims[0] * (y + dims[1] * z)),
                    &v, 4);
      }
    }
  }
  const volume v(dims, sample_type::f32, bytes, {0.5, 2.0, 1.0}, {-3.0, 7.0, 1.5});
  const double w = 23.3;
  const vec3 lo{-3.0, 7.0, 1.5};
  const vec3 hi{-3.0 + 29 * 0.5, 7.0 + 36 * 2.0, 1.5 + 22 * 1.0};
  for (const std::int32_t stride : {2, 4, 8, 16}) {
    SCOPED_TRACE(stride);
    const triangle_mesh m = uniform_surface(v, w, stride, scrambled_loop, 5);
    ASSERT_FALSE(m.empty());
    EXPECT_TRUE(test::check_valid_cut(m, lo, hi));
    vec3 top = lo;
    for (const vec3& p : m.vertices) {
      for (std::size_t q = 0; q < 3; ++q) {
        ASSERT_GE(p[q], lo[q]);
        ASSERT_LE(p[q], hi[q]);
        top[q] = std::max(top[q], p[q]);
      }
      const double value = f((p[0] + 3.0) / 0.5, (p[1] - 7.0) / 2.0, p[2] - 1.5);
      ASSERT_NEAR(value, w, 1e-9);
    }
    // The plane x/2 + y/4 + z = 23.3 meets the box's last y and z planes (y index 36, z 22)
    // inside the box; a surface cut off at the last whole stride would stop short of them.
    EXPECT_EQ(top[1], hi[1]);
    EXPECT_EQ(top[2], hi[2]);
  }
  // The grid read: every stride-th index and the last.
  EXPECT_EQ(uniform_grid_dims(dims, 4),
            (index3{9, 10, 7}));  // 0, 4, …, 28, 29; 0, …, 36; 0, …, 20, 22
  EXPECT_EQ(uniform_grid_dims({33, 2, 1}, 8), (index3{5, 2, 1}));
}

TEST(UniformSurface, stride_one_is_the_finest_surface_and_bad_strides_are_refused) {
  const volume v = make_sphere_field({21, 19, 17}, {10.0, 9.0, 8.0});
  EXPECT_TRUE(same_bytes(uniform_surface(v, 7.0, 1), finest_surface(v, 7.0)));
  for (const std::int32_t bad : {0, -2, 3, 6, 1 << 15}) {
    EXPECT_THROW((void)uniform_surface(v, 7.0, bad), error) << bad;
  }
  EXPECT_THROW((void)uniform_surface(v, std::nan(""), 2), error);
  const volume image({16, 16, 1}, sample_type::u8, std::vector<std::byte>(256));
  EXPECT_THROW((void)uniform_surface(image, 0.5, 2), error);
  // Every stride up to one cell for the whole box: surfaces, valid, within the box.
  for (std::int32_t stride = 2; stride <= 32; stride *= 2) {
    SCOPED_TRACE(stride);
    EXPECT_TRUE(test::check_valid_cut(uniform_surface(v, 7.0, stride), {0, 0, 0}, {20, 18, 16}));
  }
}

// ---- ladder_surface(): uniform cuts, coarse to fine, until a deadline.

TEST(LadderSurface, a_distant_deadline_climbs_every_stride_to_the_finest_cut) {
  // Longest axis 64 cells: strides 8 (the largest leaving 8 cells), 4, 2 and 1, each heard by
  // the progress callback in turn (two passes over its own rows), the last the finest cut.
  const volume v = make_sphere_field({65, 40, 33}, {31.0, 19.5, 16.2});
  const double w = 14.0;
  std::vector<std::uint64_t> totals;
  std::vector<std::int32_t> strides;
  const ladder_progress heard = [&](std::int32_t stride, std::uint64_t, std::uint64_t total) {
    if (totals.empty() || totals.back() != total) {
      totals.push_back(total);
      strides.push_back(stride);
    }
  };
  const auto far = std::chrono::steady_clock::now() + std::chrono::hours(1);
  const ladder_result l = ladder_surface(v, w, far, scrambled_loop, 6, heard);
  EXPECT_EQ(l.stride, 1);
  EXPECT_EQ(l.levels_done, 4);
  EXPECT_FALSE(l.abandoned);
  EXPECT_GE(l.first_seconds, 0.0);
  EXPECT_TRUE(same_bytes(l.mesh, finest_surface(v, w)));
  std::vector<std::uint64_t> expected;
  for (const std::int32_t stride : {8, 4, 2, 1}) {
    const index3 d = uniform_grid_dims(v.dims(), stride);
    expected.push_back(static_cast<std::uint64_t>(2 * d[1] * d[2]));
  }
  EXPECT_EQ(totals, expected);
  EXPECT_EQ(strides, (std::vector<std::int32_t>{8, 4, 2, 1}));
}

TEST(LadderSurface, a_passed_deadline_gives_the_coarsest_cut_and_a_2d_field_its_finest) {
  const volume v = make_sphere_field({65, 40, 33}, {31.0, 19.5, 16.2});
  const auto past = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  const ladder_result l = ladder_surface(v, 14.0, past);
  EXPECT_EQ(l.stride, 8);
  EXPECT_EQ(l.levels_done, 1);
  EXPECT_FALSE(l.mesh.empty());
  EXPECT_TRUE(same_bytes(l.mesh, uniform_surface(v, 14.0, 8)));
  // A 2D field has no coarser uniform cut: its finest (no cube, so no triangle: a surface needs
  // a third dimension), whatever the deadline, and no other.
  std::vector<std::byte> bytes(24 * 20);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::byte>((i * 37) % 11);
  const volume image({24, 20, 1}, sample_type::u8, bytes);
  const ladder_result flat = ladder_surface(image, 4.5, past);
  EXPECT_EQ(flat.stride, 1);
  EXPECT_EQ(flat.levels_done, 1);
  EXPECT_TRUE(same_bytes(flat.mesh, finest_surface(image, 4.5)));
}

TEST(LadderSurface, gives_up_the_cut_the_deadline_passes_in_and_keeps_the_last_one_done) {
  // Stride 2's first pass is held past the deadline (the callback sleeps): its work is dropped
  // and the stride-4 cut, done before, is the result.
  const volume v = make_sphere_field({65, 40, 33}, {31.0, 19.5, 16.2});
  const index3 d2 = uniform_grid_dims(v.dims(), 2);
  const auto rows2 = static_cast<std::uint64_t>(2 * d2[1] * d2[2]);
  bool slept = false;
  const ladder_progress slow = [&](std::int32_t, std::uint64_t, std::uint64_t total) {
    if (total == rows2 && !slept) {
      slept = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(400));
    }
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(300);
  const ladder_result l = ladder_surface(v, 14.0, deadline, {}, 1, slow);
  EXPECT_TRUE(slept);
  EXPECT_TRUE(l.abandoned);
  EXPECT_EQ(l.stride, 4);
  EXPECT_EQ(l.levels_done, 2);
  EXPECT_TRUE(same_bytes(l.mesh, uniform_surface(v, 14.0, 4)));
  // What the caller's callback throws still leaves the call.
  const ladder_progress refuse = [](std::int32_t, std::uint64_t, std::uint64_t) {
    throw error("stop");
  };
  EXPECT_THROW((void)ladder_surface(v, 14.0, deadline, {}, 1, refuse), error);
}

TEST(LadderSurface, in_slabs_of_a_few_planes_every_cut_is_the_same_and_a_stop_gives_one_up) {
  // A grid held in slabs of 4 planes, as one past finest_whole_grid_bytes is in slabs of its
  // corner bytes: every cut is uniform_surface()'s, byte for byte, though none is sized at once;
  // a stop asked for while the finest cut's slabs go gives it up and keeps the last one done.
  const volume v = make_sphere_field({65, 40, 33}, {31.0, 19.5, 16.2});
  const double w = 14.0;
  detail::ladder_hooks hooks;
  hooks.slab_bytes = std::size_t{65} * 40 * 4;
  std::vector<std::int32_t> made;
  std::vector<triangle_mesh> cuts;
  hooks.on_cut = [&](triangle_mesh&& m, std::int32_t stride) {
    made.push_back(stride);
    cuts.push_back(std::move(m));
  };
  std::uint64_t finest_rows = 0;
  const ladder_progress rows = [&](std::int32_t stride, std::uint64_t, std::uint64_t total) {
    if (stride == 1) finest_rows = total;
  };
  const auto far = std::chrono::steady_clock::now() + std::chrono::hours(1);
  const ladder_result l = detail::ladder_surface(v, w, far, scrambled_loop, 6, rows, hooks);
  EXPECT_EQ(l.stride, 1);
  EXPECT_FALSE(l.abandoned);
  ASSERT_EQ(made, (std::vector<std::int32_t>{8, 4, 2, 1}));
  // In 9 slabs: both passes' rows, and the plane after each of the first 8 counted again.
  EXPECT_EQ(finest_rows, std::uint64_t{2 * 40 * 33 + 8 * 40});
  for (std::size_t k = 0; k < made.size(); ++k) {
    SCOPED_TRACE(made[k]);
    EXPECT_TRUE(same_bytes(cuts[k], uniform_surface(v, w, made[k])));
  }
  made.clear();
  cuts.clear();
  bool finest_begun = false;
  const ladder_progress heard = [&](std::int32_t stride, std::uint64_t done, std::uint64_t) {
    finest_begun = finest_begun || (stride == 1 && done > 0);
  };
  hooks.stopping = [&] { return finest_begun; };
  const ladder_result stopped = detail::ladder_surface(v, w, far, {}, 1, heard, hooks);
  EXPECT_TRUE(stopped.abandoned);
  EXPECT_EQ(stopped.stride, 2);
  EXPECT_EQ(made, (std::vector<std::int32_t>{8, 4, 2}));
}

}  // namespace
}  // namespace progiso
