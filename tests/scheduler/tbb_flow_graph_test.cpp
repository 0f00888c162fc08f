// The oneTBB flow-graph handoffs the scheduler is built on: results computed in parallel on
// worker threads, handed as heap objects to a serial node, with a limiter bounding the items in
// flight. Under the tsan preset this runs against the instrumented oneTBB of
// scripts/build-tsan-tbb.sh; against Debian's uninstrumented libtbb, TSan cannot see the
// synchronisation inside TBB and reports every such handoff as a race (docs/ARCHITECTURE.md,
// "Tests").
#include <progiso/scheduler/tbb_environment.hpp>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/flow_graph.h>
#include <tbb/info.h>

namespace {

namespace flow = tbb::flow;

// A result made on one thread and consumed on another: both the object and its vector are heap
// blocks written by the producer and read, then freed, by the consumer.
struct item_result {
  int index = 0;
  std::vector<std::int64_t> terms;

  [[nodiscard]] std::int64_t value() const {
    return std::accumulate(terms.begin(), terms.end(), std::int64_t{0});
  }
};

// item i carries (i mod 7) + 1 terms, each equal to i.
std::int64_t expected_value(int i) { return std::int64_t{i} * (i % 7 + 1); }

TEST(TbbEnvironment, default_concurrency_is_tbbs_and_positive) {
  EXPECT_GE(progiso::scheduler::default_concurrency(), 1);
  EXPECT_EQ(progiso::scheduler::default_concurrency(), tbb::info::default_concurrency());
}

TEST(TbbFlowGraph, heap_results_reach_serial_node_once_with_exact_sum) {
  constexpr int item_count = 4000;
  constexpr std::size_t max_in_flight = 16;

  flow::graph graph;

  // The input node's body runs serially, so `next` needs no synchronisation of its own.
  int next = 0;
  flow::input_node<int> source(graph, [&](tbb::flow_control& control) {
    if (next == item_count) {
      control.stop();
      return 0;
    }
    return next++;
  });

  flow::limiter_node<int> limiter(graph, max_in_flight);

  // Items between the limiter and the serial node's return. relaxed is enough: one counter, and
  // TBB orders a consumer's decrement before the limiter admits the item that replaces it.
  std::atomic<int> in_flight{0};
  std::atomic<int> most_in_flight{0};

  flow::function_node<int, item_result*> compute(graph, flow::unlimited, [&](int i) {
    const int now = in_flight.fetch_add(1, std::memory_order_relaxed) + 1;
    int seen = most_in_flight.load(std::memory_order_relaxed);
    while (now > seen &&
           !most_in_flight.compare_exchange_weak(seen, now, std::memory_order_relaxed)) {
    }
    auto result = std::make_unique<item_result>();
    result->index = i;
    result->terms.assign(static_cast<std::size_t>(i % 7 + 1), std::int64_t{i});
    return result.release();
  });

  // Touched only by the serial node's body: the results of every worker thread meet here.
  std::vector<int> times_seen(item_count, 0);
  std::int64_t sum = 0;
  flow::function_node<item_result*, flow::continue_msg> consume(
      graph, flow::serial, [&](item_result* raw) {
        const std::unique_ptr<item_result> result(raw);
        ++times_seen.at(static_cast<std::size_t>(result->index));
        sum += result->value();
        in_flight.fetch_sub(1, std::memory_order_relaxed);
        return flow::continue_msg{};
      });

  flow::make_edge(source, limiter);
  flow::make_edge(limiter, compute);
  flow::make_edge(compute, consume);
  flow::make_edge(consume, limiter.decrementer());
  source.activate();
  graph.wait_for_all();

  std::int64_t expected_sum = 0;
  for (int i = 0; i < item_count; ++i) expected_sum += expected_value(i);
  EXPECT_EQ(sum, expected_sum);
  EXPECT_TRUE(std::all_of(times_seen.begin(), times_seen.end(), [](int n) { return n == 1; }));
  EXPECT_EQ(in_flight.load(), 0);
  EXPECT_GE(most_in_flight.load(), 1);
  EXPECT_LE(most_in_flight.load(), static_cast<int>(max_in_flight));
}

}  // namespace
