// The engine's full-refinement order (plane_lists): the lowest occupied plane first, last in
// first out within a plane; give_upper_half() splits the occupied planes in two without losing
// or repeating a diamond; drain() hands every diamond back.
#include <progiso/core/refine/detail/plane_lists.hpp>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace progiso::detail {
namespace {

constexpr std::size_t planes = 16;
constexpr std::uint64_t plane_size = 100;

std::vector<std::uint64_t> pop_all(plane_lists& p) {
  std::vector<std::uint64_t> out;
  while (!p.empty()) out.push_back(p.pop());
  return out;
}

std::vector<std::uint64_t> sorted(std::vector<std::uint64_t> v) {
  std::sort(v.begin(), v.end());
  return v;
}

TEST(PlaneLists, pops_the_lowest_plane_first_and_the_last_pushed_within_a_plane) {
  plane_lists p;
  p.reset(planes, plane_size);
  EXPECT_TRUE(p.empty());
  for (const std::uint64_t i : {705u, 301u, 1599u, 350u, 0u, 399u, 720u}) p.push(i);
  EXPECT_EQ(p.size(), 7u);
  EXPECT_EQ(p.pop(), 0u);
  EXPECT_EQ(p.pop(), 399u);  // plane 3: pushed 301, 350, 399
  // A diamond pushed below the planes taken so far is next.
  p.push(150);
  EXPECT_EQ(p.pop(), 150u);
  EXPECT_EQ(pop_all(p), (std::vector<std::uint64_t>{350, 301, 720, 705, 1599}));
}

TEST(PlaneLists, giving_the_upper_half_moves_the_planes_above_the_middle_and_keeps_every_diamond) {
  std::mt19937_64 rng(3);
  for (int round = 0; round < 200; ++round) {
    plane_lists p;
    p.reset(planes, plane_size);
    std::vector<std::uint64_t> all;
    const std::size_t n = 2 + rng() % 40;
    const std::uint64_t lo = rng() % planes;
    const std::uint64_t hi = lo + rng() % (planes - lo);  // occupied planes lo..hi
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint64_t z = lo + rng() % (hi - lo + 1);
      all.push_back(z * plane_size + rng() % plane_size);
      p.push(all.back());
    }
    plane_lists q;
    p.give_upper_half(q);
    EXPECT_EQ(p.size() + q.size(), n);
    ASSERT_FALSE(p.empty());
    ASSERT_FALSE(q.empty());
    std::vector<std::uint64_t> mine = pop_all(p);
    std::vector<std::uint64_t> given = pop_all(q);
    const std::uint64_t top_kept = *std::max_element(mine.begin(), mine.end()) / plane_size;
    const std::uint64_t lowest_given = *std::min_element(given.begin(), given.end()) / plane_size;
    // Two slabs split at the middle of the occupied planes (one plane shared only when
    // everything lay on it).
    const std::uint64_t first = *std::min_element(all.begin(), all.end()) / plane_size;
    const std::uint64_t last = *std::max_element(all.begin(), all.end()) / plane_size;
    if (first != last) {
      const std::uint64_t middle = first + (last - first + 1) / 2;
      EXPECT_LT(top_kept, middle);
      EXPECT_GE(lowest_given, middle);
    } else {
      EXPECT_EQ(mine.size(), n / 2 + n % 2) << "one plane: half of its list each";
    }
    mine.insert(mine.end(), given.begin(), given.end());
    EXPECT_EQ(sorted(mine), sorted(all)) << "a diamond was lost or repeated";
  }
}

TEST(PlaneLists, one_diamond_is_not_given_away_and_drain_hands_every_diamond_back) {
  plane_lists p;
  p.reset(planes, plane_size);
  p.push(512);
  plane_lists q;
  p.give_upper_half(q);
  EXPECT_EQ(p.size(), 1u);
  EXPECT_TRUE(q.empty());
  for (const std::uint64_t i : {3u, 1404u, 517u}) p.push(i);
  std::vector<std::uint64_t> drained;
  p.drain([&](std::uint64_t i) { drained.push_back(i); });
  EXPECT_TRUE(p.empty());
  EXPECT_EQ(sorted(drained), (std::vector<std::uint64_t>{3, 512, 517, 1404}));
  // Reused after a drain: the same order as fresh lists.
  p.push(900);
  p.push(100);
  EXPECT_EQ(pop_all(p), (std::vector<std::uint64_t>{100, 900}));
}

}  // namespace
}  // namespace progiso::detail
