// frame_feed: a render thread's surface fed through Boost.Lockfree queues by a producer thread.
// The render thread ends holding the engine's latest cut, triangle for triangle; a stalled one
// makes the producer wait (latest wins, memory bounded).
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/frame_feed.hpp>

#include <array>
#include <chrono>
#include <map>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/render_checks.hpp"

namespace progiso {
namespace {

using test::buffer_triangles;
using test::slot_triangles;

bool same_cut(const cut_mark& a, const cut_mark& b) {
  return a.owner == b.owner && a.generation == b.generation && a.records == b.records &&
         a.root == b.root;
}

// Updates until the feed holds the engine's latest cut (the run is over); returns the updates
// that took frames.
std::size_t catch_up(frame_feed& feed, const engine& e) {
  std::size_t updates = 0;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (;;) {
    const bool idle = !e.running();
    if (feed.update() > 0) ++updates;
    if (idle && same_cut(feed.mark(), e.snapshot().mark())) return updates;
    if (std::chrono::steady_clock::now() > give_up) {
      ADD_FAILURE() << "the feed never caught up";
      return updates;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

void expect_holds_latest_cut(const frame_feed& feed, const engine& e, bool normals) {
  render_buffers b;
  e.snapshot().mesh_into(b, normals ? vertex_normals::gradient : vertex_normals::none);
  EXPECT_EQ(slot_triangles(feed.surface(), false), buffer_triangles(b, false));
  if (normals) {
    EXPECT_EQ(slot_triangles(feed.surface(), true), buffer_triangles(b, true));
  }
}

TEST(FrameFeed, a_render_thread_ends_holding_the_engines_latest_cut) {
  const volume v = make_marschner_lobb({49, 45, 41});
  for (const bool uniform : {false, true}) {
    for (const bool normals : {false, true}) {
      SCOPED_TRACE(testing::Message() << "uniform " << uniform << " normals " << normals);
      engine_options o;
      o.threads = 2;
      o.uniform_cuts = uniform;
      o.progress_interval = 256;
      engine e(v, 0.5, o);
      frame_feed_options fo;
      fo.normals = normals ? vertex_normals::gradient : vertex_normals::none;
      fo.poll = std::chrono::microseconds(200);
      frame_feed feed(e, fo);
      e.start(refine_goal::error(0.02));
      std::size_t updates = catch_up(feed, e);
      expect_holds_latest_cut(feed, e, normals);
      // An isovalue change: the new root surface arrives whole, in a pool.
      e.set_isovalue(0.4);
      e.wait();
      updates += catch_up(feed, e);
      expect_holds_latest_cut(feed, e, normals);
      e.refine_full();
      updates += catch_up(feed, e);
      expect_holds_latest_cut(feed, e, normals);
      EXPECT_GE(updates, 3u);
      const frame_feed_statistics st = feed.statistics();
      EXPECT_EQ(st.taken, st.frames);
      EXPECT_GE(st.pools, 2u);  // the first cut, the new isovalue's
    }
  }
}

TEST(FrameFeed, a_stalled_render_thread_makes_the_producer_wait_and_then_skips_versions) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine_options o;
  o.threads = 2;
  o.uniform_cuts = false;  // many cuts on the way
  o.progress_interval = 64;
  engine e(v, 0.5, o);
  frame_feed_options fo;
  fo.depth = 2;
  fo.poll = std::chrono::microseconds(100);
  frame_feed feed(e, fo);
  e.start(refine_goal::full());
  e.wait();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // Nothing taken: at most `depth` frames were made, however many cuts were published.
  EXPECT_LE(feed.statistics().frames, 2u);
  EXPECT_LE(feed.update(), 2u);
  catch_up(feed, e);
  expect_holds_latest_cut(feed, e, false);
}

TEST(FrameFeed, written_slots_are_the_ones_to_upload) {
  const volume v = make_marschner_lobb({41, 41, 41});
  engine_options o;
  o.threads = 1;
  o.uniform_cuts = false;
  engine e(v, 0.5, o);
  frame_feed_options fo;
  fo.poll = std::chrono::microseconds(100);
  frame_feed feed(e, fo);
  // A renderer's copy of the pool, kept by uploading after every update what it says changed.
  std::vector<float> uploaded;
  std::size_t partial = 0;
  const auto sync = [&] {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!same_cut(feed.mark(), e.snapshot().mark()) &&
           std::chrono::steady_clock::now() < give_up) {
      if (feed.update() == 0) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        continue;
      }
      const std::span<const float> now = feed.surface().positions();
      if (feed.replaced()) {
        uploaded.assign(now.begin(), now.end());
        continue;
      }
      ++partial;
      uploaded.resize(now.size());
      for (const std::uint32_t slot : feed.written()) {
        std::copy_n(now.data() + 9 * std::size_t{slot}, 9, uploaded.data() + 9 * std::size_t{slot});
      }
    }
    const std::span<const float> now = feed.surface().positions();
    EXPECT_TRUE(std::equal(uploaded.begin(), uploaded.end(), now.begin(), now.end()));
  };
  sync();
  for (int step = 0; step < 5; ++step) {
    e.refine(refine_goal::triangles(2000 + 1500 * static_cast<std::uint64_t>(step)));
    sync();
  }
  EXPECT_GT(partial, 0u);  // changes, not only whole pools
  expect_holds_latest_cut(feed, e, false);
}

TEST(FrameFeed, a_depth_outside_its_range_is_refused) {
  const volume v = make_marschner_lobb({17, 17, 17});
  engine e(v, 0.5);
  frame_feed_options fo;
  fo.depth = 0;
  EXPECT_THROW(frame_feed(e, fo), error);
  fo.depth = 65;
  EXPECT_THROW(frame_feed(e, fo), error);
}

}  // namespace
}  // namespace progiso
