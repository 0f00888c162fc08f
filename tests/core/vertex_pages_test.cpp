// vertex_pages: per-grid-vertex words in bricks made when first written. Every grid point has
// its own word; a word never written reads 0 and costs nothing; memory follows the words
// written (a plane of them makes bricks in proportion to its area, not the grid's volume, and
// the sparse centres of a coarse scale share bricks as densely as the finest ones); threads
// racing to make a brick agree on one; clear() frees everything.

#include <progiso/core/refine/detail/vertex_pages.hpp>

#include <atomic>
#include <cstdint>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace progiso::detail {
namespace {

TEST(VertexPages, every_grid_point_has_its_own_word_and_unwritten_words_read_zero) {
  const hierarchy hier({19, 23, 17});  // padded: grid_max is not a multiple of a brick
  vertex_pages<std::uint32_t> words(hier);
  const ipoint g = hier.grid_max();
  // Nothing written: nothing found, nothing made.
  EXPECT_EQ(words.find(ipoint{3, 5, 7}), nullptr);
  EXPECT_EQ(words.bricks(), 0U);
  for (std::int32_t z = 0; z <= g[2]; ++z) {
    for (std::int32_t y = 0; y <= g[1]; ++y) {
      for (std::int32_t x = 0; x <= g[0]; ++x) {
        const ipoint p{x, y, z};
        std::uint32_t& w = words.at(p);
        EXPECT_EQ(w, 0U);
        w = static_cast<std::uint32_t>(hier.index(p) + 1);
      }
    }
  }
  for (std::int32_t z = 0; z <= g[2]; ++z) {
    for (std::int32_t y = 0; y <= g[1]; ++y) {
      for (std::int32_t x = 0; x <= g[0]; ++x) {
        const ipoint p{x, y, z};
        const std::uint32_t* w = words.find(p);
        ASSERT_NE(w, nullptr);
        EXPECT_EQ(*w, hier.index(p) + 1);
        EXPECT_EQ(words.find(hier.index(p)), w);  // by grid index: the same word
      }
    }
  }
}

TEST(VertexPages, memory_follows_the_words_written_not_the_grid) {
  const hierarchy hier({513, 513, 513});
  vertex_pages<std::uint32_t> words(hier);
  const std::uint64_t flat_bytes = hier.vertex_count() * sizeof(std::uint32_t);
  // The table alone: far below a flat array of the grid.
  EXPECT_LT(words.bytes() * 1000, flat_bytes);
  // One plane z = 200 written: its 513² words in bricks of 4³, about 129² of them (a quarter more
  // for the plane's points on coarser lattices, each a plane a quarter the size).
  for (std::int32_t y = 0; y <= 512; ++y) {
    for (std::int32_t x = 0; x <= 512; ++x) words.at(ipoint{x, y, 200}) = 1;
  }
  const std::size_t plane = words.bricks();
  EXPECT_GE(plane, 129U * 129U);
  EXPECT_LE(plane, 129U * 129U * 14 / 10);
  EXPECT_LT(words.bytes(), 4 * (513ULL * 513ULL * 4 * sizeof(std::uint32_t)));
  EXPECT_LT(words.bytes() * 50, flat_bytes);
  // Isolated words, a brick each.
  words.at(ipoint{0, 0, 0}) = 1;
  words.at(ipoint{400, 4, 500}) = 1;
  EXPECT_EQ(words.bricks(), plane + 2);
  words.clear();
  EXPECT_EQ(words.bricks(), 0U);
  EXPECT_EQ(words.find(ipoint{7, 9, 200}), nullptr);
  EXPECT_EQ(words.at(ipoint{7, 9, 200}), 0U);  // made again, zeroed
}

TEST(VertexPages, the_sparse_centres_of_a_coarse_scale_share_bricks) {
  // Every 16th point of a 513³ grid, as the centres of scale-32 diamonds are spaced: 33³ words
  // 16 apart. In the grid's own bricks each would hold a brick of 4³ words alone; on their level's
  // lattice they are neighbours, 4³ to a brick.
  const hierarchy hier({513, 513, 513});
  vertex_pages<std::uint32_t> words(hier);
  std::uint32_t n = 0;
  for (std::int32_t z = 0; z <= 512; z += 16) {
    for (std::int32_t y = 0; y <= 512; y += 16) {
      for (std::int32_t x = 0; x <= 512; x += 16) words.at(ipoint{x, y, z}) = ++n;
    }
  }
  EXPECT_EQ(n, 33U * 33U * 33U);
  EXPECT_LT(words.bricks() * 16, std::size_t{n});
  // Each still its own word.
  n = 0;
  for (std::int32_t z = 0; z <= 512; z += 16) {
    for (std::int32_t y = 0; y <= 512; y += 16) {
      for (std::int32_t x = 0; x <= 512; x += 16) {
        const std::uint32_t* w = words.find(ipoint{x, y, z});
        ASSERT_NE(w, nullptr);
        EXPECT_EQ(*w, ++n);
      }
    }
  }
  EXPECT_EQ(words.find(ipoint{8, 0, 0}), nullptr);  // a finer lattice's point: never written
}

TEST(VertexPages, threads_making_the_same_bricks_agree_on_each_word) {
  const hierarchy hier({129, 129, 129});
  vertex_pages<std::uint32_t> words(hier);
  constexpr int threads = 4;
  std::vector<std::vector<std::uint32_t*>> seen(threads);
  std::atomic<int> ready{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      // release/acquire: a start line, so the threads race for the same bricks.
      ready.fetch_add(1, std::memory_order_acq_rel);
      while (ready.load(std::memory_order_acquire) < threads) {
      }
      for (std::int32_t z = 0; z <= 128; z += 3) {
        for (std::int32_t y = 0; y <= 128; y += 5) {
          for (std::int32_t x = 0; x <= 128; x += 2) {
            std::uint32_t& w = words.at(ipoint{x, y, z});
            std::atomic_ref<std::uint32_t>(w).fetch_add(1, std::memory_order_relaxed);
            seen[static_cast<std::size_t>(t)].push_back(&w);
          }
        }
      }
    });
  }
  for (std::thread& th : pool) th.join();
  for (int t = 1; t < threads; ++t) EXPECT_EQ(seen[static_cast<std::size_t>(t)], seen[0]);
  std::set<const std::uint32_t*> distinct(seen[0].begin(), seen[0].end());
  EXPECT_EQ(distinct.size(), seen[0].size());
  for (const std::uint32_t* w : seen[0]) EXPECT_EQ(*w, static_cast<std::uint32_t>(threads));
}

}  // namespace
}  // namespace progiso::detail
