#include <progiso/core/range_data.hpp>

#include <progiso/core/assert.hpp>
#include <progiso/core/detail/range_entry.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <vector>

namespace progiso {

struct range_data::impl {
  virtual ~impl() = default;
  [[nodiscard]] virtual diamond_range get(const diamond& d) const noexcept = 0;
  [[nodiscard]] virtual diamond_range get_at(const ipoint& c) const noexcept = 0;
  [[nodiscard]] virtual diamond_range get_at(const ipoint& c, std::int32_t h) const noexcept = 0;
  [[nodiscard]] virtual bool empty_at(const ipoint& c, std::int32_t h) const noexcept = 0;
  [[nodiscard]] virtual bool straddles_at(const ipoint& c, std::int32_t h,
                                          const detail::sample_threshold& w) const noexcept = 0;
  [[nodiscard]] virtual std::size_t byte_size() const noexcept = 0;
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

// The shape of a stencil: the subtree of the diamond centred at c, every vertex of every
// descendant's tetrahedra and every descendant's split (centre, spine ends), as grid offsets
// from c, sorted, without repeats. It depends only on c modulo 4 (scale 1) or 8 (scale-2 edge
// midpoints), not on the volume, so it is found once per process by walking the subtree in a
// probe hierarchy (the walk costs milliseconds; every range_data used to repeat it).
struct stencil_shape {
  bool used = false;
  std::vector<ipoint> points;
  std::vector<std::array<ipoint, 3>> splits;
};

struct stencil_shapes {
  std::array<stencil_shape, 64> scale1;  // by class_of(c): c mod 4 per axis
  std::array<stencil_shape, 512> edge2;  // scale-2 edge midpoints, by c mod 8 per axis
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
  return shape;
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
    for (std::int32_t cls = 0; cls < 512; ++cls) {
      const ipoint c{16 + (cls & 7), 16 + ((cls >> 3) & 7), 16 + ((cls >> 6) & 7)};
      if (((c[0] | c[1] | c[2]) & 1) != 0 || !probe.is_diamond(c)) continue;
      if (probe.scale_of(c) != 2 || probe.make_diamond(c).type != 2) continue;
      t.edge2[static_cast<std::size_t>(cls)] = walk_subtree(probe, c);
    }
    return t;
  }();
  return table;
}

// One dense array of entries per scale, clipped to the part of the grid whose diamonds have a
// descendant reaching into the data box. Per axis, the vertices of the subtree of a diamond of
// scale h centred at c lie within c ± r h, with r = 3 for edge midpoints (own radius h/2 away
// plus a half-scale cube centre's subtree), 4 for face and 5 for cube centres (one more step of
// h each); a scale-1 cube centre's subtree stops at edge midpoints, radius 3. Centres with
// c_q ≥ data_max_q + 5h (scale 1 cube centres: data_max_q + 3) therefore have empty ranges.
template <class T>
class typed_range_data final : public range_data::impl {
  // Offsets of the samples and splits of a subtree of fixed shape (see make_stencils()).
  struct stencil {
    std::vector<std::int64_t> points;                 // linear offsets
    std::vector<std::array<std::int64_t, 3>> splits;  // centre, spine ends
    std::vector<ipoint> rel_points;                   // the same as grid offsets
    std::vector<std::array<ipoint, 3>> rel_splits;
  };

 public:
  typed_range_data(const volume& v, const hierarchy& h) {
    vol = &v;
    hier = &h;
    samples_ = v.visit_samples([](const auto* p) { return reinterpret_cast<const T*>(p); });
    const int levels = h.levels();
    // Level k ≥ 1 holds scale 2^k, indexed by centre / h. Scale 1 (level 0) is not stored.
    levels_.resize(static_cast<std::size_t>(std::max(levels, 1)));
    for (int k = 1; k < levels; ++k) {
      level& lv = levels_[static_cast<std::size_t>(k)];
      for (std::size_t q = 0; q < 3; ++q) {
        const std::int32_t dmax = h.data_max()[q];
        const std::int32_t gmax = h.grid_max()[q];
        const std::int32_t hh = std::int32_t{1} << k;
        lv.n[q] = std::min((dmax + 5 * hh - 1) / hh, gmax / hh) + 1;
      }
      lv.entries.assign(static_cast<std::size_t>(lv.n[0]) * static_cast<std::size_t>(lv.n[1]) *
                            static_cast<std::size_t>(lv.n[2]),
                        empty_entry());
    }
    build();
  }

