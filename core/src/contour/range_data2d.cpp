#include <progiso/core/contour/range_data2d.hpp>

#include <progiso/core/field/detail/subdivision.hpp>
#include <progiso/core/ranges/detail/range_entry.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

struct range_data2d::impl {
  virtual ~impl() = default;
  [[nodiscard]] virtual diamond_range get(const diamond2& d) const noexcept = 0;
  [[nodiscard]] virtual diamond_range get_at(const ipoint2& c) const noexcept = 0;
  // get_at() for a caller that knows c's scale.
  [[nodiscard]] virtual diamond_range get_scaled(const ipoint2& c, std::int32_t) const noexcept {
    return get_at(c);
  }
  [[nodiscard]] virtual std::size_t byte_size() const noexcept = 0;
  [[nodiscard]] virtual std::int32_t finest_stored_scale() const noexcept = 0;
  const volume* image = nullptr;
  const hierarchy2d* hier = nullptr;

  [[nodiscard]] double value(const ipoint2& p) const noexcept {
    return image->value(p[0], p[1], 0);
  }

  // The definition: centre, spine ends and in-grid apexes; empty when wholly beyond the data.
  [[nodiscard]] diamond_range own(const diamond2& d) const noexcept {
    diamond_range r;
    if (hier->outside_data(d.centre, d.scale)) return r;
    const double fc = value(d.centre);
    const double f0 = value(d.spine[0]);
    const double f1 = value(d.spine[1]);
    r.lo = std::min({fc, f0, f1});
    r.hi = std::max({fc, f0, f1});
    for (std::size_t m = 0; m < 2; ++m) {
      if (!((d.ring_in_grid >> m) & 1u)) continue;
      const double f = value(d.ring[m]);
      r.lo = std::min(r.lo, f);
      r.hi = std::max(r.hi, f);
    }
    r.error = std::abs(fc - 0.5 * (f0 + f1));
    return r;
  }

  static void merge(diamond_range& into, const diamond_range& r) noexcept {
    detail::merge(into, r);
  }
};

namespace {

using detail::decode;
using detail::error_type;
using detail::quantize_error;
template <class T>
using entry = detail::range_entry<T>;

// One array per stored scale h = 2^k holding the centres of that scale only: with i = c / h,
// the rows i_y odd hold every i_x, the rows i_y even only odd i_x (the others are coarser
// centres). Rows and columns stop at n = min((data_max + subtree_reach(0, h) − 1) / h,
// grid_max / h) + 1: beyond, every descendant lies outside the data box.
struct level_shape {
  ipoint2 n{};
  std::size_t even_row = 0;  // entries in a row with i_y even
  std::size_t odd_row = 0;   // entries in a row with i_y odd

  level_shape() = default;
  level_shape(const hierarchy2d& hier, std::int32_t h) {
    for (std::size_t q = 0; q < 2; ++q) {
      const std::int32_t reach = range_data2d::subtree_reach(0, h);
      n[q] = std::min((hier.data_max()[q] + reach - 1) / h, hier.grid_max()[q] / h) + 1;
    }
    even_row = static_cast<std::size_t>(n[0] / 2);
    odd_row = static_cast<std::size_t>(n[0]);
  }
  [[nodiscard]] std::size_t size() const noexcept {
    return static_cast<std::size_t>((n[1] + 1) / 2) * even_row +
           static_cast<std::size_t>(n[1] / 2) * odd_row;
  }
  // Slot of the first entry of row j (0 ≤ j < n[1]).
  [[nodiscard]] std::size_t row_begin(std::int32_t j) const noexcept {
    return static_cast<std::size_t>((j + 1) / 2) * even_row +
           static_cast<std::size_t>(j / 2) * odd_row;
  }
  // Slot of centre c (c / h has an odd coordinate); size() when beyond the clipped extent.
  [[nodiscard]] std::size_t slot(const ipoint2& c, int k) const noexcept {
    const std::int32_t i = c[0] >> k;
    const std::int32_t j = c[1] >> k;
    if (i >= n[0] || j >= n[1]) return size();
    PROGISO_ASSERT(((i | j) & 1) != 0);
    return row_begin(j) + static_cast<std::size_t>((j & 1) != 0 ? i : i / 2);
  }
};

template <class T>
class typed_range_data2d final : public range_data2d::impl {
 public:
  typed_range_data2d(const volume& v, const hierarchy2d& h) {
    image = &v;
    hier = &h;
    samples_ = v.visit_samples([](const auto* p) { return reinterpret_cast<const T*>(p); });
    width_ = v.dims()[0];
    const int levels = h.levels();
    // Finest stored level: 1 (scale 2), raised for tiny padded images until the arrays fit.
    std::vector<level_shape> shapes(static_cast<std::size_t>(std::max(levels, 1)));
    std::vector<std::size_t> bytes_from(static_cast<std::size_t>(std::max(levels, 1)) + 1, 0);
    for (int k = levels - 1; k >= 1; --k) {
      const auto ku = static_cast<std::size_t>(k);
      shapes[ku] = level_shape(h, std::int32_t{1} << k);
      bytes_from[ku] = bytes_from[ku + 1] + shapes[ku].size() * sizeof(entry<T>);
    }
    first_stored_ = std::max(levels, 1);
    for (int k = 1; k < levels; ++k) {
      if (bytes_from[static_cast<std::size_t>(k)] <= v.byte_size()) {
        first_stored_ = k;
        break;
      }
    }
    levels_.resize(static_cast<std::size_t>(std::max(levels, 1)));
    for (int k = first_stored_; k < levels; ++k) {
      level& lv = levels_[static_cast<std::size_t>(k)];
      lv.shape = shapes[static_cast<std::size_t>(k)];
      lv.entries.assign(lv.shape.size(), empty_entry());
    }
    build();
  }

