#include <progiso/core/hierarchy/hierarchy.hpp>

#include <algorithm>
#include <bit>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso {
namespace {

ipoint add(const ipoint& a, const ipoint& b) noexcept {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}

ipoint axis(int q, std::int32_t len) noexcept {
  ipoint v{0, 0, 0};
  v[static_cast<std::size_t>(q)] = len;
  return v;
}

}  // namespace

int hierarchy::choose_levels(const ipoint& data_max, std::int64_t min_extent) noexcept {
  int largest = 0;  // largest L with 2^L ≤ the smallest extent
  while ((std::int64_t{2} << largest) <= min_extent) ++largest;
  const auto padded = [&](int l) {  // grid vertices with root cubes of side 2^l
    const std::int64_t n = std::int64_t{1} << l;
    double v = 1.0;
    for (std::size_t q = 0; q < 3; ++q) v *= static_cast<double>((data_max[q] + n - 1) / n * n + 1);
    return v;
  };
  const int smallest = std::min(largest, min_root_levels);
  double fewest = padded(largest);
  for (int l = smallest; l < largest; ++l) fewest = std::min(fewest, padded(l));
  int l = largest;
  while (l > smallest && padded(l) > max_padding_ratio * fewest) --l;
  return l;
}

hierarchy::hierarchy(const index3& data_dims) {
  std::int64_t min_extent = data_dims[0] - 1;
  for (std::size_t q = 0; q < 3; ++q) {
    if (data_dims[q] < 2) {
      throw error("volume dims " + std::to_string(data_dims[0]) + "," +
                  std::to_string(data_dims[1]) + "," + std::to_string(data_dims[2]) +
                  ": 3D extraction needs at least 2 samples along every axis");
    }
    if (data_dims[q] > (std::int64_t{1} << 15) + 1) {
      throw error("hierarchy: dims above 32769 per axis are not supported");
    }
    min_extent = std::min(min_extent, data_dims[q] - 1);
  }
  for (std::size_t q = 0; q < 3; ++q) data_max_[q] = static_cast<std::int32_t>(data_dims[q] - 1);
  levels_ = choose_levels(data_max_, min_extent);
  root_ = std::int32_t{1} << levels_;
  for (std::size_t q = 0; q < 3; ++q) {
    cubes_[q] = (data_max_[q] + root_ - 1) / root_;
    grid_max_[q] = cubes_[q] * root_;
  }
  stride_y_ = static_cast<std::uint64_t>(grid_max_[0]) + 1;
  stride_z_ = stride_y_ * (static_cast<std::uint64_t>(grid_max_[1]) + 1);
  vertex_count_ = stride_z_ * (static_cast<std::uint64_t>(grid_max_[2]) + 1);
  inverse_y_ = 1.0 / static_cast<double>(stride_y_);
  for (unsigned code = 0; code < doubled_offset_.size(); ++code) {
    const std::array<int, 3> o = half_offset_of(code);
    doubled_offset_[code] = std::int64_t{o[0]} + o[1] * static_cast<std::int64_t>(stride_y_) +
                            o[2] * static_cast<std::int64_t>(stride_z_);
  }
  inverse_z_ = 1.0 / static_cast<double>(stride_z_);
}

bool hierarchy::is_diamond(const ipoint& p) const noexcept {
  return in_grid(p) && scale_of(p) < root_;
}