  [[nodiscard]] diamond_range get(const diamond& d) const noexcept override {
    if (d.scale == 1) return scale1_at(d.centre);
    const entry<T>* e = find(d.centre, d.scale);
    if (e == nullptr) return {};
    return decode(*e);
  }

  [[nodiscard]] diamond_range get_at(const ipoint& c) const noexcept override {
    return get_at(c, hier->scale_of(c));
  }

  [[nodiscard]] bool straddles_at(const ipoint& c, std::int32_t h,
                                  const detail::sample_threshold& w) const noexcept override {
    if (h != 1) return get_at(c, h).straddles(w.w);
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
    const entry<T>* e = find(c, h);
    return e == nullptr || decode(*e).empty();
  }

  [[nodiscard]] diamond_range get_at(const ipoint& c, std::int32_t h) const noexcept override {
    if (h == 1) return scale1_at(c);
    const entry<T>* e = find(c, h);
    if (e == nullptr) return {};
    return decode(*e);
  }

  [[nodiscard]] std::size_t byte_size() const noexcept override {
    std::size_t b = 0;
    for (const auto& lv : levels_) b += lv.entries.size() * sizeof(entry<T>);
    return b;
  }

 private:
  struct level {
    ipoint n{};
    std::vector<entry<T>> entries;
  };

  static entry<T> empty_entry() noexcept { return detail::empty_entry<T>(); }

  [[nodiscard]] std::size_t slot(const ipoint& c, std::int32_t h, const level*& lv) const noexcept {
    lv = &levels_[static_cast<std::size_t>(std::countr_zero(static_cast<std::uint32_t>(h)))];
    const ipoint i{c[0] / h, c[1] / h, c[2] / h};
    for (std::size_t q = 0; q < 3; ++q) {
      if (i[q] >= lv->n[q]) return std::numeric_limits<std::size_t>::max();
    }
    return static_cast<std::size_t>(i[0]) +
           static_cast<std::size_t>(lv->n[0]) *
               (static_cast<std::size_t>(i[1]) +
                static_cast<std::size_t>(lv->n[1]) * static_cast<std::size_t>(i[2]));
  }

  [[nodiscard]] const entry<T>* find(const ipoint& c, std::int32_t h) const noexcept {
    const level* lv = nullptr;
    const std::size_t s = slot(c, h, lv);
    return s == std::numeric_limits<std::size_t>::max() ? nullptr : &lv->entries[s];
  }

  void store(const ipoint& c, std::int32_t h, const diamond_range& r) noexcept {
    const level* lv = nullptr;
    const std::size_t s = slot(c, h, lv);
    if (s == std::numeric_limits<std::size_t>::max()) return;
    entry<T>& e = const_cast<level*>(lv)->entries[s];
    if (r.empty()) {
      e = empty_entry();
    } else {
      e.lo = static_cast<T>(r.lo);
      e.hi = static_cast<T>(r.hi);
    }
    e.error = quantize_error<error_type<T>>(r.error);
  }