  [[nodiscard]] diamond_range get(const diamond2& d) const noexcept override {
    if (d.scale == 1) return scale1(d.centre);
    const int k = std::countr_zero(static_cast<std::uint32_t>(d.scale));
    if (k < first_stored_) return on_demand(d);
    return stored(d.centre, k);
  }

  [[nodiscard]] diamond_range get_at(const ipoint2& c) const noexcept override {
    return get_scaled(c, hier->scale_of(c));
  }

  [[nodiscard]] diamond_range get_scaled(const ipoint2& c, std::int32_t h) const noexcept override {
    PROGISO_ASSERT(h == hier->scale_of(c));
    if (h == 1) return scale1(c);
    const int k = std::countr_zero(static_cast<std::uint32_t>(h));
    if (k < first_stored_) return on_demand(hier->make_diamond(c));
    return stored(c, k);
  }

  [[nodiscard]] std::size_t byte_size() const noexcept override {
    std::size_t b = 0;
    for (const level& lv : levels_) b += lv.entries.size() * sizeof(entry<T>);
    return b;
  }

  [[nodiscard]] std::int32_t finest_stored_scale() const noexcept override {
    return std::int32_t{1} << first_stored_;
  }

 private:
  struct level {
    level_shape shape;
    std::vector<entry<T>> entries;
  };

  static entry<T> empty_entry() noexcept { return detail::empty_entry<T>(); }

  static entry<T> encode(const diamond_range& r) noexcept {
    entry<T> e = empty_entry();
    if (!r.empty()) {
      e.lo = static_cast<T>(r.lo);
      e.hi = static_cast<T>(r.hi);
    }
    e.error = quantize_error<error_type<T>>(r.error);
    return e;
  }

  [[nodiscard]] diamond_range stored(const ipoint2& c, int k) const noexcept {
    const level& lv = levels_[static_cast<std::size_t>(k)];
    const std::size_t s = lv.shape.slot(c, k);
    if (s == lv.entries.size()) return {};
    return decode(lv.entries[s]);
  }

  // own(), reading the typed samples (clamped into the data box, as volume::value() does) with
  // no switch on the sample type per sample: the same values, so the same range and error.
  [[nodiscard]] diamond_range typed_own(const diamond2& d) const noexcept {
    diamond_range r;
    if (hier->outside_data(d.centre, d.scale)) return r;
    const ipoint2& dmax = hier->data_max();
    const auto at = [&](const ipoint2& q) {
      return samples_[std::clamp(q[0], 0, dmax[0]) + width_ * std::clamp(q[1], 0, dmax[1])];
    };
    const T fc = at(d.centre);
    const T f0 = at(d.spine[0]);
    const T f1 = at(d.spine[1]);
    T lo = std::min({fc, f0, f1});
    T hi = std::max({fc, f0, f1});
    for (std::size_t m = 0; m < 2; ++m) {
      if (!((d.ring_in_grid >> m) & 1u)) continue;
      const T f = at(d.ring[m]);
      lo = std::min(lo, f);
      hi = std::max(hi, f);
    }
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    r.error = std::abs(static_cast<double>(fc) -
                       0.5 * (static_cast<double>(f0) + static_cast<double>(f1)));
    return r;
  }

