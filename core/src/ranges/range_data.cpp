#include <progiso/core/ranges/range_data.hpp>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/ranges/detail/range_entry.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

namespace progiso {

struct range_data::impl {
  virtual ~impl() = default;
  [[nodiscard]] virtual diamond_range get(const diamond& d) const noexcept = 0;
  [[nodiscard]] virtual diamond_range get_at(const ipoint& c) const noexcept = 0;
  [[nodiscard]] virtual diamond_range get_at(const ipoint& c, std::int32_t h) const noexcept = 0;
  [[nodiscard]] virtual bool empty_at(const ipoint& c, std::int32_t h) const noexcept = 0;
  [[nodiscard]] virtual double error_at(const ipoint& c, std::int32_t h) const noexcept {
    return get_at(c, h).error;
  }
  // range_data::test_upto() and error_upto(): exact unless an implementation stops early.
  [[nodiscard]] virtual straddle_and_error test_upto(
      const ipoint& c, std::int32_t h, double /*bound*/,
      const detail::sample_threshold& w) const noexcept {
    const diamond_range r = get_at(c, h);
    return {r.straddles(w.w), r.error};
  }
  [[nodiscard]] virtual double error_upto(const ipoint& c, std::int32_t h,
                                          double /*bound*/) const noexcept {
    return error_at(c, h);
  }
  [[nodiscard]] virtual bool straddles_at(const ipoint& c, std::int32_t h,
                                          const detail::sample_threshold& w) const noexcept = 0;
  [[nodiscard]] virtual std::size_t byte_size() const noexcept = 0;
  // The staged build (range_data(…, staged)): independent pieces of the min/max pass, then
  // finish(); then those of the error pass, then finish_errors(), which sets errors_exact.
  [[nodiscard]] virtual std::size_t piece_count() const noexcept = 0;
  // Pieces read about the same unless an implementation knows better.
  [[nodiscard]] virtual std::uint64_t piece_work(std::size_t first,
                                                 std::size_t last) const noexcept {
    return last - first;
  }
  virtual void build_pieces(std::size_t first, std::size_t last, const parallel_loop& run) = 0;
  virtual void finish(const parallel_loop& run) = 0;
  [[nodiscard]] virtual std::size_t error_piece_count() const noexcept = 0;
  virtual void build_error_pieces(std::size_t first, std::size_t last,
                                  const parallel_loop& run) = 0;
  virtual void finish_errors(const parallel_loop& run) = 0;
  // range_data::piece_bytes(): none unless an implementation's pieces are plain bytes.
  [[nodiscard]] virtual std::span<std::byte> piece_bytes(std::size_t /*first*/,
                                                         std::size_t /*last*/) noexcept {
    return {};
  }
  // Both passes for pieces [first, last) (one task per piece reads its slab once into cache).
  virtual void build_both(std::size_t first, std::size_t last, const parallel_loop& run) {
    build_pieces(first, last, run);
    build_error_pieces(first, last, run);
  }
  // Set (release) once the error pass is finished; until then errors of scale ≥ 2 are hi − lo.
  std::atomic<bool> errors_exact{false};
  const volume* vol = nullptr;
  const hierarchy* hier = nullptr;

  [[nodiscard]] double value(const ipoint& p) const noexcept {
    return vol->value(p[0], p[1], p[2]);
  }

