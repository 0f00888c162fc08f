#include <progiso/core/contour/hierarchy2d.hpp>

#include <algorithm>
#include <bit>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso {
namespace {

int log2_of(std::int32_t h) noexcept { return std::countr_zero(static_cast<std::uint32_t>(h)); }

}  // namespace

hierarchy2d::hierarchy2d(std::int64_t width, std::int64_t height) {
  constexpr std::int64_t max_dim = (std::int64_t{1} << 20) + 1;
  if (width < 2 || height < 2 || width > max_dim || height > max_dim) {
    throw error("image size " + std::to_string(width) + "x" + std::to_string(height) +
                ": expected 2 to 1048577 samples per axis");
  }
  const std::int64_t min_extent = std::min(width, height) - 1;
  levels_ = 0;
  while ((std::int64_t{2} << levels_) <= min_extent) ++levels_;
  root_ = std::int32_t{1} << levels_;
  data_max_ = {static_cast<std::int32_t>(width - 1), static_cast<std::int32_t>(height - 1)};
  for (std::size_t q = 0; q < 2; ++q) {
    squares_[q] = (data_max_[q] + root_ - 1) / root_;
    grid_max_[q] = squares_[q] * root_;
  }
  stride_ = static_cast<std::uint64_t>(grid_max_[0]) + 1;
  vertex_count_ = stride_ * (static_cast<std::uint64_t>(grid_max_[1]) + 1);
}

int hierarchy2d::depth_of(const ipoint2& p) const noexcept {
  const int lg = log2_of(scale_of(p));
  const int odd = ((p[0] >> lg) & 1) + ((p[1] >> lg) & 1);
  return 2 * (levels_ - 1 - lg) + (2 - odd);
}

int hierarchy2d::parents(const diamond2& d, std::array<ipoint2, 2>& out) const noexcept {
  int n = 0;
  if (d.depth == 0) return 0;
  for (std::size_t m = 0; m < 2; ++m) {
    if (!((d.ring_in_grid >> m) & 1u) || scale_of(d.ring[m]) >= root_) continue;
    if (depth_of(d.ring[m]) == d.depth - 1) out[static_cast<std::size_t>(n++)] = d.ring[m];
  }
  return n;
}

int hierarchy2d::parent_count(const ipoint2& c) const noexcept {
  const std::int32_t h = scale_of(c);
  const int lg = log2_of(h);
  const bool odd_x = ((c[0] >> lg) & 1) != 0;
  const bool odd_y = ((c[1] >> lg) & 1) != 0;
  // A square centre's parents are two corners of its own square (none for a root).
  if (odd_x && odd_y) return h == root_ / 2 ? 0 : 2;
  // An edge midpoint's parents are the square centres on either side of its edge.
  const std::size_t j = odd_x ? 1 : 0;
  return (c[j] - h >= 0 ? 1 : 0) + (c[j] + h <= grid_max_[j] ? 1 : 0);
}

int hierarchy2d::children(const diamond2& d, std::array<ipoint2, 4>& out) const noexcept {
  int n = 0;
  const ipoint2& c = d.centre;
  const std::int32_t h = d.scale;
  const auto push = [&](const ipoint2& p) {
    if (in_grid(p)) out[static_cast<std::size_t>(n++)] = p;
  };
  if (d.type == 0) {
    push({c[0] + h, c[1]});
    push({c[0] - h, c[1]});
    push({c[0], c[1] + h});
    push({c[0], c[1] - h});
  } else if (h >= 2) {
    const std::int32_t g = h / 2;
    push({c[0] + g, c[1] + g});
    push({c[0] - g, c[1] + g});
    push({c[0] + g, c[1] - g});
    push({c[0] - g, c[1] - g});
  }
  return n;
}

ipoint2 hierarchy2d::root_centre(std::uint64_t r) const noexcept {
  const auto sx = static_cast<std::uint64_t>(squares_[0]);
  return {static_cast<std::int32_t>(r % sx) * root_ + root_ / 2,
          static_cast<std::int32_t>(r / sx) * root_ + root_ / 2};
}

void hierarchy2d::root_triangles(std::uint64_t r,
                                 std::array<std::array<ipoint2, 3>, 2>& out) const noexcept {
  const auto sx = static_cast<std::uint64_t>(squares_[0]);
  const ipoint2 m{static_cast<std::int32_t>(r % sx) * root_,
                  static_cast<std::int32_t>(r / sx) * root_};
  // Diagonal from the corner at even multiples of N to the corner at odd multiples.
  ipoint2 e{}, o{};
  for (std::size_t q = 0; q < 2; ++q) {
    const bool even = ((m[q] / root_) & 1) == 0;
    e[q] = even ? m[q] : m[q] + root_;
    o[q] = even ? m[q] + root_ : m[q];
  }
  out[0] = {e, o, ipoint2{o[0], e[1]}};
  out[1] = {e, o, ipoint2{e[0], o[1]}};
}

std::array<ipoint2, 2> hierarchy2d::edge_ends(std::uint64_t key) const noexcept {
  const ipoint2 d2 = edge_key2_point(key);
  std::array<ipoint2, 2> e{};
  const int odd = (d2[0] & 1) + (d2[1] & 1);
  if (odd == 0) {
    e = make_diamond({d2[0] / 2, d2[1] / 2}).spine;
  } else {
    for (std::size_t q = 0; q < 2; ++q) {
      if (d2[q] & 1) {
        const std::int32_t lo = (d2[q] - 1) / 2;
        const bool lo_even = (lo & 1) == 0;
        e[0][q] = odd == 1 || lo_even ? lo : lo + 1;
        e[1][q] = odd == 1 || lo_even ? lo + 1 : lo;
      } else {
        e[0][q] = e[1][q] = d2[q] / 2;
      }
    }
  }
  if (vertex_less2(e[1], e[0])) std::swap(e[0], e[1]);
  return e;
}

}  // namespace progiso
