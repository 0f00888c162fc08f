// Readers: what changed between two snapshots of one isovalue (surface_snapshot::change_since).
//
// The cut of watermark W holds a triangle of record r < W iff its owner has no record below W
// (docs/ARCHITECTURE.md, invariant 3). From W1 to W2 of one root, then:
//  * added: the triangles of records [W1, W2) whose owner has no record below W2;
//  * gone: the triangles of records below W1 whose owner has a record in [W1, W2). A diamond's
//    triangles lie in the tetrahedra its parents' splits made (a root diamond's, in the root
//    surface), so for each record of the window the records of its parents are scanned for the
//    triangles it owns: the work is the window's records and their parents', not the cut.
// Triangles of the window whose owner also split in the window were never seen: in neither list.

#include "engine_impl.hpp"

#include <progiso/core/surface/detail/mesh_clip.hpp>

namespace progiso {

namespace {

// Ids (surface_change.hpp): a split record's triangle k (k < 32: at most 16 groups of at most 2
// triangles) is record << 5 | k; the root surface's triangle k has root_triangle_bit set.
constexpr std::uint64_t root_id_bit = root_triangle_bit;
[[nodiscard]] constexpr std::uint64_t record_triangle_id(std::uint64_t r, std::uint64_t k) {
  return (r << 5) | k;
}

// One part's output: ids, float positions (9 per piece) and, for normals, the corners' physical
// positions as doubles (3 per piece: add_vertex_normals reads them as mesh_into()'s do).
struct change_part {
  std::vector<std::uint64_t> gone;
  std::vector<std::uint64_t> added;
  std::vector<std::uint64_t> hidden;
  std::vector<float> positions;
  std::vector<vec3> corners;
  bool root_split = false;  // a root diamond's record is in the part (after an earlier cut)
};

// The grid positions of recently seen surface vertices, by edge key, direct-mapped: a record's
// triangles share corners, and records published together are grid neighbours, so most corners
// are found here instead of being decoded and interpolated again.
class corner_cache {
 public:
  template <class Make>
  const vec3& get(std::uint64_t key, Make&& make) {
    const auto i = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> (64 - bits));
    if (keys_[i] != key) {
      keys_[i] = key;
      values_[i] = make(key);
    }
    return values_[i];
  }

 private:
  // 4 K corners (128 KB, on the heap: a part may run on a worker's stack): larger tables found
  // no more corners (bench/README.md).
  static constexpr int bits = 12;
  std::vector<std::uint64_t> keys_ =
      std::vector<std::uint64_t>(std::size_t{1} << bits, ~std::uint64_t{0});
  std::vector<vec3> values_ = std::vector<vec3>(std::size_t{1} << bits);
};

class change_maker {
 public:
  change_maker(const detail::engine_root& root, const hierarchy& hier, const volume& vol,
               std::uint64_t w1, std::uint64_t w2, bool doubles)
      : root_(root), hier_(hier), vol_(vol), w1_(w1), w2_(w2), doubles_(doubles) {
    const ipoint& m = hier.data_max();
    box_ = vec3{static_cast<double>(m[0]), static_cast<double>(m[1]), static_cast<double>(m[2])};
  }

  // Records [lo, hi) of the window.
  void run(std::uint64_t lo, std::uint64_t hi, change_part& out) const {
    // Room for every triangle of the records (an upper bound: pages never written are never
    // mapped), so that the part's arrays never move while they grow.
    std::uint64_t most = lo == 0 ? root_.root_triangles.size() : 0;
    for (std::uint64_t q = std::max<std::uint64_t>(lo, 1); q < hi; ++q) {
      most += 2 * std::uint64_t{root_.records[q].count};
    }
    out.added.reserve(out.added.size() + most);
    out.positions.reserve(out.positions.size() + 9 * most);
    if (doubles_) out.corners.reserve(out.corners.size() + 3 * most);
    corner_cache cache;
    for (std::uint64_t q = lo; q < hi; ++q) {
      if (q == 0) {
        add_root(out, cache);
        continue;
      }
      const detail::engine_record& rec = root_.records[q];
      if (w1_ > 0) {
        remove_owned_by(rec.diamond, out);
        out.root_split = out.root_split || detail::record_depth(hier_, rec) == 0;
      }
      add_record(q, rec, out, cache);
    }
  }

  // Root triangles whose owner split in the window: one pass over the root surface.
  void remove_from_root(change_part& out) const {
    const std::vector<owned_triangle>& tris = root_.root_triangles;
    for (std::size_t k = 0; k < tris.size(); ++k) {
      if (tris[k].owner == no_owner) continue;
      const std::uint32_t r = root_.record_index(tris[k].owner);
      if (r >= w1_ && r < w2_) out.gone.push_back(root_id_bit | k);
    }
  }

 private:
  [[nodiscard]] bool split_in_later(std::uint64_t owner) const noexcept {
    if (owner == no_owner) return false;
    const std::uint32_t r = root_.record_index(owner);
    return r != 0 && r < w2_;
  }

