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

namespace progiso {
namespace {

using corners = std::array<float, 9>;

std::map<corners, int> triangles_of(const render_slots& s, bool normals) {
  std::map<corners, int> out;
  const std::span<const float> src = normals ? s.normals() : s.positions();
  for (std::size_t slot = 0; slot < s.slot_count(); ++slot) {
    if (s.id_of(slot) == render_slots::free_slot) continue;
    corners c{};
    std::copy_n(src.data() + 9 * slot, 9, c.data());
    ++out[c];
  }
  return out;
}

std::map<corners, int> triangles_of(const render_buffers& b, bool normals) {
  std::map<corners, int> out;
  const std::vector<float>& src = normals ? b.normals : b.positions;
  for (std::size_t t = 0; t < b.triangle_count(); ++t) {
    corners c{};
    for (std::size_t k = 0; k < 9; ++k) c[k] = src[3 * b.indices[3 * t + k / 3] + k % 3];
    ++out[c];
  }
  return out;
}

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
  EXPECT_EQ(triangles_of(feed.surface(), false), triangles_of(b, false));
  if (normals) {
    EXPECT_EQ(triangles_of(feed.surface(), true), triangles_of(b, true));
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
