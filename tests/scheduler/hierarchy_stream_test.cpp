// The output hierarchy as a stream (core/surface/hierarchy_stream.hpp, written by
// hierarchy_exporter): a consumer without the volume makes from a stream, or a prefix of it, the
// cut the engine makes of the same split set, vertex for vertex; a truncated or corrupt stream
// gets one error.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/hierarchy_export.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/test_data.hpp"

namespace progiso {
namespace {

engine_options with_threads(unsigned n) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = n;
  return o;
}

using bytes = std::vector<std::byte>;

// An exporter into memory; `chunks` records where each chunk ended.
struct memory_stream {
  bytes data;
  std::vector<std::size_t> chunk_ends;
  hierarchy_stream_writer::sink sink() {
    return [this](std::span<const std::byte> b) {
      data.insert(data.end(), b.begin(), b.end());
      chunk_ends.push_back(data.size());
    };
  }
};

// The whole stream of e's current cut.
bytes stream_of(const engine& e) {
  memory_stream m;
  hierarchy_exporter out(e, m.sink());
  out.write(e.snapshot());
  out.finish();
  return m.data;
}

void expect_same_mesh(const triangle_mesh& a, const triangle_mesh& b) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  EXPECT_TRUE(a.vertices == b.vertices);  // bit for bit
  EXPECT_TRUE(a.triangles == b.triangles);
}

std::uint64_t split_count(const hierarchy_stream::split_set& s) {
  return static_cast<std::uint64_t>(std::count(s.begin() + 1, s.end(), std::uint8_t{1}));
}

TEST(HierarchyStream, FullCutEqualsEngineMeshVertexForVertex) {
  for (const unsigned threads : {1u, 2u}) {
    engine e(make_marschner_lobb({41, 37, 33}), 0.5, with_threads(threads));
    e.refine_full();
    const hierarchy_stream h = hierarchy_stream::decode(stream_of(e));
    const surface_snapshot s = e.snapshot();
    EXPECT_TRUE(h.complete());
    EXPECT_EQ(h.records(), s.split_count());
    EXPECT_EQ(h.triangle_count(h.all()), s.triangle_count());
    expect_same_mesh(h.mesh(h.all()), s.mesh());
  }
}

TEST(HierarchyStream, ErrorCutsEqualEngineMeshCut) {
  engine e(make_gaussian_blobs({48, 40, 44}, 6, 7u), 0.3, with_threads(2));
  e.refine_full();
  const hierarchy_stream h = hierarchy_stream::decode(stream_of(e));
  const surface_snapshot s = e.snapshot();
  for (const double err : {0.0, 0.001, 0.01, 0.05, 0.2, 10.0}) {
    const hierarchy_stream::split_set split = h.by_error(err);
    expect_same_mesh(h.mesh(split), s.mesh_cut(err));
    expect_same_mesh(h.mesh(split), s.mesh_of_records(split));
  }
}

TEST(HierarchyStream, TriangleBudgetCutIsTheLargestErrorCutWithinIt) {
  engine e(make_marschner_lobb({45, 45, 45}), 0.5, with_threads(2));
  e.refine_full();
  const hierarchy_stream h = hierarchy_stream::decode(stream_of(e));
  const surface_snapshot s = e.snapshot();
  const std::uint64_t finest = s.triangle_count();
  for (const std::uint64_t k : {std::uint64_t{0}, finest / 50, finest / 4, finest / 2, finest}) {
    double threshold = 0.0;
    const hierarchy_stream::split_set split = h.by_triangles(k, &threshold);
    const std::uint64_t n = h.triangle_count(split);
    if (split_count(split) > 0) {
      EXPECT_LE(n, k);
    }
    if (threshold >= 0.0) {
      // The cut is the engine's cut by that error, and the next larger one exceeds k.
      expect_same_mesh(h.mesh(split), s.mesh_cut(threshold));
      hierarchy_stream::split_set more = split;
      bool grew = false;
      for (std::uint64_t r = 1; r <= h.records(); ++r) {
        if (h.error_of(r) == threshold) {
          more[r] = 1;
          grew = true;
        }
      }
      if (grew) {
        EXPECT_GT(h.triangle_count(more), k);
      }
    } else {
      EXPECT_EQ(split_count(split), h.records());
    }
    EXPECT_EQ(h.mesh(split).triangles.size(), s.mesh_of_records(split).triangles.size());
  }
}

