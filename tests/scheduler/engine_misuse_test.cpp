// The engine as an embedder might misuse it: a temporary volume, control calls from
// inside the progress callback, a callback that throws, budgets beyond the clock's range.
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/scheduler/engine.hpp>

#include <atomic>
#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "support/mesh_checks.hpp"

namespace progiso {
namespace {

engine_options progress_every(std::uint64_t n, std::function<void(const engine_progress&)> f) {
  engine_options o;
  o.uniform_cuts = false;  // these tests are of split records (uniform_cuts_test.cpp: the passes)
  o.threads = 2;
  o.progress_interval = n;
  o.progress = std::move(f);
  return o;
}

TEST(EngineMisuse, a_temporary_volume_is_owned_by_the_engine) {
  // Compiled before the owning overload, this kept a reference to a destroyed volume.
  engine e(make_marschner_lobb({33, 33, 33}), 0.5);
  EXPECT_TRUE(e.refine_full());
  const triangle_mesh m = e.snapshot().mesh();
  EXPECT_GT(m.triangles.size(), 1000u);
  EXPECT_TRUE(test::edge_manifold(m));
  EXPECT_EQ(e.field().dims(), (index3{33, 33, 33}));

  auto shared = std::make_shared<const volume>(make_marschner_lobb({17, 17, 17}));
  engine f(shared, 0.5);
  shared.reset();  // the engine keeps it alive
  EXPECT_TRUE(f.refine_full());
  EXPECT_GT(f.snapshot().mesh().triangles.size(), 100u);
  EXPECT_THROW(engine(std::shared_ptr<const volume>(), 0.5), error);
}

TEST(EngineMisuse, cancel_from_the_progress_callback_requests_a_stop) {
  const volume v = make_marschner_lobb({65, 65, 65});
  engine* self = nullptr;
  std::atomic<int> calls{0};
  engine e(v, 0.5, progress_every(64, [&](const engine_progress&) {
             ++calls;
             self->cancel();  // aborted the process ("terminate called…") before
           }));
  self = &e;
  EXPECT_FALSE(e.refine_full()) << "the run must end as cancelled";
  EXPECT_GE(calls.load(), 1);
  EXPECT_FALSE(e.done());
  const engine_statistics s = e.statistics();
  EXPECT_GE(s.cancelled_runs, 1u);
  // Stopped within about one batch per worker after the first callback, far from the end.
  EXPECT_LT(s.refine.splits, 64u * 40u);
  // The engine stays usable: the published cut is valid and a later run finishes.
  EXPECT_TRUE(test::edge_manifold(e.snapshot().mesh()));
  self = nullptr;
  engine g(v, 0.5);
  EXPECT_TRUE(g.refine_full());
}

TEST(EngineMisuse, control_calls_that_would_wait_for_their_own_run_throw_from_the_callback) {
  const volume v = make_marschner_lobb({33, 33, 33});
  engine* self = nullptr;
  std::string seen;
  engine e(v, 0.5, progress_every(16, [&](const engine_progress&) {
             try {
               self->set_isovalue(0.25);
             } catch (const error& x) {
               seen = x.what();
               throw;  // stops the run; rethrown by refine() on the control thread
             }
           }));
  self = &e;
  EXPECT_THROW((void)e.refine_full(), error);
  EXPECT_NE(seen.find("progress callback"), std::string::npos) << seen;
  EXPECT_EQ(e.isovalue(), 0.5);
  // The error was delivered once; the next run, without a failing callback, works.
  self = nullptr;
}

TEST(EngineMisuse, an_exception_from_the_callback_stops_the_run_and_reaches_the_caller) {
  const volume v = make_marschner_lobb({33, 33, 33});
  std::atomic<int> calls{0};
  engine e(v, 0.5, progress_every(16, [&](const engine_progress&) {
             ++calls;
             throw std::runtime_error("viewer closed");
           }));
  try {
    e.refine_full();
    ADD_FAILURE() << "expected the callback's exception";
  } catch (const std::runtime_error& x) {
    EXPECT_EQ(std::string(x.what()), "viewer closed");
  }
  EXPECT_EQ(calls.load(), 1) << "the callback is not called again once it threw";
  e.start(refine_goal::full());
  EXPECT_THROW(e.wait(), std::runtime_error);  // each run reports its own callback error
}

TEST(EngineMisuse, a_budget_beyond_the_clock_range_refines_fully) {
  const volume v = make_marschner_lobb({17, 17, 17});
  engine e(v, 0.5);
  EXPECT_TRUE(e.refine_for(std::chrono::steady_clock::duration::max()));
  EXPECT_TRUE(e.done());
  extract_options o;
  o.goal = refine_goal::within(std::chrono::duration<double>(9.3e9));  // 295 years
  const extract_result timed = extract_isosurface_parallel(v, 0.5, o, 2);
  o.goal = refine_goal::full();
  const extract_result full = extract_isosurface_parallel(v, 0.5, o, 2);
  EXPECT_EQ(timed.mesh.triangles.size(), full.mesh.triangles.size());
}

}  // namespace
}  // namespace progiso