  // Own range: spine, ring (grid vertices only) and centre; empty when wholly in the padding.
  [[nodiscard]] diamond_range own(const diamond& d) const noexcept {
    diamond_range r;
    if (hier->outside_data(d.centre, d.scale)) return r;
    const double fc = value(d.centre);
    const double f0 = value(d.spine[0]);
    const double f1 = value(d.spine[1]);
    double lo = std::min({fc, f0, f1});
    double hi = std::max({fc, f0, f1});
    for (int m = 0; m < d.ring_size; ++m) {
      if (!((d.ring_in_grid >> m) & 1u)) continue;
      const double f = value(d.ring[static_cast<std::size_t>(m)]);
      lo = std::min(lo, f);
      hi = std::max(hi, f);
    }
    r.lo = lo;
    r.hi = hi;
    r.error = std::abs(fc - 0.5 * (f0 + f1));
    return r;
  }
};

namespace {

using detail::error_type;
using detail::quantize_error;

// The shape of a stencil: the subtree of the diamond centred at c, every vertex of every
// descendant's tetrahedra and every descendant's split (centre, spine ends), as grid offsets
// from c, sorted, without repeats. It depends only on c modulo 4, not on the volume, so it is found
// once per process by walking the subtree in a probe hierarchy (the walk is costly beside a
// range build; every range_data used to repeat it).
struct stencil_shape {
  bool used = false;
  std::vector<ipoint> points;
  std::vector<std::array<ipoint, 3>> splits;
  std::vector<std::array<std::uint8_t, 3>> split_index;  // the splits as indices into points
};

struct stencil_shapes {
  std::array<stencil_shape, 64> scale1;  // by class_of(c): c mod 4 per axis
};

stencil_shape walk_subtree(const hierarchy& probe, const ipoint& c) {
  std::vector<diamond> sub{probe.make_diamond(c)};
  std::vector<ipoint> seen{c};
  for (std::size_t k = 0; k < sub.size(); ++k) {
    std::array<ipoint, 8> ch{};
    const int n = probe.children(sub[k], ch);
    for (int i = 0; i < n; ++i) {
      const ipoint& x = ch[static_cast<std::size_t>(i)];
      if (std::find(seen.begin(), seen.end(), x) != seen.end()) continue;
      seen.push_back(x);
      sub.push_back(probe.make_diamond(x));
    }
  }
  stencil_shape shape;
  shape.used = true;
  const auto rel = [&](const ipoint& p) { return ipoint{p[0] - c[0], p[1] - c[1], p[2] - c[2]}; };
  for (const diamond& d : sub) {
    shape.points.push_back(rel(d.centre));
    shape.points.push_back(rel(d.spine[0]));
    shape.points.push_back(rel(d.spine[1]));
    for (int m = 0; m < d.ring_size; ++m) {
      shape.points.push_back(rel(d.ring[static_cast<std::size_t>(m)]));
    }
    shape.splits.push_back({rel(d.centre), rel(d.spine[0]), rel(d.spine[1])});
  }
  std::sort(shape.points.begin(), shape.points.end());
  shape.points.erase(std::unique(shape.points.begin(), shape.points.end()), shape.points.end());
  std::sort(shape.splits.begin(), shape.splits.end());
  shape.splits.erase(std::unique(shape.splits.begin(), shape.splits.end()), shape.splits.end());
  const auto index = [&](const ipoint& p) {
    const auto at = std::lower_bound(shape.points.begin(), shape.points.end(), p);
    return static_cast<std::uint8_t>(at - shape.points.begin());
  };
  for (const auto& t : shape.splits)
    shape.split_index.push_back({index(t[0]), index(t[1]), index(t[2])});
  return shape;
}

std::size_t class_of(const ipoint& c) noexcept {
  return static_cast<std::size_t>((c[0] & 3) | ((c[1] & 3) << 2) | ((c[2] & 3) << 4));
}

const stencil_shapes& stencil_shape_table() {
  // A function-local static: made once, thread-safe, on first use.
  static const stencil_shapes table = [] {
    stencil_shapes t;
    const hierarchy probe({33, 33, 33});
    for (std::int32_t cls = 0; cls < 64; ++cls) {
      const ipoint c{8 + (cls & 3), 8 + ((cls >> 2) & 3), 8 + ((cls >> 4) & 3)};
      if (((c[0] | c[1] | c[2]) & 1) == 0) continue;  // scale ≥ 2: stored, no stencil
      t.scale1[static_cast<std::size_t>(cls)] = walk_subtree(probe, c);
    }
    return t;
  }();
  return table;
}

// Diamonds of scale h ≥ 2: a min/max pyramid over bricks.
//
// Per axis, every vertex of every tetrahedron in the subtree of a diamond of scale h centred at c
// lies within c ± R, R = r h - 2 with r = 5 for cube centres, 4 for face centres, 3 for edge
// midpoints: the reach of a scale-1 edge midpoint is 1, and a face centre's children (edge
// midpoints at ± h), a cube centre's (face centres at ± h) and an edge midpoint's (cube centres
// at ± h/2, scale h/2) each add their offset, which solves to r h - 2. A child's box lies inside
// its parent's (h/2 + 5h/2 - 2 = 3h - 2, h + 4h - 2 = 5h - 2, h + 3h - 2 = 4h - 2).
//
// Level 0 of the pyramid holds, for every brick of 4 × 4 × 4 grid vertices, the min and max of
// the samples and the largest own split error |f(c) - (f(a) + f(b)) / 2| of the vertices in it
// (every vertex but a root-cube corner is a diamond centre with spine a, b); level k + 1 merges
// 2 × 2 × 2 bricks of level k. The bricks cover the grid and 4 vertices more on every side, with
// clamped samples (the padding's values, and those the scale-1 stencils read near the boundary),
// so the scale-1 stencils' ranges and errors lie inside every parent's. A diamond's range is the
// merge of the bricks that meet its box, at the finest level whose bricks are at least 2R / 3
// vertices wide (at most 4 bricks per axis, 64 in all). A superset of the subtree's values and
// errors, so sound for culling; nested, because a child's box lies in its parent's and a
// smaller box never takes a coarser level (each brick lies in one brick of every coarser
// level). Bytes: 3 samples per 64 vertices, plus 1/7 for the coarser levels: about 5% of the
// volume's. The build is one streaming pass, run in slabs of 4 planes by `parallel`.
template <class T>
class typed_range_data final : public range_data::impl {
  // Offsets of the samples and splits of a subtree of fixed shape (see make_stencils()).
  struct stencil {
    std::vector<std::int64_t> points;                 // linear offsets
    std::vector<std::array<std::int64_t, 3>> splits;  // centre, spine ends
    std::vector<ipoint> rel_points;                   // the same as grid offsets
    std::vector<std::array<ipoint, 3>> rel_splits;
    std::vector<std::array<std::uint8_t, 3>> split_index;  // `splits` as indices into `points`
    std::vector<std::int64_t> split_points;                // the points the splits read, ascending
    std::vector<std::array<std::uint8_t, 3>> split_local;  // `splits` as indices into them
  };
  // The most points a scale-1 stencil has (a cube centre's subtree: its 5 × 5 × 5 box at most).
  static constexpr std::size_t max_stencil_points = 125;
  using error_t = error_type<T>;
  struct brick {
    T lo;
    T hi;
    error_t error;
  };
  // Level 0's bricks are left uninitialised: build_minmax_slab() writes every brick's lo and hi,
  // build_error_slab() every brick's error (read only once errors_exact is set). A zero-filled
  // vector would fault its pages, one by one, on one thread before the parallel slabs start;
  // left to the slabs, each thread faults its own.
  template <class U>
  struct uninitialised_allocator : std::allocator<U> {
    template <class V>
    struct rebind {
      using other = uninitialised_allocator<V>;
    };
    template <class V>
    void construct(V* p) noexcept(std::is_nothrow_default_constructible_v<V>) {
      ::new (static_cast<void*>(p)) V;  // default-initialised: nothing written for a brick
    }
    template <class V, class... Args>
    void construct(V* p, Args&&... args) {
      ::new (static_cast<void*>(p)) V(std::forward<Args>(args)...);
    }
  };
  struct level {
    ipoint n{};  // bricks per axis
    std::vector<brick, uninitialised_allocator<brick>> bricks;
    [[nodiscard]] const brick& at(std::int32_t x, std::int32_t y, std::int32_t z) const noexcept {
      return bricks[static_cast<std::size_t>(x) +
                    static_cast<std::size_t>(n[0]) *
                        (static_cast<std::size_t>(y) +
                         static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(z))];
    }
  };
  static constexpr std::int32_t origin = -4;  // the bricks' first vertex on every axis

 public:
  // Allocates the pyramid's finest level; build_pieces() and finish() fill it.
  typed_range_data(const volume& v, const hierarchy& h) {
    vol = &v;
    hier = &h;
    samples_ = v.visit_samples([](const auto* p) { return reinterpret_cast<const T*>(p); });
    make_stencils();
    allocate();
  }

  [[nodiscard]] std::size_t piece_count() const noexcept override {
    return static_cast<std::size_t>(levels_[0].n[2]);
  }
  // The sample planes each slab reads (build_minmax_slab's clamped z range).
  [[nodiscard]] std::uint64_t piece_work(std::size_t first,
                                         std::size_t last) const noexcept override {
    const std::int32_t dz = hier->data_max()[2];
    std::uint64_t planes = 0;
    for (std::size_t k = first; k < last; ++k) {
      const auto kz = static_cast<std::int32_t>(k);
      const std::int32_t z0 = std::clamp(origin + 4 * kz, 0, dz);
      const std::int32_t z1 = std::clamp(origin + 4 * kz + 3, 0, dz);
      planes += static_cast<std::uint64_t>(z1 - z0 + 1);
    }
    return planes;
  }
  void build_pieces(std::size_t first, std::size_t last,
                    const range_data::parallel_loop& run) override {
    run_loop(run, last - first, [this, first](std::size_t k) {
      build_minmax_slab(static_cast<std::int32_t>(first + k));
    });
  }
  [[nodiscard]] std::size_t error_piece_count() const noexcept override { return piece_count(); }
  // Piece kz is plane kz of level 0 (build_minmax_slab and build_error_slab write nothing else).
  [[nodiscard]] std::span<std::byte> piece_bytes(std::size_t first,
                                                 std::size_t last) noexcept override {
    static_assert(std::is_trivially_copyable_v<brick>);
    level& l0 = levels_[0];
    const std::size_t plane = static_cast<std::size_t>(l0.n[0]) * static_cast<std::size_t>(l0.n[1]);
    return {reinterpret_cast<std::byte*>(l0.bricks.data() + first * plane),
            (last - first) * plane * sizeof(brick)};
  }
  void build_both(std::size_t first, std::size_t last,
                  const range_data::parallel_loop& run) override {
    run_loop(run, last - first, [this, first](std::size_t k) {
      build_minmax_slab(static_cast<std::int32_t>(first + k));
      build_error_slab(static_cast<std::int32_t>(first + k));
    });
  }
  void build_error_pieces(std::size_t first, std::size_t last,
                          const range_data::parallel_loop& run) override {
    run_loop(run, last - first, [this, first](std::size_t k) {
      build_error_slab(static_cast<std::int32_t>(first + k));
    });
  }

