// Poison-on-retire stress (invariant 5, docs/ARCHITECTURE.md: no use-after-free). Writers replace a
// shared root and the leaf inside it, retiring what they unlink; the deleter poisons every
// field and parks the node in a per-thread quarantine before freeing it, so a reader that
// touched reclaimed memory reads the poison (and ASan reports the access once the quarantine
// frees it). Readers sleep 0–50 µs at random points inside their guards and check a magic word
// and a payload derived from the version on every access. At the end every node ever created
// was deleted exactly once. Runs PROGISO_STRESS_SECONDS per variant (default 1).
#include <progiso/concurrent/epoch.hpp>

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "support/stress_support.hpp"

namespace progiso {
namespace {

constexpr std::uint64_t live_magic = 0x4c4956454e4f4445;  // "LIVENODE"
constexpr std::uint64_t poison = 0xdeadbeefdeadbeef;

std::atomic<std::uint64_t> created{0};
std::atomic<std::uint64_t> deleted{0};
std::atomic<std::uint64_t> deleted_twice{0};  // deleter saw a node that was not live
std::atomic<std::uint64_t> violations{0};     // reader saw poison or a torn payload
std::atomic<std::uint64_t> next_version{0};

std::uint64_t payload_word(std::uint64_t version, std::size_t i) {
  std::uint64_t z = version * 0x9e3779b97f4a7c15 + i;  // splitmix64 finaliser
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9;
  z = (z ^ (z >> 27)) * 0x94d049bb133111eb;
  return z ^ (z >> 31);
}

struct node : epoch_object {
  explicit node(std::uint64_t v) : version(v) {
    for (std::size_t i = 0; i < words.size(); ++i) words[i] = payload_word(v, i);
    created.fetch_add(1, std::memory_order_relaxed);  // relaxed: a count read after joins
  }
  node(const node&) = delete;
  node& operator=(const node&) = delete;
  ~node() = default;

  std::uint64_t magic = live_magic;
  std::uint64_t version;
  std::array<std::uint64_t, 4> words{};
  std::atomic<node*> child{nullptr};  // a root's leaf; null in a leaf
};

// Checks a node and returns its version; `expected` (when given) catches a node whose memory
// was freed and reused for another one between two checks.
std::uint64_t check(const node* n, std::uint64_t expected = poison) {
  bool ok = n->magic == live_magic && (expected == poison || n->version == expected);
  for (std::size_t i = 0; ok && i < n->words.size(); ++i) {
    ok = n->words[i] == payload_word(n->version, i);
  }
  if (!ok) violations.fetch_add(1, std::memory_order_relaxed);  // relaxed: read after joins
  return n->version;
}

// Poisoned nodes wait here (the last 65 536 per thread, a few milliseconds' worth) before they
// are freed, so that stale reads see the poison rather than a reused allocation.
class quarantine {
 public:
  quarantine() = default;
  quarantine(const quarantine&) = delete;
  quarantine& operator=(const quarantine&) = delete;
  ~quarantine() { release_all(); }

  void push(node* n) {
    if (nodes_.size() < capacity) {
      nodes_.push_back(n);
      return;
    }
    delete std::exchange(nodes_[oldest_], n);
    oldest_ = (oldest_ + 1) % capacity;
  }
  void release_all() noexcept {
    for (node* n : nodes_) delete n;
    nodes_.clear();
    oldest_ = 0;
  }