  // The triangles owned by diamond d in the records of its parents split before the window.
  void remove_owned_by(std::uint64_t d, change_part& out) const {
    const diamond dm = hier_.make_diamond(hier_.point(d));
    std::array<ipoint, 4> parents{};
    const int n = hier_.parents(dm, parents);
    for (int i = 0; i < n; ++i) {
      const std::uint32_t r = root_.record_index(hier_.index(parents[static_cast<std::size_t>(i)]));
      // A parent split in the window made its triangles there: never seen by the earlier cut.
      if (r == 0 || r >= w1_) continue;
      const detail::engine_record& rec = root_.records[r];
      const std::int32_t scale = detail::record_scale(hier_, rec);
      std::uint64_t k = 0;
      for (std::uint32_t g = 0; g < rec.count; ++g) {
        const packed_group& group = rec.groups[g];
        const std::size_t c = group.count();
        if (group_owner(hier_, rec.diamond, scale, group) == d) {
          for (std::size_t t = 0; t < c; ++t) out.gone.push_back(record_triangle_id(r, k + t));
        }
        k += c;
      }
    }
  }

  void add_record(std::uint64_t q, const detail::engine_record& rec, change_part& out,
                  corner_cache& cache) const {
    const std::int32_t scale = detail::record_scale(hier_, rec);
    std::uint64_t k = 0;
    std::uint64_t centre_key = 0;
    bool have_centre = false;
    for (std::uint32_t g = 0; g < rec.count; ++g) {
      const packed_group& group = rec.groups[g];
      const std::size_t c = group.count();
      if (!split_in_later(group_owner(hier_, rec.diamond, scale, group))) {
        if (!have_centre) {
          const ipoint ct = hier_.point(rec.diamond);
          centre_key = edge_key(ct, ct);
          have_centre = true;
        }
        for (std::size_t t = 0; t < c; ++t) {
          add_triangle(record_triangle_id(q, k + t), unpack_at(centre_key, scale, group, t), out,
                       cache);
        }
      }
      k += c;
    }
  }

  void add_root(change_part& out, corner_cache& cache) const {
    const std::vector<owned_triangle>& tris = root_.root_triangles;
    for (std::size_t k = 0; k < tris.size(); ++k) {
      if (!split_in_later(tris[k].owner)) add_triangle(root_id_bit | k, tris[k].keys, out, cache);
    }
  }

  // The triangle's piece, or its pieces inside the data box, as cut_mesher makes them: corners
  // by interpolate() on canonically ordered ends, crossings by clip_to_box().
  void add_triangle(std::uint64_t id, const std::array<std::uint64_t, 3>& keys, change_part& out,
                    corner_cache& cache) const {
    const auto make = [this](std::uint64_t key) {
      const std::array<ipoint, 2> e = hier_.edge_ends(key);
      return interpolate(e[0], vol_.value(e[0][0], e[0][1], e[0][2]), e[1],
                         vol_.value(e[1][0], e[1][1], e[1][2]), root_.isovalue);
    };
    std::array<vec3, 3> p{};
    bool inside = true;
    for (std::size_t v = 0; v < 3; ++v) {
      p[v] = cache.get(keys[v], make);
      inside = inside && p[v][0] <= box_[0] && p[v][1] <= box_[1] && p[v][2] <= box_[2];
    }
    if (inside) {
      out.added.push_back(id);
      for (const vec3& x : p) put(detail::physical_position(vol_, x), out);
      return;
    }
    std::array<vec3, 8> extra{};  // crossings: ids 3 …
    std::uint32_t extras = 0;
    const auto crossing = [&](const vec3& x) {
      extra[extras] = x;
      return 3 + extras++;
    };
    const auto emit = [&](const std::array<std::uint32_t, 3>& t) {
      out.added.push_back(id);
      for (const std::uint32_t c : t) {
        put(detail::physical_position(vol_, c < 3 ? p[c] : extra[c - 3]), out);
      }
    };
    const std::size_t before = out.added.size();
    (void)detail::clip_to_box(p, {0, 1, 2}, box_, crossing, emit);
    if (out.added.size() == before) out.hidden.push_back(id);
  }

  // A corner: rounded to float as fill_render_buffers() rounds it.
  void put(const vec3& x, change_part& out) const {
    for (std::size_t k = 0; k < 3; ++k) out.positions.push_back(static_cast<float>(x[k]));
    if (doubles_) out.corners.push_back(x);
  }

  const detail::engine_root& root_;
  const hierarchy& hier_;
  const volume& vol_;
  std::uint64_t w1_;
  std::uint64_t w2_;
  bool doubles_;
  vec3 box_{};
};

}  // namespace

cut_mark surface_snapshot::mark() const noexcept {
  if (!valid()) return {};
  return cut_mark{owner_, root_->generation, published_, root_->serial};
}

