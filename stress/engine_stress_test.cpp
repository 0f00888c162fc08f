// Randomized concurrent run of the engine. Reader threads take and walk
// snapshots continuously and sleep 0–50 µs at random points inside their guards, while a control
// thread changes the isovalue at random moments, starts, cancels and restarts runs, and runs
// deadlines; the engine refines with all workers. Every snapshot is checked:
//   - integrity: its root is alive and its records well-formed (retired roots are poisoned
//     before they are freed, so a snapshot reading a reclaimed root fails here, or under ASan);
//   - a valid surface: edge-manifold, consistently oriented, open only on the data box, no
//     degenerate triangles, no self-intersections (CGAL exact predicates);
//   - exactly one isovalue and the right cut: equal to the sequential refiner's surface for the
//     snapshot's split set at the snapshot's isovalue (a mix of isovalues would move vertices);
//   - cuts of one root only grow.
// Beside them, a render thread follows the engine through a frame_feed (its producer takes
// snapshots and makes changes while all this goes on) and, once the runs are over, must hold
// the last cut triangle for triangle; and a stream writer exports every root of records it sees
// (hierarchy_exporter), each stream decoding to the last cut it wrote.
// At shutdown every published root has been reclaimed exactly once.
// Runs PROGISO_STRESS_SECONDS (default 1).
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/scheduler/engine.hpp>
#include <progiso/scheduler/frame_feed.hpp>
#include <progiso/scheduler/hierarchy_export.hpp>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include <gtest/gtest.h>

#include "support/engine_stress.hpp"
#include "support/mesh_checks.hpp"
#include "support/reference_mt.hpp"
#include "support/render_checks.hpp"
#include "support/stress_support.hpp"