  // The definition for a diamond of an unstored scale ≥ 2: own range and children's.
  [[nodiscard]] diamond_range on_demand(const diamond2& d) const noexcept {
    diamond_range r = typed_own(d);
    std::array<ipoint2, 4> ch{};
    const int n = hier->children(d, ch);
    for (int i = 0; i < n; ++i) merge(r, get_at(ch[static_cast<std::size_t>(i)]));
    return r;
  }

  // Scale-1 square centres (both coordinates odd) of the two rows last asked for. Each is a child
  // of two edge midpoints of scale 2, one in the row above it and one below, so building scale 2
  // row by row computes each of them once instead of twice.
  struct square_rows {
    std::array<std::int32_t, 2> y{-1, -1};
    std::array<std::vector<entry<T>>, 2> entries;
    // Integer samples: per column of the row, lo, hi and the split errors, in the sample type.
    std::vector<T> lo, hi;
    std::vector<error_type<T>> across, vertical, main_diagonal, other_diagonal;

    void fill(const typed_range_data2d& data, std::int32_t row) {
      if (y[0] == row || y[1] == row) return;
      const std::size_t slot = y[0] < y[1] ? 0 : 1;  // the older row
      y[slot] = row;
      std::vector<entry<T>>& out = entries[slot];
      const std::int32_t xmax = data.hier->grid_max()[0];
      out.resize(static_cast<std::size_t>(xmax / 2));
      const ipoint2& dmax = data.hier->data_max();
      // Columns whose 13 samples lie in the data box: 2 ≤ x ≤ dmax − 2 (rows likewise).
      std::int32_t x0 = 3, x1 = dmax[0] - 2;  // odd x in [x0, x1] run in columns
      if constexpr (std::is_integral_v<T>) {
        if (row < 2 || row + 2 > dmax[1] || x1 < x0) x1 = x0 - 2;
      } else {
        x1 = x0 - 2;
      }
      for (std::int32_t x = 1; x < xmax; x += 2) {
        if (x == x0 && x1 >= x0) {
          fill_columns(data, row, x0, x1, out);
          x = x1;
          continue;
        }
        out[static_cast<std::size_t>(x / 2)] = encode(data.scale1({x, row}));
      }
    }

