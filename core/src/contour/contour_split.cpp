#include <progiso/core/contour/contour_split.hpp>

#include <algorithm>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/contour/detail/contour_frontier.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso {

std::string_view to_string(contour_case c) noexcept {
  static constexpr std::string_view names[] = {"none", "a", "b", "c", "d", "e", "f", "g", "h"};
  return names[static_cast<std::size_t>(c)];
}

std::string_view to_string(contour_primitive p) noexcept {
  static constexpr std::string_view names[] = {"VertexMove", "VertexSplit", "VertexOpen",
                                               "EdgeFlip",   "NewEdge",     "NewLoop"};
  return names[static_cast<std::size_t>(p)];
}

namespace {

// march_triangle(), also naming the corners its segment joins: ends[k] = {lone corner, other
// corner} of the edge of out[k].
bool march_corners(const std::array<ipoint2, 3>& p, const std::array<double, 3>& f, double isovalue,
                   std::array<std::uint64_t, 2>& out,
                   std::array<std::array<std::size_t, 2>, 2>& ends) noexcept {
  const bool b0 = f[0] > isovalue;
  const bool b1 = f[1] > isovalue;
  const bool b2 = f[2] > isovalue;
  if (b0 == b1 && b1 == b2) return false;
  // The lone vertex differs in colour from the other two.
  const std::size_t lone = b1 == b2 ? 0 : (b0 == b2 ? 1 : 2);
  const std::size_t o1 = (lone + 1) % 3;
  const std::size_t o2 = (lone + 2) % 3;
  out = {edge_key2(p[lone], p[o1]), edge_key2(p[lone], p[o2])};
  ends = {{{lone, o1}, {lone, o2}}};
  const bool lone_black = (lone == 0 ? b0 : (lone == 1 ? b1 : b2));
  const ipoint2& black = lone_black ? p[lone] : p[o1];
  const ipoint2 m1 = edge_key2_point(out[0]);
  const ipoint2 m2 = edge_key2_point(out[1]);
  const std::int64_t ux = m2[0] - m1[0], uy = m2[1] - m1[1];
  const std::int64_t vx = 2 * std::int64_t{black[0]} - m1[0];
  const std::int64_t vy = 2 * std::int64_t{black[1]} - m1[1];
  if (ux * vy - uy * vx < 0) {
    std::swap(out[0], out[1]);
    std::swap(ends[0], ends[1]);
  }
  return true;
}

}  // namespace

bool march_triangle(const std::array<ipoint2, 3>& p, const std::array<double, 3>& f,
                    double isovalue, std::array<std::uint64_t, 2>& out) noexcept {
  std::array<std::array<std::size_t, 2>, 2> ends{};
  return march_corners(p, f, isovalue, out, ends);
}

namespace {

// The diamond owning a new triangle of a split, (spine end, centre, apex) or (centre, spine end,
// apex): the one centred on its longest edge, from the spine end to the apex (the halves of a
// right isosceles triangle are right-angled at the centre), or none when that edge is a finest
// one (odd doubled midpoint).
std::uint64_t owner_of(const hierarchy2d& hier, const ipoint2& end, const ipoint2& apex) noexcept {
  const std::int32_t sx = end[0] + apex[0];
  const std::int32_t sy = end[1] + apex[1];
  if ((sx | sy) & 1) return ~std::uint64_t{0};
  const ipoint2 m{sx / 2, sy / 2};
  return hier.is_diamond(m) ? hier.index(m) : ~std::uint64_t{0};
}

// The primitive sequence of a split; with Keys false only the primitives' kinds (what the
// refiners count), and the keys naming their vertices are never computed.
template <bool Keys>
struct op_list {
  contour_split_summary& s;
  void add(contour_primitive k, std::uint64_t a0, std::uint64_t a1 = no_key,
           std::uint64_t a2 = no_key, std::uint64_t a3 = no_key) {
    if constexpr (Keys) {
      s.ops[static_cast<std::size_t>(s.op_count++)] = contour_op{k, {a0, a1, a2, a3}};
    } else {
      s.ops[static_cast<std::size_t>(s.op_count++)].kind = k;
    }
  }
};

}  // namespace

