#include <progiso/core/contour/contour_split.hpp>

#include <algorithm>

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

vec2 interpolate2(const ipoint2& a, double fa, const ipoint2& b, double fb,
                  double isovalue) noexcept {
  const bool swap = vertex_less2(b, a);
  const ipoint2& p = swap ? b : a;
  const ipoint2& q = swap ? a : b;
  const double fp = swap ? fb : fa;
  const double fq = swap ? fa : fb;
  double t = (isovalue - fp) / (fq - fp);
  if (!(t >= interpolation_margin)) t = interpolation_margin;
  if (t > 1.0 - interpolation_margin) t = 1.0 - interpolation_margin;
  return {static_cast<double>(p[0]) + t * static_cast<double>(q[0] - p[0]),
          static_cast<double>(p[1]) + t * static_cast<double>(q[1] - p[1])};
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

std::uint64_t owner_of(const hierarchy2d& hier, const std::array<ipoint2, 3>& t) noexcept {
  std::int64_t best = -1;
  std::size_t bi = 0, bj = 1;
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = i + 1; j < 3; ++j) {
      const std::int64_t dx = t[i][0] - t[j][0];
      const std::int64_t dy = t[i][1] - t[j][1];
      if (dx * dx + dy * dy > best) {
        best = dx * dx + dy * dy;
        bi = i;
        bj = j;
      }
    }
  }
  const std::int32_t sx = t[bi][0] + t[bj][0];
  const std::int32_t sy = t[bi][1] + t[bj][1];
  if ((sx | sy) & 1) return ~std::uint64_t{0};
  const ipoint2 m{sx / 2, sy / 2};
  return hier.is_diamond(m) ? hier.index(m) : ~std::uint64_t{0};
}

struct op_list {
  contour_split_summary& s;
  void add(contour_primitive k, std::uint64_t a0, std::uint64_t a1 = no_key,
           std::uint64_t a2 = no_key, std::uint64_t a3 = no_key) {
    s.ops[static_cast<std::size_t>(s.op_count++)] = contour_op{k, {a0, a1, a2, a3}};
  }
};

}  // namespace

namespace {

// compute_contour_split(), each new segment handed to emit(owner, keys, triangle, values, ends)
// (ends as march_corners()).
template <class Emit>
contour_split_summary split_diamond(const hierarchy2d& hier, const volume& image, double w,
                                    const diamond2& d, Emit&& emit) {
  contour_split_summary s;
  const auto value = [&](const ipoint2& p) { return image.value(p[0], p[1], 0); };
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
  for (int i = 0; i < n; ++i) {
    const side& x = sides[static_cast<std::size_t>(i)];
    std::array<std::uint64_t, 2> k{};
    if (march_triangle({c, dd, x.p}, {fc, fd, x.f}, w, k)) ++s.removed_segments;
    for (int half = 0; half < 2; ++half) {
      const std::array<ipoint2, 3> t =
          half == 0 ? std::array<ipoint2, 3>{c, e, x.p} : std::array<ipoint2, 3>{e, dd, x.p};
      const std::array<double, 3> f =
          half == 0 ? std::array<double, 3>{fc, fe, x.f} : std::array<double, 3>{fe, fd, x.f};
      std::array<std::array<std::size_t, 2>, 2> ends{};
      if (march_corners(t, f, w, k, ends)) {
        emit(owner_of(hier, t), k, t, f, ends);
        ++s.added_segments;
      }
    }
  }

  // ---- Case and primitives. -----------------------------------------------------------------
  const auto K = [](const ipoint2& p, const ipoint2& q) { return edge_key2(p, q); };
  op_list ops{s};
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

}  // namespace

contour_split_summary compute_contour_split(const hierarchy2d& hier, const volume& image, double w,
                                            const diamond2& d, std::vector<owned_segment>& out) {
  return split_diamond(hier, image, w, d,
                       [&out](std::uint64_t owner, const std::array<std::uint64_t, 2>& k,
                              const std::array<ipoint2, 3>&, const std::array<double, 3>&,
                              const std::array<std::array<std::size_t, 2>, 2>&) {
                         out.push_back({owner, k});
                       });
}

namespace detail {

contour_split_summary compute_placed_contour_split(const hierarchy2d& hier, const volume& image,
                                                   double isovalue, const diamond2& d,
                                                   std::vector<placed_segment>& out) {
  return split_diamond(
      hier, image, isovalue, d,
      [&out, isovalue](std::uint64_t owner, const std::array<std::uint64_t, 2>& k,
                       const std::array<ipoint2, 3>& t, const std::array<double, 3>& f,
                       const std::array<std::array<std::size_t, 2>, 2>& ends) {
        const auto at = [&](std::size_t e) {
          const auto [a, b] = ends[e];
          return interpolate2(t[a], f[a], t[b], f[b], isovalue);
        };
        out.push_back({{owner, k}, {at(0), at(1)}});
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