    // encode(scale1()) of the odd columns x0..x1 of `row`, all in the data box, integer samples:
    // each quantity over every column x0 − 1 .. x1 + 1 first (loops the compiler vectorises),
    // then the odd columns picked. The same samples and integer arithmetic, so the same entries.
    void fill_columns(const typed_range_data2d& data, std::int32_t row, std::int32_t x0,
                      std::int32_t x1, std::vector<entry<T>>& out) {
      using wide = std::conditional_t<(sizeof(T) < 4), std::int32_t, std::int64_t>;
      // Signed column indices: column i reads i − 2 .. i + 2, and i − 2 is −1 at i = 1.
      const std::ptrdiff_t n = x1 - x0 + 3;  // columns x0 − 1 .. x1 + 1
      const auto size = static_cast<std::size_t>(n);
      lo.resize(size);
      hi.resize(size);
      across.resize(size);
      vertical.resize(size);
      main_diagonal.resize(size);
      other_diagonal.resize(size);
      const std::int64_t w = data.width_;
      // Restrict: the sample type may be a character type, which would alias every output.
      const T* __restrict r0 = data.samples_ + (x0 - 1) + w * row;  // column x0 − 1 of the row
      const T* __restrict rn = r0 - w;
      const T* __restrict rs = r0 + w;
      const T* __restrict rnn = r0 - 2 * w;
      const T* __restrict rss = r0 + 2 * w;
      T* __restrict out_lo = lo.data();
      T* __restrict out_hi = hi.data();
      error_type<T>* __restrict out_vertical = vertical.data();
      error_type<T>* __restrict out_across = across.data();
      error_type<T>* __restrict out_main = main_diagonal.data();
      error_type<T>* __restrict out_other = other_diagonal.data();
      const auto err = [](T mid, T a, T b) {
        wide v = 2 * static_cast<wide>(mid) - static_cast<wide>(a) - static_cast<wide>(b);
        v = v < 0 ? -v : v;
        return static_cast<error_type<T>>((v + 1) >> 1);
      };
      // Quantities at column i ≥ 1 read columns i − 1 .. i + 1 (and i ± 2 on the row itself).
      for (std::ptrdiff_t i = 1; i + 1 < n; ++i) {
        const T a = std::min(std::min(rn[i - 1], rn[i]), rn[i + 1]);
        const T b = std::min(std::min(rs[i - 1], rs[i]), rs[i + 1]);
        const T c = std::min(std::min(r0[i - 2], r0[i - 1]), std::min(r0[i], r0[i + 1]));
        const T d = std::min(std::min(r0[i + 2], rnn[i]), rss[i]);
        out_lo[i] = std::min(std::min(a, b), std::min(c, d));
      }
      for (std::ptrdiff_t i = 1; i + 1 < n; ++i) {
        const T a = std::max(std::max(rn[i - 1], rn[i]), rn[i + 1]);
        const T b = std::max(std::max(rs[i - 1], rs[i]), rs[i + 1]);
        const T c = std::max(std::max(r0[i - 2], r0[i - 1]), std::max(r0[i], r0[i + 1]));
        const T d = std::max(std::max(r0[i + 2], rnn[i]), rss[i]);
        out_hi[i] = std::max(std::max(a, b), std::max(c, d));
      }
      for (std::ptrdiff_t i = 0; i < n; ++i) out_vertical[i] = err(r0[i], rn[i], rs[i]);
      // One output per loop: with three, the compiler's aliasing checks outnumber its limit and
      // the loop stays scalar.
      for (std::ptrdiff_t i = 1; i + 1 < n; ++i) {
        out_across[i] =
            std::max(err(rn[i], rn[i - 1], rn[i + 1]), err(rs[i], rs[i - 1], rs[i + 1]));
      }
      for (std::ptrdiff_t i = 1; i + 1 < n; ++i) out_main[i] = err(r0[i], rn[i - 1], rs[i + 1]);
      for (std::ptrdiff_t i = 1; i + 1 < n; ++i) out_other[i] = err(r0[i], rn[i + 1], rs[i - 1]);
      for (std::int32_t x = x0; x <= x1; x += 2) {
        const auto i = static_cast<std::size_t>(x - x0 + 1);
        // As scale1(): the own spine joins the corners ≡ 0 mod 4 when c ≡ (1, 1) or (3, 3) mod 4.
        const bool main = ((x ^ row) & 2) == 0;
        const error_type<T> e =
            std::max(std::max(main ? main_diagonal[i] : other_diagonal[i], across[i]),
                     std::max(vertical[i - 1], vertical[i + 1]));
        out[static_cast<std::size_t>(x / 2)] = {lo[i], hi[i], e};
      }
    }

    [[nodiscard]] const entry<T>& at(const ipoint2& c) const noexcept {
      PROGISO_ASSERT(c[1] == y[0] || c[1] == y[1]);
      return entries[c[1] == y[0] ? 0 : 1][static_cast<std::size_t>(c[0] / 2)];
    }
  };