  [[nodiscard]] diamond_range get(const diamond& d) const noexcept override {
    return get_at(d.centre, d.scale);
  }

  [[nodiscard]] diamond_range get_at(const ipoint& c) const noexcept override {
    return get_at(c, hier->scale_of(c));
  }

  [[nodiscard]] bool straddles_at(const ipoint& c, std::int32_t h,
                                  const detail::sample_threshold& w) const noexcept override {
    if (h != 1) {
      bool high = false;
      bool low = false;
      return visit_box(c, h, [&](const brick& b) {
               high = high || w.above(b.hi);
               low = low || !w.above(b.lo);
               return !(high && low);
             }) == visit::stopped;
    }
    const place where = scale1_place(c);
    if (where == place::outside) return false;  // empty: wholly in the padding
    const stencil& st = stencils_[class_of(c)];
    if (where == place::inside) {
      const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
      return straddle_over([base](std::int64_t o) { return base[o]; }, st.points, w);
    }
    return straddle_over(clamped_reader(c), st.rel_points, w);
  }

  [[nodiscard]] bool empty_at(const ipoint& c, std::int32_t h) const noexcept override {
    if (h == 1) return scale1_place(c) == place::outside;
    return outside(c, h);
  }

  [[nodiscard]] double error_at(const ipoint& c, std::int32_t h) const noexcept override {
    if (h != 1) return get_at(c, h).error;
    const place where = scale1_place(c);
    if (where != place::inside) return scale1_at(c).error;
    const stencil& st = stencils_[class_of(c)];
    const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
    std::array<T, max_stencil_points> v;  // NOLINT(cppcoreguidelines-pro-type-member-init)
    for (std::size_t i = 0; i < st.split_points.size(); ++i) v[i] = base[st.split_points[i]];
    return split_error([&v](std::uint8_t k) { return v[k]; }, st.split_local);
  }

  // Both stop reading once the answer is known. Scale ≥ 2 (exact errors): the bricks are
  // visited until the range is known to straddle w and the error to exceed `bound` (a coarse
  // diamond's error mostly does after a few of its up to 64 bricks). Scale 1 inside the data
  // box: the splits' errors until one exceeds `bound`, then the straddle test, which stops at
  // the first samples on both sides, instead of the whole stencil's range and every split.
  [[nodiscard]] straddle_and_error test_upto(
      const ipoint& c, std::int32_t h, double bound,
      const detail::sample_threshold& w) const noexcept override {
    if (h == 1) {
      const place where = scale1_place(c);
      if (where == place::outside) return {false, 0.0};
      if (where == place::across) return range_data::impl::test_upto(c, h, bound, w);
      const stencil& st = stencils_[class_of(c)];
      const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
      const auto at = [base](std::int64_t o) { return base[o]; };
      return {straddle_over(at, st.points, w), split_error(at, st.splits, bound)};
    }
    // acquire: pairs with the release in finish_errors(); the bricks' errors are then written.
    if (!errors_exact.load(std::memory_order_acquire)) {
      return range_data::impl::test_upto(c, h, bound, w);
    }
    error_t err{};
    bool high = false;
    bool low = false;
    (void)visit_box(c, h, [&](const brick& b) {
      err = b.error > err ? b.error : err;
      high = high || w.above(b.hi);
      low = low || !w.above(b.lo);
      return !(high && low && static_cast<double>(err) > bound);
    });
    return {high && low, static_cast<double>(err)};
  }

  [[nodiscard]] double error_upto(const ipoint& c, std::int32_t h,
                                  double bound) const noexcept override {
    if (h == 1) {
      if (scale1_place(c) != place::inside) return error_at(c, h);
      const stencil& st = stencils_[class_of(c)];
      const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
      return split_error([base](std::int64_t o) { return base[o]; }, st.splits, bound);
    }
    // acquire: pairs with the release in finish_errors(); the bricks' errors are then written.
    if (!errors_exact.load(std::memory_order_acquire)) return error_at(c, h);
    error_t err{};
    (void)visit_box(c, h, [&](const brick& b) {
      err = b.error > err ? b.error : err;
      return !(static_cast<double>(err) > bound);
    });
    return static_cast<double>(err);
  }

  [[nodiscard]] diamond_range get_at(const ipoint& c, std::int32_t h) const noexcept override {
    if (h == 1) return scale1_at(c);
    T lo = std::numeric_limits<T>::max();
    T hi = std::numeric_limits<T>::lowest();
    error_t err{};
    // acquire: pairs with the release in finish_errors(); the bricks' errors are then written.
    const bool exact = errors_exact.load(std::memory_order_acquire);
    if (visit_box(c, h, [&](const brick& b) {
          lo = b.lo < lo ? b.lo : lo;
          hi = b.hi > hi ? b.hi : hi;
          if (exact) err = b.error > err ? b.error : err;
          return true;
        }) == visit::empty) {
      return {};
    }
    diamond_range r;
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    // Before the error pass: hi − lo, a bound on every split error between values in [lo, hi],
    // still nested (a child's range lies in its parent's).
    r.error = exact ? static_cast<double>(err) : r.hi - r.lo;
    return r;
  }

  [[nodiscard]] std::size_t byte_size() const noexcept override {
    std::size_t b = 0;
    for (const auto& lv : levels_) b += lv.bricks.size() * sizeof(brick);
    return b;
  }

 private:
  // Box radius (see above) of the diamond centred at c of scale h ≥ 2.
  [[nodiscard]] static std::int32_t reach(const ipoint& c, std::int32_t h) noexcept {
    const int odd = ((c[0] / h) & 1) + ((c[1] / h) & 1) + ((c[2] / h) & 1);  // 3 - type
    return (2 + odd) * h - 2;
  }
  [[nodiscard]] bool outside(const ipoint& c, std::int32_t h) const noexcept {
    const std::int32_t r = reach(c, h);
    const ipoint& dm = hier->data_max();
    return c[0] - r >= dm[0] || c[1] - r >= dm[1] || c[2] - r >= dm[2];
  }

  enum class visit { empty, done, stopped };
  // Calls f(brick) for the bricks that meet the box of the diamond centred at c (scale h ≥ 2)
  // until f returns false.
  template <class F>
  visit visit_box(const ipoint& c, std::int32_t h, F&& f) const noexcept {
    if (outside(c, h)) return visit::empty;
    const std::int32_t r = reach(c, h);
    std::size_t k = 0;
    while (k + 1 < levels_.size() && 3 * (std::int32_t{4} << k) < 2 * r) ++k;
    const level& lv = levels_[k];
    const int shift = 2 + static_cast<int>(k);
    ipoint b0{};
    ipoint b1{};
    for (std::size_t q = 0; q < 3; ++q) {
      b0[q] = std::max(c[q] - r - origin, 0) >> shift;
      b1[q] = std::min((c[q] + r - origin) >> shift, lv.n[q] - 1);
    }
    for (std::int32_t z = b0[2]; z <= b1[2]; ++z) {
      for (std::int32_t y = b0[1]; y <= b1[1]; ++y) {
        for (std::int32_t x = b0[0]; x <= b1[0]; ++x) {
          if (!f(lv.at(x, y, z))) return visit::stopped;
        }
      }
    }
    return visit::done;
  }

