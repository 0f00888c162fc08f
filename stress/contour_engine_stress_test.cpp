// Randomized concurrent run of the contour engine: reader threads take snapshots and extract
// them continuously, pausing 0–50 µs at random points inside their guards, while a control
// thread changes the isovalue, starts, cancels and restarts runs and runs deadlines. Every
// snapshot is checked:
//   - integrity: its root is alive and its records well-formed (retired roots are poisoned
//     before they are freed, so a snapshot reading a reclaimed root fails here, or under ASan);
//   - a valid contour: vertices used at most twice, consistent orientation, open chains ending
//     on the image border, no crossings (CGAL exact predicates), all of the snapshot's isovalue;
//   - cuts of one root only grow, and a held snapshot's contour never changes.
// At shutdown every root (one per isovalue) has been reclaimed exactly once.
// Runs PROGISO_STRESS_SECONDS (default 1).
#include <progiso/scheduler/contour_engine.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/contour_checks.hpp"
#include "support/engine_stress.hpp"
#include "support/stress_support.hpp"

namespace progiso {
namespace {

using clock = std::chrono::steady_clock;

volume ripples(std::int64_t w, std::int64_t h) {
  std::vector<std::byte> b(static_cast<std::size_t>(w * h) * sizeof(float));
  auto* p = reinterpret_cast<float*>(b.data());
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      const double fx = static_cast<double>(x);
      const double fy = static_cast<double>(y);
      p[x + w * y] =
          static_cast<float>(std::sin(fx * 0.13) * std::cos(fy * 0.11) + 0.002 * (fx - fy));
    }
  }
  return volume({w, h, 1}, sample_type::f32, std::move(b));
}

TEST(ContourEngineStress,
     readers_extract_snapshots_while_runs_are_cancelled_and_the_isovalue_changes) {
  const test::stall_watchdog watchdog("the contour reader/control stress test",
                                      test::stall_limit());
  const volume img = ripples(300, 220);
  const test::box2 box = test::image_box(img);
  const std::vector<double> isovalues{0.0, 0.3, -0.2, 0.55, 0.1};
  std::mutex reclaim_mutex;
  std::multiset<std::uint64_t> reclaimed;
  std::uint64_t generations = 0;
  std::uint64_t control_ops = 0;
  struct counts_t {
    std::uint64_t snapshots = 0, segments = 0, violations = 0;
    std::string first;
  };
  std::vector<counts_t> counts(2);
  {
    contour_engine_options o;
    o.poison_retired = true;
    o.reclamation.reclaim_threshold = 2;
    o.reclamation.era_frequency = 1;
    o.on_reclaim = [&](std::uint64_t g) {
      const std::lock_guard lock(reclaim_mutex);
      reclaimed.insert(g);
    };
    contour_engine e(img, isovalues[0], o);
    const auto end = clock::now() + test::stress_duration();
    std::atomic<bool> finished{false};
    std::vector<std::thread> readers;
    for (std::size_t t = 0; t < counts.size(); ++t) {
      readers.emplace_back([&, t] {
        std::mt19937 rng(static_cast<unsigned>(300 + t));
        std::uniform_int_distribution<int> us(0, 50);
        const auto pause = [&] { std::this_thread::sleep_for(std::chrono::microseconds(us(rng))); };
        counts_t& c = counts[t];
        std::map<std::uint64_t, std::uint64_t> last_splits;  // per generation
        const auto violation = [&c](const std::string& what) {
          if (c.violations++ == 0) c.first = what;
        };
        // acquire: pairs with the release-store in test::control_until(); the flag orders nothing
        // else.
        while (!finished.load(std::memory_order_acquire)) {
          const contour_snapshot s = e.snapshot();
          ++c.snapshots;
          pause();
          if (!s.check_integrity()) {
            violation("snapshot integrity (poisoned or garbage root)");
            continue;
          }
          const std::uint64_t g = s.generation();
          if (s.split_count() < last_splits[g]) violation("a cut of one root shrank");
          last_splits[g] = s.split_count();
          const contour_set first = s.extract();
          pause();
          c.segments += first.segment_count();
          for (const polyline& p : first.polylines) {
            if (p.isovalue != s.isovalue()) violation("a polyline of another isovalue");
          }
          if (auto r = test::check_valid_contour(first, box); !r) {
            violation(std::string("invalid contour: ") + r.message());
          }
          const contour_set again = s.extract();
          if (again.vertices != first.vertices || again.polylines.size() != first.polylines.size())
            violation("a held snapshot's contour changed");
          if (!s.check_integrity()) violation("integrity lost while the snapshot was held");
        }
      });
    }
    std::mt19937 rng(11);
    generations = test::control_until(e, rng, isovalues, 0.01, end, finished, readers, control_ops);
  }
  test::expect_each_root_reclaimed_once(reclaimed, generations);
  std::uint64_t snapshots = 0;
  for (const auto& c : counts) {
    snapshots += c.snapshots;
    EXPECT_EQ(c.violations, 0U) << c.first;
  }
  EXPECT_GT(snapshots, 0U);
  std::printf(
      "contour engine stress: %llu control operations (%llu isovalue changes), %llu "
      "snapshots checked\n",
      static_cast<unsigned long long>(control_ops), static_cast<unsigned long long>(generations),
      static_cast<unsigned long long>(snapshots));
}

}  // namespace
}  // namespace progiso