TEST(HierarchyStream, BoxCutIsFinestInsideClosedAndValid) {
  const volume v = make_gyroid_field({40, 36, 44}, 14.0);
  engine e(v, 0.1, with_threads(2));
  e.refine_full();
  const hierarchy_stream h = hierarchy_stream::decode(stream_of(e));
  const surface_snapshot s = e.snapshot();
  const std::array<double, 3> lo{8, 6, 10};
  const std::array<double, 3> hi{22, 20, 30};
  const hierarchy_stream::split_set split = h.in_box(lo, hi);
  EXPECT_LT(split_count(split), h.records());
  EXPECT_GT(split_count(split), h.records() / 10);
  const triangle_mesh m = h.mesh(split);  // throws unless closed under parents
  expect_same_mesh(m, s.mesh_of_records(split));
  const auto box = test::data_box(v);
  EXPECT_TRUE(test::check_valid_cut(m, box[0], box[1]));
  // Inside the box the cut is the finest surface: every finest triangle wholly inside it is in
  // the cut.
  const triangle_mesh finest = s.mesh();
  const auto inside = [&](const triangle_mesh& mesh) {
    std::vector<test::position_triangle> out;
    for (const test::position_triangle& t : test::canonical_triangles(mesh)) {
      bool in = true;
      for (const vec3& p : t) {
        for (std::size_t q = 0; q < 3; ++q) in = in && p[q] >= lo[q] && p[q] <= hi[q];
      }
      if (in) out.push_back(t);
    }
    return out;
  };
  const auto want = inside(finest);
  const auto got = inside(m);
  ASSERT_FALSE(want.empty());
  EXPECT_TRUE(want == got);
}

TEST(HierarchyStream, PrefixAtAChunkIsTheEarlierSnapshot) {
  engine e(make_marschner_lobb({65, 65, 65}), 0.5, with_threads(2));
  memory_stream m;
  hierarchy_exporter out(e, m.sink());
  e.refine(refine_goal::triangles(2000));
  const surface_snapshot early = e.snapshot();
  out.write(early);
  const std::size_t early_bytes = m.data.size();
  e.refine_full();
  out.write(e.snapshot());
  out.finish();
  ASSERT_GT(m.data.size(), early_bytes);
  const std::span<const std::byte> all(m.data);
  const hierarchy_stream prefix = hierarchy_stream::decode(all.first(early_bytes));
  EXPECT_FALSE(prefix.complete());
  EXPECT_EQ(prefix.records(), early.split_count());
  expect_same_mesh(prefix.mesh(prefix.all()), early.mesh());
  // A prefix by record count: the engine's cut of those records.
  const hierarchy_stream full = hierarchy_stream::decode(all);
  const surface_snapshot last = e.snapshot();
  const std::uint64_t k = full.records() / 3;
  const hierarchy_stream first_k = hierarchy_stream::decode(all, k);
  EXPECT_EQ(first_k.records(), k);
  EXPECT_FALSE(first_k.complete());
  std::vector<std::uint8_t> split(last.split_count() + 1, 0);
  std::fill(split.begin() + 1, split.begin() + static_cast<std::ptrdiff_t>(k) + 1, 1);
  expect_same_mesh(first_k.mesh(first_k.all()), last.mesh_of_records(split));
}

TEST(HierarchyStream, EveryTruncationIsAPrefixOrOneError) {
  engine e(make_sphere_field({12, 11, 10}, {5.5, 5.0, 4.5}), 3.5, with_threads(1));
  memory_stream m;
  hierarchy_exporter out(e, m.sink());
  e.refine(refine_goal::triangles(60));
  out.write(e.snapshot());
  e.refine_full();
  out.write(e.snapshot());
  out.finish();
  const std::span<const std::byte> all(m.data);
  std::size_t prefixes = 0;
  for (std::size_t n = 0; n < m.data.size(); ++n) {
    const bool boundary =
        std::find(m.chunk_ends.begin(), m.chunk_ends.end(), n) != m.chunk_ends.end();
    try {
      const hierarchy_stream h = hierarchy_stream::decode(all.first(n));
      EXPECT_TRUE(boundary) << "a stream cut at byte " << n << " inside a chunk was accepted";
      EXPECT_FALSE(h.complete());
      (void)h.mesh(h.all());
      ++prefixes;
    } catch (const error& err) {
      // The header and root chunks are needed; any later chunk boundary is a prefix.
      EXPECT_TRUE(!boundary || n <= m.chunk_ends[2]) << n << ": " << err.what();
      EXPECT_NE(std::string(err.what()).find("hierarchy stream: byte"), std::string::npos);
    }
  }
  EXPECT_GE(prefixes, 2u);
}