  // ---- Build: finest stored scale first; within a scale, edge midpoints (type 1, whose
  // children are square centres of half the scale) before square centres (type 0, whose
  // children are this scale's edge midpoints). A diamond whose subtree lies in the data box
  // (nearly all but a margin of subtree_reach along the border) is summarised from the typed
  // samples and its children's entries, a row's run of them in one loop (interior_run(); the
  // same entries as interior(), one diamond at a time); the others run the definition.
  void build() {
    const int levels = hier->levels();
    square_rows squares;
    for (int k = first_stored_; k < levels; ++k) {
      level& lv = levels_[static_cast<std::size_t>(k)];
      const std::int32_t h = std::int32_t{1} << k;
      const bool children_stored = k - 1 >= first_stored_;
      for (const int type : {1, 0}) {
        const std::int32_t reach = range_data2d::subtree_reach(type, h);
        for (std::int32_t j = 0; j < lv.shape.n[1]; ++j) {
          // Type 0: both of i, j odd; type 1: exactly one of them.
          const bool j_odd = (j & 1) != 0;
          if (type == 0 && !j_odd) continue;
          const std::int32_t i0 = type == 0 || !j_odd ? 1 : 0;
          const bool rows_inside = j * h - reach >= 0 && j * h + reach <= hier->data_max()[1];
          const bool from_square_rows = h == 2 && type == 1 && rows_inside;
          if (from_square_rows) {
            squares.fill(*this, j * h - 1);
            squares.fill(*this, j * h + 1);
          }
          // The entries whose subtree lies in the data box, i in [ia, ib], in one run.
          std::int32_t ia = lv.shape.n[0];
          std::int32_t ib = -1;
          if (rows_inside && (type == 0 || from_square_rows || children_stored)) {
            ia = (reach + h - 1) / h;
            ia += (ia - i0) & 1;
            ib = std::min(lv.shape.n[0] - 1, (hier->data_max()[0] - reach) / h);
            ib -= (ib - i0) & 1;
          }
          for (std::int32_t i = i0; i < lv.shape.n[0]; i += 2) {
            if (i == ia && ia <= ib) {
              interior_run(lv, k, type, j, ia, ib, squares);
              i = ib;
              continue;
            }
            const ipoint2 c{i * h, j * h};
            PROGISO_ASSERT(hier->is_diamond(c) && hier->scale_of(c) == h);
            const bool inside =
                rows_inside && c[0] - reach >= 0 && c[0] + reach <= hier->data_max()[0];
            entry<T>& out = lv.entries[lv.shape.slot(c, k)];
            // Inside with its children at hand, an entry is part of the run above; inside
            // otherwise only in a tiny padded image's first stored level (children on demand).
            if (!inside) {
              out = encode(on_demand(hier->make_diamond(c)));
            } else {
              out = interior(c, h, k, type, [&](const ipoint2& ch) { return encode(get_at(ch)); });
            }
          }
        }
      }
    }
  }

  // interior() of the entries i = ia, ia + 2, …, ib of row j of level k (type `type`, every
  // subtree in the data box), in one loop: the children's entries are read through four
  // pointers that each step by a fixed stride, the samples through one, and the entries are
  // written in slot order (every other slot in odd rows). Type 1's children: scale 1's square
  // centres from the row buffers (scale 2) or level k − 1's (both indices odd: 2i ± 1, 2j ± 1);
  // type 0's: this level's edge midpoints in row j (i ± 1) and in rows j ± 1 (i / 2).
  void interior_run(level& lv, int k, int type, std::int32_t j, std::int32_t ia, std::int32_t ib,
                    const square_rows& squares) {
    const std::int32_t h = std::int32_t{1} << k;
    const std::int64_t w = width_;
    const std::int64_t hh = h;
    const std::int64_t y = std::int64_t{j} * h;
    const T* p = samples_ + std::int64_t{ia} * h + w * y;
    entry<T>* out = lv.entries.data() + lv.shape.slot({ia * h, j * h}, k);
    // An odd row holds every i (its edge midpoints and square centres interleave), an even row
    // odd i only.
    const std::ptrdiff_t out_stride = (j & 1) != 0 ? 2 : 1;
    std::array<const entry<T>*, 4> ch{};
    std::array<std::ptrdiff_t, 4> stride{};
    std::int64_t spine = 0;
    std::int64_t ring = 0;
    if (type == 1) {
      const bool along_x = (ia & 1) != 0;
      spine = along_x ? hh : hh * w;
      ring = along_x ? hh * w : hh;
      if (h == 2) {
        const entry<T>* up = &squares.at({2 * ia - 1, j * h - 1});
        const entry<T>* down = &squares.at({2 * ia - 1, j * h + 1});
        ch = {up, up + 1, down, down + 1};
        stride = {2, 2, 2, 2};
      } else {
        const level& fine = levels_[static_cast<std::size_t>(k - 1)];
        const entry<T>* up = fine.entries.data() + fine.shape.row_begin(2 * j - 1) + (2 * ia - 1);
        const entry<T>* down = fine.entries.data() + fine.shape.row_begin(2 * j + 1) + (2 * ia - 1);
        ch = {up, up + 2, down, down + 2};
        stride = {4, 4, 4, 4};
      }
    } else {
      const entry<T>* same = lv.entries.data() + lv.shape.row_begin(j) + (ia - 1);
      ch = {same, same + 2, lv.entries.data() + lv.shape.row_begin(j - 1) + ia / 2,
            lv.entries.data() + lv.shape.row_begin(j + 1) + ia / 2};
      stride = {2, 2, 1, 1};
    }
    // Type 0's spine: sy per row; sx alternates along the row (x + h ≡ 0 or 2h mod 4h).
    const std::int64_t sy = ((y + h) & (4 * hh - 1)) == 0 ? 1 : -1;
    std::int64_t sx = ((std::int64_t{ia} * h + h) & (4 * hh - 1)) == 0 ? 1 : -1;
    for (std::int32_t i = ia; i <= ib; i += 2) {
      if (type == 0) {
        spine = hh * (sx + w * sy);
        ring = hh * (sx - w * sy);
        sx = -sx;
      }
      entry<T> e = own_entry(p, spine, ring);
      for (std::size_t m = 0; m < 4; ++m) {
        merge_entry(e, *ch[m]);
        ch[m] += stride[m];
      }
      *out = e;
      out += out_stride;
      p += 2 * hh;
    }
  }