diamond hierarchy::make_diamond(const ipoint& c) const noexcept {
  PROGISO_ASSERT(is_diamond(c));
  diamond d;
  d.centre = c;
  const std::int32_t h = scale_of(c);
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  d.scale = h;
  ipoint s{0, 0, 0};
  int odd_axes[3];
  int even_axes[3];
  int n_odd = 0;
  int n_even = 0;
  for (int q = 0; q < 3; ++q) {
    const auto uq = static_cast<std::size_t>(q);
    if ((c[uq] >> lg) & 1) {
      s[uq] = ((c[uq] + h) & (4 * h - 1)) == 0 ? 1 : -1;
      odd_axes[n_odd++] = q;
    } else {
      even_axes[n_even++] = q;
    }
  }
  d.type = 3 - n_odd;
  d.depth = 3 * (levels_ - 1 - lg) + d.type;
  const ipoint hs{h * s[0], h * s[1], h * s[2]};
  d.spine[0] = {c[0] - hs[0], c[1] - hs[1], c[2] - hs[2]};
  d.spine[1] = add(c, hs);
  const ipoint& a = d.spine[0];
  switch (d.type) {
    case 0: {
      // The six cube corners off the diagonal, walking around it: each step changes one axis.
      const ipoint ex = axis(0, 2 * hs[0]);
      const ipoint ey = axis(1, 2 * hs[1]);
      const ipoint ez = axis(2, 2 * hs[2]);
      d.ring_size = 6;
      d.ring[0] = add(a, ex);
      d.ring[1] = add(add(a, ex), ey);
      d.ring[2] = add(a, ey);
      d.ring[3] = add(add(a, ey), ez);
      d.ring[4] = add(a, ez);
      d.ring[5] = add(add(a, ez), ex);
      break;
    }
    case 1: {
      // Two cube centres across the face, alternating with the face's other two corners.
      const int i = odd_axes[0];
      const int j = odd_axes[1];
      const int k = even_axes[0];
      const ipoint ek = axis(k, h);
      ipoint q =
          add(axis(i, hs[static_cast<std::size_t>(i)]), axis(j, -hs[static_cast<std::size_t>(j)]));
      d.ring_size = 4;
      d.ring[0] = add(c, ek);
      d.ring[1] = add(c, q);
      d.ring[2] = {c[0] - ek[0], c[1] - ek[1], c[2] - ek[2]};
      d.ring[3] = {c[0] - q[0], c[1] - q[1], c[2] - q[2]};
      break;
    }
    default: {
      // Four face centres alternating with four cube centres around the axis edge.
      const int j = even_axes[0];
      const int k = even_axes[1];
      static constexpr int dj[8] = {1, 1, 0, -1, -1, -1, 0, 1};
      static constexpr int dk[8] = {0, 1, 1, 1, 0, -1, -1, -1};
      d.ring_size = 8;
      for (std::size_t m = 0; m < 8; ++m) {
        d.ring[m] = add(c, add(axis(j, dj[m] * h), axis(k, dk[m] * h)));
      }
      break;
    }
  }
  d.ring_in_grid = 0;
  for (int m = 0; m < d.ring_size; ++m) {
    if (in_grid(d.ring[static_cast<std::size_t>(m)])) {
      d.ring_in_grid = static_cast<std::uint8_t>(d.ring_in_grid | (1u << m));
    }
  }
  return d;
}

int hierarchy::parents(const diamond& d, std::array<ipoint, 4>& out) const noexcept {
  int n = 0;
  if (d.depth == 0) return 0;
  for (int m = 0; m < d.ring_size; ++m) {
    const ipoint& r = d.ring[static_cast<std::size_t>(m)];
    if (!((d.ring_in_grid >> m) & 1u) || scale_of(r) >= root_) continue;
    if (depth_of(r) == d.depth - 1) out[static_cast<std::size_t>(n++)] = r;
  }
  return n;
}

int hierarchy::parent_count(const ipoint& c) const noexcept {
  const std::int32_t h = scale_of(c);
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  int odd = 0;
  for (std::size_t q = 0; q < 3; ++q) odd += (c[q] >> lg) & 1;
  if (odd == 3) {
    // A cube centre: its parents are three corners of its own cube, inside the grid, unless
    // it is a root.
    return h == root_ / 2 ? 0 : 3;
  }
  // Face centres and edge midpoints: parents at c ± h along each even axis.
  int n = 0;
  for (std::size_t q = 0; q < 3; ++q) {
    if ((c[q] >> lg) & 1) continue;
    n += c[q] - h >= 0 ? 1 : 0;
    n += c[q] + h <= grid_max_[q] ? 1 : 0;
  }
  return n;
}

int hierarchy::children(const diamond& d, std::array<ipoint, 8>& out) const noexcept {
  return children_at(d.centre, d.scale, d.type, out);
}

int hierarchy::children(const ipoint& c, std::array<ipoint, 8>& out) const noexcept {
  const std::int32_t h = scale_of(c);
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  int odd = 0;
  for (std::size_t q = 0; q < 3; ++q) odd += (c[q] >> lg) & 1;
  return children_at(c, h, 3 - odd, out);
}

int hierarchy::children_at(const ipoint& c, std::int32_t h, int type,
                           std::array<ipoint, 8>& out) const noexcept {
  int n = 0;
  auto push = [&](const ipoint& p) {
    if (in_grid(p)) out[static_cast<std::size_t>(n++)] = p;
  };
  if (type == 2) {
    if (h < 2) return 0;
    const std::int32_t g = h / 2;
    for (int m = 0; m < 8; ++m) {
      push({c[0] + ((m & 1) ? g : -g), c[1] + ((m & 2) ? g : -g), c[2] + ((m & 4) ? g : -g)});
    }
    return n;
  }
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  for (int q = 0; q < 3; ++q) {
    const auto uq = static_cast<std::size_t>(q);
    const bool odd = ((c[uq] >> lg) & 1) != 0;
    if (type == 1 && !odd) continue;
    push(add(c, axis(q, h)));
    push(add(c, axis(q, -h)));
  }
  return n;
}

