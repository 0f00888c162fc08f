// prefault(): the pages of a large buffer are mapped by one call, before the first write; small
// buffers and kernels without MADV_POPULATE_WRITE are left alone. release_in_parts(): the pages
// of a buffer about to be freed handed back by slices.

#include <progiso/core/base/detail/prefault.hpp>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

namespace progiso {
namespace {

// Pages of [p, p + bytes) the kernel holds in memory, by mincore().
std::size_t resident_pages(void* p, std::size_t bytes) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> in((bytes + page - 1) / page);
  EXPECT_EQ(mincore(p, bytes, in.data()), 0);
  std::size_t n = 0;
  for (const unsigned char b : in) n += b & 1u;
  return n;
}

struct fresh_mapping {
  explicit fresh_mapping(std::size_t n) : bytes(n) {
    p = mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  }
  ~fresh_mapping() {
    if (p != MAP_FAILED) munmap(p, bytes);
  }
  fresh_mapping(const fresh_mapping&) = delete;
  fresh_mapping& operator=(const fresh_mapping&) = delete;
  std::size_t bytes;
  void* p;
};

// A loop that runs each body on its own thread, as the engine's would on several, counting its
// calls and the bodies run.
struct threads_per_body {
  std::mutex mutex;
  std::set<std::size_t> bodies;
  std::size_t calls = 0;
  const parallel_loop run = [this](std::size_t n, const std::function<void(std::size_t)>& body) {
    {
      const std::lock_guard lock(mutex);
      ++calls;
    }
    std::vector<std::thread> threads;
    for (std::size_t k = 0; k < n; ++k) {
      threads.emplace_back([this, &body, k] {
        body(k);
        const std::lock_guard lock(mutex);
        bodies.insert(k);
      });
    }
    for (auto& t : threads) t.join();
  };
};

bool kernel_populates() {
  fresh_mapping probe(4096);
  return probe.p != MAP_FAILED && madvise(probe.p, 4096, 23 /* MADV_POPULATE_WRITE */) == 0;
}

TEST(Prefault, maps_every_page_of_a_large_fresh_buffer_before_it_is_written) {
  if (!kernel_populates()) GTEST_SKIP() << "this kernel has no MADV_POPULATE_WRITE (Linux 5.14)";
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t bytes = 8 * detail::prefault_min_bytes;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  EXPECT_EQ(resident_pages(m.p, bytes), 0u);  // anonymous pages are mapped on first touch
  detail::prefault(m.p, bytes);
  EXPECT_EQ(resident_pages(m.p, bytes), bytes / page);
  // Mapped for writing, zero-filled: the buffer reads as zeros.
  const auto* b = static_cast<const unsigned char*>(m.p);
  for (std::size_t i = 0; i < bytes; i += page) ASSERT_EQ(b[i], 0);
}

TEST(Prefault, maps_only_the_whole_pages_inside_an_unaligned_range) {
  if (!kernel_populates()) GTEST_SKIP() << "this kernel has no MADV_POPULATE_WRITE (Linux 5.14)";
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t bytes = 4 * detail::prefault_min_bytes;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  auto* base = static_cast<unsigned char*>(m.p);
  // From the middle of page 1 to the middle of the second-to-last page: pages 2 … last − 2.
  detail::prefault(base + page + page / 2, bytes - 3 * page);
  std::vector<unsigned char> in(bytes / page);
  ASSERT_EQ(mincore(m.p, bytes, in.data()), 0);
  EXPECT_EQ(in[0] & 1u, 0u);
  EXPECT_EQ(in[1] & 1u, 0u);
  for (std::size_t i = 2; i + 2 < in.size(); ++i) EXPECT_EQ(in[i] & 1u, 1u) << "page " << i;
  EXPECT_EQ(in[in.size() - 2] & 1u, 0u);
  EXPECT_EQ(in[in.size() - 1] & 1u, 0u);
}

TEST(Prefault, leaves_small_buffers_to_fault_page_by_page) {
  const std::size_t bytes = detail::prefault_min_bytes / 2;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  detail::prefault(m.p, bytes);
  EXPECT_EQ(resident_pages(m.p, bytes), 0u);
}

TEST(Prefault, in_parts_maps_every_page_in_slices_of_at_least_the_minimum_through_the_loop) {
  if (!kernel_populates()) GTEST_SKIP() << "this kernel has no MADV_POPULATE_WRITE (Linux 5.14)";
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  // 5.5 MiB in up to 8 parts: 5 slices (a slice is at least 1 MiB), the last one shorter.
  const std::size_t bytes = 5 * detail::prefault_min_bytes + detail::prefault_min_bytes / 2;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  threads_per_body loop;
  detail::prefault_in_parts(loop.run, 8, m.p, bytes);
  EXPECT_EQ(loop.calls, 1u);
  EXPECT_EQ(loop.bodies.size(), 5u);
  EXPECT_EQ(resident_pages(m.p, bytes), bytes / page);
  // One part: one call on this thread, the loop untouched; the whole range mapped all the same.
  fresh_mapping one(bytes);
  ASSERT_NE(one.p, MAP_FAILED);
  detail::prefault_in_parts(loop.run, 1, one.p, bytes);
  EXPECT_EQ(loop.calls, 1u);
  EXPECT_EQ(resident_pages(one.p, bytes), bytes / page);
}

TEST(Prefault,
     release_in_parts_frees_the_whole_pages_inside_the_range_in_slices_and_keeps_the_rest) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  // The minimum plus half a MiB and a page, released from the middle of its first page to the
  // middle of its last: the whole pages between go, in 8 slices through the loop.
  const std::size_t bytes = detail::release_min_bytes + detail::prefault_min_bytes / 2 + page;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  auto* base = static_cast<unsigned char*>(m.p);
  std::fill(base, base + bytes, std::uint8_t{0xab});
  const std::size_t pages = bytes / page;
  ASSERT_EQ(resident_pages(m.p, bytes), pages);
  threads_per_body loop;
  detail::release_in_parts(loop.run, 8, base + page / 2, bytes - page);
  EXPECT_EQ(loop.calls, 1u);
  EXPECT_EQ(loop.bodies.size(), 8u);
  std::vector<unsigned char> in(pages);
  ASSERT_EQ(mincore(m.p, bytes, in.data()), 0);
  EXPECT_EQ(in[0] & 1u, 1u);          // partly outside the range: kept
  EXPECT_EQ(in[pages - 1] & 1u, 1u);  // likewise
  for (std::size_t i = 1; i + 1 < pages; ++i) ASSERT_EQ(in[i] & 1u, 0u) << "page " << i;
  // The kept pages keep their bytes, inside the range too; the freed ones read as zeros.
  EXPECT_EQ(base[0], 0xab);
  EXPECT_EQ(base[page - 1], 0xab);
  EXPECT_EQ(base[bytes - 1], 0xab);
  EXPECT_EQ(base[bytes - page], 0xab);
  for (std::size_t i = page; i + page < bytes; i += page / 2) ASSERT_EQ(base[i], 0) << i;
  // One part: nothing is released (a single thread gains nothing over free()), the loop unused.
  fresh_mapping one(bytes);
  ASSERT_NE(one.p, MAP_FAILED);
  std::fill_n(static_cast<unsigned char*>(one.p), bytes, std::uint8_t{0xab});
  detail::release_in_parts(loop.run, 1, one.p, bytes);
  EXPECT_EQ(loop.calls, 1u);
  EXPECT_EQ(resident_pages(one.p, bytes), pages);
}