  // The entry on_demand() gives a diamond of a stored scale whose subtree lies in the data box,
  // so every point it reads is a data sample in the grid: the same samples and the same own
  // error in double, merged with the children's entries in the sample type (an entry's bounds
  // are samples, and rounding an error up commutes with taking the largest), hence the same
  // entry, without making the diamond and its children as objects. Type 0 (square centre): its 4
  // corners (spine along the diagonal hierarchy2d::make_diamond picks) and its edge midpoints of
  // the same scale (stored before it); type 1 (edge midpoint): spine along its odd axis, apexes
  // along the other, and the 4 square centres of half its scale (child(centre) gives a child's
  // entry). interior_run() does the same over a row's run, reading the children's stored entries;
  // this one serves a tiny padded image's first stored scale, whose children are not stored.
  template <class Child>
  [[nodiscard]] entry<T> interior(const ipoint2& c, std::int32_t h, int k, int type,
                                  Child&& child) const noexcept {
    const T* p = samples_ + c[0] + width_ * c[1];
    const std::int64_t w = width_;
    const std::int64_t hh = h;
    std::int64_t spine = 0;  // offset of one spine end (the other is at −spine)
    std::int64_t ring = 0;   // offset of one apex (the other at −ring)
    if (type == 0) {
      const std::int64_t sx = ((c[0] + h) & (4 * h - 1)) == 0 ? 1 : -1;
      const std::int64_t sy = ((c[1] + h) & (4 * h - 1)) == 0 ? 1 : -1;
      spine = hh * (sx + w * sy);
      ring = hh * (sx - w * sy);
    } else {
      const bool along_x = ((c[0] >> k) & 1) != 0;
      spine = along_x ? hh : hh * w;
      ring = along_x ? hh * w : hh;
    }
    entry<T> e = own_entry(p, spine, ring);
    const std::int32_t g = type == 0 ? h : h / 2;
    const std::array<ipoint2, 4> children =
        type == 0
            ? std::array<ipoint2, 4>{ipoint2{c[0] + h, c[1]}, ipoint2{c[0] - h, c[1]},
                                     ipoint2{c[0], c[1] + h}, ipoint2{c[0], c[1] - h}}
            : std::array<ipoint2, 4>{ipoint2{c[0] + g, c[1] + g}, ipoint2{c[0] - g, c[1] + g},
                                     ipoint2{c[0] + g, c[1] - g}, ipoint2{c[0] - g, c[1] - g}};
    for (const ipoint2& ch : children) merge_entry(e, child(ch));
    return e;
  }

  // The entry of a diamond's own samples, centred at p (spine ends at ± spine, apexes at ± ring,
  // all in the data box): their range and the split error, in the stored form.
  static entry<T> own_entry(const T* p, std::int64_t spine, std::int64_t ring) noexcept {
    const T fc = p[0];
    const T f0 = p[-spine];
    const T f1 = p[spine];
    const T g0 = p[ring];
    const T g1 = p[-ring];
    return {std::min({fc, f0, f1, g0, g1}), std::max({fc, f0, f1, g0, g1}),
            stored_split_error(fc, f0, f1)};
  }
  // A child's entry merged into its parent's (bounds are samples; errors already rounded up).
  static void merge_entry(entry<T>& e, const entry<T>& x) noexcept {
    e.lo = std::min(e.lo, x.lo);
    e.hi = std::max(e.hi, x.hi);
    e.error = std::max(e.error, x.error);
  }