// Parent counts from the parent's side (the hierarchy's facts in docs/ARCHITECTURE.md, as
// parent_count() applies them):
//  * type 0 at c (scale h) has the face centres f = c ± h e_q (type 1, scale h). A face centre's
//    parents lie at f ± h along its one even axis q: c itself and c ± 2h e_q.
//  * type 1 at c (scale h, even axis q0) has the edge midpoints e = c ± h e_q on its odd axes
//    (type 2, scale h), whose even axes are q0 and q: parents c, c ± 2h e_q and e ± h e_q0.
//  * type 2 at c (scale h ≥ 2) has the cube centres c + (h/2)(±1, ±1, ±1) (type 0), each with
//    three parents (corners of its own cube; a child is never a root).
child_list hierarchy::children_of(const ipoint& c, std::int32_t h, int type) const noexcept {
  child_list out;
  // Away from the grid's faces (c ± 2h inside) every child and every parent candidate is a grid
  // vertex: all children, with 2 (face centres), 4 (edge midpoints) or 3 (cube centres) parents.
  if (c[0] >= 2 * h && c[1] >= 2 * h && c[2] >= 2 * h && c[0] + 2 * h <= grid_max_[0] &&
      c[1] + 2 * h <= grid_max_[1] && c[2] + 2 * h <= grid_max_[2]) {
    if (type == 2) {
      out.type = 0;
      out.scale = h / 2;
      if (h < 2) return out;
      const std::int32_t g = h / 2;
      for (std::size_t m = 0; m < 8; ++m) {
        out.centre[m] = {c[0] + ((m & 1) ? g : -g), c[1] + ((m & 2) ? g : -g),
                         c[2] + ((m & 4) ? g : -g)};
      }
      out.parents.fill(3);
      out.count = 8;
      return out;
    }
    out.scale = h;
    out.type = type + 1;
    const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
    const std::uint8_t parents = type == 0 ? 2 : 4;
    for (std::size_t q = 0; q < 3; ++q) {
      if (type == 1 && ((c[q] >> lg) & 1) == 0) continue;  // the face centre's even axis
      for (const std::int32_t s : {h, -h}) {
        const auto i = static_cast<std::size_t>(out.count++);
        out.centre[i] = c;
        out.centre[i][q] += s;
        out.parents[i] = parents;
      }
    }
    return out;
  }
  const auto within = [&](std::int64_t v, std::size_t q) { return v >= 0 && v <= grid_max_[q]; };
  if (type == 2) {
    out.type = 0;
    out.scale = h / 2;
    if (h < 2) return out;
    const std::int32_t g = h / 2;
    for (int m = 0; m < 8; ++m) {
      const ipoint p{c[0] + ((m & 1) ? g : -g), c[1] + ((m & 2) ? g : -g),
                     c[2] + ((m & 4) ? g : -g)};
      if (!in_grid(p)) continue;
      const auto i = static_cast<std::size_t>(out.count++);
      out.centre[i] = p;
      out.parents[i] = 3;
    }
    return out;
  }
  out.scale = h;
  out.type = type + 1;
  const int lg = std::countr_zero(static_cast<std::uint32_t>(h));
  std::size_t q0 = 0;  // type 1: the even axis
  for (std::size_t q = 0; q < 3; ++q) {
    if (((c[q] >> lg) & 1) == 0) q0 = q;
  }
  const int beside = type == 1 ? (within(std::int64_t{c[q0]} - h, q0) ? 1 : 0) +
                                     (within(std::int64_t{c[q0]} + h, q0) ? 1 : 0)
                               : 0;
  for (std::size_t q = 0; q < 3; ++q) {
    if (type == 1 && q == q0) continue;
    for (const std::int32_t s : {h, -h}) {
      ipoint p = c;
      p[q] += s;
      if (!within(p[q], q)) continue;
      const auto i = static_cast<std::size_t>(out.count++);
      out.centre[i] = p;
      out.parents[i] =
          static_cast<std::uint8_t>(1 + (within(std::int64_t{c[q]} + 2 * s, q) ? 1 : 0) + beside);
    }
  }
  return out;
}

void hierarchy::root_tets(std::uint64_t r,
                          std::array<std::array<ipoint, 4>, 6>& out) const noexcept {
  const auto cx = static_cast<std::uint64_t>(cubes_[0]);
  const auto cy = static_cast<std::uint64_t>(cubes_[1]);
  // The diagonal joins the corner whose coordinates are even multiples of N to the corner
  // whose coordinates are odd multiples of N (the reflected pattern, consistent across cubes).
  out = cube_tetrahedra(
      {static_cast<std::int32_t>(r % cx) * root_, static_cast<std::int32_t>((r / cx) % cy) * root_,
       static_cast<std::int32_t>(r / (cx * cy)) * root_},
      root_);
}

std::array<ipoint, 2> hierarchy::spine_ends(const ipoint& d2) const noexcept {
  std::array<ipoint, 2> e = make_diamond({d2[0] / 2, d2[1] / 2, d2[2] / 2}).spine;
  if (vertex_less(e[1], e[0])) std::swap(e[0], e[1]);
  return e;
}

}  // namespace progiso
