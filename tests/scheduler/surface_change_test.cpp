// Changes between snapshots (surface_snapshot::change_since) and the slot pool that follows them
// (render_slots): applied in order, the pool holds exactly the cut of the latest snapshot.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/surface/surface_change.hpp>
#include <progiso/scheduler/engine.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <map>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"
#include "support/render_checks.hpp"

namespace progiso {
namespace {

using test::buffer_triangles;
using test::slot_triangles;

// What a follow saw of clipping: added pieces that shared their triangle's id with the piece
// before, and triangles that were hidden (wholly past the data box) and later gone.
struct clip_counts {
  std::size_t shared = 0;
  std::size_t hidden_then_gone = 0;
};

// Follows e's refinement towards `goals` (one after another), a change per step.
clip_counts expect_slots_follow(engine& e, const std::vector<refine_goal>& goals, bool normals) {
  const vertex_normals nv = normals ? vertex_normals::gradient : vertex_normals::none;
  render_slots slots;
  surface_change change;
  cut_mark mark;
  render_buffers whole;
  std::size_t nonempty_gone = 0;
  clip_counts counts;
  std::set<std::uint64_t> hidden;
  for (const refine_goal& goal : goals) {
    e.refine(goal);
    const surface_snapshot s = e.snapshot();
    s.change_since(mark, change, nv);
    EXPECT_EQ(change.rebuilt, mark.records == 0);
    nonempty_gone += change.gone.empty() ? 0U : 1U;
    for (std::size_t j = 1; j < change.added.size(); ++j) {
      counts.shared += change.added[j] == change.added[j - 1] ? 1U : 0U;
    }
    for (const std::uint64_t id : change.gone) counts.hidden_then_gone += hidden.count(id);
    hidden.insert(change.hidden.begin(), change.hidden.end());
    slots.apply(change);
    mark = s.mark();
    s.mesh_into(whole, nv);
    EXPECT_EQ(slots.triangle_count(), whole.triangle_count()) << s.split_count() << " splits";
    EXPECT_EQ(slot_triangles(slots, false), buffer_triangles(whole, false));
    if (normals) {
      EXPECT_EQ(slot_triangles(slots, true), buffer_triangles(whole, true));
    }
  }
  EXPECT_GT(nonempty_gone, 0U) << "no step removed a triangle: the test shows nothing";
  return counts;
}

std::vector<refine_goal> budget_steps(std::uint64_t first, std::uint64_t last) {
  std::vector<refine_goal> goals;
  for (std::uint64_t k = first; k < last; k *= 2) goals.push_back(refine_goal::triangles(k));
  goals.push_back(refine_goal::full());
  return goals;
}

engine_options with_threads(unsigned n) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = n;
  return o;
}

TEST(SurfaceChange, applied_in_order_the_slots_hold_each_snapshots_cut_triangle_for_triangle) {
  for (const unsigned threads : {1U, 2U}) {
    engine e(make_marschner_lobb({33, 33, 33}), 0.5, with_threads(threads));
    expect_slots_follow(e, budget_steps(64, 8192), false);
  }
}

// 37 × 29 × 41 and 32³ samples: the hierarchy is padded past the data box, so coarse triangles
// are clipped into pieces that share an id, or hidden wholly (and later removed by id).
TEST(SurfaceChange, clipped_pieces_hidden_triangles_and_normals_follow_on_padded_hierarchies) {
  clip_counts seen;
  // Blobs inside the box, and a sphere about a point near the box's far corner, which the box
  // cuts (its surface reaches the padding).
  struct input {
    volume v;
    double w;
  };
  std::vector<input> inputs;
  inputs.push_back({make_gaussian_blobs({37, 29, 41}, 6, 7u), 0.4});
  inputs.push_back({make_sphere_field({32, 32, 32}, {27.5, 26.5, 28.5}), 9.0});
  for (const input& in : inputs) {
    engine e(in.v, in.w, with_threads(2));
    const ipoint& m = e.hierarchy_of().data_max();
    const ipoint& g = e.hierarchy_of().grid_max();
    ASSERT_TRUE(m[0] < g[0] || m[1] < g[1] || m[2] < g[2]) << "the hierarchy is not padded";
    const clip_counts c = expect_slots_follow(e, budget_steps(16, 4096), true);
    seen.shared += c.shared;
    seen.hidden_then_gone += c.hidden_then_gone;
  }
  EXPECT_GT(seen.shared, 0U) << "no triangle was clipped into pieces: the test shows nothing";
  EXPECT_GT(seen.hidden_then_gone, 0U) << "no hidden triangle was removed later";
}

TEST(SurfaceChange, every_prefix_of_the_publication_order_is_a_valid_cut_and_prefixes_chain) {
  // Two threads publish records as they finish; every prefix is still a cut (a record comes
  // after its parents'), so a renderer may catch up by prefixes (truncate()).
  const volume v = make_gaussian_blobs({33, 31, 35}, 6, 9u);
  engine e(v, 0.35, with_threads(2));
  e.refine_full();
  const std::uint64_t records = e.snapshot().mark().records;
  ASSERT_GT(records, 2000u);
  const auto box = test::data_box(v);
  render_slots slots;
  surface_change change;
  cut_mark mark;
  render_buffers whole;
  std::vector<std::uint64_t> prefixes{1, 2, 3};
  for (std::uint64_t k = 5; k < records; k = k * 3 / 2) prefixes.push_back(k);
  prefixes.push_back(records);
  for (const std::uint64_t k : prefixes) {
    surface_snapshot s = e.snapshot();
    s.truncate(k);
    ASSERT_EQ(s.mark().records, k);
    ASSERT_EQ(s.split_count(), k - 1);
    const triangle_mesh m = s.mesh();
    EXPECT_TRUE(test::check_valid_cut(m, box[0], box[1])) << "prefix " << k;
    s.change_since(mark, change, vertex_normals::gradient);
    slots.apply(change);
    mark = s.mark();
    s.mesh_into(whole, vertex_normals::gradient);
    EXPECT_EQ(slot_triangles(slots, true), buffer_triangles(whole, true)) << "prefix " << k;
  }
  surface_snapshot s = e.snapshot();
  s.truncate(0);
  EXPECT_EQ(s.mark().records, 1u);  // the root surface at least
  surface_snapshot t = e.snapshot();
  t.truncate(records + 10);
  EXPECT_EQ(t.mark().records, records);  // no more than it holds
}

TEST(SurfaceChange, an_unchanged_cut_gives_an_empty_change_and_an_isovalue_change_a_rebuild) {
  engine e(make_marschner_lobb({33, 33, 33}), 0.5, with_threads(2));
  e.refine(refine_goal::triangles(2000));
  render_slots slots;
  surface_change change;
  cut_mark mark;
  {
    const surface_snapshot s = e.snapshot();
    s.change_since(mark, change);
    slots.apply(change);
    mark = s.mark();
    s.change_since(mark, change);
    EXPECT_FALSE(change.rebuilt);
    EXPECT_TRUE(change.gone.empty());
    EXPECT_TRUE(change.added.empty());
  }
  e.set_isovalue(0.3);
  e.refine(refine_goal::triangles(1000));
  const surface_snapshot s = e.snapshot();
  s.change_since(mark, change);
  EXPECT_TRUE(change.rebuilt);
  EXPECT_TRUE(change.gone.empty());
  slots.apply(change);
  render_buffers whole;
  s.mesh_into(whole);
  EXPECT_EQ(slot_triangles(slots, false), buffer_triangles(whole, false));
  EXPECT_EQ(slots.slot_count(), whole.triangle_count()) << "a rebuild starts the pool afresh";
}

TEST(SurfaceChange, a_mark_of_another_engine_gives_a_rebuild_of_the_whole_cut) {
  engine a(make_marschner_lobb({33, 33, 33}), 0.5, with_threads(1));
  engine b(make_marschner_lobb({33, 33, 33}), 0.5, with_threads(1));
  // b's cut has more records than the mark: only the owner tells the mark is not b's.
  a.refine(refine_goal::triangles(1000));
  b.refine(refine_goal::triangles(3000));
  cut_mark of_a;
  {
    const surface_snapshot s = a.snapshot();
    of_a = s.mark();
  }
  const surface_snapshot s = b.snapshot();
  ASSERT_EQ(of_a.generation, s.mark().generation);  // same generation: only the owner differs
  ASSERT_LT(of_a.records, s.mark().records);
  surface_change change;
  s.change_since(of_a, change);
  EXPECT_TRUE(change.rebuilt);
  render_slots slots;
  slots.apply(change);
  render_buffers whole;
  s.mesh_into(whole);
  EXPECT_EQ(slot_triangles(slots, false), buffer_triangles(whole, false));
}

// The render side on its own thread, taking its own snapshots while a full run publishes.
TEST(SurfaceChange, a_render_thread_follows_a_background_run_to_the_finest_cut) {
  engine e(make_marschner_lobb({49, 49, 49}), 0.5, with_threads(2));
  e.start(refine_goal::full());
  std::size_t frames = 0;
  std::thread render([&] {
    render_slots slots;
    surface_change change;
    cut_mark mark;
    while (true) {
      const bool last = !e.running();  // read before the snapshot: then it holds the last cut
      const surface_snapshot s = e.snapshot();
      s.change_since(mark, change);
      slots.apply(change);
      mark = s.mark();
      ++frames;
      if (last) {
        render_buffers whole;
        s.mesh_into(whole);
        EXPECT_EQ(slot_triangles(slots, false), buffer_triangles(whole, false));
        return;
      }
    }
  });
  render.join();
  e.wait();
  EXPECT_TRUE(e.done());
  EXPECT_GE(frames, 1U);
}

TEST(RenderSlots, freed_slots_collapse_and_are_reused_before_the_pool_grows) {
  render_slots slots;
  surface_change c;
  c.rebuilt = true;
  for (std::uint64_t id = 0; id < 4; ++id) {
    c.added.push_back(id);
    for (std::uint64_t k = 0; k < 9; ++k) c.positions.push_back(static_cast<float>(id * 10 + k));
  }
  EXPECT_EQ(slots.apply(c), 4U);
  c.clear();
  c.gone = {1, 2};
  c.added = {32};  // record 1's triangle 0
  c.positions.assign(9, 5.0F);
  slots.apply(c);
  EXPECT_EQ(slots.slot_count(), 4U);
  EXPECT_EQ(slots.triangle_count(), 3U);
  std::size_t free = 0;
  for (std::size_t s = 0; s < slots.slot_count(); ++s) {
    if (slots.id_of(s) != render_slots::free_slot) continue;
    ++free;
    const float* p = slots.positions().data() + 9 * s;
    for (std::size_t k = 3; k < 9; ++k) EXPECT_EQ(p[k], p[k % 3]) << "a free slot is not collapsed";
  }
  EXPECT_EQ(free, 1U);
  EXPECT_EQ(slots.written().size(), 3U);  // two freed, one of them reused
}

TEST(RenderSlots, a_change_applied_twice_or_out_of_order_is_refused_and_changes_nothing) {
  render_slots slots;
  surface_change first;
  first.rebuilt = true;
  first.added = {10, 11, 11};  // triangle 11 clipped into two pieces
  first.positions.assign(27, 1.0F);
  slots.apply(first);
  surface_change second;
  second.gone = {11};
  second.added = {32};  // record 1's triangle 0
  second.positions.assign(9, 2.0F);
  slots.apply(second);
  EXPECT_EQ(slots.triangle_count(), 2U);
  const std::vector<float> before(slots.positions().begin(), slots.positions().end());
  EXPECT_THROW(slots.apply(second), error);  // 11 is gone already
  surface_change stale;
  stale.gone = {10, 10};
  EXPECT_THROW(slots.apply(stale), error);
  surface_change again;
  again.added = {33};  // record 1 again
  again.positions.assign(9, 3.0F);
  EXPECT_THROW(slots.apply(again), error);
  EXPECT_EQ(slots.triangle_count(), 2U);
  EXPECT_TRUE(std::equal(before.begin(), before.end(), slots.positions().begin()));
  surface_change unordered;
  unordered.added = {100, 70};
  unordered.positions.assign(18, 4.0F);
  EXPECT_THROW(slots.apply(unordered), error);
  EXPECT_EQ(slots.triangle_count(), 2U);
  EXPECT_TRUE(std::equal(before.begin(), before.end(), slots.positions().begin()));
  surface_change bad;
  bad.added = {130};
  EXPECT_THROW(slots.apply(bad), error);  // no positions
}

}  // namespace
}  // namespace progiso
