#include <progiso/core/range_data.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

namespace progiso {

struct range_data::impl {
  virtual ~impl() = default;
  [[nodiscard]] virtual diamond_range get(const diamond& d) const noexcept = 0;
  [[nodiscard]] virtual std::size_t byte_size() const noexcept = 0;
  const volume* vol = nullptr;
  const hierarchy* hier = nullptr;

  [[nodiscard]] double value(const ipoint& p) const noexcept { return vol->value(p[0], p[1], p[2]); }

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
    if (r.empty()) {
      into.error = std::max(into.error, r.error);
      return;
    }
    if (into.empty()) {
      const double e = std::max(into.error, r.error);
      into = r;
      into.error = e;
      return;
    }
    into.lo = std::min(into.lo, r.lo);
    into.hi = std::max(into.hi, r.hi);
    into.error = std::max(into.error, r.error);
  }

  // Nested range of a scale-1 face or edge diamond, computed from samples.
  [[nodiscard]] diamond_range fine(const diamond& d) const noexcept {
    diamond_range r = own(d);
    if (d.type == 1) {
      std::array<ipoint, 8> ch{};
      const int n = hier->children(d, ch);
      for (int i = 0; i < n; ++i) merge(r, own(hier->make_diamond(ch[static_cast<std::size_t>(i)])));
    }
    return r;
  }
};

namespace {

template <class T>
struct error_type_of {
  using type = std::make_unsigned_t<T>;
};
template <>
struct error_type_of<float> {
  using type = float;
};
template <>
struct error_type_of<double> {
  using type = float;
};
template <class T>
using error_type = typename error_type_of<T>::type;

template <class T>
struct entry {
  T lo;
  T hi;
  error_type<T> error;
};

template <class E>
E quantize_error(double e) noexcept {
  if constexpr (std::is_floating_point_v<E>) {
    auto f = static_cast<float>(e);
    if (static_cast<double>(f) < e) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
  } else {
    const double c = std::ceil(e);
    if (c >= static_cast<double>(std::numeric_limits<E>::max())) return std::numeric_limits<E>::max();
    return static_cast<E>(c);
  }
}

// One dense array of entries per scale, clipped to the part of the grid whose diamonds have a
// descendant reaching into the data box. Per axis, the vertices of the subtree of a diamond of
// scale h centred at c lie within c ± r h, with r = 3 for edge midpoints (own radius h/2 away
// plus a half-scale cube centre's subtree), 4 for face and 5 for cube centres (one more step of
// h each); a scale-1 cube centre's subtree stops at edge midpoints, radius 3. Centres with
// c_q ≥ data_max_q + 5h (scale 1 cube centres: data_max_q + 3) therefore have empty ranges.
template <class T>
class typed_range_data final : public range_data::impl {
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
    if (d.scale == 1) return d.type == 0 ? scale1_cube(d) : fine(d);
    const entry<T>* e = find(d.centre, d.scale);
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

  static entry<T> empty_entry() noexcept {
    return {std::numeric_limits<T>::max(), std::numeric_limits<T>::lowest(), error_type<T>{}};
  }