  // ---- the build -----------------------------------------------------------------------------

  // Sample at grid vertex p (any integer point), clamped into the data box.
  [[nodiscard]] T clamped(std::int32_t x, std::int32_t y, std::int32_t z) const noexcept {
    const ipoint& dm = hier->data_max();
    return samples_[vol->linear(std::clamp(x, 0, dm[0]), std::clamp(y, 0, dm[1]),
                                std::clamp(z, 0, dm[2]))];
  }

  // Own split error of the vertex p, from clamped samples; 0 for root-cube corners.
  [[nodiscard]] double own_error(std::int32_t x, std::int32_t y, std::int32_t z) const noexcept {
    const int cap = hier->levels();
    const auto tz = [cap](std::int32_t v) {
      return v == 0 ? cap : std::min(cap, std::countr_zero(static_cast<std::uint32_t>(v)));
    };
    const int lg = std::min({tz(x), tz(y), tz(z)});
    if (lg >= cap) return 0.0;
    const std::int32_t h = std::int32_t{1} << lg;
    const ipoint c{x, y, z};
    ipoint s{};
    for (std::size_t q = 0; q < 3; ++q) {
      s[q] = ((c[q] >> lg) & 1) == 0 ? 0 : (((c[q] + h) & (4 * h - 1)) == 0 ? h : -h);
    }
    const double fc = static_cast<double>(clamped(x, y, z));
    const double fa = static_cast<double>(clamped(x - s[0], y - s[1], z - s[2]));
    const double fb = static_cast<double>(clamped(x + s[0], y + s[1], z + s[2]));
    return std::abs(fc - 0.5 * (fa + fb));
  }

  // Spine step of a scale-1 vertex along an axis where its coordinate is v: 0 when v is even,
  // else +1 when v = 3 mod 4, -1 when v = 1 mod 4.
  static std::int32_t unit_step(std::int32_t v) noexcept {
    return (v & 1) == 0 ? 0 : ((v & 3) == 3 ? 1 : -1);
  }

  // Level 0 (the bricks of plane slab kz are build_slab(kz)), then the coarser levels (finish).
  void allocate() {
    const ipoint& gm = hier->grid_max();
    level l0;
    for (std::size_t q = 0; q < 3; ++q) l0.n[q] = (gm[q] + 4 - origin) / 4 + 1;
    l0.bricks.resize(static_cast<std::size_t>(l0.n[0]) * static_cast<std::size_t>(l0.n[1]) *
                     static_cast<std::size_t>(l0.n[2]));
    levels_.push_back(std::move(l0));
  }

 public:
  // The coarser levels, each from the one below it, one plane of bricks per item of `run`
  // (every plane of a level is independent; run alone on one thread it was a large part of the
  // whole build at many threads; bench/README.md).
  void finish(const range_data::parallel_loop& run) override {
    PROGISO_ASSERT(levels_.size() == 1);
    while (levels_.back().n[0] > 1 || levels_.back().n[1] > 1 || levels_.back().n[2] > 1) {
      const level& fine = levels_.back();
      level coarse;
      for (std::size_t q = 0; q < 3; ++q) coarse.n[q] = (fine.n[q] + 1) / 2;
      // Uninitialised: every brick is written below.
      coarse.bricks.resize(static_cast<std::size_t>(coarse.n[0]) *
                           static_cast<std::size_t>(coarse.n[1]) *
                           static_cast<std::size_t>(coarse.n[2]));
      by_planes(coarse, run, [&](brick& out, std::int32_t x, std::int32_t y, std::int32_t z) {
        // lo and hi only: a level-0 brick's error is unwritten until the error pass.
        const brick& first = fine.at(2 * x, 2 * y, 2 * z);
        brick m{first.lo, first.hi, error_t{}};
        for (int d = 1; d < 8; ++d) {
          const brick* b = covered(fine, x, y, z, d);
          if (b == nullptr) continue;
          m.lo = b->lo < m.lo ? b->lo : m.lo;
          m.hi = b->hi > m.hi ? b->hi : m.hi;
        }
        out = m;
      });
      levels_.push_back(std::move(coarse));
    }
  }

  // The coarser levels' errors, from level 0's (finish() made the levels): each coarse brick's
  // is the largest of the bricks it covers, one plane of a level per item of `run`.
  void finish_errors(const range_data::parallel_loop& run) override {
    PROGISO_ASSERT(levels_.size() > 1 || levels_[0].bricks.size() == 1);
    for (std::size_t k = 1; k < levels_.size(); ++k) {
      const level& fine = levels_[k - 1];
      level& coarse = levels_[k];
      by_planes(coarse, run, [&](brick& out, std::int32_t x, std::int32_t y, std::int32_t z) {
        error_t m{};
        for (int d = 0; d < 8; ++d) {
          const brick* b = covered(fine, x, y, z, d);
          if (b != nullptr) m = b->error > m ? b->error : m;
        }
        out.error = m;
      });
    }
    // release: pairs with the acquire in get_at(); the errors above are written before it.
    errors_exact.store(true, std::memory_order_release);
  }

 private:
  // f(brick, x, y, z) for every brick of `lv`, one plane (z) per item of `run`: each item writes
  // only the bricks of its own plane.
  template <class F>
  static void by_planes(level& lv, const range_data::parallel_loop& run, const F& f) {
    run_loop(run, static_cast<std::size_t>(lv.n[2]), [&](std::size_t item) {
      const auto z = static_cast<std::int32_t>(item);
      brick* out =
          &lv.bricks[static_cast<std::size_t>(lv.n[0]) * static_cast<std::size_t>(lv.n[1]) * item];
      for (std::int32_t y = 0; y < lv.n[1]; ++y) {
        for (std::int32_t x = 0; x < lv.n[0]; ++x) f(*out++, x, y, z);
      }
    });
  }

  // Brick d (0 … 7) of `fine` under the brick (x, y, z) of the level above it, or null past
  // the far faces of an odd-sized `fine`.
  [[nodiscard]] static const brick* covered(const level& fine, std::int32_t x, std::int32_t y,
                                            std::int32_t z, int d) noexcept {
    const std::int32_t fx = 2 * x + (d & 1);
    const std::int32_t fy = 2 * y + ((d >> 1) & 1);
    const std::int32_t fz = 2 * z + ((d >> 2) & 1);
    if (fx >= fine.n[0] || fy >= fine.n[1] || fz >= fine.n[2]) return nullptr;
    return &fine.at(fx, fy, fz);
  }

