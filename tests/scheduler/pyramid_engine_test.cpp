// pyramid_engine (scheduler/pyramid_engine.hpp): a pyramid's surface, coarse first. On a
// three-level pyramid of a bumpy ball (level k samples every 2^k-th point of level 0, spacing
// 2^k, so every level is the same object): the coarsest level's surface is shown as soon as it
// is read, while the finer levels' reads are held back; the finest is shown once read and
// refined, with the mesh an engine on that level alone gives; a reader sees whole levels only,
// each snapshot a closed surface of the level it names, and never a coarser level after a finer
// one; an isovalue change reaches the levels read before it and those read after; a failed read
// is rethrown by wait() with the coarser level still shown; cancel() stops a read between chunks
// and a later start() reads again; a passed deadline reads nothing more.
#include <progiso/scheduler/pyramid_engine.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <cstring>
#include <future>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/base/error.hpp>

#include "support/mesh_checks.hpp"

namespace progiso {
namespace {

constexpr std::size_t pyramid_levels = 3;

// Level k of the pyramid: 2^(6 − k) + 1 samples a side, spacing 2^k.
volume ball_level(std::size_t k) {
  const std::int64_t step = std::int64_t{1} << k;
  const std::int64_t n = 64 / step + 1;
  std::vector<std::byte> bytes(static_cast<std::size_t>(n * n * n) * sizeof(float));
  auto* f = reinterpret_cast<float*>(bytes.data());
  for (std::int64_t z = 0; z < n; ++z) {
    for (std::int64_t y = 0; y < n; ++y) {
      for (std::int64_t x = 0; x < n; ++x) {
        const double px = static_cast<double>(x * step) - 31.7;
        const double py = static_cast<double>(y * step) - 32.4;
        const double pz = static_cast<double>(z * step) - 32.2;
        const double r = std::sqrt(px * px + py * py + pz * pz);
        const double bumps = 2.5 * std::sin(px * 0.35) * std::sin(py * 0.3) * std::sin(pz * 0.4);
        f[(z * n + y) * n + x] = static_cast<float>(r + bumps);
      }
    }
  }
  const auto s = static_cast<double>(step);
  return volume({n, n, n}, sample_type::f32, std::move(bytes), {s, s, s});
}

/// A reader whose finer levels wait for open() (the coarsest is read at once), counting reads.
class gated_reader {
 public:
  pyramid_level_reader reader() {
    return [this](std::size_t k, const std::function<bool()>& stop) -> std::optional<volume> {
      reads_.fetch_add(1, std::memory_order_relaxed);
      if (k + 1 < pyramid_levels) {
        std::unique_lock<std::mutex> lock(mutex_);
        // A read's chunks: the stop is asked while it waits.
        while (open_ <= pyramid_levels - 1 - k - 1) {
          if (stop && stop()) return std::nullopt;
          cv_.wait_for(lock, std::chrono::milliseconds(1));
        }
      }
      if (fail_level_ && *fail_level_ == k) throw error("level " + std::to_string(k) + ": bad");
      return ball_level(k);
    };
  }
  /// Lets the next finer level's read finish.
  void open_one() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      ++open_;
    }
    cv_.notify_all();
  }
  void open_all() {
    for (std::size_t i = 0; i < pyramid_levels; ++i) open_one();
  }
  /// Until `n` reads have begun (the coarsest one's included).
  void wait_for_reads(int n) const {
    while (reads_.load(std::memory_order_relaxed) < n) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  std::optional<std::size_t> fail_level_;
  std::atomic<int> reads_{0};

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::size_t open_ = 0;  // finer levels whose read may finish
};

triangle_mesh alone(std::size_t k, double iso) {
  engine e(ball_level(k), iso);
  e.refine_full();
  return e.snapshot().mesh();
}

void expect_same_mesh(const triangle_mesh& a, const triangle_mesh& b, const std::string& what) {
  EXPECT_EQ(a.triangles, b.triangles) << what;
  ASSERT_EQ(a.vertices.size(), b.vertices.size()) << what;
  EXPECT_EQ(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(vec3)), 0)
      << what;
}