  // Finest stored level first, then coarser scales; within a scale edge, face, then cube centres,
  // so every diamond's children are done before it. Children of stored diamonds are stored
  // themselves, except those of the scale-1 cube centres, which use the stencils below.
  void build() {
    const hierarchy& h = *hier;
    const int levels = h.levels();
    make_stencils();
    for (int k = 1; k < levels; ++k) {
      const level& lv = levels_[static_cast<std::size_t>(k)];
      const std::int32_t hh = std::int32_t{1} << k;
      for (int type = 2; type >= 0; --type) {
        for (std::int32_t z = 0; z < lv.n[2]; ++z) {
          for (std::int32_t y = 0; y < lv.n[1]; ++y) {
            for (std::int32_t x = 0; x < lv.n[0]; ++x) {
              const ipoint c{x * hh, y * hh, z * hh};
              const int odd = (x & 1) + (y & 1) + (z & 1);
              if (3 - odd != type || odd == 0) continue;
              if (!h.is_diamond(c)) continue;
              if (k == 1 && type == 2) {
                const stencil& st = edge2_stencils_[static_cast<std::size_t>(
                    (c[0] & 7) | ((c[1] & 7) << 3) | ((c[2] & 7) << 6))];
                // Its subtree reaches 3 per axis; beyond that it is wholly in the padding.
                const ipoint& dm = h.data_max();
                const bool outside = c[0] - 3 >= dm[0] || c[1] - 3 >= dm[1] || c[2] - 3 >= dm[2];
                store(c, hh,
                      outside          ? diamond_range{}
                      : interior(c, 3) ? read_stencil(st, c)
                                       : read_stencil_clamped(st, c));
                continue;
              }
              if (hh >= 2 && interior(c, hh)) {
                store(c, hh, from_own_stencil(k, c));
                continue;
              }
              const diamond d = h.make_diamond(c);
              diamond_range r = own(d);
              std::array<ipoint, 8> ch{};
              const int n = h.children(d, ch);
              const std::int32_t child_scale = d.type == 2 ? hh / 2 : hh;
              for (int i = 0; i < n; ++i) {
                const ipoint& cc = ch[static_cast<std::size_t>(i)];
                if (child_scale == 1) {
                  merge(r, scale1_at(cc));
                } else if (const entry<T>* e = find(cc, child_scale)) {
                  merge(r, decode(*e));
                }
              }
              store(c, hh, r);
            }
          }
        }
      }
    }
  }

  // Stored diamonds away from the data boundary: own samples and children's entries through
  // offsets that depend only on the scale and (c / h) mod 4, made on first use per class.
  struct own_stencil {
    bool made = false;
    std::vector<std::int64_t> points;  // spine ends first, then ring; centre implied
    std::vector<ipoint> children;
    std::int32_t child_scale = 0;
  };