  // One slab of level-0 bricks' errors: 4 planes of vertices, row by row. Bricks whose vertices
  // and spine ends all lie in the data box take fixed offsets, by the row's kind (which axes of y,
  // z are odd) and x mod 4; the others, and vertices of scale ≥ 4, take own_error().
  void build_error_slab(std::int32_t kz) {
    level& l0 = levels_[0];
    const ipoint& dm = hier->data_max();
    const std::int32_t nx = l0.n[0];
    std::vector<double> err(static_cast<std::size_t>(nx) * static_cast<std::size_t>(l0.n[1]), 0.0);
    const auto row_of = [&](std::int32_t y, std::int32_t z) {
      return samples_ + vol->linear(0, std::clamp(y, 0, dm[1]), std::clamp(z, 0, dm[2]));
    };
    // Bricks [x0, x0 + 3] with x0 - 2 ≥ 0 and x0 + 5 ≤ data_max: no clamping on x.
    const std::int32_t fast_lo = std::max(0, (2 - origin + 3) / 4);
    const std::int32_t fast_hi = std::min(nx - 1, (dm[0] - 5 - origin) / 4);
    const bool scale2_rows = hier->levels() >= 2;  // else x = 2 mod 4 is a root corner
    const auto d = [](T v) { return static_cast<double>(v); };
    const auto e3 = [](double c, double a, double b) { return std::abs(c - 0.5 * (a + b)); };
    for (std::int32_t z = origin + 4 * kz; z < origin + 4 * kz + 4; ++z) {
      for (std::int32_t y = origin; y < origin + 4 * l0.n[1]; ++y) {
        const T* own = row_of(y, z);
        const std::size_t first =
            static_cast<std::size_t>(nx) * static_cast<std::size_t>((y - origin) >> 2);
        const std::int32_t sy = unit_step(y);
        const std::int32_t sz = unit_step(z);
        const bool odd_row = sy != 0 || sz != 0;  // every vertex of the row has scale 1
        // Odd rows: the spine ends' rows. Even rows: those of the scale-2 vertices (x = 2 mod 4,
        // and x = 0 mod 4 when y or z is 2 mod 4).
        const std::int32_t sy2 = (y & 3) == 2 ? ((y & 7) == 6 ? 2 : -2) : 0;
        const std::int32_t sz2 = (z & 3) == 2 ? ((z & 7) == 6 ? 2 : -2) : 0;
        const T* a_row = odd_row ? row_of(y - sy, z - sz) : row_of(y - sy2, z - sz2);
        const T* b_row = odd_row ? row_of(y + sy, z + sz) : row_of(y + sy2, z + sz2);
        const bool x0_scale2 = sy2 != 0 || sz2 != 0;
        for (std::int32_t bx = 0; bx < nx; ++bx) {
          const std::int32_t x0 = origin + 4 * bx;
          double e = 0.0;
          if (bx >= fast_lo && bx <= fast_hi && (odd_row || scale2_rows)) {
            const T* f = own + x0;
            const T* a = a_row + x0;
            const T* b = b_row + x0;
            if (odd_row) {
              // x0: spine (0, sy, sz); x0 + 1: (-1, ...); x0 + 2: (0, ...); x0 + 3: (+1, ...).
              e = std::max(std::max(e3(d(f[0]), d(a[0]), d(b[0])), e3(d(f[1]), d(a[2]), d(b[0]))),
                           std::max(e3(d(f[2]), d(a[2]), d(b[2])), e3(d(f[3]), d(a[2]), d(b[4]))));
            } else {
              const std::int32_t sx2 = ((x0 + 2) & 7) == 6 ? 2 : -2;
              e = std::max(std::max(e3(d(f[1]), d(f[0]), d(f[2])), e3(d(f[3]), d(f[2]), d(f[4]))),
                           e3(d(f[2]), d(a[2 - sx2]), d(b[2 + sx2])));
              e = std::max(e, x0_scale2 ? e3(d(f[0]), d(a[0]), d(b[0])) : own_error(x0, y, z));
            }
          } else {
            for (std::int32_t x = x0; x < x0 + 4; ++x) e = std::max(e, own_error(x, y, z));
          }
          const std::size_t s = first + static_cast<std::size_t>(bx);
          err[s] = std::max(err[s], e);
        }
      }
    }
    brick* out = l0.bricks.data() + static_cast<std::size_t>(kz) * err.size();
    for (std::size_t s = 0; s < err.size(); ++s) out[s].error = quantize_error<error_t>(err[s]);
  }

  // One slab of level-0 bricks' min and max: per row of bricks, the 16 sample rows (4 y × 4 z,
  // clamped into the data box) reduced element by element in the sample type (vectorised by
  // the compiler), then each brick's 4 columns (clamped the same way).
  void build_minmax_slab(std::int32_t kz) {
    level& l0 = levels_[0];
    const ipoint& dm = hier->data_max();
    const auto width = static_cast<std::size_t>(dm[0]) + 1;
    std::vector<T> rlo(width);
    std::vector<T> rhi(width);
    for (std::int32_t by = 0; by < l0.n[1]; ++by) {
      std::fill(rlo.begin(), rlo.end(), std::numeric_limits<T>::max());
      std::fill(rhi.begin(), rhi.end(), std::numeric_limits<T>::lowest());
      // Distinct clamped rows only (beyond the data box they repeat its last one).
      const std::int32_t y0 = std::clamp(origin + 4 * by, 0, dm[1]);
      const std::int32_t y1 = std::clamp(origin + 4 * by + 3, 0, dm[1]);
      const std::int32_t z0 = std::clamp(origin + 4 * kz, 0, dm[2]);
      const std::int32_t z1 = std::clamp(origin + 4 * kz + 3, 0, dm[2]);
      for (std::int32_t z = z0; z <= z1; ++z) {
        for (std::int32_t y = y0; y <= y1; ++y) {
          const T* row = samples_ + vol->linear(0, y, z);
          T* lo = rlo.data();
          T* hi = rhi.data();
          for (std::size_t x = 0; x < width; ++x) {
            const T v = row[x];
            lo[x] = v < lo[x] ? v : lo[x];
            hi[x] = v > hi[x] ? v : hi[x];
          }
        }
      }
      brick* out = &l0.bricks[static_cast<std::size_t>(l0.n[0]) *
                              (static_cast<std::size_t>(by) +
                               static_cast<std::size_t>(l0.n[1]) * static_cast<std::size_t>(kz))];
      for (std::int32_t bx = 0; bx < l0.n[0]; ++bx) {
        const std::int32_t x0 = std::clamp(origin + 4 * bx, 0, dm[0]);
        const std::int32_t x1 = std::clamp(origin + 4 * bx + 3, 0, dm[0]);
        T l = std::numeric_limits<T>::max();
        T u = std::numeric_limits<T>::lowest();
        for (std::int32_t x = x0; x <= x1; ++x) {
          l = rlo[static_cast<std::size_t>(x)] < l ? rlo[static_cast<std::size_t>(x)] : l;
          u = rhi[static_cast<std::size_t>(x)] > u ? rhi[static_cast<std::size_t>(x)] : u;
        }
        out[bx].lo = l;
        out[bx].hi = u;
      }
    }
  }

  // Nested range of a scale-1 diamond: a stencil read away from the data boundary, the
  // definition (own range and descendants') near it.
  [[nodiscard]] diamond_range scale1_at(const ipoint& c) const noexcept {
    // Empty when the subtree lies wholly in the padding. Its reach per axis: 1 for an edge
    // midpoint; for a face centre 2 along its odd axes and 1 along the even one; 2 for a cube
    // centre. These nest: a child's reach plus its offset never exceeds its parent's.
    // The stencil is read directly when the subtree lies in the data box, clamped otherwise.
    const place where = scale1_place(c);
    if (where == place::outside) return {};
    const stencil& st = stencils_[class_of(c)];
    return where == place::inside ? read_stencil(st, c) : read_stencil_clamped(st, c);
  }