namespace progiso {
namespace {

using namespace std::chrono_literals;
using clock = std::chrono::steady_clock;

void random_pause(std::mt19937& rng) {
  std::uniform_int_distribution<int> us(0, 50);
  std::this_thread::sleep_for(std::chrono::microseconds(us(rng)));
}

struct reader_counts {
  std::uint64_t snapshots = 0;
  std::uint64_t triangles_walked = 0;
  std::uint64_t violations = 0;
  std::string first_violation;
};

TEST(EngineStress, readers_walk_snapshots_while_runs_are_cancelled_and_the_isovalue_changes) {
  const test::stall_watchdog watchdog("the reader/control stress test", test::stall_limit());
  const volume v = make_gaussian_blobs({41, 37, 39}, 7, 19u);
  const auto box = test::data_box(v);
  const std::vector<double> isovalues{0.35, 0.4, 0.5, 0.6, 0.45};
  // Runs by priority on both schedules (engine_options::schedule), half the time each.
  for (const refinement_schedule schedule :
       {refinement_schedule::tasks, refinement_schedule::flow_graph}) {
    SCOPED_TRACE(static_cast<int>(schedule));
    std::mutex reclaim_mutex;
    std::multiset<std::uint64_t> reclaimed;
    std::uint64_t generations = 0;
    std::uint64_t roots = 0;
    std::uint64_t control_ops = 0;
    std::vector<reader_counts> counts(4);  // two readers, the render thread, the stream writer
    {
      engine_options o;
      o.poison_retired = true;
      o.reclamation.reclaim_threshold = 2;  // reclaim as early as possible: more chances to catch
      o.reclamation.era_frequency = 1;      // a use after free
      o.batch = 8;
      o.schedule = schedule;
      o.on_reclaim = [&](std::uint64_t g) {
        const std::lock_guard lock(reclaim_mutex);
        reclaimed.insert(g);
      };
      engine e(v, isovalues[0], o);
      const auto end = clock::now() + test::stress_duration() / 2;
      std::atomic<bool> finished{false};

      std::vector<std::thread> readers;
      frame_feed_options fo;
      fo.poll = 200us;
      fo.depth = 2;
      frame_feed feed(e, fo);  // destroyed before the engine
      readers.emplace_back([&] {
        // The render thread: updates at random moments; once the runs are over (finished is
        // set after the last cancel), it must catch up with the last cut.
        std::mt19937 rng(300);
        reader_counts& c = counts[2];
        // acquire: pairs with the release-store in test::control_until().
        while (!finished.load(std::memory_order_acquire)) {
          c.snapshots += feed.update();
          random_pause(rng);
        }
        const cut_mark last = e.snapshot().mark();
        const auto give_up = clock::now() + 30s;
        while (!(feed.mark().root == last.root && feed.mark().records == last.records) &&
               clock::now() < give_up) {
          c.snapshots += feed.update();
          std::this_thread::sleep_for(200us);
        }
        render_buffers b;
        e.snapshot().mesh_into(b);
        c.triangles_walked += b.triangle_count();
        if (test::slot_triangles(feed.surface()) != test::buffer_triangles(b)) {
          ++c.violations;
          c.first_violation = "the render thread's pool differs from the last cut";
        }
      });
      readers.emplace_back([&] {
        // The stream writer: every root of records it sees, exported; each finished stream
        // must decode, and its full cut must be the last snapshot it wrote.
        std::mt19937 rng(400);
        reader_counts& c = counts[3];
        std::vector<std::byte> bytes;
        std::optional<hierarchy_exporter> out;
        std::uint64_t root = 0;
        triangle_mesh last_written;
        const auto check = [&] {
          if (!out) return;
          out->finish();
          try {
            const hierarchy_stream h = hierarchy_stream::decode(bytes);
            if (auto r = test::same_surface(h.mesh(h.all()), last_written); !r) {
              ++c.violations;
              c.first_violation = std::string("stream cut: ") + r.message();
            }
          } catch (const std::exception& x) {
            ++c.violations;
            c.first_violation = std::string("stream refused: ") + x.what();
          }
          out.reset();
          bytes.clear();
        };
        // acquire: pairs with the release-store in test::control_until().
        while (!finished.load(std::memory_order_acquire)) {
          const surface_snapshot s = e.snapshot();
          if (s.uniform_stride() > 0) continue;
          if (s.mark().root != root) {
            check();
            root = s.mark().root;
            out.emplace(e, [&bytes](std::span<const std::byte> b) {
              bytes.insert(bytes.end(), b.begin(), b.end());
            });
          }
          out->write(s);
          last_written = s.mesh();
          ++c.snapshots;
          random_pause(rng);
        }
        check();
      });
      for (std::size_t t = 0; t < 2; ++t) {
        readers.emplace_back([&, t] {
          std::mt19937 rng(static_cast<unsigned>(100 + t));
          reader_counts& c = counts[t];
          std::map<std::uint64_t, std::uint64_t> last_splits;  // per root (cut_mark::root)
          const auto violation = [&c](const std::string& what) {
            if (c.violations++ == 0) c.first_violation = what;
          };
          // acquire: pairs with the release-store in test::control_until(); the flag orders nothing
          // else.
          while (!finished.load(std::memory_order_acquire)) {
            const surface_snapshot s = e.snapshot();
            ++c.snapshots;
            random_pause(rng);
            if (!s.check_integrity()) {
              violation("snapshot integrity (poisoned or garbage root)");
              continue;
            }
            const std::uint64_t g = s.mark().root;
            if (s.split_count() < last_splits[g]) violation("a cut of one root shrank");
            last_splits[g] = s.split_count();
            const triangle_mesh m = s.mesh();
            random_pause(rng);
            c.triangles_walked += m.triangles.size();
            if (auto r = test::check_valid_cut(m, box[0], box[1]); !r) {
              violation(std::string("invalid cut: ") + r.message());
            }
            refiner replay(e.field(), e.hierarchy_of(), e.ranges(), s.isovalue(),
                           refine_order::breadth_first);
            if (s.uniform_stride() > 0) {
              // A uniform cut (made by passes): its split set is every diamond of scale ≥ the
              // stride, which is_split() tells.
              replay.refine_set([&](std::uint64_t d) { return s.is_split(d); });
            } else {
              std::unordered_set<std::uint64_t> split;
              s.for_each_split([&](std::uint64_t d) { split.insert(d); });
              random_pause(rng);
              replay.refine_set([&](std::uint64_t d) { return split.count(d) != 0; });
              if (replay.statistics().splits != split.size())
                violation("split set not parent-closed");
            }
            if (auto r = test::same_surface(m, replay.extract()); !r) {
              violation(std::string("differs from the sequential replay: ") + r.message());
            }
            if (!s.check_integrity()) violation("integrity lost while the snapshot was held");
          }
        });
      }

      std::mt19937 rng(7);
      generations =
          test::control_until(e, rng, isovalues, 0.02, end, finished, readers, control_ops);
      roots = e.statistics().roots;
    }
    test::expect_each_root_reclaimed_once(reclaimed, generations, roots);
    std::uint64_t snapshots = 0;
    std::uint64_t violations = 0;
    std::uint64_t triangles = 0;
    for (const auto& c : counts) {
      snapshots += c.snapshots;
      violations += c.violations;
      triangles += c.triangles_walked;
      EXPECT_EQ(c.violations, 0u) << c.first_violation;
    }
    EXPECT_GT(snapshots, 0u);
    std::printf(
        "engine stress (%s): %llu control operations (%llu isovalue changes), %llu snapshots "
        "checked, "
        "%llu triangles walked, %llu violations\n",
        schedule == refinement_schedule::tasks ? "tasks" : "flow graph",
        static_cast<unsigned long long>(control_ops), static_cast<unsigned long long>(generations),
        static_cast<unsigned long long>(snapshots), static_cast<unsigned long long>(triangles),
        static_cast<unsigned long long>(violations));
  }
}

// The range data is built once, on first use, by whichever thread asks first: readers calling
// engine::ranges() race a run's driver for it on fresh engines with one and two threads (half of
// the races with deadline runs first, which build it in pieces between slices of refinement).
// Every race ends (no thread waits for the build while it holds an arena slot the build needs),
// every caller sees the same data, equal to a sequential build, and the run reaches its goal,
// the full surface.
TEST(EngineStress, the_first_range_build_raced_by_readers_and_a_run_ends_with_one_build) {
  const test::stall_watchdog watchdog("the range build race", test::stall_limit());
  const volume v = make_gaussian_blobs({57, 49, 53}, 9, 5u);
  const hierarchy h(v.dims());
  const range_data sequential(v, h);
  const auto end = clock::now() + test::stress_duration();
  std::uint64_t races = 0;
  std::uint64_t mismatches = 0;
  for (unsigned threads = 1; clock::now() < end || races < 4; threads = 3 - threads, ++races) {
    engine_options o;
    o.threads = threads;
    engine e(v, 0.4, o);
    test::phase_signal go;
    std::vector<const range_data*> seen(3, nullptr);
    std::vector<std::thread> readers;
    for (std::size_t t = 0; t < seen.size(); ++t) {
      readers.emplace_back([&, t] {
        go.wait_for(1);
        seen[t] = &e.ranges();
      });
    }
    go.advance_to(1);
    // Every other race starts with deadline runs, which build the data piece by piece between
    // slices of unculled refinement, while the readers' ranges() build what is left.
    if (races % 2 == 1) {
      for (int k = 0; k < 3; ++k) (void)e.refine_for(std::chrono::milliseconds(1 + k));
    }
    const bool reached = e.refine_full();
    for (auto& r : readers) r.join();
    for (const range_data* r : seen) {
      if (r != &e.ranges()) ++mismatches;
    }
    EXPECT_EQ(e.ranges().byte_size(), sequential.byte_size());
    EXPECT_EQ(e.ranges().get(h.point(0)).error, sequential.get(h.point(0)).error);
    EXPECT_TRUE(reached);
    EXPECT_TRUE(e.done());
    if (races < 2) {
      EXPECT_TRUE(test::same_surface(e.snapshot().mesh(),
                                     test::reference_marching_tetrahedra(v, 0.4).mesh));
    }
  }
  EXPECT_EQ(mismatches, 0u) << "every caller sees the one build";
  std::printf("range build races: %llu\n", static_cast<unsigned long long>(races));
}

}  // namespace
}  // namespace progiso
