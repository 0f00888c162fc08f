// zeroed_array and add_in_place(): a large array reads as zeros with its pages untouched, and
// add_in_place() first touches a fresh page with a write (one page fault, where a load and a
// store take two: the load maps the shared zero page, the store's fault replaces it and flushes
// the TLB of every core running the process).

#include <progiso/core/base/zeroed_array.hpp>

#include <atomic>
#include <cstddef>
#include <cstdint>

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

namespace progiso {
namespace {

#if defined(__x86_64__) && !PROGISO_ADD_IN_PLACE_ATOMIC
constexpr bool add_in_place_is_one_instruction = true;
#else
constexpr bool add_in_place_is_one_instruction = false;
#endif

long minor_faults_of_this_thread() {
  rusage u{};
  EXPECT_EQ(getrusage(RUSAGE_THREAD, &u), 0);
  return u.ru_minflt;
}

// A fresh mmap-backed array of `bytes`, on small pages (huge pages would fault once per 2 MiB
// either way, and the counts below compare per-page behaviour).
template <class T>
zeroed_array<T> fresh_small_pages(std::size_t bytes) {
  zeroed_array<T> a(bytes / sizeof(T));
  EXPECT_GT(bytes, zeroed_array<T>::heap_max_bytes);  // mapped, not from the heap
  (void)madvise(a.get(), bytes, MADV_NOHUGEPAGE);
  return a;
}

// Page faults taken while touching one element per page of a fresh array with `touch`.
template <class T, class Touch>
long faults_touching_each_page(Touch&& touch) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t bytes = std::size_t{32} << 20;
  zeroed_array<T> a = fresh_small_pages<T>(bytes);
  const std::size_t step = page / sizeof(T);
  const long before = minor_faults_of_this_thread();
  for (std::size_t i = 0; i < a.size(); i += step) touch(a[i]);
  return minor_faults_of_this_thread() - before;
}

TEST(ZeroedArray, add_in_place_adds_wraps_and_returns_the_new_value) {
  zeroed_array<std::uint32_t> w(8);
  EXPECT_EQ(add_in_place(w[3], std::uint32_t{5}), 5u);
  EXPECT_EQ(add_in_place(w[3], ~std::uint32_t{0}), 4u);  // adding all ones subtracts one
  EXPECT_EQ(w[3], 4u);
  EXPECT_EQ(add_in_place(w[0], ~std::uint32_t{0}), ~std::uint32_t{0});  // wraps below zero
  EXPECT_EQ(w[2], 0u);
  EXPECT_EQ(w[4], 0u);

  zeroed_array<std::uint8_t> b(8);
  b[1] = 0x80;  // a flag above the count bits stays
  EXPECT_EQ(add_in_place(b[1], std::uint8_t{1}), 0x81u);
  EXPECT_EQ(add_in_place(b[1], std::uint8_t{1}), 0x82u);
  b[5] = 0xff;
  EXPECT_EQ(add_in_place(b[5], std::uint8_t{1}), 0u);  // wraps
  EXPECT_EQ(b[0], 0u);
  EXPECT_EQ(b[2], 0u);
}

TEST(ZeroedArray, a_large_array_reads_as_zeros) {
  zeroed_array<std::uint32_t> a((std::size_t{16} << 20) / sizeof(std::uint32_t));
  for (std::size_t i = 0; i < a.size(); i += 997) ASSERT_EQ(a[i], 0u);
  a[a.size() - 1] = 7;
  a.zero();
  EXPECT_EQ(a[a.size() - 1], 0u);
}

TEST(ZeroedArray, add_in_place_touches_a_fresh_page_with_one_fault_where_load_and_store_take_two) {
  if (!add_in_place_is_one_instruction) {
    GTEST_SKIP() << "add_in_place() is a load and a store on this target or under ThreadSanitizer";
  }
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const auto pages = static_cast<long>((std::size_t{32} << 20) / page);
  // The control: a load, then a store. Where the kernel maps no zero page on a read fault
  // (vm.use_zero_page off), both take one fault a page and there is nothing to tell apart.
  const long split = faults_touching_each_page<std::uint32_t>([](std::uint32_t& x) {
    const std::uint32_t v = std::atomic_ref<std::uint32_t>(x).load(std::memory_order_relaxed);
    std::atomic_ref<std::uint32_t>(x).store(v - 1, std::memory_order_relaxed);
  });
  if (split < pages + pages / 2) GTEST_SKIP() << "reads of fresh pages map no zero page here";
  const long words = faults_touching_each_page<std::uint32_t>(
      [](std::uint32_t& x) { (void)add_in_place(x, ~std::uint32_t{0}); });
  const long bytes = faults_touching_each_page<std::uint8_t>(
      [](std::uint8_t& x) { (void)add_in_place(x, std::uint8_t{1}); });
  // A few faults of the test's own (its stack, the allocator) are allowed for.
  EXPECT_LE(words, pages + 64) << "load and store: " << split;
  EXPECT_LE(bytes, pages + 64) << "load and store: " << split;
  EXPECT_GE(words, pages - 64);  // every page was touched
}

}  // namespace
}  // namespace progiso