namespace {

// Marching one new triangle of a split by table. Corners 0, 1, 2; edge q joins corners q and
// q + 1 mod 3 (0: 01, 1: 12, 2: 20). For colour bits b (bit i: corner i black) of a crossed
// triangle, the lone corner is the one whose colour the other two do not share, and the segment
// runs from the crossing on the edge (lone, lone + 1) to the one on (lone, lone + 2), swapped so
// that black lies on its left: march_triangle()'s rule, where the sign of that test is the
// triangle's orientation, negated when the lone corner is white (tests/core/contour_split_test.cpp
// checks the two against each other for every colouring).
struct triangle_case {
  std::uint8_t crossed;
  std::uint8_t lone_black;
  std::array<std::uint8_t, 2> edges;  // edge indices of the two ends, lone corner's order
};
constexpr std::array<triangle_case, 8> triangle_cases = [] {
  std::array<triangle_case, 8> t{};
  for (unsigned bits = 1; bits < 7; ++bits) {
    const bool b0 = (bits & 1u) != 0, b1 = (bits & 2u) != 0, b2 = (bits & 4u) != 0;
    const unsigned lone = b1 == b2 ? 0 : (b0 == b2 ? 1 : 2);
    // Edge (lone, lone + 1) is edge `lone`; edge (lone, lone + 2) is edge lone + 2 mod 3.
    t[bits] = {1,
               static_cast<std::uint8_t>((bits >> lone) & 1u),
               {static_cast<std::uint8_t>(lone), static_cast<std::uint8_t>((lone + 2) % 3)}};
  }
  return t;
}();

// The split class's case and primitive kinds, by the rules split_diamond() follows with keys
// (tests/core/contour_split_test.cpp checks the two against each other for every colouring).
// Bits: 1 spine0 (c) black, 2 spine1 (d) black, 4 centre (e) black, 8 first apex in the grid
// black, 16 second black; then 32 × triangle count.
constexpr contour_split_class classify(unsigned k) noexcept {
  contour_split_class out;
  const bool bc = (k & 1u) != 0, bd = (k & 2u) != 0, be = (k & 4u) != 0;
  const bool a = (k & 8u) != 0, b = (k & 16u) != 0;
  const unsigned n = k >> 5;
  const auto add = [&out](contour_primitive p) { out.ops[out.op_count++] = p; };
  if (n == 0) return out;
  if (bc != bd) {
    add(contour_primitive::vertex_move);
    if (a != be) add(contour_primitive::vertex_split);
    if (n == 2 && b != be) add(contour_primitive::vertex_split);
    out.kind = n == 2 && a != b ? contour_case::c : (a == be ? contour_case::a : contour_case::b);
  } else if (be == bc) {
    if (a != bc) add(contour_primitive::vertex_split);
    if (n == 2 && b != bc) add(contour_primitive::vertex_split);
    out.kind =
        n == 2 && a != b ? contour_case::e : (a == bc ? contour_case::none : contour_case::d);
  } else if (n == 2) {
    if (a == bc && b == bc) {
      out.kind = contour_case::g;
      add(contour_primitive::new_loop);
    } else if (a != bc && b != bc) {
      out.kind = contour_case::h;
      add(contour_primitive::edge_flip);
      add(contour_primitive::vertex_split);
      add(contour_primitive::vertex_split);
    } else {
      out.kind = contour_case::f;
      add(contour_primitive::vertex_split);
      add(contour_primitive::vertex_split);
      add(contour_primitive::vertex_split);
    }
  } else if (a == bc) {
    out.kind = contour_case::g;
    add(contour_primitive::new_edge);
    add(contour_primitive::vertex_split);
  } else {
    out.kind = contour_case::h;
    add(contour_primitive::vertex_split);
    add(contour_primitive::vertex_open);
  }
  return out;
}

constexpr std::array<contour_split_class, contour_split_classes> split_classes = [] {
  std::array<contour_split_class, contour_split_classes> t{};
  for (unsigned k = 0; k < contour_split_classes; ++k) t[k] = classify(k);
  return t;
}();

// compute_contour_split(), each new segment handed to emit(owner, keys, positions) (positions
// computed only when Placed: interpolate2 of each crossed edge, once per edge; the primitives'
// keys only when Keys); value(p) reads the sample at grid point p, clamped into the data box.
template <bool Placed, bool Keys, class Value, class Emit>
contour_split_summary split_diamond(const hierarchy2d& hier, Value&& value, double w,
                                    const diamond2& d, Emit&& emit) {
  contour_split_summary s;
  const ipoint2& c = d.spine[0];
  const ipoint2& dd = d.spine[1];
  const ipoint2& e = d.centre;
  const double fc = value(c), fd = value(dd), fe = value(e);
  const bool bc = fc > w, bd = fd > w, be = fe > w;
  struct side {
    ipoint2 p;
    double f;
    bool black;
  };
  std::array<side, 2> sides{};
  int n = 0;
  for (std::size_t m = 0; m < 2; ++m) {
    if (!((d.ring_in_grid >> m) & 1u)) continue;
    const double f = value(d.ring[m]);
    sides[static_cast<std::size_t>(n++)] = {d.ring[m], f, f > w};
  }
  s.triangles = n;
  s.boundary = n == 1;

  // ---- Segments: old triangles (counted), new triangles (recorded). ------------------------
  const auto place = [&](const ipoint2& a, double fa, const ipoint2& b, double fb) {
    if constexpr (Placed) {
      return interpolate2(a, fa, b, fb, w);
    } else {
      return vec2{};
    }
  };
  const vec2 at_ce = bc != be ? place(c, fc, e, fe) : vec2{};
  const vec2 at_ed = be != bd ? place(e, fe, dd, fd) : vec2{};
  const std::uint64_t key_ce = edge_key2(c, e);
  const std::uint64_t key_ed = edge_key2(e, dd);
  const std::int64_t ux = e[0] - c[0], uy = e[1] - c[1];
  for (int i = 0; i < n; ++i) {
    const side& x = sides[static_cast<std::size_t>(i)];
    if (bc != bd || bc != x.black) ++s.removed_segments;
    // Both halves, (c, e, x) and (e, dd, x), turn the same way as (c, e, x): e lies on c–dd.
    const bool clockwise =
        ux * (std::int64_t{x.p[1]} - c[1]) - uy * (std::int64_t{x.p[0]} - c[0]) < 0;
    const vec2 at_ex = be != x.black ? place(e, fe, x.p, x.f) : vec2{};
    const vec2 at_cx = bc != x.black ? place(c, fc, x.p, x.f) : vec2{};
    const vec2 at_dx = bd != x.black ? place(dd, fd, x.p, x.f) : vec2{};
    const std::uint64_t key_ex = edge_key2(e, x.p);
    for (int half = 0; half < 2; ++half) {
      // Corners (c, e, x): edges ce, ex, xc; corners (e, dd, x): edges ed, dx, xe.
      const unsigned bits = half == 0 ? (bc ? 1u : 0u) | (be ? 2u : 0u) | (x.black ? 4u : 0u)
                                      : (be ? 1u : 0u) | (bd ? 2u : 0u) | (x.black ? 4u : 0u);
      const triangle_case& tc = triangle_cases[bits];
      if (tc.crossed == 0) continue;
      const std::array<std::uint64_t, 3> keys =
          half == 0 ? std::array<std::uint64_t, 3>{key_ce, key_ex, edge_key2(c, x.p)}
                    : std::array<std::uint64_t, 3>{key_ed, edge_key2(dd, x.p), key_ex};
      const std::array<const vec2*, 3> at =
          half == 0 ? std::array<const vec2*, 3>{&at_ce, &at_ex, &at_cx}
                    : std::array<const vec2*, 3>{&at_ed, &at_dx, &at_ex};
      std::size_t q0 = tc.edges[0], q1 = tc.edges[1];
      if ((tc.lone_black != 0) == clockwise) std::swap(q0, q1);
      emit(owner_of(hier, half == 0 ? c : dd, x.p),
           std::array<std::uint64_t, 2>{keys[q0], keys[q1]}, std::array<vec2, 2>{*at[q0], *at[q1]});
      ++s.added_segments;
    }
  }

  // ---- Case and primitives. -----------------------------------------------------------------
  s.split_class = static_cast<std::uint8_t>(
      (bc ? 1u : 0u) | (bd ? 2u : 0u) | (be ? 4u : 0u) | (n >= 1 && sides[0].black ? 8u : 0u) |
      (n == 2 && sides[1].black ? 16u : 0u) | (static_cast<unsigned>(n) << 5));
  if constexpr (!Keys) {
    // The kinds alone, by table: no branch on the colours.
    const contour_split_class& k = split_classes[s.split_class];
    s.kind = k.kind;
    s.op_count = k.op_count;
    for (std::size_t i = 0; i < 4; ++i) s.ops[i].kind = k.ops[i];
    return s;
  }
  const auto K = [](const ipoint2& p, const ipoint2& q) { return edge_key2(p, q); };
  op_list<Keys> ops{s};
  if (n == 0) return s;
  const side& sa = sides[0];
  if (bc != bd) {
    const std::uint64_t moved = bc != be ? K(c, e) : K(e, dd);
    ops.add(contour_primitive::vertex_move, K(c, dd), moved);
    for (int i = 0; i < n; ++i) {
      const side& x = sides[static_cast<std::size_t>(i)];
      if (x.black == be) continue;
      const std::uint64_t old_side = x.black != bc ? K(c, x.p) : K(dd, x.p);
      ops.add(contour_primitive::vertex_split, moved, K(e, x.p), old_side);
    }
    if (n == 2) {
      const side& sb = sides[1];
      s.kind = sa.black == sb.black ? (sa.black == be ? contour_case::a : contour_case::b)
                                    : contour_case::c;
    } else {
      s.kind = sa.black == be ? contour_case::a : contour_case::b;
    }
  } else if (be == bc) {
    for (int i = 0; i < n; ++i) {
      const side& x = sides[static_cast<std::size_t>(i)];
      if (x.black == bc) continue;
      ops.add(contour_primitive::vertex_split, K(c, x.p), K(e, x.p), K(dd, x.p));
    }
    if (n == 2) {
      const side& sb = sides[1];
      s.kind = sa.black == sb.black ? (sa.black == bc ? contour_case::none : contour_case::d)
                                    : contour_case::e;
    } else {
      s.kind = sa.black == bc ? contour_case::none : contour_case::d;
    }
  } else if (n == 2) {
    const side& sb = sides[1];
    if (sa.black == bc && sb.black == bc) {
      s.kind = contour_case::g;
      ops.add(contour_primitive::new_loop, K(c, e), K(sa.p, e), K(dd, e), K(sb.p, e));
    } else if (sa.black != bc && sb.black != bc) {
      s.kind = contour_case::h;
      ops.add(contour_primitive::edge_flip, K(c, sa.p), K(dd, sa.p), K(c, sb.p), K(dd, sb.p));
      ops.add(contour_primitive::vertex_split, K(c, sa.p), K(c, e), K(c, sb.p));
      ops.add(contour_primitive::vertex_split, K(dd, sa.p), K(dd, e), K(dd, sb.p));
    } else {
      s.kind = contour_case::f;
      const side& x = sa.black != bc ? sa : sb;
      const side& y = sa.black != bc ? sb : sa;
      ops.add(contour_primitive::vertex_split, K(c, x.p), K(c, e), K(dd, x.p));
      ops.add(contour_primitive::vertex_split, K(c, e), K(y.p, e), K(dd, x.p));
      ops.add(contour_primitive::vertex_split, K(y.p, e), K(dd, e), K(dd, x.p));
    }
  } else if (sa.black == bc) {
    s.kind = contour_case::g;
    ops.add(contour_primitive::new_edge, K(c, e), K(sa.p, e));
    ops.add(contour_primitive::vertex_split, K(sa.p, e), K(dd, e));
  } else {
    s.kind = contour_case::h;
    ops.add(contour_primitive::vertex_split, K(dd, sa.p), K(dd, e), K(c, sa.p));
    ops.add(contour_primitive::vertex_open, K(dd, e), K(c, e), K(c, sa.p));
  }
  return s;
}

// Calls f(value) with a reader of the image's samples at grid points, clamped into the data box:
// typed (one switch per split, not one per sample) unless the image is smoothed.
template <class F>
decltype(auto) with_sample_reader(const volume& image, F&& f) {
  if (image.subdivided() != nullptr) {
    return f([&image](const ipoint2& p) { return image.value(p[0], p[1], 0); });
  }
  const std::int32_t xmax = static_cast<std::int32_t>(image.dims()[0] - 1);
  const std::int32_t ymax = static_cast<std::int32_t>(image.dims()[1] - 1);
  return image.visit_samples([&](const auto* samples) {
    return f([samples, xmax, ymax](const ipoint2& p) {
      const std::int64_t x = std::clamp(p[0], 0, xmax);
      const std::int64_t y = std::clamp(p[1], 0, ymax);
      return static_cast<double>(samples[x + (std::int64_t{xmax} + 1) * y]);
    });
  });
}

}  // namespace