  // Where the subtree of the scale-1 diamond centred at c lies: wholly in the padding (its range
  // is empty), wholly in the data box (its stencil is read directly), or across the box's faces.
  enum class place { outside, inside, across };
  [[nodiscard]] place scale1_place(const ipoint& c) const noexcept {
    const ipoint& dmax = hier->data_max();
    bool inside = true;
    for (std::size_t q = 0; q < 3; ++q) {
      const std::int32_t reach = scale1_reach(c, q);
      if (c[q] - reach >= dmax[q]) return place::outside;
      inside = inside && c[q] - reach >= 0 && c[q] + reach <= dmax[q];
    }
    return inside ? place::inside : place::across;
  }

  // How far the subtree of the scale-1 diamond centred at c reaches along axis q (make_stencils
  // checks it against every stencil).
  static std::int32_t scale1_reach(const ipoint& c, std::size_t q) noexcept {
    const int odd = (c[0] & 1) + (c[1] & 1) + (c[2] & 1);
    return odd == 1 ? 1 : (odd == 3 ? 2 : ((c[q] & 1) ? 2 : 1));
  }

  // Near the data boundary the same stencil is read with clamped samples (padding and points
  // beyond the grid take the nearest data value): a superset of the exact range and error, so
  // still sound for culling and still nested, since every caller uses this same function.
  [[nodiscard]] diamond_range read_stencil_clamped(const stencil& st,
                                                   const ipoint& c) const noexcept {
    return summarise(clamped_reader(c), st.rel_points, st.rel_splits);
  }

  // Samples at c + o, o a stencil offset, with clamped coordinates. Offsets lie in [-2, 2] per
  // axis: the clamped coordinates' shares of the linear index are computed once per diamond.
  struct clamped_samples {
    const T* samples;
    std::array<std::array<std::int64_t, 7>, 3> part;
    T operator()(const ipoint& o) const noexcept {
      return samples[part[0][static_cast<std::size_t>(o[0] + 3)] +
                     part[1][static_cast<std::size_t>(o[1] + 3)] +
                     part[2][static_cast<std::size_t>(o[2] + 3)]];
    }
  };
  [[nodiscard]] clamped_samples clamped_reader(const ipoint& c) const noexcept {
    const index3& d = vol->dims();
    const std::array<std::int64_t, 3> stride{1, d[0], d[0] * d[1]};
    clamped_samples r{samples_, {}};
    for (std::size_t q = 0; q < 3; ++q) {
      for (std::size_t k = 0; k < 7; ++k) {
        const std::int64_t v = std::int64_t{c[q]} + static_cast<std::int64_t>(k) - 3;
        r.part[q][k] = std::clamp<std::int64_t>(v, 0, d[q] - 1) * stride[q];
      }
    }
    return r;
  }

  // Whether the samples at(p), p = 0 and every p in `points`, straddle w, as summarise()'s
  // range would (lo <= w < hi), stopping as soon as they do.
  template <class At, class Point>
  [[nodiscard]] static bool straddle_over(const At& at, const std::vector<Point>& points,
                                          const detail::sample_threshold& w) {
    const T first = at(Point{});
    if constexpr (!std::is_integral_v<T>) {
      if (first != first) return false;  // NaN first: summarise()'s lo and hi stay NaN
    }
    bool high = w.above(first);
    bool low = !high;
    for (const Point& o : points) {
      const T v = at(o);
      if (w.above(v)) {
        high = true;
      } else if (v == v) {  // not NaN: NaN never becomes lo or hi
        low = true;
      }
      if (high && low) return true;
    }
    return false;
  }

  // The largest split error |f(c) − (f(a) + f(b)) / 2| over `splits` (centre, spine ends), each
  // sample read as at(point). Integers: twice the error, |2 f(c) − f(a) − f(b)|, in integers,
  // exact for every integer sample type (at most 34 bits); half of it is the same double as the
  // floating formula.
  //
  // With a `bound`, it stops at the first split whose error exceeds it: the largest when that
  // is at most the bound, else a value above it.
  template <class At, class Split>
  [[nodiscard]] static double split_error(const At& at, const std::vector<Split>& splits,
                                          double bound = std::numeric_limits<double>::infinity()) {
    if constexpr (std::is_integral_v<T>) {
      std::int64_t twice = 0;
      for (const auto& s : splits) {
        const std::int64_t e = 2 * static_cast<std::int64_t>(at(s[0])) -
                               static_cast<std::int64_t>(at(s[1])) -
                               static_cast<std::int64_t>(at(s[2]));
        twice = std::max(twice, e < 0 ? -e : e);
        if (0.5 * static_cast<double>(twice) > bound) break;
      }
      return 0.5 * static_cast<double>(twice);
    } else {
      double err = 0.0;
      for (const auto& s : splits) {
        const double e =
            std::abs(static_cast<double>(at(s[0])) -
                     0.5 * (static_cast<double>(at(s[1])) + static_cast<double>(at(s[2]))));
        err = e > err ? e : err;
        if (err > bound) break;
      }
      return err;
    }
  }