  // The stored (rounded up) form of the split error |mid − (a + b) / 2|: for integer samples
  // ⌈|2 mid − a − b| / 2⌉ in integers (the error is a half-integer, exact in double, so this is
  // quantize_error() of it), else quantize_error() of the double.
  static error_type<T> stored_split_error(T mid, T a, T b) noexcept {
    if constexpr (std::is_integral_v<T>) {
      using wide = std::conditional_t<(sizeof(T) < 4), std::int32_t, std::int64_t>;
      wide v = 2 * static_cast<wide>(mid) - static_cast<wide>(a) - static_cast<wide>(b);
      v = v < 0 ? -v : v;
      return static_cast<error_type<T>>((v + 1) >> 1);
    } else {
      return quantize_error<error_type<T>>(std::abs(
          static_cast<double>(mid) - 0.5 * (static_cast<double>(a) + static_cast<double>(b))));
    }
  }

  // ---- Scale 1 (3/4 of all diamonds), on demand. An edge midpoint (type 1) is a leaf: its own
  // 5 samples (centre, spine along the odd axis, apexes along the even one) and 1 split. A
  // square centre (type 0) adds its 4 edge-midpoint children: the 3 × 3 block around it plus
  // the 4 points at distance 2 along the axes (the children's far apexes), 13 samples and 5
  // splits. Where all of those lie in the data box they are read straight from the typed
  // samples; elsewhere the definition runs (same values, same arithmetic, so the same result).
  [[nodiscard]] diamond_range scale1(const ipoint2& c) const noexcept {
    const ipoint2& dmax = hier->data_max();
    const bool square = (c[0] & 1) != 0 && (c[1] & 1) != 0;
    const std::int32_t reach = range_data2d::subtree_reach(square ? 0 : 1, 1);
    if (c[0] - reach >= dmax[0] || c[1] - reach >= dmax[1]) return {};
    const bool inside =
        c[0] >= reach && c[1] >= reach && c[0] + reach <= dmax[0] && c[1] + reach <= dmax[1];
    if (!inside) {
      const diamond2 d = hier->make_diamond(c);
      diamond_range r = typed_own(d);
      std::array<ipoint2, 4> ch{};
      const int n = hier->children(d, ch);
      for (int i = 0; i < n; ++i) {
        merge(r, typed_own(hier->make_diamond(ch[static_cast<std::size_t>(i)])));
      }
      return r;
    }
    const T* p = samples_ + c[0] + width_ * c[1];
    const std::int64_t w = width_;
    const auto split = [](T mid, T a, T b) {
      return std::abs(static_cast<double>(mid) -
                      0.5 * (static_cast<double>(a) + static_cast<double>(b)));
    };
    if (!square) {
      // Spine along the odd axis, apexes along the even one.
      const std::int64_t along = (c[0] & 1) != 0 ? 1 : w;
      const std::int64_t across = (c[0] & 1) != 0 ? w : 1;
      const T f0 = p[-along];
      const T f1 = p[along];
      const T lo = std::min({p[0], f0, f1, p[-across], p[across]});
      const T hi = std::max({p[0], f0, f1, p[-across], p[across]});
      return {static_cast<double>(lo), static_cast<double>(hi), split(p[0], f0, f1)};
    }
    const T nw = p[-w - 1];
    const T ne = p[-w + 1];
    const T sw = p[w - 1];
    const T se = p[w + 1];
    const T n = p[-w];
    const T s = p[w];
    const T west = p[-1];
    const T east = p[1];
    const T lo =
        std::min({p[0], nw, ne, sw, se, n, s, west, east, p[-2 * w], p[2 * w], p[-2], p[2]});
    const T hi =
        std::max({p[0], nw, ne, sw, se, n, s, west, east, p[-2 * w], p[2 * w], p[-2], p[2]});
    // The own spine joins the corner whose coordinates are ≡ 0 mod 4 to the opposite one:
    // (nw, se) when c ≡ (1, 1) or (3, 3) mod 4, else (ne, sw).
    const bool main_diagonal = ((c[0] ^ c[1]) & 2) == 0;
    double err = main_diagonal ? split(p[0], nw, se) : split(p[0], ne, sw);
    err = std::max(
        {err, split(n, nw, ne), split(s, sw, se), split(west, nw, sw), split(east, ne, se)});
    return {static_cast<double>(lo), static_cast<double>(hi), err};
  }