const contour_split_class& contour_split_class_info(std::size_t k) noexcept {
  PROGISO_ASSERT(k < contour_split_classes);
  return split_classes[k];
}

contour_split_summary compute_contour_split(const hierarchy2d& hier, const volume& image, double w,
                                            const diamond2& d, std::vector<owned_segment>& out) {
  return with_sample_reader(image, [&](auto&& value) {
    return split_diamond<false, true>(
        hier, value, w, d,
        [&out](std::uint64_t owner, const std::array<std::uint64_t, 2>& k,
               const std::array<vec2, 2>&) {
          out.push_back({owner, k});
        });
  });
}

namespace detail {

contour_split_summary compute_placed_contour_split(const hierarchy2d& hier, const volume& image,
                                                   double isovalue, const diamond2& d,
                                                   std::vector<placed_segment>& out) {
  return with_sample_reader(image, [&](auto&& value) {
    return split_diamond<true, false>(
        hier, value, isovalue, d,
        [&out](std::uint64_t owner, const std::array<std::uint64_t, 2>& k,
               const std::array<vec2, 2>& pos) {
          out.push_back({{owner, k}, pos});
        });
  });
}

contour_split_summary compute_placed_contour_split(const hierarchy2d& hier, const volume& image,
                                                   double isovalue, const diamond2& d,
                                                   placed_segment* out) {
  return with_sample_reader(image, [&](auto&& value) {
    return split_diamond<true, false>(
        hier, value, isovalue, d,
        [&out](std::uint64_t owner, const std::array<std::uint64_t, 2>& k,
               const std::array<vec2, 2>& pos) {
          *out++ = {{owner, k}, pos};
        });
  });
}

}  // namespace detail