  static diamond_range decode(const entry<T>& e) noexcept {
    diamond_range r;
    r.lo = static_cast<double>(e.lo);
    r.hi = static_cast<double>(e.hi);
    r.error = static_cast<double>(e.error);
    return r;
  }

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
              const diamond d = h.make_diamond(c);
              diamond_range r = own(d);
              std::array<ipoint, 8> ch{};
              const int n = h.children(d, ch);
              const std::int32_t child_scale = d.type == 2 ? hh / 2 : hh;
              for (int i = 0; i < n; ++i) {
                const ipoint& cc = ch[static_cast<std::size_t>(i)];
                if (child_scale == 1) {
                  merge(r, scale1_cube(h.make_diamond(cc)));
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

  // Nested range of a scale-1 cube centre: a stencil read away from the data boundary, the
  // definition (own range and children's) near it.
  [[nodiscard]] diamond_range scale1_cube(const diamond& d) const noexcept {
    if (interior(d.centre)) return from_stencil(d.centre);
    diamond_range r = own(d);
    std::array<ipoint, 8> ch{};
    const int n = hier->children(d, ch);
    for (int i = 0; i < n; ++i) merge(r, fine(hier->make_diamond(ch[static_cast<std::size_t>(i)])));
    return r;
  }

  // ---- Scale-1 cube centres away from the data boundary: fixed stencils. --------------------
  // The subtree of a scale-1 cube centre (itself, 6 face centres, 12 edge midpoints) has a
  // shape that depends only on c mod 4, so its vertices and split errors are read through
  // offset tables built once from the hierarchy itself, straight from the typed samples.
  struct stencil {
    std::vector<std::int64_t> points;                         // linear offsets
    std::vector<std::array<std::int64_t, 3>> splits;          // centre, spine ends
  };

  [[nodiscard]] bool interior(const ipoint& c) const noexcept {
    for (std::size_t q = 0; q < 3; ++q) {
      if (c[q] < 2 || c[q] + 2 > hier->data_max()[q]) return false;
    }
    return true;
  }

  void make_stencils() {
    const hierarchy probe({17, 17, 17});
    const auto& dims = vol->dims();
    const auto lin = [&](const ipoint& p, const ipoint& c) {
      return (p[0] - c[0]) + dims[0] * ((p[1] - c[1]) + dims[1] * std::int64_t{p[2] - c[2]});
    };
    for (int cls = 0; cls < 8; ++cls) {
      const ipoint c{(cls & 1) ? 7 : 5, (cls & 2) ? 7 : 5, (cls & 4) ? 7 : 5};
      std::vector<diamond> sub{probe.make_diamond(c)};
      std::array<ipoint, 8> ch{};
      const int n1 = probe.children(sub[0], ch);
      for (int i = 0; i < n1; ++i) {
        const diamond f = probe.make_diamond(ch[static_cast<std::size_t>(i)]);
        sub.push_back(f);
        std::array<ipoint, 8> gc{};
        const int n2 = probe.children(f, gc);
        for (int j = 0; j < n2; ++j) sub.push_back(probe.make_diamond(gc[static_cast<std::size_t>(j)]));
      }
      stencil& st = stencils_[static_cast<std::size_t>(cls)];
      for (const diamond& d : sub) {
        st.points.push_back(lin(d.centre, c));
        st.points.push_back(lin(d.spine[0], c));
        st.points.push_back(lin(d.spine[1], c));
        for (int m = 0; m < d.ring_size; ++m) st.points.push_back(lin(d.ring[static_cast<std::size_t>(m)], c));
        st.splits.push_back({lin(d.centre, c), lin(d.spine[0], c), lin(d.spine[1], c)});
      }
      std::sort(st.points.begin(), st.points.end());
      st.points.erase(std::unique(st.points.begin(), st.points.end()), st.points.end());
      std::sort(st.splits.begin(), st.splits.end());
      st.splits.erase(std::unique(st.splits.begin(), st.splits.end()), st.splits.end());
    }
  }

  [[nodiscard]] diamond_range from_stencil(const ipoint& c) const noexcept {
    const int cls = ((c[0] & 3) == 3 ? 1 : 0) | ((c[1] & 3) == 3 ? 2 : 0) | ((c[2] & 3) == 3 ? 4 : 0);
    const stencil& st = stencils_[static_cast<std::size_t>(cls)];
    const T* base = samples_ + vol->linear(c[0], c[1], c[2]);
    T lo = base[0];
    T hi = base[0];
    for (const std::int64_t o : st.points) {
      const T v = base[o];
      lo = v < lo ? v : lo;
      hi = v > hi ? v : hi;
    }
    double err = 0.0;
    for (const auto& s : st.splits) {
      const double e = std::abs(static_cast<double>(base[s[0]]) -
                                0.5 * (static_cast<double>(base[s[1]]) + static_cast<double>(base[s[2]])));
      err = e > err ? e : err;
    }
    diamond_range r;
    r.lo = static_cast<double>(lo);
    r.hi = static_cast<double>(hi);
    r.error = err;
    return r;
  }

  std::array<stencil, 8> stencils_;
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
diamond_range range_data::own(const diamond& d) const noexcept { return impl_->own(d); }
std::size_t range_data::byte_size() const noexcept { return impl_->byte_size(); }

}  // namespace progiso
