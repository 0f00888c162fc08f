// progiso/core/refine/detail/vertex_pages.hpp — per-grid-vertex words whose memory follows what a
// refinement writes, not the grid: bricks of 4³ words, made when first written, found through a
// two-level table (blocks of 8³ bricks, each block's table made when first needed), one table per
// lattice level.
//
// The refiners keep a word per grid vertex (a split flag, a count of split parents, a record
// index) but write only those of the diamonds they visit: near the surface, and at coarse
// scales, where ranges are loose, sparsely around it. A flat array indexed by grid index reserves
// the whole grid (4 bytes a vertex: 4 GiB at 1024³, 32 GiB at 2048³), which a process whose
// memory is capped below that cannot even map, and lazily mapped it commits a 4 KiB page per
// x-row the surface crosses.
//
// Levels: a diamond of scale h has its centre on the lattice of spacing h and on no coarser one
// (h is the lowest set bit of x | y | z: hierarchy::scale_of). Point p of level t is kept at
// p >> t in that level's own table, so the centres of one scale are neighbours there,
// whatever their spacing in the grid. An error-driven cut stops at coarse scales over most of the
// surface; had its centres shared the grid's bricks, each of them, 2^t apart, would have paid a
// whole brick for one word. (The origin, with no set bit, is the point 0 of a level of its own.)
// Small bricks commit 4³ words (256 bytes of 32-bit words) around each word written: dense near the
// surface, and little per isolated diamond, which larger bricks would pay in full. What the grid
// itself costs is the top tables, 8 bytes per 32³ vertices and 8/7 of that over all levels.
//
// Words are addressed by the grid point, or by the grid index hierarchy::index() gives (what
// records and triangles name a diamond by; one division pair more). find() and load() never
// allocate: a word whose brick was never written reads 0. at() makes what is missing, from any
// thread: a fresh zeroed table or brick is installed by a compare-and-swap, so threads racing for
// it agree on one (the losers free their own). Elements follow T's own rules: callers access
// words through atomic_ref as before, and never hold more than the word.
//
// clear() frees every brick and block table (no concurrent access), so memory follows the
// current refinement rather than every one a long session has seen. Throws std::bad_alloc when
// a table or brick cannot be allocated.
#pragma once

#include <array>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>

#include <progiso/core/hierarchy/hierarchy.hpp>

namespace progiso::detail {

template <class T>
class vertex_pages {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  static constexpr int brick_bits = 2;  // 4 vertices per axis
  static constexpr int block_bits = 3;  // 8 bricks per axis: 32 vertices
  static constexpr std::size_t brick_words = std::size_t{1} << (3 * brick_bits);
  static constexpr std::size_t block_bricks = std::size_t{1} << (3 * block_bits);

  vertex_pages() = default;
  explicit vertex_pages(const hierarchy& hier) : hier_(&hier) {
    const ipoint& g = hier.grid_max();
    // A level per lattice spacing 2^t up to the origin's, each with its own table (one block
    // from the largest coordinate's level on).
    for (const std::int32_t c : g) {
      if (c < 0 || c >= static_cast<std::int32_t>(origin_level_bit)) throw std::bad_alloc();
    }
    for (int t = 0; t < max_levels; ++t) {
      level& l = level_[static_cast<std::size_t>(t)];
      l.base = count_;
      for (std::size_t a = 0; a < 3; ++a) {
        l.blocks[a] = (static_cast<std::uint64_t>(g[a]) >> (t + brick_bits + block_bits)) + 1;
      }
      count_ += l.blocks[0] * l.blocks[1] * l.blocks[2];
    }
    // Every brick the tables have, plus one per racing thread that may lose a brick it took.
    chunk_count_ = (count_ * block_bricks + 256) / chunk_bricks + 1;
    top_ = new std::atomic<block*>[count_]();       // null: a block never written
    chunks_ = new std::atomic<T*>[chunk_count_]();  // null: a chunk not needed yet
  }
  vertex_pages(const vertex_pages&) = delete;
  vertex_pages& operator=(const vertex_pages&) = delete;
  vertex_pages(vertex_pages&& o) noexcept { take(o); }
  vertex_pages& operator=(vertex_pages&& o) noexcept {
    if (this != &o) {
      release();
      take(o);
    }
    return *this;
  }
  ~vertex_pages() { release(); }

  /// The word of grid point p, or null when its brick was never written (or this holds no
  /// table: a default-constructed one, as a uniform cut's root has).
  [[nodiscard]] T* find(const ipoint& p) const noexcept {
    if (top_ == nullptr) return nullptr;
    const level_point q = on_level(p);
    const block* b = top_[block_of(q)].load(std::memory_order_acquire);  // partner: install()
    if (b == nullptr) return nullptr;
    T* brick = b->bricks[brick_of(q)].load(std::memory_order_acquire);  // partner: install()
    return brick == nullptr ? nullptr : brick + offset_of(q);
  }
  [[nodiscard]] T* find(std::uint64_t index) const noexcept { return find(hier_->point(index)); }

