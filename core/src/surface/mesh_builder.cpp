#include <progiso/core/surface/detail/mesh_builder.hpp>

#include <algorithm>
#include <bit>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/surface/marching.hpp>

namespace progiso::detail {

mesh_builder::mesh_builder(const hierarchy& hier, const volume& vol, double w, std::size_t expected)
    : hier_(hier), vol_(vol), w_(w), keys_(expected) {
  for (std::size_t q = 0; q < 3; ++q) box_[q] = static_cast<double>(hier.data_max()[q]);
  // A closed surface has about half as many vertices as triangles; clipping at the data box
  // (padded hierarchies only) adds some of both. Reserving for them saves a copy of each array.
  const bool padded = hier.grid_max() != hier.data_max();
  const std::size_t slack = padded ? expected / 8 + 64 : 0;
  grid_.reserve(expected + slack);
  mesh_.triangles.reserve(2 * (expected + slack));
}

vec3 mesh_builder::physical(const vec3& p) const noexcept {
  const auto& sp = vol_.spacing();
  const auto& org = vol_.origin();
  vec3 r{};
  for (std::size_t q = 0; q < 3; ++q) r[q] = org[q] + p[q] * sp[q];
  return r;
}

triangle_mesh mesh_builder::finish() {
  // In place: the grid positions are not needed after this (no second array to fault in).
  mesh_.vertices = std::move(grid_);
  for (vec3& v : mesh_.vertices) v = physical(v);
  drop_unused(mesh_, suspects_);
  return std::move(mesh_);
}

// Every vertex is used (in order of first use) unless clipping left one of its triangles' inside
// corners out (a corner on the box's face with the rest of the piece beyond it) and no other
// triangle uses it: then the unused ones are dropped.
void drop_unused(triangle_mesh& m, const std::vector<std::uint32_t>& suspects) {
  if (suspects.empty()) return;
  const std::size_t count = m.vertices.size();
  {
    std::vector<bool> used(count, false);
    for (const auto& t : m.triangles) {
      for (const std::uint32_t v : t) used[v] = true;
    }
    if (std::all_of(suspects.begin(), suspects.end(),
                    [&used](std::uint32_t v) { return used[v]; })) {
      return;
    }
  }
  std::vector<std::uint32_t> remap(count, ~std::uint32_t{0});
  std::uint32_t n = 0;
  for (auto& t : m.triangles) {
    for (auto& v : t) {
      if (remap[v] == ~std::uint32_t{0}) remap[v] = n++;
      v = remap[v];
    }
  }
  if (n != count) {
    std::vector<vec3> kept(n);
    for (std::size_t i = 0; i < count; ++i) {
      if (remap[i] != ~std::uint32_t{0}) kept[remap[i]] = m.vertices[i];
    }
    m.vertices = std::move(kept);
  } else {
    std::vector<vec3> ordered(n);
    for (std::size_t i = 0; i < count; ++i) ordered[remap[i]] = m.vertices[i];
    m.vertices = std::move(ordered);
  }
}

// One builder fed the whole sequence numbers vertices in order of first use. Part j's vertices in
// its own order of first use, less those an earlier part used, come in that order after all the
// vertices of parts 0 … j − 1: so a vertex's id is its part's base plus its rank among the
// vertices its part owns (it owns those no earlier part used), and its clip vertices and edge
// vertices keep their places among each other. Triangles keep their order, part after part.
triangle_mesh mesh_builder::join(std::vector<mesh_builder>& parts, const parallel_loop& run) {
  PROGISO_ASSERT(!parts.empty());
  if (parts.size() == 1) return parts[0].finish();
  constexpr std::uint32_t owned = ~std::uint32_t{0};
  struct part_ids {
    std::vector<std::uint64_t> key;   // per vertex: its edge key, or empty_key (a clip vertex)
    std::vector<std::uint32_t> from;  // per vertex: `owned`, or the earlier part that owns it
    std::vector<std::uint32_t> id;    // per vertex: rank among the owned, or id in part `from`;
                                      // then the id in the joined mesh
    std::uint64_t z_lo = ~std::uint64_t{0};
    std::uint64_t z_hi = 0;
    std::uint32_t owned_count = 0;
  };
  const std::size_t n = parts.size();
  std::vector<part_ids> ids(n);
  const auto z_of = [](std::uint64_t key) { return key >> (2 * edge_key_bits); };
  // 1. Each vertex's origin (its key, or a clip vertex), and the z range of each part's keys.
  run_loop(run, n, [&](std::size_t j) {
    const mesh_builder& p = parts[j];
    part_ids& d = ids[j];
    d.key.assign(p.grid_.size(), flat_map::empty_key);
    p.keys_.for_each([&d, &z_of](std::uint64_t key, std::uint32_t v) {
      if ((v & outside_bit) != 0) return;
      d.key[v] = key;
      d.z_lo = std::min(d.z_lo, z_of(key));
      d.z_hi = std::max(d.z_hi, z_of(key));
    });
  });
  // 2. Each vertex's owner: the first part that has it.
  run_loop(run, n, [&](std::size_t j) {
    const mesh_builder& p = parts[j];
    part_ids& d = ids[j];
    const std::size_t count = p.grid_.size();
    d.from.assign(count, owned);
    d.id.assign(count, 0);
    for (std::size_t v = 0; v < count; ++v) {
      const std::uint64_t key = d.key[v];
      for (std::size_t i = 0; i < j; ++i) {
        const std::uint32_t* found = nullptr;
        if (key != flat_map::empty_key) {
          const std::uint64_t z = z_of(key);
          if (z < ids[i].z_lo || z > ids[i].z_hi) continue;
          found = parts[i].keys_.find(key);
        } else if (const auto it = parts[i].clipped_.find(p.grid_[v]);
                   it != parts[i].clipped_.end()) {
          found = &it->second;
        }
        if (found != nullptr) {
          d.from[v] = static_cast<std::uint32_t>(i);
          d.id[v] = *found;
          break;
        }
      }
      if (d.from[v] == owned) d.id[v] = d.owned_count++;
    }
  });
  // 3. Bases; the owned vertices' ids.
  std::vector<std::size_t> vertex_base(n + 1, 0);
  std::vector<std::size_t> triangle_base(n + 1, 0);
  for (std::size_t j = 0; j < n; ++j) {
    vertex_base[j + 1] = vertex_base[j] + ids[j].owned_count;
    triangle_base[j + 1] = triangle_base[j] + parts[j].mesh_.triangles.size();
  }
  PROGISO_ASSERT(vertex_base[n] < outside_bit);
  run_loop(run, n, [&](std::size_t j) {
    part_ids& d = ids[j];
    const auto base = static_cast<std::uint32_t>(vertex_base[j]);
    for (std::size_t v = 0; v < d.id.size(); ++v) {
      if (d.from[v] == owned) d.id[v] += base;
    }
  });
  // 4. The shared vertices' ids (their owners' ids are final), the owned vertices' positions,
  //    the triangles.
  triangle_mesh m;
  m.vertices.resize(vertex_base[n]);
  m.triangles.resize(triangle_base[n]);
  run_loop(run, n, [&](std::size_t j) {
    mesh_builder& p = parts[j];
    part_ids& d = ids[j];
    for (std::size_t v = 0; v < d.id.size(); ++v) {
      if (d.from[v] == owned) {
        m.vertices[d.id[v]] = p.physical(p.grid_[v]);
      } else {
        d.id[v] = ids[d.from[v]].id[d.id[v]];
      }
    }
    std::size_t t = triangle_base[j];
    for (const auto& tri : p.mesh_.triangles) {
      m.triangles[t++] = {d.id[tri[0]], d.id[tri[1]], d.id[tri[2]]};
    }
    p.mesh_.triangles = {};
  });
  // Step 4 reads ids[from].id only at owned vertices, which it does not write: no race.
  std::vector<std::uint32_t> suspects;
  for (std::size_t j = 0; j < n; ++j) {
    for (const std::uint32_t v : parts[j].suspects_) suspects.push_back(ids[j].id[v]);
  }
  drop_unused(m, suspects);
  return m;
}

std::uint32_t mesh_builder::new_vertex(std::uint64_t key) {
  const auto ends = hier_.edge_ends(key);
  const double fa = vol_.value(ends[0][0], ends[0][1], ends[0][2]);
  const double fb = vol_.value(ends[1][0], ends[1][1], ends[1][2]);
  const vec3 p = interpolate(ends[0], fa, ends[1], fb, w_);
  if (p[0] <= box_[0] && p[1] <= box_[1] && p[2] <= box_[2]) {
    PROGISO_ASSERT(grid_.size() < outside_bit);
    grid_.push_back(p);
    return static_cast<std::uint32_t>(grid_.size() - 1);
  }
  PROGISO_ASSERT(outside_.size() < outside_bit);
  outside_.push_back(p);
  return static_cast<std::uint32_t>(outside_.size() - 1) | outside_bit;
}

std::uint32_t mesh_builder::clip_vertex(const vec3& p) {
  const auto [it, inserted] = clipped_.try_emplace(p, static_cast<std::uint32_t>(grid_.size()));
  if (inserted) grid_.push_back(p);
  return it->second;
}

void mesh_builder::clip(const std::array<std::uint32_t, 3>& ids) {
  const std::array<vec3, 3> p{position(ids[0]), position(ids[1]), position(ids[2])};
  const std::array<bool, 3> used = clip_to_box(
      p, ids, box_, [this](const vec3& x) { return clip_vertex(x); },
      [this](const std::array<std::uint32_t, 3>& t) { mesh_.triangles.push_back(t); });
  for (std::size_t j = 0; j < 3; ++j) {
    if ((ids[j] & outside_bit) == 0 && !used[j]) suspects_.push_back(ids[j]);
  }
}

std::size_t mesh_builder::position_hash::operator()(const vec3& p) const noexcept {
  std::uint64_t h = 0;
  for (const double v : p) {
    // + 0.0 makes -0.0 hash as 0.0 (they compare equal).
    h = (h ^ std::bit_cast<std::uint64_t>(v + 0.0)) * 0x9E3779B97F4A7C15ULL;
  }
  return static_cast<std::size_t>(h ^ (h >> 29));
}

}  // namespace progiso::detail
