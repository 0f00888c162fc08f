#include <progiso/core/contour/detail/contour_frontier.hpp>

#include <bit>
#include <utility>

namespace progiso::detail {

vec2 place_contour_vertex(const hierarchy2d& hier, const volume& image, double isovalue,
                          std::uint64_t key) noexcept {
  const auto e = hier.edge_ends(key);
  return interpolate2(e[0], image.value(e[0][0], e[0][1], 0), e[1],
                      image.value(e[1][0], e[1][1], 0), isovalue);
}

void root_contour(const hierarchy2d& hier, const volume& image, double isovalue,
                  std::vector<placed_segment>& segments, std::vector<ipoint2>& roots) {
  std::array<std::array<ipoint2, 3>, 2> tris{};
  const bool has_diamond = hier.root_size() >= 2;
  for (std::uint64_t r = 0; r < hier.root_count(); ++r) {
    hier.root_triangles(r, tris);
    const ipoint2 centre = hier.root_centre(r);
    const std::uint64_t owner = has_diamond ? hier.index(centre) : no_owner2;
    for (const auto& t : tris) {
      std::array<double, 3> f{};
      for (std::size_t i = 0; i < 3; ++i) f[i] = image.value(t[i][0], t[i][1], 0);
      std::array<std::uint64_t, 2> k{};
      if (march_triangle(t, f, isovalue, k)) {
        segments.push_back({{owner, k},
                            {place_contour_vertex(hier, image, isovalue, k[0]),
                             place_contour_vertex(hier, image, isovalue, k[1])}});
      }
    }
    if (has_diamond) roots.push_back(centre);
  }
}

namespace {
constexpr std::uint64_t empty_slot = ~std::uint64_t{0};
}  // namespace

contour_assembler::contour_assembler(const hierarchy2d& hier, double isovalue, std::size_t expected)
    : bx_(static_cast<double>(hier.data_max()[0])),
      by_(static_cast<double>(hier.data_max()[1])),
      isovalue_(isovalue),
      compact_keys_(2 * std::int64_t{hier.grid_max()[0]} < 65536 &&
                    2 * std::int64_t{hier.grid_max()[1]} < 65536),
      ids_(compact_keys_ ? 16 : expected + 16) {
  if (compact_keys_) {
    std::size_t capacity = 16;
    while (capacity < expected + 16) capacity *= 2;
    compact_.assign(capacity, empty_slot);
    compact_shift_ = 32 - std::countr_zero(capacity);
  }
  // About one vertex per segment on closed contours: neither array grows by copying.
  out_.vertices.reserve(expected + 16);
  segs_.reserve(expected);
}

std::uint32_t contour_assembler::compact_id(std::uint32_t key, const vec2& p) {
  const std::size_t mask = compact_.size() - 1;
  std::size_t i = (key * 0x9E3779B1u) >> compact_shift_;
  while (true) {
    const std::uint64_t s = compact_[i];
    if (s == empty_slot) break;
    if (static_cast<std::uint32_t>(s >> 32) == key) return static_cast<std::uint32_t>(s);
    i = (i + 1) & mask;
  }
  const auto id = static_cast<std::uint32_t>(out_.vertices.size());
  out_.vertices.push_back(p);
  compact_[i] = (std::uint64_t{key} << 32) | id;
  if (2 * ++compact_size_ > compact_.size()) grow_compact();
  return id;
}

void contour_assembler::grow_compact() {
  std::vector<std::uint64_t> old(2 * compact_.size(), empty_slot);
  old.swap(compact_);
  --compact_shift_;
  const std::size_t mask = compact_.size() - 1;
  for (const std::uint64_t s : old) {
    if (s == empty_slot) continue;
    std::size_t i = (static_cast<std::uint32_t>(s >> 32) * 0x9E3779B1u) >> compact_shift_;
    while (compact_[i] != empty_slot) i = (i + 1) & mask;
    compact_[i] = s;
  }
}

std::uint32_t contour_assembler::key_id(std::uint64_t key, const vec2& p) {
  if (compact_keys_) {
    // Doubled coordinates below 2^16: x | y << 16. (No slot is all ones: its id would be 2^32−1.)
    return compact_id(static_cast<std::uint32_t>((key & 0xFFFFu) | ((key >> 16) & 0xFFFF0000u)), p);
  }
  const auto [id, inserted] =
      ids_.try_emplace(key, static_cast<std::uint32_t>(out_.vertices.size()));
  if (inserted) out_.vertices.push_back(p);
  return id;
}

void contour_assembler::begin_record(std::uint64_t diamond) {
  local_ = diamond != no_owner2;
  local_count_ = 0;
}

std::uint32_t contour_assembler::end_id(std::uint64_t key, const vec2& p) {
  // A unit edge (its doubled midpoint has exactly one odd coordinate) is held only by the four
  // triangles around the finest edge midpoint at one of its ends, which that diamond's split
  // makes and nothing splits again: its vertex is named here. Other keys go through the table.
  const ipoint2 m = edge_key2_point(key);
  if (local_ && ((m[0] ^ m[1]) & 1) != 0) {
    for (std::uint32_t i = 0; i < local_count_; ++i) {
      if (local_keys_[i] == key) return local_ids_[i];
    }
    const auto id = static_cast<std::uint32_t>(out_.vertices.size());
    out_.vertices.push_back(p);
    PROGISO_ASSERT(local_count_ < local_keys_.size());
    local_keys_[local_count_] = key;
    local_ids_[local_count_++] = id;
    return id;
  }
  return key_id(key, p);
}

std::uint32_t contour_assembler::point_id(const vec2& p) {
  const auto [it, inserted] =
      clipped_.try_emplace(p, static_cast<std::uint32_t>(out_.vertices.size()));
  if (inserted) out_.vertices.push_back(p);
  return it->second;
}

void contour_assembler::add(const placed_segment& ps) {
  const owned_segment& s = ps.seg;
  const vec2 p = ps.pos[0];
  const vec2 q = ps.pos[1];
  if (p[0] <= bx_ && p[1] <= by_ && q[0] <= bx_ && q[1] <= by_) {
    segs_.push_back({end_id(s.keys[0], p), end_id(s.keys[1], q)});
    return;
  }
  // Clip against x ≤ bx and y ≤ by; crossings computed from the lexicographically ordered
  // ends so that neighbours agree exactly. The direction of the segment is kept. When the
  // inside end lies on the border line, what remains is that point: the segment is dropped.
  vec2 a = p, b = q;
  bool a_orig = true, b_orig = true;
  for (std::size_t axis = 0; axis < 2; ++axis) {
    const double lim = axis == 0 ? bx_ : by_;
    const bool ain = a[axis] <= lim;
    const bool bin = b[axis] <= lim;
    if (ain && bin) continue;
    if ((!ain && !bin) || (ain && a[axis] == lim) || (bin && b[axis] == lim)) return;
    vec2 u = a, v = b;
    if (v < u) std::swap(u, v);
    const double t = (lim - u[axis]) / (v[axis] - u[axis]);
    vec2 x{u[0] + t * (v[0] - u[0]), u[1] + t * (v[1] - u[1])};
    x[axis] = lim;
    if (!ain) {
      a = x;
      a_orig = false;
    } else {
      b = x;
      b_orig = false;
    }
  }
  if (a == b) return;
  const std::uint32_t ia = a_orig ? end_id(s.keys[0], p) : point_id(a);
  const std::uint32_t ib = b_orig ? end_id(s.keys[1], q) : point_id(b);
  if (ia != ib) segs_.push_back({ia, ib});
}

contour_set contour_assembler::finish(const std::array<double, 2>& origin,
                                      const std::array<double, 2>& spacing) {
  contour_set out = std::move(out_);
  // Chain: every vertex has at most one outgoing and one incoming segment.
  const std::uint32_t none = ~std::uint32_t{0};
  std::vector<std::uint32_t> next(out.vertices.size(), none);
  std::vector<std::uint8_t> has_in(out.vertices.size(), 0);
  for (const auto& s : segs_) {
    next[s[0]] = s[1];
    has_in[s[1]] = 1;
  }
  std::vector<std::uint8_t> used(out.vertices.size(), 0);
  const auto walk = [&](std::uint32_t start, bool closed) {
    polyline pl;
    pl.closed = closed;
    pl.isovalue = isovalue_;
    std::uint32_t v = start;
    while (v != none && !used[v]) {
      used[v] = 1;
      pl.vertices.push_back(v);
      v = next[v];
    }
    if (pl.vertices.size() >= 2) out.polylines.push_back(std::move(pl));
  };
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!has_in[v] && next[v] != none) walk(v, false);
  }
  for (std::uint32_t v = 0; v < out.vertices.size(); ++v) {
    if (!used[v] && next[v] != none) walk(v, true);
  }
  // Physical coordinates: origin + grid position × spacing, as for volumes.
  for (vec2& p : out.vertices) {
    p = {origin[0] + p[0] * spacing[0], origin[1] + p[1] * spacing[1]};
  }
  segs_.clear();
  return out;
}

}  // namespace progiso::detail