  /// The word of grid point p, made (zeroed) when missing. Any thread.
  [[nodiscard]] T& at(const ipoint& p) {
    const level_point q = on_level(p);
    std::atomic<block*>& top = top_[block_of(q)];
    block* b = top.load(std::memory_order_acquire);  // partner: install()
    if (b == nullptr) [[unlikely]] {
      b = make_block(top);
    }
    std::atomic<T*>& slot = b->bricks[brick_of(q)];
    T* brick = slot.load(std::memory_order_acquire);  // partner: install()
    if (brick == nullptr) [[unlikely]] {
      brick = make_brick(slot);
    }
    return brick[offset_of(q)];
  }
  [[nodiscard]] T& at(std::uint64_t index) { return at(hier_->point(index)); }

  /// Asks for the cache line of p's word when its brick exists (a hint; never allocates).
  void prefetch(const ipoint& p) const noexcept {
    if (top_ == nullptr) return;
    const level_point q = on_level(p);
    // acquire: partner install(); the block's slots are read next, so its zeroing must be
    // ordered before that read. A stale null only skips the prefetch.
    const block* b = top_[block_of(q)].load(std::memory_order_acquire);
    if (b == nullptr) return;
    // relaxed: the brick is only prefetched, never read here.
    T* brick = b->bricks[brick_of(q)].load(std::memory_order_relaxed);
    if (brick != nullptr) __builtin_prefetch(brick + offset_of(q), 1);
  }

  /// Bytes held: the top table, block tables and bricks made since construction or clear().
  [[nodiscard]] std::size_t bytes() const noexcept {
    // relaxed: statistics.
    return count_ * sizeof(std::atomic<block*>) +
           blocks_made_.load(std::memory_order_relaxed) * sizeof(block) +
           bricks_made_.load(std::memory_order_relaxed) * brick_words * sizeof(T);
  }
  /// Bricks made since construction or the last clear().
  [[nodiscard]] std::size_t bricks() const noexcept {
    return bricks_made_.load(std::memory_order_relaxed);  // relaxed: a statistic
  }

  /// Frees every brick and block table: every word reads 0 again. No concurrent access.
  void clear() noexcept {
    for (std::uint64_t i = 0; i < count_; ++i) {
      // relaxed (both): no concurrent access (the caller's contract).
      delete top_[i].exchange(nullptr, std::memory_order_relaxed);
    }
    for (std::uint64_t i = 0; i < chunk_count_; ++i) {
      std::free(chunks_[i].exchange(nullptr, std::memory_order_relaxed));  // relaxed: as above
    }
    next_brick_.store(0, std::memory_order_relaxed);   // relaxed: no concurrent access
    bricks_made_.store(0, std::memory_order_relaxed);  // relaxed: no concurrent access
    blocks_made_.store(0, std::memory_order_relaxed);  // relaxed: no concurrent access
  }

 private:
  struct block {
    std::atomic<T*> bricks[block_bricks] = {};  // null: a brick never written
  };

  // A grid point as its level's lattice point (see the header).
  struct level_point {
    std::uint32_t x, y, z, t;
  };
  [[nodiscard]] static level_point on_level(const ipoint& p) noexcept {
    const auto x = static_cast<std::uint32_t>(p[0]);
    const auto y = static_cast<std::uint32_t>(p[1]);
    const auto z = static_cast<std::uint32_t>(p[2]);
    // The origin has no set bit: the top level's point 0 (no branch for it).
    const auto t = static_cast<std::uint32_t>(std::countr_zero(x | y | z | origin_level_bit));
    return {x >> t, y >> t, z >> t, t};
  }
  [[nodiscard]] std::uint64_t block_of(const level_point& q) const noexcept {
    constexpr int s = brick_bits + block_bits;
    const level& l = level_[q.t];
    return l.base + (std::uint64_t{q.x} >> s) +
           l.blocks[0] * ((std::uint64_t{q.y} >> s) + l.blocks[1] * (std::uint64_t{q.z} >> s));
  }
  [[nodiscard]] static std::size_t brick_of(const level_point& q) noexcept {
    constexpr std::uint32_t mask = (1u << block_bits) - 1;
    const auto c = [](std::uint32_t v) { return (v >> brick_bits) & mask; };
    return static_cast<std::size_t>(c(q.x) | c(q.y) << block_bits | c(q.z) << (2 * block_bits));
  }
  [[nodiscard]] static std::size_t offset_of(const level_point& q) noexcept {
    constexpr std::uint32_t mask = (1u << brick_bits) - 1;
    return static_cast<std::size_t>((q.x & mask) | (q.y & mask) << brick_bits |
                                    (q.z & mask) << (2 * brick_bits));
  }