namespace {

// The change to a uniform cut (engine_root::base) from any other cut: the whole cut, its
// triangle k named as the root surface's triangle k is (a uniform cut's root holds no other
// triangle), corners gathered from its final mesh; in parts on the engine's threads.
void uniform_change(const engine& e, const triangle_mesh& base, surface_change& out,
                    bool with_normals) {
  out.rebuilt = true;
  const std::size_t n = base.triangles.size();
  out.added.resize(n);
  out.positions.resize(9 * n);
  std::vector<vec3> normals;
  if (with_normals) {
    triangle_mesh points;
    points.vertices = base.vertices;
    e.add_normals(points);
    normals = std::move(points.normals);
    out.normals.resize(9 * n);
  }
  const auto gather = [&](std::size_t lo, std::size_t hi) {
    for (std::size_t t = lo; t < hi; ++t) {
      out.added[t] = root_id_bit | t;
      for (std::size_t c = 0; c < 3; ++c) {
        const std::uint32_t v = base.triangles[t][c];
        for (std::size_t k = 0; k < 3; ++k) {
          out.positions[9 * t + 3 * c + k] = static_cast<float>(base.vertices[v][k]);
          if (with_normals) out.normals[9 * t + 3 * c + k] = static_cast<float>(normals[v][k]);
        }
      }
    }
  };
  const std::size_t threads = e.threads();
  constexpr std::size_t chunk = std::size_t{1} << 16;
  if (threads <= 1 || n <= chunk) {
    gather(0, n);
    return;
  }
  tbb::task_arena arena(static_cast<int>(threads));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, (n + chunk - 1) / chunk,
                      [&](std::size_t i) { gather(i * chunk, std::min(n, (i + 1) * chunk)); });
  });
}

}  // namespace

void surface_snapshot::change_since(const cut_mark& earlier, surface_change& out,
                                    vertex_normals normals) const {
  PROGISO_ASSERT(valid());
  out.clear();
  const std::uint64_t w2 = published_;
  const bool same_root = earlier.owner == owner_ && earlier.generation == root_->generation &&
                         earlier.root == root_->serial;
  if (root_->base_stride > 0) {
    if (!same_root || earlier.records != w2) {
      uniform_change(*owner_, root_->base, out, normals == vertex_normals::gradient);
    }
    return;
  }
  out.rebuilt = !same_root || earlier.records == 0 || earlier.records > w2;
  const std::uint64_t w1 = out.rebuilt ? 0 : earlier.records;
  const engine& e = *owner_;
  const bool with_normals = normals == vertex_normals::gradient;
  const change_maker maker(*root_, e.hierarchy_of(), e.field(), w1, w2, with_normals);

  // Parts as a mesh's (reader_parts), joined in record order: the same change for every thread
  // count. One part writes into `out`'s own storage.
  const std::uint64_t window = w2 - w1;
  const std::size_t threads = e.threads();
  const std::size_t parts = detail::reader_parts(window, threads);
  std::vector<change_part> pieces(parts);
  const auto swap_out = [&](change_part& p) {
    p.gone.swap(out.gone);
    p.added.swap(out.added);
    p.hidden.swap(out.hidden);
    p.positions.swap(out.positions);
  };
  const auto run_part = [&](std::size_t i) {
    maker.run(w1 + window * i / parts, w1 + window * (i + 1) / parts, pieces[i]);
  };
  if (parts == 1) {
    swap_out(pieces[0]);
    run_part(0);
    swap_out(pieces[0]);
  } else {
    tbb::task_arena arena(static_cast<int>(std::min(threads, parts)));
    arena.execute([&] { tbb::parallel_for(std::size_t{0}, parts, run_part); });
    std::size_t gone = 0;
    std::size_t added = 0;
    std::size_t hidden = 0;
    for (const change_part& p : pieces) {
      gone += p.gone.size();
      added += p.added.size();
      hidden += p.hidden.size();
    }
    out.gone.reserve(gone);
    out.added.reserve(added);
    out.hidden.reserve(hidden);
    out.positions.reserve(9 * added);
    for (const change_part& p : pieces) {
      out.gone.insert(out.gone.end(), p.gone.begin(), p.gone.end());
      out.added.insert(out.added.end(), p.added.begin(), p.added.end());
      out.hidden.insert(out.hidden.end(), p.hidden.begin(), p.hidden.end());
      out.positions.insert(out.positions.end(), p.positions.begin(), p.positions.end());
    }
  }
  // A root diamond in the window took triangles of the root surface with it.
  bool root_split = false;
  for (const change_part& p : pieces) root_split = root_split || p.root_split;
  if (root_split) {
    change_part from_root;
    maker.remove_from_root(from_root);
    out.gone.insert(out.gone.end(), from_root.gone.begin(), from_root.gone.end());
  }
  const std::size_t added = out.added.size();
  if (with_normals && added > 0) {
    triangle_mesh m;
    m.vertices.reserve(3 * added);
    for (const change_part& p : pieces)
      m.vertices.insert(m.vertices.end(), p.corners.begin(), p.corners.end());
    m.triangles.resize(added);
    for (std::size_t t = 0; t < added; ++t) {
      const auto v = static_cast<std::uint32_t>(3 * t);
      m.triangles[t] = {v, v + 1, v + 2};
    }
    e.add_normals(m);
    out.normals.resize(9 * added);
    for (std::size_t v = 0; v < m.normals.size(); ++v) {
      for (std::size_t k = 0; k < 3; ++k)
        out.normals[3 * v + k] = static_cast<float>(m.normals[v][k]);
    }
  }
}

}  // namespace progiso