TEST(HierarchyStream, CorruptBytesGetOneError) {
  engine e(make_sphere_field({16, 16, 16}, {7.5, 7.5, 7.5}), 5.0, with_threads(1));
  e.refine_full();
  const bytes good = stream_of(e);
  // Every single flipped byte is caught: by the magic, the version, or a chunk's CRC.
  for (std::size_t i = 0; i < good.size(); i += 7) {
    bytes b = good;
    b[i] ^= std::byte{0x5A};
    try {
      (void)hierarchy_stream::decode(b);
      ADD_FAILURE() << "a flipped byte " << i << " was accepted";
    } catch (const error& err) {
      EXPECT_NE(std::string(err.what()).find("hierarchy stream: byte"), std::string::npos);
    }
  }
  bytes longer = good;
  longer.push_back(std::byte{0});
  EXPECT_THROW((void)hierarchy_stream::decode(longer), error);
}

TEST(HierarchyStream, RecordsBeforeTheirParentsAreRefused) {
  engine e(make_sphere_field({16, 16, 16}, {7.5, 7.5, 7.5}), 5.0, with_threads(1));
  e.refine_full();
  const surface_snapshot s = e.snapshot();
  // Re-encode the same records without the first split: its children lose their parent.
  const hierarchy_stream h = hierarchy_stream::decode(stream_of(e));
  ASSERT_GT(h.records(), 2u);
  hierarchy_stream_header hd = h.header();
  std::vector<double> corners(detail::root_corner_count(h.grid()));
  for (std::uint64_t i = 0; i < corners.size(); ++i) {
    const ipoint p = detail::root_corner(h.grid(), i);
    corners[i] = e.field().value(p[0], p[1], p[2]);
  }
  std::vector<owned_triangle> root;
  memory_stream m;
  hierarchy_stream_writer w(m.sink(), hd, corners, root);
  hierarchy_stream_record r;
  r.diamond = h.diamond(2);
  const ipoint c = h.grid().point(r.diamond);
  r.value = e.field().value(c[0], c[1], c[2]);
  r.error = h.error_of(2);
  // A diamond at depth > 0 written first has no parent record.
  if (h.grid().depth_of(c) > 0) {
    w.add(r);
    w.finish();
    try {
      (void)hierarchy_stream::decode(m.data);
      ADD_FAILURE() << "a record before its parents was accepted";
    } catch (const error& err) {
      EXPECT_NE(std::string(err.what()).find("parents"), std::string::npos) << err.what();
    }
  }
  // A split set that is not closed under parents is refused by the cut.
  hierarchy_stream::split_set open = h.all();
  open[1] = 0;
  EXPECT_THROW((void)h.mesh(open), error);
}

// At most 32 bytes of stream per triangle of the finest cut (the bound), on real data.
TEST(HierarchyStream, BytesPerFinestTriangleOnSharedVolumes) {
  const auto dir = test::shared_data_dir();
  if (!dir) GTEST_SKIP() << "no shared data";
  for (const char* name : {"hipip", "brainsmall"}) {
    const test::shared_volume* info = test::find_shared_volume(name);
    ASSERT_NE(info, nullptr);
    engine e(test::load_shared_volume(*info, *dir), info->isovalues[0], with_threads(2));
    e.refine_full();
    const bytes b = stream_of(e);
    const double per =
        static_cast<double>(b.size()) / static_cast<double>(e.snapshot().mesh().triangles.size());
    EXPECT_LE(per, 32.0) << name;
    RecordProperty(std::string(name) + "_bytes_per_triangle", std::to_string(per));
  }
}

}  // namespace
}  // namespace progiso