  // Range of the samples at(p) for p = 0 and every p in `points`, and the largest split error
  // |at(c) - (at(a) + at(b)) / 2| over the (c, a, b) in `splits`. NaN samples never replace a
  // number (comparisons with NaN are false).
  template <class At, class Point>
  [[nodiscard]] static diamond_range summarise(const At& at, const std::vector<Point>& points,
                                               const std::vector<std::array<Point, 3>>& splits) {
    const T first = at(Point{});
    T lo = first;
    T hi = first;
    for (const Point& o : points) {
      const T v = at(o);
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    const double err = split_error(at, splits);
    diamond_range r;
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    r.error = err;
    return r;
  }

  // ---- Scale-1 diamonds away from the data boundary: fixed stencils. -------------------------
  // The subtree of a scale-1 diamond (a cube centre: itself, 6 face centres, 12 edge midpoints;
  // a face centre: itself and 4 edge midpoints; an edge midpoint: itself) has a shape that
  // depends only on c mod 4, so its vertices and split errors are read through offset tables
  // built once from the hierarchy itself, straight from the typed samples.

  // A stencil in this volume's layout: the class's relative offsets (stencil_shapes()) as
  // linear offsets, sorted and without repeats (on a thin volume two grid offsets can share one).
  [[nodiscard]] stencil make_stencil(const stencil_shape& shape) const {
    const auto& dims = vol->dims();
    const auto lin = [&](const ipoint& o) {
      return o[0] + dims[0] * (o[1] + dims[1] * std::int64_t{o[2]});
    };
    stencil st;
    st.rel_points = shape.points;
    st.rel_splits = shape.splits;
    for (const ipoint& o : shape.points) st.points.push_back(lin(o));
    for (const auto& t : shape.splits) st.splits.push_back({lin(t[0]), lin(t[1]), lin(t[2])});
    std::sort(st.points.begin(), st.points.end());
    st.points.erase(std::unique(st.points.begin(), st.points.end()), st.points.end());
    std::sort(st.splits.begin(), st.splits.end());
    st.splits.erase(std::unique(st.splits.begin(), st.splits.end()), st.splits.end());
    PROGISO_ASSERT(st.points.size() <= max_stencil_points);
    const auto index = [&](std::int64_t o) {
      const auto at = std::lower_bound(st.points.begin(), st.points.end(), o);
      PROGISO_ASSERT(at != st.points.end() && *at == o);
      return static_cast<std::uint8_t>(at - st.points.begin());
    };
    for (const auto& t : st.splits)
      st.split_index.push_back({index(t[0]), index(t[1]), index(t[2])});
    for (const auto& t : st.splits)
      st.split_points.insert(st.split_points.end(), t.begin(), t.end());
    std::sort(st.split_points.begin(), st.split_points.end());
    st.split_points.erase(std::unique(st.split_points.begin(), st.split_points.end()),
                          st.split_points.end());
    const auto local = [&](std::int64_t o) {
      return static_cast<std::uint8_t>(
          std::lower_bound(st.split_points.begin(), st.split_points.end(), o) -
          st.split_points.begin());
    };
    for (const auto& t : st.splits)
      st.split_local.push_back({local(t[0]), local(t[1]), local(t[2])});
    return st;
  }

  // Scale-1 diamonds: one stencil per c mod 4. The shapes are made once per process.
  void make_stencils() {
    const stencil_shapes& shapes = stencil_shape_table();
    for (std::size_t cls = 0; cls < shapes.scale1.size(); ++cls) {
      if (!shapes.scale1[cls].used) continue;
      stencils_[cls] = make_stencil(shapes.scale1[cls]);
#if defined(PROGISO_ENABLE_ASSERTS)
      const auto k = static_cast<std::int32_t>(cls);
      const ipoint c{8 + (k & 3), 8 + ((k >> 2) & 3), 8 + ((k >> 4) & 3)};
      for (const ipoint& o : shapes.scale1[cls].points) {
        for (std::size_t q = 0; q < 3; ++q) PROGISO_ASSERT(std::abs(o[q]) <= scale1_reach(c, q));
      }
#endif
    }
  }

  // The stencil's samples are read once into a local array and the splits' errors computed from
  // it (a split's three samples are points of the stencil): the same range and error as
  // summarise(), with a third of its sample loads. An error-driven refinement computes one per
  // ready scale-1 diamond, ~7 in 8 of all.
  [[nodiscard]] diamond_range read_stencil(const stencil& st, const ipoint& c) const noexcept {
    const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
    std::array<T, max_stencil_points> v;  // NOLINT(cppcoreguidelines-pro-type-member-init)
    const std::size_t n = st.points.size();
    // Two minima and maxima in turn: one chain of 125 dependent min/max instructions was most of
    // the time. A NaN sample is skipped, a NaN centre makes the range NaN, as in summarise().
    const T first = base[0];
    T lo0 = first;
    T hi0 = first;
    T lo1 = first;
    T hi1 = first;
    std::size_t i = 0;
    for (; i + 2 <= n; i += 2) {
      const T x = base[st.points[i]];
      const T y = base[st.points[i + 1]];
      v[i] = x;
      v[i + 1] = y;
      lo0 = x < lo0 ? x : lo0;
      hi0 = x > hi0 ? x : hi0;
      lo1 = y < lo1 ? y : lo1;
      hi1 = y > hi1 ? y : hi1;
    }
    if (i < n) {
      const T x = base[st.points[i]];
      v[i] = x;
      lo0 = x < lo0 ? x : lo0;
      hi0 = x > hi0 ? x : hi0;
    }
    const T lo = lo1 < lo0 ? lo1 : lo0;
    const T hi = hi1 > hi0 ? hi1 : hi0;
    const double err = split_error([&v](std::uint8_t k) { return v[k]; }, st.split_index);
    diamond_range r;
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    r.error = err;
    return r;
  }

  std::array<stencil, 64> stencils_;
  const T* samples_ = nullptr;
  std::vector<level> levels_;
};

// Smoothed volumes (smoothing.hpp): the fine samples exist only on demand, so the range of a
// diamond is bounded from the data. Its subtree lies in the box c ± R (R = r h − 2 as above, which
// holds at h = 1 too: r − 2 ≥ the scale-1 reach); the fine samples of that box are made from the
// data samples their rows reach (subdivision::reach), so they lie within the data's [m, M] there,
// widened by λ (M − m) where the box meets the smoothed region (detail::subdivided_range, over a
// min/max pyramid of the data). Nested: a child's box lies in its parent's, so its data box lies
// in its parent's and the pyramid answers from bricks inside its parent's. The error bound is hi −
// lo: every split error |f(c) − (f(a) + f(b)) / 2| of the subtree lies between values within [lo,
// hi].
class subdivided_range_data final : public range_data::impl {
 public:
  subdivided_range_data(const volume& v, const hierarchy& h)
      : sub_(*v.subdivided()), data_(sub_.data()) {
    vol = &v;
    hier = &h;
  }
  [[nodiscard]] std::size_t piece_count() const noexcept override { return data_.slab_count(); }
  void build_pieces(std::size_t first, std::size_t last,
                    const range_data::parallel_loop& run) override {
    data_.build_slabs(first, last, run);
  }
  void finish(const range_data::parallel_loop& /*run*/) override { data_.finish(); }
  // The error bound is hi − lo from the start: no error pass.
  [[nodiscard]] std::size_t error_piece_count() const noexcept override { return 0; }
  void build_error_pieces(std::size_t /*first*/, std::size_t /*last*/,
                          const range_data::parallel_loop& /*run*/) override {}
  void finish_errors(const range_data::parallel_loop& /*run*/) override {
    errors_exact.store(true, std::memory_order_release);  // release: as in typed_range_data
  }

  [[nodiscard]] diamond_range get(const diamond& d) const noexcept override {
    return get_at(d.centre, d.scale);
  }
  [[nodiscard]] diamond_range get_at(const ipoint& c) const noexcept override {
    return get_at(c, hier->scale_of(c));
  }
  [[nodiscard]] diamond_range get_at(const ipoint& c, std::int32_t h) const noexcept override {
    if (empty_at(c, h)) return {};
    if (h == 1 && scale1_inside(c)) return scale1_exact(c);
    return bound(c, h);
  }
  [[nodiscard]] bool empty_at(const ipoint& c, std::int32_t h) const noexcept override {
    const std::int32_t r = reach(c, h);
    const ipoint& dm = hier->data_max();
    return c[0] - r >= dm[0] || c[1] - r >= dm[1] || c[2] - r >= dm[2];
  }
  [[nodiscard]] bool straddles_at(const ipoint& c, std::int32_t h,
                                  const detail::sample_threshold& w) const noexcept override {
    if (empty_at(c, h) || !bound(c, h).straddles(w.w)) return false;
    return h != 1 || !scale1_inside(c) || scale1_exact(c).straddles(w.w);
  }
  [[nodiscard]] std::size_t byte_size() const noexcept override {
    return sub_.byte_size() + data_.byte_size();
  }

