// append_log: single-writer appends, and reserved slots filled by several threads outside the
// writers' mutex, published by watermark in log order (as the engine's full-refinement tasks
// publish their records).
#include <progiso/concurrent/append_log.hpp>
#include <progiso/core/base/zeroed_array.hpp>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

struct item {
  std::uint64_t index;
  std::uint64_t check;  // index × 3 + 1, so a half-written or garbage slot shows
};

TEST(AppendLog, push_back_and_publish_show_a_prefix) {
  append_log<item, 2> log;  // chunks of 4
  for (std::uint64_t i = 0; i < 10; ++i) log.push_back({i, i * 3 + 1});
  EXPECT_EQ(log.published(), 0u);
  log.publish();
  ASSERT_EQ(log.published(), 10u);
  for (std::uint64_t i = 0; i < 10; ++i) EXPECT_EQ(log[i].check, i * 3 + 1);
}

TEST(AppendLog, reserve_spans_every_chunk_its_slots_lie_in_and_filled_slots_read_back) {
  append_log<item, 2> log;  // chunks of 4
  log.push_back({0, 1});
  EXPECT_EQ(log.reserve(0), 1u);
  const std::size_t a = log.reserve(9);  // slots 1..9: the rest of chunk 0, chunks 1 and 2
  const std::size_t b = log.reserve(3);  // slots 10..12: the rest of chunk 2, chunk 3
  ASSERT_EQ(a, 1u);
  ASSERT_EQ(b, 10u);
  EXPECT_EQ(log.size(), 13u);
  for (std::size_t i = 13; i-- > 1;) log.at_unpublished(i) = {i, i * 3 + 1};  // any order
  log.publish(10);
  EXPECT_EQ(log.published(), 10u);
  log.publish(13);
  ASSERT_EQ(log.published(), 13u);
  for (std::uint64_t i = 0; i < 13; ++i) {
    EXPECT_EQ(log[i].index, i);
    EXPECT_EQ(log[i].check, i * 3 + 1);
  }
  EXPECT_EQ(log.byte_size(), 4 * 4 * sizeof(item));
}

TEST(AppendLog, a_log_on_a_released_directory_starts_empty_and_appends_like_a_fresh_one) {
  using log_t = append_log<item, 2, 8>;  // chunks of 4, at most 8 of them
  zeroed_array<item*> directory(0);
  {
    log_t first;
    for (std::uint64_t i = 0; i < 13; ++i) first.push_back({i, i * 3 + 1});  // four chunks
    first.publish();
    directory = first.release_directory();
    EXPECT_EQ(first.size(), 0u);
    EXPECT_EQ(first.published(), 0u);
    EXPECT_EQ(first.byte_size(), 0u);
  }  // the emptied log destroys nothing twice (ASan)
  ASSERT_EQ(directory.size(), log_t::max_chunks);
  for (std::size_t c = 0; c < directory.size(); ++c) {
    EXPECT_EQ(directory[c], nullptr) << "chunk " << c << " of the old log is still named";
  }
  log_t second(std::move(directory));
  EXPECT_EQ(second.size(), 0u);
  EXPECT_EQ(second.published(), 0u);
  for (std::uint64_t i = 0; i < 32; ++i) second.push_back({i, i * 7});  // every chunk
  second.publish();
  ASSERT_EQ(second.published(), 32u);
  for (std::uint64_t i = 0; i < 32; ++i) EXPECT_EQ(second[i].check, i * 7);
  EXPECT_THROW(second.push_back({32, 0}), std::length_error);  // 8 chunks of 4: full
  EXPECT_THROW(log_t(zeroed_array<item*>(3)), std::invalid_argument);
}

// Writers reserve ranges under a mutex, fill them without it, and move the watermark over the
// filled ranges at the front; a reader checks that every slot below each watermark it sees is
// filled. Under ThreadSanitizer this also checks the happens-before the protocol relies on.
TEST(AppendLog, writers_filling_reserved_slots_concurrently_publish_only_filled_prefixes) {
  append_log<item, 6> log;  // chunks of 64: many chunk allocations while others fill
  constexpr int writers = 3;
  constexpr std::size_t per_writer = 20000;
  std::mutex mutex;
  struct range {
    std::size_t end;
    bool filled;
  };
  std::deque<range> unfilled;
  std::atomic<bool> done{false};
  std::atomic<std::size_t> bad{0};

  std::thread reader([&] {
    std::size_t seen = 0;
    // acquire: pairs with the release store below; ends the loop after the writers joined.
    while (!done.load(std::memory_order_acquire)) {
      const std::size_t n = log.published();
      for (std::size_t i = seen; i < n; ++i) {
        if (log[i].index != i || log[i].check != i * 3 + 1) {
          bad.fetch_add(1, std::memory_order_relaxed);  // relaxed: a count read after join
        }
      }
      seen = n;
    }
  });
  std::vector<std::thread> threads;
  for (int w = 0; w < writers; ++w) {
    threads.emplace_back([&, w] {
      std::size_t written = 0;
      std::size_t step = 1 + static_cast<std::size_t>(w) * 7;
      while (written < per_writer) {
        const std::size_t k = std::min(step, per_writer - written);
        step = step % 97 + 13;
        std::size_t first = 0;
        {
          const std::lock_guard lock(mutex);
          first = log.reserve(k);
          unfilled.push_back({first + k, false});
        }
        for (std::size_t i = first; i < first + k; ++i) log.at_unpublished(i) = {i, i * 3 + 1};
        {
          const std::lock_guard lock(mutex);
          for (range& r : unfilled) {
            if (r.end == first + k) r.filled = true;
          }
          std::size_t mark = 0;
          while (!unfilled.empty() && unfilled.front().filled) {
            mark = unfilled.front().end;
            unfilled.pop_front();
          }
          if (mark != 0) log.publish(mark);
        }
        written += k;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  done.store(true, std::memory_order_release);  // release: pairs with the reader's acquire
  reader.join();
  EXPECT_TRUE(unfilled.empty());
  ASSERT_EQ(log.published(), writers * per_writer);
  EXPECT_EQ(bad.load(std::memory_order_relaxed), 0u);  // relaxed: the reader has joined
  for (std::size_t i = 0; i < log.published(); ++i) ASSERT_EQ(log[i].check, i * 3 + 1);
}

}  // namespace
}  // namespace progiso