 private:
  static constexpr std::size_t capacity = std::size_t{1} << 16;
  std::vector<node*> nodes_;
  std::size_t oldest_ = 0;
};

thread_local quarantine parked;

void poison_and_park(node* n) noexcept {
  if (n->magic != live_magic) deleted_twice.fetch_add(1, std::memory_order_relaxed);
  // volatile: the stores must happen although nobody may read the node afterwards.
  volatile std::uint64_t& magic = n->magic;
  magic = poison;
  volatile std::uint64_t& version = n->version;
  version = poison;
  for (std::uint64_t& w : n->words) {
    volatile std::uint64_t& word = w;
    word = poison;
  }
  deleted.fetch_add(1, std::memory_order_relaxed);  // relaxed: read after joins
  parked.push(n);
}

// A root owns the leaf it holds when it is reclaimed (that leaf was never retired on its own).
struct poison_delete {
  void operator()(node* n) const noexcept {
    // relaxed: the deleter runs after every guard that reached `n` ended (acquire-load (7) in
    // flush()), which orders the last exchange into `child` before this load.
    if (node* leaf = n->child.load(std::memory_order_relaxed)) poison_and_park(leaf);
    poison_and_park(n);
  }
};

node* make_node(epoch_domain& domain) {
  return make_managed<node>(domain, next_version.fetch_add(1, std::memory_order_relaxed));
}

struct variant {
  std::string name;
  epoch_options options;
  int readers;
  int writers;
  bool churn;  // writers leave and re-register, handing garbage over as orphans
};

void PrintTo(const variant& v, std::ostream* os) { *os << v.name; }

class EpochPoison : public testing::TestWithParam<variant> {};

TEST_P(EpochPoison, readers_never_see_a_reclaimed_node_and_every_node_is_deleted_once) {
  const variant& v = GetParam();
  created = 0;
  deleted = 0;
  deleted_twice = 0;
  violations = 0;
  std::atomic<std::uint64_t> reads{0};
  std::atomic<std::uint64_t> writes{0};
  {
    epoch_domain domain(v.options);
    node* first = make_node(domain);
    first->child.store(make_node(domain), std::memory_order_relaxed);  // published below
    std::atomic<node*> root{first};
    std::atomic<bool> stop{false};
    std::vector<std::thread> threads;

    for (int r = 0; r < v.readers; ++r) {
      threads.emplace_back([&, r] {
        epoch_participant p(domain);
        std::mt19937_64 rng(static_cast<std::uint64_t>(r) + 1);
        const auto nap = [&rng] {
          if (rng() % 2 == 0) std::this_thread::sleep_for(std::chrono::microseconds(rng() % 51));
        };
        std::uint64_t done = 0;
        // relaxed: a stop request; the threads are joined before anything is checked.
        while (!stop.load(std::memory_order_relaxed)) {
          epoch_guard g = p.pin();
          nap();
          const node* top = g.protect(root);
          const std::uint64_t top_version = check(top);
          nap();
          const node* leaf = g.protect(top->child);
          const std::uint64_t leaf_version = check(leaf);
          nap();
          check(top, top_version);
          check(leaf, leaf_version);
          check(g.protect(root));  // raises the reservation inside a long guard
          nap();
          check(top, top_version);
          ++done;
        }
        reads.fetch_add(done, std::memory_order_relaxed);  // relaxed: read after joins
      });
    }

    for (int w = 0; w < v.writers; ++w) {
      threads.emplace_back([&, w] {
        auto p = std::make_unique<epoch_participant>(domain);
        std::mt19937_64 rng(static_cast<std::uint64_t>(w) + 1001);
        std::uint64_t done = 0;
        while (!stop.load(std::memory_order_relaxed)) {  // relaxed: as above
          if (v.churn && done % 257 == 256) {
            p.reset();
            p = std::make_unique<epoch_participant>(domain);
          }
          if (rng() % 4 == 0) {
            node* leaf = make_node(domain);
            node* top = make_node(domain);
            top->child.store(leaf, std::memory_order_relaxed);  // published by the exchange
            p->retire<poison_delete>(root.exchange(top));
          } else {
            epoch_guard g = p->pin();
            node* top = g.protect(root);
            node* old = top->child.exchange(make_node(domain));
            g.unpin();
            p->retire<poison_delete>(old);
          }
          ++done;
        }
        writes.fetch_add(done, std::memory_order_relaxed);  // relaxed: read after joins
      });
    }

    std::this_thread::sleep_for(test::stress_duration());
    stop.store(true, std::memory_order_relaxed);  // relaxed: see the readers
    for (std::thread& t : threads) t.join();

    epoch_participant last(domain);
    last.retire<poison_delete>(root.exchange(nullptr));
    last.flush();
    domain.drain();
    const epoch_statistics s = domain.statistics();
    EXPECT_EQ(s.pending, 0u);
    EXPECT_EQ(s.reclaimed, s.retired);
  }
  parked.release_all();
  std::cout << "[ measured ] " << v.name << ": " << reads.load() << " guarded reads, "
            << writes.load() << " replacements, " << created.load() << " nodes\n";
  EXPECT_GT(reads.load(), 0u);
  EXPECT_GT(writes.load(), 0u);
  EXPECT_EQ(violations.load(), 0u) << "a reader saw a poisoned or torn node";
  EXPECT_EQ(deleted_twice.load(), 0u);
  EXPECT_EQ(deleted.load(), created.load()) << "every node deleted exactly once";
}

INSTANTIATE_TEST_SUITE_P(
    Variants, EpochPoison,
    testing::Values(variant{"defaults", {}, 3, 1, false},
                    variant{"busy_clock_fallback_churn",
                            {.reclaim_threshold = 4, .era_frequency = 1, .protect_attempts = 0},
                            3,
                            2,
                            true},
                    variant{"plain_epochs", {.interval_based = false}, 2, 2, false}),
    [](const testing::TestParamInfo<variant>& param) { return param.param.name; });

}  // namespace
}  // namespace progiso