namespace {

key_segment seg(std::uint64_t a, std::uint64_t b) noexcept {
  return a < b ? key_segment{a, b} : key_segment{b, a};
}

void take(std::vector<key_segment>& segs, std::uint64_t a, std::uint64_t b, const char* op) {
  const auto it = std::find(segs.begin(), segs.end(), seg(a, b));
  if (it == segs.end()) {
    throw error(std::string(op) + ": the contour has no segment between the given vertices");
  }
  segs.erase(it);
}

}  // namespace

void apply_contour_ops(std::vector<key_segment>& segs, const contour_op* ops, int count) {
  for (int i = 0; i < count; ++i) {
    const contour_op& op = ops[i];
    const auto& a = op.args;
    switch (op.kind) {
      case contour_primitive::vertex_move: {
        bool found = false;
        for (auto& s : segs) {
          for (auto& k : s) {
            if (k == a[0]) {
              k = a[1];
              found = true;
            }
          }
          s = seg(s[0], s[1]);
        }
        if (!found) throw error("VertexMove: the contour has no such vertex");
        break;
      }
      case contour_primitive::vertex_split:
        if (a[2] != no_key) {
          take(segs, a[0], a[2], "VertexSplit");
          segs.push_back(seg(a[1], a[2]));
        }
        segs.push_back(seg(a[0], a[1]));
        break;
      case contour_primitive::vertex_open:
        take(segs, a[0], a[2], "VertexOpen");
        segs.push_back(seg(a[1], a[2]));
        break;
      case contour_primitive::edge_flip:
        take(segs, a[0], a[1], "EdgeFlip");
        take(segs, a[2], a[3], "EdgeFlip");
        segs.push_back(seg(a[0], a[2]));
        segs.push_back(seg(a[1], a[3]));
        break;
      case contour_primitive::new_edge:
        segs.push_back(seg(a[0], a[1]));
        break;
      case contour_primitive::new_loop:
        segs.push_back(seg(a[0], a[1]));
        segs.push_back(seg(a[1], a[2]));
        segs.push_back(seg(a[2], a[3]));
        segs.push_back(seg(a[3], a[0]));
        break;
    }
  }
}

}  // namespace progiso
