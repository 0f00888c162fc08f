// The ready queue's largest-error-first order: bands of errors at most error_bucket_widest wide,
// taken largest first, last in first out inside a band; an aimed target splits a band exactly.
#include <progiso/core/refine/detail/ready_queue.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace progiso::detail {
namespace {

struct item {
  double error;
  int depth;
  std::uint64_t index;
};

std::vector<item> drain(ready_queue<item>& q) {
  std::vector<item> out;
  while (!q.empty()) {
    out.push_back(q.top());
    q.pop();
  }
  return out;
}

TEST(ErrorBucket, is_monotone_with_bands_of_the_declared_widths) {
  EXPECT_EQ(error_bucket(0.0), 0u);
  EXPECT_EQ(error_bucket(-1.0), 0u);
  EXPECT_GT(error_bucket(std::numeric_limits<double>::denorm_min()), 0u);
  EXPECT_GT(error_bucket(std::numeric_limits<double>::quiet_NaN()),
            error_bucket(std::numeric_limits<double>::infinity()));
  EXPECT_GT(error_bucket(std::numeric_limits<double>::infinity()),
            error_bucket(std::numeric_limits<double>::max()));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> exponent(-40.0, 40.0);
  for (int k = 0; k < 10000; ++k) {
    const double a = std::pow(2.0, exponent(rng));
    const double b = std::pow(2.0, exponent(rng));
    if (a < b) {
      ASSERT_LE(error_bucket(a), error_bucket(b)) << a << " " << b;
    }
    const auto [lo, hi] = error_bucket_bounds(error_bucket(a));
    ASSERT_LE(lo, a);
    ASSERT_LT(a, hi);
    ASSERT_LE(hi / lo, error_bucket_widest + 1e-12);
    ASSERT_GE(hi / lo, error_bucket_narrowest - 1e-12);
    ASSERT_EQ(error_bucket(lo), error_bucket(a));
    ASSERT_EQ(error_bucket(hi), error_bucket(a) + 1);
  }
}

TEST(ReadyQueue, takes_bands_largest_first_and_each_band_last_in_first_out) {
  ready_queue<item> q;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> exponent(-20.0, 3.0);
  std::vector<item> pushed;
  for (std::uint64_t i = 0; i < 5000; ++i) {
    pushed.push_back({std::pow(2.0, exponent(rng)), 0, i});
    q.push(pushed.back());
  }
  ASSERT_EQ(q.size(), pushed.size());
  const std::vector<item> out = drain(q);
  ASSERT_EQ(out.size(), pushed.size());
  for (std::size_t k = 1; k < out.size(); ++k) {
    const std::uint32_t a = error_bucket(out[k - 1].error);
    const std::uint32_t b = error_bucket(out[k].error);
    ASSERT_GE(a, b) << "a smaller band before a larger one";
    if (a == b) {
      ASSERT_GT(out[k - 1].index, out[k].index) << "not last in first out in a band";
    }
  }
}

TEST(ReadyQueue, interleaved_pushes_never_take_a_smaller_band_before_a_queued_larger_one) {
  // As in a refinement: every pop may push children of no larger error.
  ready_queue<item> q;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> shrink(0.3, 1.0);
  for (std::uint64_t i = 0; i < 8; ++i) q.push({1.0 + static_cast<double>(i), 0, i});
  std::uint64_t next = 8;
  std::uint32_t last = std::numeric_limits<std::uint32_t>::max();
  std::size_t taken = 0;
  while (!q.empty() && taken < 20000) {
    const item t = q.top();
    const std::uint32_t b = error_bucket(t.error);
    ASSERT_LE(b, last) << "children pushed later may not outrank what was taken before";
    last = b;
    q.pop();
    ++taken;
    if (next < 15000) {
      for (int c = 0; c < 2; ++c) q.push({t.error * shrink(rng), t.depth + 1, next++});
    }
  }
  EXPECT_TRUE(q.empty());
}

TEST(ReadyQueue, an_aimed_target_takes_every_item_above_it_before_any_other) {
  const auto [lo, hi] = error_bucket_bounds(error_bucket(0.1));
  const double target = 0.5 * (lo + hi);
  ready_queue<item> q;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> in_band(lo, hi);
  std::size_t above = 0;
  for (std::uint64_t i = 0; i < 2000; ++i) {
    const double e = in_band(rng);
    above += e > target ? 1 : 0;
    q.push({e, 0, i});
  }
  ASSERT_GT(above, 0u);
  ASSERT_LT(above, 2000u);
  q.aim_at(target);           // re-ranks what is queued
  q.push({target, 0, 9000});  // not above
  q.push({std::nextafter(target, 1.0), 0, 9001});
  ++above;
  std::size_t taken = 0;
  while (!q.empty() && q.top().error > target) {
    q.pop();
    ++taken;
  }
  EXPECT_EQ(taken, above);
  const std::vector<item> rest = drain(q);
  for (const item& it : rest) EXPECT_LE(it.error, target);
  EXPECT_EQ(rest.size(), 2001 - above + 1);
}

TEST(ReadyQueue, first_in_first_out_keeps_order_across_interleaved_pushes_pops_and_peeks) {
  // Far more items than one block of the queue's storage, with pops in between, so that the
  // front advances through blocks while the back grows.
  ready_queue<item> q(queue_discipline::fifo);
  std::uint64_t next_in = 0;
  std::uint64_t next_out = 0;
  for (int round = 0; round < 200; ++round) {
    for (int k = 0; k < 150; ++k, ++next_in) q.push({1.0, 0, next_in});
    for (int k = 0; k < 100; ++k, ++next_out) {
      ASSERT_EQ(q.top().index, next_out);
      const item* ahead = q.peek(7);
      ASSERT_NE(ahead, nullptr);
      EXPECT_EQ(ahead->index, next_out + 7);
      q.pop();
    }
    ASSERT_EQ(q.size(), next_in - next_out);
  }
  EXPECT_EQ(q.peek(q.size()), nullptr);
  while (!q.empty()) {
    ASSERT_EQ(q.top().index, next_out++);
    q.pop();
  }
  EXPECT_EQ(next_out, next_in);
}

TEST(ReadyQueue, cold_items_are_the_top_bands_own_from_before_it_was_the_top_in_the_order_named) {
  // A refinement's pattern: pops, children pushed into the band being taken (hot), into lower
  // bands (cold once their band is the top), now and then above it. Indices count pushes, so an
  // item of the top band is cold exactly when it was pushed before the band became the top
  // (a band made the top by a push holds only hot items).
  ready_queue<item> q;
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> exponent(-12.0, 0.0);
  std::uint64_t pushed = 0;
  std::uint64_t became_top = 0;  // pushes before the present top band became the top
  std::uint64_t top_rank = 0;
  std::vector<std::uint64_t> named;  // cold items named ahead, in the order they come
  const auto push = [&](double e) {
    const bool was_empty = q.empty();
    q.push({e, 0, pushed++});
    if (was_empty || q.top_rank() != top_rank) {  // a new top band, made by this push
      top_rank = q.top_rank();
      became_top = pushed - 1;
      named.clear();
    }
  };
  for (int k = 0; k < 400; ++k) push(std::pow(2.0, exponent(rng)));
  std::size_t cold_taken = 0;
  std::size_t named_checked = 0;
  for (int step = 0; step < 20000 && !q.empty(); ++step) {
    const item top = q.top();
    ASSERT_EQ(q.top_is_cold(), top.index < became_top) << "step " << step;
    if (q.top_is_cold()) {
      ++cold_taken;
      ASSERT_NE(q.cold_ahead(0), nullptr);
      ASSERT_EQ(q.cold_ahead(0)->index, top.index);
      if (!named.empty()) {
        ASSERT_EQ(named.front(), top.index) << "not the cold item named ahead";
        ++named_checked;
      }
      named.clear();
      for (std::size_t a = 1; a <= 3; ++a) {
        if (const item* next = q.cold_ahead(a)) named.push_back(next->index);
      }
    }
    q.pop();
    if (!q.empty() && q.top_rank() != top_rank) {  // the band ran out: the next is the top
      top_rank = q.top_rank();
      became_top = pushed;
      named.clear();
    }
    // Children: mostly into the band just taken, some below it, a few above.
    const int children = static_cast<int>(unit(rng) * 4.0);
    for (int c = 0; c < children; ++c) {
      const double u = unit(rng);
      push(u < 0.6    ? top.error * (1.0 - 0.01 * unit(rng))
           : u < 0.95 ? top.error / 8.0
                      : top.error * 4.0);
    }
  }
  EXPECT_GT(cold_taken, 1000u);
  EXPECT_GT(named_checked, 500u);
}

TEST(ReadyQueue, a_band_taken_and_pushed_whole_leaves_the_queue_that_item_by_item_would) {
  // The engine's band tasks take the top band in one piece and give back the children ranked
  // below it one rank at a time. Against a queue driven item by item with the same items:
  // the band (in the order pop() gives it), the sizes, the cold items and the final order.
  for (const double target : {-std::numeric_limits<double>::infinity(), 0.01}) {
    ready_queue<item> one;   // item by item
    ready_queue<item> bulk;  // take_top_band / push_band
    one.aim_at(target);
    bulk.aim_at(target);
    std::mt19937_64 rng(41);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::uniform_real_distribution<double> exponent(-14.0, 0.0);
    std::uint64_t next = 0;
    for (int k = 0; k < 300; ++k) {
      const item it{std::pow(2.0, exponent(rng)), 0, next++};
      one.push(it);
      bulk.push(it);
    }
    const auto same_cold = [&](const char* when, int round) {
      ASSERT_EQ(one.top_is_cold(), bulk.top_is_cold()) << when << ", round " << round;
      for (std::size_t a = 0; a < 4; ++a) {
        const item* x = one.cold_ahead(a);
        const item* y = bulk.cold_ahead(a);
        ASSERT_EQ(x == nullptr, y == nullptr) << when << ", round " << round;
        if (x != nullptr) {
          ASSERT_EQ(x->index, y->index) << when << ", round " << round;
        }
      }
    };
    for (int round = 0; round < 400 && !one.empty(); ++round) {
      ASSERT_EQ(one.top_rank(), bulk.top_rank());
      same_cold("before a band", round);
      const std::uint64_t floor = one.top_rank();
      std::vector<item> band_one;
      while (!one.empty() && one.top_rank() == floor) {
        band_one.push_back(one.top());
        one.pop();
      }
      std::vector<item> band_bulk = bulk.take_top_band();  // the next one at the back
      ASSERT_EQ(band_bulk.size(), band_one.size()) << "round " << round;
      for (std::size_t i = 0; i < band_one.size(); ++i) {
        ASSERT_EQ(band_bulk[band_bulk.size() - 1 - i].index, band_one[i].index)
            << "round " << round;
      }
      ASSERT_EQ(one.size(), bulk.size());
      if (!one.empty()) same_cold("after a band", round);
      // Children of the band's items: mostly below it, some in it and above it (new top bands).
      std::vector<item> children;
      for (const item& parent : band_one) {
        const int n = static_cast<int>(unit(rng) * 3.0);
        for (int c = 0; c < n; ++c) {
          const double u = unit(rng);
          const double e = u < 0.7   ? parent.error / (1.0 + 15.0 * unit(rng))
                           : u < 0.9 ? parent.error
                                     : parent.error * 3.0;
          children.push_back({e, 0, next++});
        }
      }
      std::vector<std::pair<std::uint64_t, std::vector<item>>> by_rank;
      for (const item& c : children) {
        one.push(c);
        const std::uint64_t rank = bulk.rank(c.error);
        auto at = std::find_if(by_rank.begin(), by_rank.end(),
                               [&](const auto& p) { return p.first == rank; });
        if (at == by_rank.end()) at = by_rank.insert(by_rank.end(), {rank, {}});
        at->second.push_back(c);
      }
      for (auto& [rank, items] : by_rank) bulk.push_band(rank, std::move(items));
      ASSERT_EQ(one.size(), bulk.size()) << "round " << round;
      if (!one.empty()) same_cold("after the children", round);
      if (one.size() > 20000) break;
    }
    const std::vector<item> rest_one = drain(one);
    const std::vector<item> rest_bulk = drain(bulk);
    ASSERT_EQ(rest_one.size(), rest_bulk.size());
    for (std::size_t i = 0; i < rest_one.size(); ++i) {
      ASSERT_EQ(rest_one[i].index, rest_bulk[i].index) << "at " << i;
    }
  }
}

TEST(ReadyQueue, switching_disciplines_keeps_every_item) {
  ready_queue<item> q(queue_discipline::lifo);
  for (std::uint64_t i = 0; i < 300; ++i)
    q.push({std::ldexp(1.0, -static_cast<int>(i % 30)), 0, i});
  q.set_discipline(queue_discipline::largest_error);
  EXPECT_EQ(q.size(), 300u);
  for (int k = 0; k < 100; ++k) q.pop();
  q.set_discipline(queue_discipline::lifo);
  EXPECT_EQ(q.size(), 200u);
  // Largest error first hands its items on smallest band first: last in first out then starts
  // with the largest left.
  EXPECT_EQ(q.top().error, std::ldexp(1.0, -10));
  q.set_discipline(queue_discipline::fifo);
  std::vector<item> out = drain(q);
  EXPECT_EQ(out.size(), 200u);
  std::vector<bool> seen(300, false);
  for (const item& it : out) {
    EXPECT_FALSE(seen[it.index]);
    seen[it.index] = true;
  }
}

}  // namespace
}  // namespace progiso::detail