  [[nodiscard]] diamond_range from_own_stencil(int k, const ipoint& c) {
    const std::int32_t hh = std::int32_t{1} << k;
    const std::size_t cls = static_cast<std::size_t>(((c[0] >> k) & 3) | (((c[1] >> k) & 3) << 2) |
                                                     (((c[2] >> k) & 3) << 4));
    own_stencil& st = own_stencils_[static_cast<std::size_t>(k)][cls];
    if (!st.made) {
      const diamond d = hier->make_diamond(c);
      const auto& dims = vol->dims();
      const auto lin = [&](const ipoint& p) {
        return (p[0] - c[0]) + dims[0] * ((p[1] - c[1]) + dims[1] * std::int64_t{p[2] - c[2]});
      };
      st.points = {lin(d.spine[0]), lin(d.spine[1])};
      for (int m = 0; m < d.ring_size; ++m)
        st.points.push_back(lin(d.ring[static_cast<std::size_t>(m)]));
      std::array<ipoint, 8> ch{};
      const int n = hier->children(d, ch);
      for (int i = 0; i < n; ++i) {
        const ipoint& x = ch[static_cast<std::size_t>(i)];
        st.children.push_back({x[0] - c[0], x[1] - c[1], x[2] - c[2]});
      }
      st.child_scale = d.type == 2 ? hh / 2 : hh;
      st.made = true;
    }
    const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
    T lo = base[0];
    T hi = base[0];
    for (const std::int64_t o : st.points) {
      const T v = base[o];
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    diamond_range r;
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    r.error =
        std::abs(static_cast<double>(base[0]) - 0.5 * (static_cast<double>(base[st.points[0]]) +
                                                       static_cast<double>(base[st.points[1]])));
    for (const ipoint& o : st.children) {
      const ipoint x{c[0] + o[0], c[1] + o[1], c[2] + o[2]};
      if (st.child_scale == 1) {
        merge(r, scale1_at(x));
      } else if (const entry<T>* e = find(x, st.child_scale)) {
        merge(r, decode(*e));
      }
    }
    return r;
  }

  std::vector<std::array<own_stencil, 64>> own_stencils_{32};

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

  // Samples at c + o, o a stencil offset, with clamped coordinates. Offsets lie in [-3, 3] per
  // axis (scale-2 edge midpoints reach 3, scale-1 stencils 2): the clamped coordinates' shares
  // of the linear index, seven per axis, are computed once per diamond.
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
    double err = 0.0;
    if constexpr (std::is_integral_v<T>) {
      // Twice the error, |2 f(c) - f(a) - f(b)|, in integers: exact for every integer sample
      // type (at most 34 bits), and half of it is the same double as the formula below.
      std::int64_t twice = 0;
      for (const auto& s : splits) {
        const std::int64_t e = 2 * static_cast<std::int64_t>(at(s[0])) -
                               static_cast<std::int64_t>(at(s[1])) -
                               static_cast<std::int64_t>(at(s[2]));
        twice = std::max(twice, e < 0 ? -e : e);
      }
      err = 0.5 * static_cast<double>(twice);
    } else {
      for (const auto& s : splits) {
        const double e =
            std::abs(static_cast<double>(at(s[0])) -
                     0.5 * (static_cast<double>(at(s[1])) + static_cast<double>(at(s[2]))));
        err = e > err ? e : err;
      }
    }
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

  static std::size_t class_of(const ipoint& c) noexcept {
    return static_cast<std::size_t>((c[0] & 3) | ((c[1] & 3) << 2) | ((c[2] & 3) << 4));
  }

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
    return st;
  }

  // Scale-1 diamonds: one stencil per c mod 4. Scale-2 edge midpoints (whose children are the
  // scale-1 cube centres, the costliest stencils): one per c mod 8, so the build reads each
  // subtree once instead of once per parent. The shapes are made once per process.
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
    for (std::size_t cls = 0; cls < shapes.edge2.size(); ++cls) {
      if (shapes.edge2[cls].used) edge2_stencils_[cls] = make_stencil(shapes.edge2[cls]);
    }
  }

  [[nodiscard]] bool interior(const ipoint& c, std::int32_t radius) const noexcept {
    for (std::size_t q = 0; q < 3; ++q) {
      if (c[q] < radius || c[q] + radius > hier->data_max()[q]) return false;
    }
    return true;
  }

  [[nodiscard]] diamond_range from_stencil(const ipoint& c) const noexcept {
    return read_stencil(stencils_[class_of(c)], c);
  }

  [[nodiscard]] diamond_range read_stencil(const stencil& st, const ipoint& c) const noexcept {
    const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
    return summarise([base](std::int64_t o) { return base[o]; }, st.points, st.splits);
  }

  std::array<stencil, 64> stencils_;
  std::array<stencil, 512> edge2_stencils_;
  const T* samples_ = nullptr;
  std::vector<level> levels_;
};

}  // namespace

range_data::range_data(const volume& vol, const hierarchy& hier) {
  vol.visit_samples([&](const auto* samples) {
    using T = std::remove_cv_t<std::remove_pointer_t<decltype(samples)>>;
    impl_ = std::make_unique<typed_range_data<T>>(vol, hier);
  });
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
bool range_data::empty(const ipoint& centre, std::int32_t scale) const noexcept {
  return impl_->empty_at(centre, scale);
}
diamond_range range_data::own(const diamond& d) const noexcept { return impl_->own(d); }
std::size_t range_data::byte_size() const noexcept { return impl_->byte_size(); }

}  // namespace progiso