 private:
  // The bound from the data over the subtree's box (see above).
  [[nodiscard]] diamond_range bound(const ipoint& c, std::int32_t h) const noexcept {
    const std::int32_t r = reach(c, h);
    const ipoint& dm = hier->data_max();
    ipoint b0{};
    ipoint b1{};
    for (std::size_t q = 0; q < 3; ++q) {
      b0[q] = std::max(c[q] - r, 0);
      b1[q] = std::min(c[q] + r, dm[q]);
    }
    return detail::subdivided_range(sub_, data_, b0, b1);
  }

  // Scale-1 diamonds whose subtree lies in the grid: the exact range and largest split error of
  // the subtree's own fine samples (the stencil's points, within ± 2 per axis), computed from the
  // rows like any sample. The bound is loosest here (the rows of a few fine samples reach 6 or
  // more data samples per axis, and the pyramid rounds out to bricks), and scale-1 diamonds are 7
  // in 8 of all. Sound: they are the subtree's values. Nested: a subset of the values that every
  // ancestor's bound covers, and the split errors lie between two of them.
  [[nodiscard]] bool scale1_inside(const ipoint& c) const noexcept {
    const ipoint& dm = hier->data_max();
    const int odd = (c[0] & 1) + (c[1] & 1) + (c[2] & 1);
    for (std::size_t q = 0; q < 3; ++q) {
      const std::int32_t r = odd == 1 ? 1 : (odd == 3 ? 2 : ((c[q] & 1) ? 2 : 1));
      if (c[q] - r < 0 || c[q] + r > dm[q]) return false;
    }
    return true;
  }
  [[nodiscard]] diamond_range scale1_exact(const ipoint& c) const noexcept {
    const stencil_shape& st = stencil_shape_table().scale1[class_of(c)];
    std::array<double, 125> v{};
    PROGISO_ASSERT(st.points.size() <= v.size());
    double lo = std::numeric_limits<double>::infinity();
    double hi = -lo;
    for (std::size_t i = 0; i < st.points.size(); ++i) {
      const ipoint& o = st.points[i];
      v[i] = sub_.at(c[0] + o[0], c[1] + o[1], c[2] + o[2]);
      lo = std::min(lo, v[i]);
      hi = std::max(hi, v[i]);
    }
    double err = 0.0;
    for (const auto& s : st.split_index) {
      err = std::max(err, std::abs(v[s[0]] - 0.5 * (v[s[1]] + v[s[2]])));
    }
    diamond_range r;
    r.lo = lo;
    r.hi = hi;
    r.error = err;
    return r;
  }
  [[nodiscard]] static std::int32_t reach(const ipoint& c, std::int32_t h) noexcept {
    const int odd = ((c[0] / h) & 1) + ((c[1] / h) & 1) + ((c[2] / h) & 1);
    return (2 + odd) * h - 2;
  }
  const detail::subdivision& sub_;
  detail::data_pyramid data_;
};

}  // namespace

range_data::range_data(const volume& vol, const hierarchy& hier, const parallel_loop& run)
    : range_data(vol, hier, staged) {
  PROGISO_ASSERT(error_piece_count() == 0 || error_piece_count() == piece_count());
  if (error_piece_count() == piece_count()) {
    build_pieces_with_errors(0, piece_count(), run);
  } else {
    build_pieces(0, piece_count(), run);
  }
  finish(run);
  finish_errors(run);
}

range_data::range_data(const volume& vol, const hierarchy& hier, staged_t /*unused*/) {
  if (vol.subdivided() != nullptr) {
    impl_ = std::make_unique<subdivided_range_data>(vol, hier);
    return;
  }
  vol.visit_samples([&](const auto* samples) {
    using T = std::remove_cv_t<std::remove_pointer_t<decltype(samples)>>;
    impl_ = std::make_unique<typed_range_data<T>>(vol, hier);
  });
}

std::size_t range_data::piece_count() const noexcept { return impl_->piece_count(); }
std::uint64_t range_data::piece_work(std::size_t first, std::size_t last) const noexcept {
  PROGISO_ASSERT(first <= last && last <= piece_count());
  return impl_->piece_work(first, last);
}
void range_data::build_pieces(std::size_t first, std::size_t last, const parallel_loop& run) {
  PROGISO_ASSERT(!complete_ && first <= last && last <= piece_count());
  impl_->build_pieces(first, last, run);
}
void range_data::finish(const parallel_loop& run) {
  PROGISO_ASSERT(!complete_);
  impl_->finish(run);
  complete_ = true;
}
std::span<std::byte> range_data::piece_bytes(std::size_t first, std::size_t last) noexcept {
  PROGISO_ASSERT(!complete_ && first <= last && last <= piece_count());
  return impl_->piece_bytes(first, last);
}
std::size_t range_data::error_piece_count() const noexcept { return impl_->error_piece_count(); }
void range_data::build_pieces_with_errors(std::size_t first, std::size_t last,
                                          const parallel_loop& run) {
  PROGISO_ASSERT(!complete_ && error_piece_count() == piece_count() && first <= last &&
                 last <= piece_count());
  impl_->build_both(first, last, run);
}
void range_data::build_error_pieces(std::size_t first, std::size_t last, const parallel_loop& run) {
  PROGISO_ASSERT(complete_ && !errors_exact() && first <= last && last <= error_piece_count());
  impl_->build_error_pieces(first, last, run);
}
void range_data::finish_errors(const parallel_loop& run) {
  PROGISO_ASSERT(complete_ && !errors_exact());
  impl_->finish_errors(run);
}
bool range_data::errors_exact() const noexcept {
  // acquire: pairs with the release in the impl's finish_errors().
  return impl_->errors_exact.load(std::memory_order_acquire);
}

range_data::~range_data() = default;
range_data::range_data(range_data&&) noexcept = default;
range_data& range_data::operator=(range_data&&) noexcept = default;

diamond_range range_data::get(const diamond& d) const noexcept { return impl_->get(d); }
diamond_range range_data::get(const ipoint& centre) const noexcept { return impl_->get_at(centre); }
diamond_range range_data::get(const ipoint& centre, std::int32_t scale) const noexcept {
  return impl_->get_at(centre, scale);
}
bool range_data::straddles(const ipoint& centre, std::int32_t scale,
                           const detail::sample_threshold& w) const noexcept {
  return impl_->straddles_at(centre, scale, w);
}
double range_data::error(const ipoint& centre, std::int32_t scale) const noexcept {
  return impl_->error_at(centre, scale);
}
straddle_and_error range_data::test_upto(const ipoint& centre, std::int32_t scale, double bound,
                                         const detail::sample_threshold& w) const noexcept {
  return impl_->test_upto(centre, scale, bound, w);
}
double range_data::error_upto(const ipoint& centre, std::int32_t scale,
                              double bound) const noexcept {
  return impl_->error_upto(centre, scale, bound);
}
bool range_data::empty(const ipoint& centre, std::int32_t scale) const noexcept {
  return impl_->empty_at(centre, scale);
}
diamond_range range_data::own(const diamond& d) const noexcept { return impl_->own(d); }
std::size_t range_data::byte_size() const noexcept { return impl_->byte_size(); }

}  // namespace progiso