  // Installs `fresh` (zeroed) in an empty slot and returns true; or, when another thread
  // installed one first, sets `fresh` to that one and returns false (the caller frees its own).
  template <class P>
  static bool install(std::atomic<P*>& slot, P*& fresh) noexcept {
    P* seen = nullptr;
    // acq_rel: the release publishes the zeroed memory to the acquire loads of find(), at() and
    // make_brick(); on failure the acquire reads the winner's, zeroed before its release.
    if (slot.compare_exchange_strong(seen, fresh, std::memory_order_acq_rel,
                                     std::memory_order_acquire)) {
      return true;
    }
    fresh = seen;
    return false;
  }

  block* make_block(std::atomic<block*>& slot) {
    block* const mine = new block;
    block* b = mine;
    if (install(slot, b)) {
      blocks_made_.fetch_add(1, std::memory_order_relaxed);  // relaxed: a statistic
    } else {
      delete mine;
    }
    return b;
  }
  // A zeroed brick from the chunks: a malloc per brick cost more than the refinement's own work
  // on the words. A brick lost to a racing thread stays unused (rare: two threads making the
  // same brick at once).
  T* make_brick(std::atomic<T*>& slot) {
    // relaxed: a ticket; the chunk it falls in is published by install().
    const std::uint64_t n = next_brick_.fetch_add(1, std::memory_order_relaxed);
    const std::uint64_t c = n / chunk_bricks;
    if (c >= chunk_count_) throw std::bad_alloc();          // more racing losses than provisioned
    T* chunk = chunks_[c].load(std::memory_order_acquire);  // partner: install()
    if (chunk == nullptr) {
      // calloc: a chunk this large is mapped fresh, its pages zeroed by the kernel when touched.
      T* const mine = static_cast<T*>(std::calloc(chunk_bricks * brick_words, sizeof(T)));
      if (mine == nullptr) throw std::bad_alloc();
      chunk = mine;
      if (!install(chunks_[c], chunk)) std::free(mine);
    }
    T* brick = chunk + (n % chunk_bricks) * brick_words;
    if (install(slot, brick)) {
      bricks_made_.fetch_add(1, std::memory_order_relaxed);  // relaxed: a statistic
    }
    return brick;
  }

  void take(vertex_pages& o) noexcept {
    hier_ = o.hier_;
    level_ = o.level_;
    count_ = std::exchange(o.count_, 0);
    top_ = std::exchange(o.top_, nullptr);
    chunk_count_ = std::exchange(o.chunk_count_, 0);
    chunks_ = std::exchange(o.chunks_, nullptr);
    next_brick_.store(o.next_brick_.exchange(0, std::memory_order_relaxed),
                      std::memory_order_relaxed);  // relaxed: no concurrent access
    // relaxed: no concurrent access while moving.
    bricks_made_.store(o.bricks_made_.exchange(0, std::memory_order_relaxed),
                       std::memory_order_relaxed);
    blocks_made_.store(o.blocks_made_.exchange(0, std::memory_order_relaxed),
                       std::memory_order_relaxed);
  }
  void release() noexcept {
    if (top_ == nullptr) return;
    clear();
    delete[] top_;
    delete[] chunks_;
    top_ = nullptr;
    chunks_ = nullptr;
  }

  // Level t's blocks: top_[base, base + blocks[0] * blocks[1] * blocks[2]).
  struct level {
    std::uint64_t base = 0;
    std::array<std::uint64_t, 3> blocks{};
  };
  static constexpr int max_levels = 17;  // coordinates below 2^16, and the origin's level
  static constexpr std::uint32_t origin_level_bit = std::uint32_t{1} << (max_levels - 1);

  const hierarchy* hier_ = nullptr;
  std::array<level, max_levels> level_{};
  std::uint64_t count_ = 0;  // blocks over all levels
  std::atomic<block*>* top_ = nullptr;
  static constexpr std::uint64_t chunk_bricks =
      (std::uint64_t{1} << 20) / (brick_words * sizeof(T));
  std::uint64_t chunk_count_ = 0;
  std::atomic<T*>* chunks_ = nullptr;  // bricks are carved from these, in order
  std::atomic<std::uint64_t> next_brick_{0};
  std::atomic<std::size_t> bricks_made_{0};
  std::atomic<std::size_t> blocks_made_{0};
};

}  // namespace progiso::detail
