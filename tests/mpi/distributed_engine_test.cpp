// The progressive engine across ranks (scheduler/mpi, distributed_engine.hpp), run under mpiexec
// on 1, 2 and 4 ranks: every test is collective. The root's snapshots are compared with the one
// process's sequential refiner, vertex for vertex.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/ranges/range_data.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/mpi/distributed_engine.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <mpi.h>

namespace progiso {
namespace {

using snapshot_ptr = std::shared_ptr<const distributed_snapshot>;

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}
int world_size() {
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

/// The one process's cut of refine_goal::error(eps) at `iso` (eps infinite: the root surface),
/// made by the sequential refiner.
class one_process {
 public:
  explicit one_process(const volume& v) : vol_(v), hier_(v.dims()), ranges_(v, hier_) {}
  const triangle_mesh& cut(double iso, double eps) {
    auto [it, fresh] = cuts_.try_emplace({iso, eps});
    if (fresh) {
      refiner one(vol_, hier_, ranges_, iso);
      one.refine_to_error(eps);
      it->second = one.extract();
    }
    return it->second;
  }

 private:
  const volume& vol_;
  hierarchy hier_;
  range_data ranges_;
  std::map<std::pair<double, double>, triangle_mesh> cuts_;
};

/// Every distinct snapshot the root shows while `f` runs, seen by a reader thread of its own.
template <class F>
std::vector<snapshot_ptr> watched(const distributed_engine& e, const F& f) {
  std::vector<snapshot_ptr> seen{e.snapshot()};
  std::atomic<bool> done{false};
  std::thread reader([&] {
    // done_ is the only thing shared with the caller: acquire pairs with the release below.
    while (!done.load(std::memory_order_acquire)) {
      snapshot_ptr s = e.snapshot();
      if (s != seen.back()) seen.push_back(std::move(s));
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  });
  f();
  done.store(true, std::memory_order_release);  // partner: the reader's acquire load
  reader.join();
  if (snapshot_ptr s = e.snapshot(); s != seen.back()) seen.push_back(std::move(s));
  return seen;
}

distributed_engine::options on(int root, unsigned threads) {
  distributed_engine::options o;
  o.root = root;
  o.threads = threads;
  return o;
}

/// Every snapshot the engine publishes, heard through options::on_snapshot (which, unlike a
/// reader polling snapshot(), misses none however loaded the machine).
struct recorder {
  std::mutex mutex;
  std::vector<snapshot_ptr> all;
  distributed_engine::options options(int root, unsigned threads) {
    distributed_engine::options o = on(root, threads);
    o.on_snapshot = [this](const snapshot_ptr& s) {
      const std::lock_guard lock(mutex);
      all.push_back(s);
    };
    return o;
  }
};

/// Each snapshot is the one process's cut of its threshold at its isovalue; the thresholds of
/// one isovalue fall, and the isovalue changes only with isovalue_changes.
void expect_consistent(const std::vector<snapshot_ptr>& seen, one_process& ref) {
  for (std::size_t k = 0; k < seen.size(); ++k) {
    const distributed_snapshot& s = *seen[k];
    SCOPED_TRACE("snapshot " + std::to_string(k) + ": isovalue " + std::to_string(s.isovalue) +
                 ", threshold " + std::to_string(s.max_error) + ", round " +
                 std::to_string(s.round));
    const triangle_mesh& want = ref.cut(s.isovalue, s.max_error);
    const std::shared_ptr<const triangle_mesh> got = s.mesh();
    EXPECT_EQ(got, s.mesh()) << "made once";
    EXPECT_EQ(got->triangles.size(), want.triangles.size());
    EXPECT_TRUE(got->vertices == want.vertices);
    EXPECT_TRUE(got->triangles == want.triangles);
    if (k == 0) continue;
    const distributed_snapshot& p = *seen[k - 1];
    if (p.isovalue_changes == s.isovalue_changes) {
      EXPECT_EQ(p.isovalue, s.isovalue);
      EXPECT_LT(s.max_error, p.max_error);
      EXPECT_GT(s.round, p.round);
    } else {
      EXPECT_GT(s.isovalue_changes, p.isovalue_changes);
    }
  }
}

/// A field whose surface crosses every rank's planes.
volume field() { return make_marschner_lobb({41, 37, 29}); }
constexpr double iso0 = 0.5;

TEST(DistributedEngine, every_snapshot_is_the_one_process_cut_of_its_threshold) {
  const volume v = field();
  recorder heard;
  distributed_engine e(MPI_COMM_WORLD, v, iso0, heard.options(0, 2));
  if (!e.is_root()) {
    EXPECT_EQ(e.snapshot(), nullptr);
    EXPECT_THROW(e.start(refine_goal::error(0.0)), error);
    EXPECT_THROW(e.set_isovalue(0.4), error);
    return;  // the destructor waits for the root's
  }
  one_process ref(v);
  const std::vector<snapshot_ptr> seen = watched(e, [&] {
    e.start(refine_goal::full());
    e.wait();
  });
  expect_consistent(seen, ref);
  EXPECT_TRUE(std::isinf(seen.front()->max_error)) << "the first snapshot is the root surface";
  // Every published snapshot, in order: the polling reader's are among them.
  expect_consistent(heard.all, ref);
  ASSERT_GE(heard.all.size(), 3u) << "the cut refined in rounds";
  EXPECT_EQ(heard.all.front(), seen.front());
  EXPECT_EQ(heard.all.back(), seen.back());
  for (const snapshot_ptr& s : seen) {
    EXPECT_NE(std::find(heard.all.begin(), heard.all.end(), s), heard.all.end());
  }
  const distributed_snapshot& last = *seen.back();
  EXPECT_TRUE(last.mesh()->triangles == ref.cut(iso0, 0.0).triangles) << "full: the error-0 cut";
  EXPECT_GT(last.splits, 0u);
}

TEST(DistributedEngine, an_error_goal_ends_on_its_thresholds_cut) {
  const volume v = field();
  distributed_engine e(MPI_COMM_WORLD, v, iso0);
  if (!e.is_root()) return;
  one_process ref(v);
  for (const double eps : {0.2, 0.05, 0.0}) {
    e.start(refine_goal::error(eps));
    e.wait();
    const snapshot_ptr s = e.snapshot();
    EXPECT_GE(s->max_error, eps);
    EXPECT_TRUE(s->mesh()->triangles == ref.cut(iso0, eps).triangles) << "error " << eps;
    EXPECT_TRUE(s->mesh()->vertices == ref.cut(iso0, eps).vertices) << "error " << eps;
  }
}

TEST(DistributedEngine, an_isovalue_change_reaches_every_rank_and_no_snapshot_mixes_two) {
  const volume v = field();
  distributed_engine e(MPI_COMM_WORLD, v, iso0, on(0, 1));
  if (!e.is_root()) return;
  one_process ref(v);
  snapshot_ptr middle;
  const std::vector<snapshot_ptr> seen = watched(e, [&] {
    e.start(refine_goal::full());
    // Mid-run: once the root shows a second round.
    while (e.snapshot()->round < 2 && e.snapshot()->max_error > 0.0) {
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
    e.set_isovalue(0.3);
    e.wait();
    middle = e.snapshot();
    // After the goal was reached: the same goal again on the new isovalue.
    e.set_isovalue(0.7);
    e.wait();
  });
  expect_consistent(seen, ref);
  const distributed_snapshot& last = *seen.back();
  EXPECT_EQ(last.isovalue, 0.7);
  EXPECT_EQ(last.isovalue_changes, 2u);
  EXPECT_TRUE(last.mesh()->triangles == ref.cut(0.7, 0.0).triangles);
  // The change mid-run was refined to the goal before the next came.
  EXPECT_EQ(middle->isovalue, 0.3);
  EXPECT_EQ(middle->isovalue_changes, 1u);
  EXPECT_TRUE(middle->mesh()->triangles == ref.cut(0.3, 0.0).triangles);
}

TEST(DistributedEngine, a_deadline_ends_on_a_round_every_rank_finished) {
  const volume v = make_gaussian_blobs({48, 40, 52}, 9, 3);
  distributed_engine e(MPI_COMM_WORLD, v, 0.4);
  if (!e.is_root()) return;
  one_process ref(v);
  for (const int ms : {0, 5, 60000}) {
    const std::vector<snapshot_ptr> seen = watched(e, [&] {
      e.start(refine_goal::within(std::chrono::milliseconds(ms)));
      e.wait();
    });
    SCOPED_TRACE(std::to_string(ms) + " ms");
    expect_consistent(seen, ref);
    if (ms == 60000) {
      EXPECT_TRUE(seen.back()->mesh()->triangles == ref.cut(0.4, 0.0).triangles);
    }
    e.cancel();  // no goal: the isovalue set again gives the root surface for the next budget
    e.set_isovalue(0.4);
    e.wait();
  }
}

TEST(DistributedEngine, a_triangle_budget_keeps_the_last_round_within_it) {
  const volume v = field();
  one_process ref(v);
  // The rounds of a full run (deterministic: each threshold is half the largest error waiting),
  // and a budget of the triangles of the last round seen before the finest.
  std::vector<snapshot_ptr> rounds;
  {
    recorder heard;
    distributed_engine e(MPI_COMM_WORLD, v, iso0, heard.options(0, 0));
    if (e.is_root()) {
      e.start(refine_goal::full());
      e.wait();
      rounds = heard.all;
    }
  }
  if (world_rank() != 0) {
    distributed_engine e(MPI_COMM_WORLD, v, iso0);
    return;
  }
  ASSERT_GE(rounds.size(), 3u);
  const distributed_snapshot& below = *rounds[rounds.size() - 2];
  const std::size_t budget = below.mesh()->triangles.size();
  ASSERT_LT(budget, rounds.back()->mesh()->triangles.size());
  distributed_engine e(MPI_COMM_WORLD, v, iso0);
  e.start(refine_goal::triangles(budget));
  e.wait();
  const snapshot_ptr s = e.snapshot();
  EXPECT_LE(s->mesh()->triangles.size(), budget);
  EXPECT_EQ(s->max_error, below.max_error) << "the last round within the budget";
  EXPECT_TRUE(s->mesh()->triangles == ref.cut(iso0, s->max_error).triangles);
  // A budget of the finest cut reaches it, going on from where the smaller one stopped (the
  // round past the smaller budget, kept but not shown, is shown now).
  e.start(refine_goal::triangles(rounds.back()->mesh()->triangles.size()));
  e.wait();
  EXPECT_TRUE(e.snapshot()->mesh()->triangles == ref.cut(iso0, 0.0).triangles);
}

TEST(DistributedEngine, cancel_stops_every_rank_and_a_new_start_goes_on) {
  const volume v = make_gaussian_blobs({64, 60, 70}, 12, 5);
  distributed_engine e(MPI_COMM_WORLD, v, 0.4);
  if (!e.is_root()) return;
  one_process ref(v);
  const std::vector<snapshot_ptr> seen = watched(e, [&] {
    e.start(refine_goal::full());
    e.cancel();
    e.wait();
    e.start(refine_goal::full());
    e.wait();
  });
  expect_consistent(seen, ref);
  EXPECT_TRUE(seen.back()->mesh()->triangles == ref.cut(0.4, 0.0).triangles);
}

TEST(DistributedEngine, destruction_during_a_run_ends_every_rank) {
  const volume v = make_gaussian_blobs({64, 60, 70}, 12, 5);
  for (int k = 0; k < 3; ++k) {
    distributed_engine e(MPI_COMM_WORLD, v, 0.4);
    if (e.is_root()) {
      e.start(refine_goal::full());
      std::this_thread::sleep_for(std::chrono::milliseconds(5 * k));
    }
  }  // every rank's destructor returns: no rank waits for a round the others left
}

TEST(DistributedEngine, any_rank_can_be_the_root) {
  const volume v = field();
  const int root = world_size() - 1;
  distributed_engine e(MPI_COMM_WORLD, v, iso0, on(root, 1));
  EXPECT_EQ(e.is_root(), world_rank() == root);
  if (!e.is_root()) {
    EXPECT_EQ(e.snapshot(), nullptr);
    e.wait();  // until the root's engine ends
    return;
  }
  one_process ref(v);
  e.start(refine_goal::error(0.05));
  e.wait();
  EXPECT_TRUE(e.snapshot()->mesh()->triangles == ref.cut(iso0, 0.05).triangles);
}

TEST(DistributedEngine, a_snapshot_outlives_its_engine_and_is_meshed_once_for_every_reader) {
  const volume v = field();
  snapshot_ptr s;
  {
    distributed_engine e(MPI_COMM_WORLD, v, iso0);
    if (e.is_root()) {
      e.start(refine_goal::error(0.02));
      e.wait();
      s = e.snapshot();
    }
  }
  if (!s) return;
  one_process ref(v);
  std::vector<std::shared_ptr<const triangle_mesh>> got(4);
  std::vector<std::thread> readers;
  for (std::size_t k = 0; k < got.size(); ++k) {
    readers.emplace_back([&got, &s, k] { got[k] = s->mesh(); });
  }
  for (std::thread& t : readers) t.join();
  for (const auto& m : got) EXPECT_EQ(m, got[0]);
  EXPECT_TRUE(got[0]->triangles == ref.cut(iso0, 0.02).triangles);
  EXPECT_TRUE(got[0]->vertices == ref.cut(iso0, 0.02).vertices);
}

TEST(DistributedEngine, refusals) {
  const volume v = field();
  EXPECT_THROW(distributed_engine(MPI_COMM_WORLD, v, iso0, on(world_size(), 1)), error);
  distributed_engine e(MPI_COMM_WORLD, v, iso0);
  if (!e.is_root()) return;
  EXPECT_THROW(e.set_isovalue(std::numeric_limits<double>::quiet_NaN()), error);
  EXPECT_THROW(e.start(refine_goal::error(-1.0)), error);
  EXPECT_THROW(e.start(refine_goal::error(0.1).focused({0, 0, 0}, {4, 4, 4})), error);
}

// Run alone by ctest (DistributedEngine.a_rank_killed_mid_run_ends_the_job), with
// PROGISO_MPI_KILL_RANK naming the rank that dies: the job must end with mpiexec's report of the
// death, not hang in the others' next collective.
TEST(DistributedEngineFault, a_rank_killed_mid_run_ends_the_job) {
  const char* kill = std::getenv("PROGISO_MPI_KILL_RANK");
  if (kill == nullptr) GTEST_SKIP() << "PROGISO_MPI_KILL_RANK is not set";
  const volume v = make_gaussian_blobs({64, 60, 70}, 12, 5);
  distributed_engine e(MPI_COMM_WORLD, v, 0.4, on(0, 1));
  if (world_rank() == std::atoi(kill)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::raise(SIGKILL);
  }
  if (e.is_root()) {
    for (int k = 0; k < 1000; ++k) {  // runs until the job is ended
      e.start(refine_goal::full());
      e.wait();
      e.set_isovalue(k % 2 == 0 ? 0.3 : 0.4);
    }
  } else {
    e.wait();  // until the root's engine ends, which it must not
  }
  ADD_FAILURE() << "the job went on after a rank died";
}

}  // namespace
}  // namespace progiso