TEST(Prefault, release_in_parts_leaves_a_buffer_below_the_minimum_to_the_allocator) {
  // Below release_min_bytes a block may sit in malloc's heap, whose pages the next allocation
  // reuses: they stay mapped.
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t bytes = detail::release_min_bytes - page;
  fresh_mapping m(bytes);
  ASSERT_NE(m.p, MAP_FAILED);
  std::fill_n(static_cast<unsigned char*>(m.p), bytes, std::uint8_t{0xab});
  threads_per_body loop;
  detail::release_in_parts(loop.run, 8, m.p, bytes);
  EXPECT_EQ(loop.calls, 0u);
  EXPECT_EQ(resident_pages(m.p, bytes), bytes / page);
  EXPECT_EQ(static_cast<unsigned char*>(m.p)[bytes / 2], 0xab);
}

TEST(Prefault, reserve_prefaulted_reserves_and_keeps_the_elements) {
  std::vector<std::uint32_t> v{1, 2, 3};
  detail::reserve_prefaulted(v, 4 * detail::prefault_min_bytes / sizeof(std::uint32_t));
  EXPECT_GE(v.capacity(), 4 * detail::prefault_min_bytes / sizeof(std::uint32_t));
  EXPECT_EQ(v, (std::vector<std::uint32_t>{1, 2, 3}));
  const std::size_t before = v.capacity();
  detail::reserve_prefaulted(v, 10);  // already large enough: nothing moves
  EXPECT_EQ(v.capacity(), before);
}

}  // namespace
}  // namespace progiso