TEST(PyramidEngine, the_coarsest_level_is_shown_at_once_and_the_finest_once_read) {
  gated_reader gate;
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  EXPECT_EQ(p.level(), 2U);
  EXPECT_EQ(p.levels_read(), 1U);
  {
    const pyramid_snapshot s = p.snapshot();
    EXPECT_EQ(s.level, 2U);
    EXPECT_EQ(s.source->field().dims(), (index3{17, 17, 17}));
    EXPECT_TRUE(s.surface.valid());  // the root surface, before any run
    EXPECT_EQ(s.surface.split_count(), 0U);
  }
  p.start(refine_goal::full());
  // The finer reads are held back: the coarsest level refines to its finest cut meanwhile.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < until) {
    const pyramid_snapshot s = p.snapshot();
    if (s.surface.triangle_count() == alone(2, 20.0).triangles.size()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(p.level(), 2U);
  expect_same_mesh(p.snapshot().surface.mesh(), alone(2, 20.0), "the coarsest level, full");
  gate.open_all();
  p.wait();
  EXPECT_EQ(p.level(), 0U);
  EXPECT_EQ(p.levels_read(), 3U);
  const pyramid_snapshot s = p.snapshot();
  EXPECT_EQ(s.source->field().dims(), (index3{65, 65, 65}));
  expect_same_mesh(s.surface.mesh(), alone(0, 20.0), "the finest level, full");
}

TEST(PyramidEngine, a_reader_sees_whole_levels_only_and_never_a_coarser_one_after_a_finer) {
  gated_reader gate;
  engine_options options;
  options.threads = 2;
  pyramid_engine p(gate.reader(), pyramid_levels, 24.0, options);
  std::atomic<bool> done{false};
  std::vector<std::string> problems;
  std::size_t looks = 0, levels_seen = 0;
  std::thread reader([&] {
    std::size_t last = pyramid_levels;
    std::vector<bool> seen(pyramid_levels, false);
    while (!done.load(std::memory_order_relaxed)) {
      const pyramid_snapshot s = p.snapshot();
      ++looks;
      if (s.level > last) problems.push_back("level " + std::to_string(s.level) + " after a finer");
      last = s.level;
      const std::int64_t n = 64 / (std::int64_t{1} << s.level) + 1;
      if (s.source->field().dims() != index3{n, n, n}) problems.push_back("another level's field");
      if (!seen[s.level] || looks % 16 == 0) {
        seen[s.level] = true;
        const triangle_mesh m = s.surface.mesh();
        if (const test::check_result c = test::watertight(m); !c) {
          problems.push_back("level " + std::to_string(s.level) + ": " + c.message);
        }
      }
    }
    for (const bool b : seen) levels_seen += b ? 1 : 0;
  });
  p.start(refine_goal::full());
  for (std::size_t i = 0; i < pyramid_levels; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    gate.open_one();
  }
  p.wait();
  // A last look after the finest level is shown.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  done.store(true, std::memory_order_relaxed);
  reader.join();
  EXPECT_TRUE(problems.empty()) << problems.front();
  EXPECT_EQ(p.level(), 0U);
  EXPECT_GE(levels_seen, 2U) << "the reader saw one level only";
  EXPECT_GT(looks, 10U);
}

TEST(PyramidEngine, an_isovalue_change_reaches_the_levels_read_before_and_after_it) {
  gated_reader gate;
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  p.start(refine_goal::full());
  gate.open_one();  // level 1
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (p.levels_read() < 2 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_EQ(p.levels_read(), 2U);
  p.set_isovalue(26.0);
  EXPECT_EQ(p.isovalue(), 26.0);
  EXPECT_EQ(p.snapshot().surface.isovalue(), 26.0);  // the shown level's new root surface
  gate.open_one();                                   // level 0, read after the change
  p.wait();
  EXPECT_EQ(p.level(), 0U);
  const pyramid_snapshot s = p.snapshot();
  EXPECT_EQ(s.surface.isovalue(), 26.0);
  expect_same_mesh(s.surface.mesh(), alone(0, 26.0), "the finest level at the new isovalue");
}

TEST(PyramidEngine, a_failed_read_is_rethrown_by_wait_with_the_coarser_level_shown) {
  gated_reader gate;
  gate.fail_level_ = 0;
  gate.open_all();
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  p.start(refine_goal::full());
  try {
    p.wait();
    ADD_FAILURE() << "expected the read's error";
  } catch (const error& e) {
    EXPECT_NE(std::string(e.what()).find("level 0: bad"), std::string::npos) << e.what();
  }
  EXPECT_EQ(p.level(), 1U);
  expect_same_mesh(p.snapshot().surface.mesh(), alone(1, 20.0), "level 1, full");
}

TEST(PyramidEngine, cancel_stops_a_read_between_chunks_and_start_reads_again) {
  gated_reader gate;
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  p.start(refine_goal::full());
  gate.wait_for_reads(2);
  p.cancel();  // the read of level 1 waits for its gate: it must stop at the next chunk
  EXPECT_EQ(p.level(), 2U);
  EXPECT_EQ(p.levels_read(), 1U);
  gate.open_all();
  p.start(refine_goal::full());
  p.wait();
  EXPECT_EQ(p.level(), 0U);
  EXPECT_EQ(p.levels_read(), 3U);
}

TEST(PyramidEngine, a_passed_deadline_reads_no_finer_level) {
  gated_reader gate;
  gate.open_all();
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  p.start(refine_goal::until(std::chrono::steady_clock::now() - std::chrono::milliseconds(1)));
  p.wait();
  EXPECT_EQ(p.level(), 2U);
  EXPECT_EQ(gate.reads_.load(std::memory_order_relaxed), 1);
  EXPECT_EQ(p.levels_read(), 1U);
  EXPECT_EQ(p.snapshot().source->field().dims(), (index3{17, 17, 17}));
}

TEST(PyramidEngine, going_away_mid_read_neither_hangs_nor_leaks_a_run) {
  gated_reader gate;
  {
    pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
    p.start(refine_goal::full());
    gate.wait_for_reads(2);
  }
  SUCCEED();
}

TEST(PyramidEngine, refuses_no_level_and_a_non_finite_isovalue) {
  gated_reader gate;
  EXPECT_THROW(pyramid_engine(gate.reader(), 0, 20.0), error);
  EXPECT_THROW(pyramid_engine(gate.reader(), pyramid_levels, std::nan("")), error);
  pyramid_engine p(gate.reader(), pyramid_levels, 20.0);
  EXPECT_THROW(p.set_isovalue(std::nan("")), error);
}

}  // namespace
}  // namespace progiso