  const T* samples_ = nullptr;
  std::int64_t width_ = 0;
  int first_stored_ = 1;
  std::vector<level> levels_;  // indexed by log2(scale); levels below first_stored_ are empty
};

// A smoothed image (smoothing.hpp): ranges bounded from the data, as for smoothed volumes
// (range_data.cpp). The subtree of a diamond lies in c ± subtree_reach(type, h) per axis; its
// fine samples are bounded by the data over what their rows reach, widened by the overshoot bound
// in the smoothed region; scale 1 takes the exact range of its own fine samples. Nested, since a
// child's box lies in its parent's (type 1 → type 0 at h/2: h/2 + 3h/2 − 1 = 2h − 1; type 0 → type
// 1 at h: h + 2h − 1 = 3h − 1). Error: hi − lo.
class subdivided_range_data2d final : public range_data2d::impl {
 public:
  subdivided_range_data2d(const volume& v, const hierarchy2d& h)
      : sub_(*v.subdivided()), data_(sub_.data(), {}) {
    image = &v;
    hier = &h;
  }
  [[nodiscard]] diamond_range get(const diamond2& d) const noexcept override {
    return get_at(d.centre);
  }
  [[nodiscard]] diamond_range get_at(const ipoint2& c) const noexcept override {
    const std::int32_t h = hier->scale_of(c);
    const int odd = ((c[0] / h) & 1) + ((c[1] / h) & 1);
    const std::int32_t r = range_data2d::subtree_reach(2 - odd, h);
    const ipoint2& dm = hier->data_max();
    if (c[0] - r >= dm[0] || c[1] - r >= dm[1]) return {};
    if (h == 1) return scale1(c);
    const ipoint b0{std::max(c[0] - r, 0), std::max(c[1] - r, 0), 0};
    const ipoint b1{std::min(c[0] + r, dm[0]), std::min(c[1] + r, dm[1]), 0};
    return detail::subdivided_range(sub_, data_, b0, b1);
  }
  [[nodiscard]] std::size_t byte_size() const noexcept override {
    return sub_.byte_size() + data_.byte_size();
  }
  [[nodiscard]] std::int32_t finest_stored_scale() const noexcept override {
    return std::int32_t{1} << 30;  // nothing stored
  }

 private:
  // Scale 1 (3/4 of all diamonds, and where the bound is loosest): the definition, from the
  // subtree's own fine samples (at most 13, clamped into the grid as every reader clamps them).
  // Sound: the subtree's values; nested: a subset of what every ancestor's bound covers.
  [[nodiscard]] diamond_range scale1(const ipoint2& c) const noexcept {
    const diamond2 d = hier->make_diamond(c);
    diamond_range r = own(d);
    std::array<ipoint2, 4> ch{};
    const int n = hier->children(d, ch);
    for (int i = 0; i < n; ++i) merge(r, own(hier->make_diamond(ch[static_cast<std::size_t>(i)])));
    return r;
  }

  const detail::subdivision& sub_;
  detail::data_pyramid data_;
};

}  // namespace

range_data2d::range_data2d(const volume& image, const hierarchy2d& hier) {
  const index3& dims = image.dims();
  if (dims[2] != 1 || dims[0] - 1 != hier.data_max()[0] || dims[1] - 1 != hier.data_max()[1]) {
    throw error("range_data2d: image of " + std::to_string(dims[0]) + "x" +
                std::to_string(dims[1]) + "x" + std::to_string(dims[2]) +
                " samples does not match the hierarchy's " +
                std::to_string(hier.data_max()[0] + 1) + "x" +
                std::to_string(hier.data_max()[1] + 1) + "x1");
  }
  if (image.subdivided() != nullptr) {
    impl_ = std::make_unique<subdivided_range_data2d>(image, hier);
    return;
  }
  image.visit_samples([&](const auto* samples) {
    using T = std::remove_cv_t<std::remove_pointer_t<decltype(samples)>>;
    impl_ = std::make_unique<typed_range_data2d<T>>(image, hier);
  });
}

range_data2d::~range_data2d() = default;
range_data2d::range_data2d(range_data2d&&) noexcept = default;
range_data2d& range_data2d::operator=(range_data2d&&) noexcept = default;

diamond_range range_data2d::get(const diamond2& d) const noexcept { return impl_->get(d); }
diamond_range range_data2d::get(const ipoint2& centre) const noexcept {
  return impl_->get_at(centre);
}
diamond_range range_data2d::get(const ipoint2& centre, std::int32_t scale) const noexcept {
  return impl_->get_scaled(centre, scale);
}
diamond_range range_data2d::own(const diamond2& d) const noexcept { return impl_->own(d); }
std::size_t range_data2d::byte_size() const noexcept { return impl_->byte_size(); }
std::int32_t range_data2d::finest_stored_scale() const noexcept {
  return impl_->finest_stored_scale();
}

}  // namespace progiso
