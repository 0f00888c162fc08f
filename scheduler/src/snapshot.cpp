// Readers: snapshots and the meshes of their cuts.

#include "engine_impl.hpp"

#include <algorithm>

#include <progiso/core/surface/detail/cut_mesher.hpp>

namespace progiso {

// ---------------------------------------------------------------------------------------------
// surface_snapshot

double surface_snapshot::isovalue() const noexcept { return root_->isovalue; }
std::uint64_t surface_snapshot::generation() const noexcept { return root_->generation; }
std::uint64_t surface_snapshot::triangle_count() const noexcept {
  return root_->records[published_ - 1].cut_triangles;
}

std::int32_t surface_snapshot::uniform_stride() const noexcept { return root_->base_stride; }

void surface_snapshot::truncate(std::uint64_t records) noexcept {
  if (root_ == nullptr || root_->base_stride > 0) return;
  published_ = std::clamp<std::uint64_t>(records, 1, published_);
}

bool surface_snapshot::is_split(std::uint64_t index) const noexcept {
  if (root_->base_stride > 0) {
    const hierarchy& hier = owner_->hierarchy_of();
    const ipoint c = hier.point(index);
    const auto corner_mask = static_cast<std::int32_t>(hier.root_size() - 1);
    if (((c[0] | c[1] | c[2]) & corner_mask) == 0) return false;  // a root cube's corner
    return hier.scale_of(c) >= root_->base_stride;
  }
  const std::uint32_t r = root_->record_index(index);
  return r != 0 && r < published_;
}

namespace {

[[noreturn]] void refuse_uniform(const char* call, std::int32_t stride) {
  throw error(std::string("surface_snapshot::") + call + ": the cut is a uniform cut of stride " +
              std::to_string(stride) +
              " made by streaming passes, which holds no split records (is_split() tells its "
              "split set; engine_options::uniform_cuts = false refines by records)");
}

}  // namespace

void surface_snapshot::for_each_split(const std::function<void(std::uint64_t)>& f) const {
  if (root_->base_stride > 0) refuse_uniform("for_each_split", root_->base_stride);
  for (std::uint64_t r = 1; r < published_; ++r) f(root_->records[r].diamond);
}

namespace {

// Calls f(owner, edge keys) for the triangles of record r whose owner passes take(owner).
template <class Take, class F>
void walk_record(const detail::engine_root& root, const hierarchy& hier, std::uint64_t r,
                 Take&& take, F&& f) {
  const detail::engine_record& rec = root.records[r];
  if (r == 0) {
    for (std::uint32_t k = 0; k < rec.count; ++k) {
      const owned_triangle& t = root.root_triangles[k];
      if (take(t.owner)) f(t.owner, t.keys);
    }
    return;
  }
  for_each_unpacked(hier, rec.diamond, detail::record_scale(hier, rec), rec.groups, 0, rec.count,
                    take, f);
}

}  // namespace

void surface_snapshot::for_each_triangle(
    const std::function<void(const owned_triangle&)>& f) const {
  if (root_->base_stride > 0) refuse_uniform("for_each_triangle", root_->base_stride);
  const auto live = [this](std::uint64_t owner) { return owner == no_owner || !is_split(owner); };
  for (std::uint64_t r = 0; r < published_; ++r) {
    walk_record(*root_, owner_->hierarchy_of(), r, live,
                [&f](std::uint64_t owner, const std::array<std::uint64_t, 3>& keys) {
                  f(owned_triangle{owner, keys});
                });
  }
}

namespace {

// The cut of a snapshot, as cut_mesher reads it: the published records, of which keep(r) are
// split in the cut.
template <class Keep>
struct snapshot_cut {
  const detail::engine_root& root;
  std::uint64_t published;
  const Keep& keep;

  [[nodiscard]] std::uint64_t records() const noexcept { return published; }
  [[nodiscard]] const detail::engine_record& record(std::uint64_t r) const noexcept {
    return root.records[r];
  }
  [[nodiscard]] bool split(std::uint64_t r) const noexcept { return keep(r); }
  [[nodiscard]] const std::vector<owned_triangle>& root_triangles() const noexcept {
    return root.root_triangles;
  }
};

}  // namespace

// The mesh of the cut made of the published records r with keep(r), by cut_mesher (no vertex
// hashing): the records in canonical order (diamond order), cut into consecutive parts, one per
// 2 K records, up to 8 per thread (the records gather where the surface is, so parts of equal
// rank ranges differ in work), on the engine's thread count. With parts eight times larger, a
// cut of a small data set had about one part per thread and waited for the largest; many
// smaller parts balance the threads and make the mesh markedly faster (bench/README.md). The
// same mesh, vertex for vertex, for every thread count. A fresh arena per call: the caller (any
// thread) takes its reserved slot at once, whatever the engine's own arena is doing.
template <class Keep>
triangle_mesh surface_snapshot::build(Keep&& keep) const {
  const engine& e = *owner_;
  const std::size_t threads = e.threads();
  const std::size_t parts = detail::reader_parts(published_, threads);
  const snapshot_cut<std::remove_cvref_t<Keep>> cut{*root_, published_, keep};
  detail::cut_mesher mesher(cut, e.hierarchy_of(), e.field(), root_->isovalue);
  if (parts == 1) return mesher.build({}, 1);
  triangle_mesh m;
  tbb::task_arena arena(static_cast<int>(std::min(threads, parts)));
  arena.execute([&] { m = mesher.build(detail::tbb_loop, parts); });
  return m;
}

triangle_mesh surface_snapshot::mesh() const {
  PROGISO_ASSERT(valid());
  if (root_->base_stride > 0) return root_->base;
  return build([](std::uint64_t) { return true; });
}

triangle_mesh surface_snapshot::mesh_of_records(const std::vector<std::uint8_t>& split) const {
  PROGISO_ASSERT(valid());
  if (split.size() != published_) {
    throw error("mesh_of_records: expected a split set of " + std::to_string(published_) +
                " entries, found " + std::to_string(split.size()));
  }
  if (root_->base_stride > 0) return root_->base;
  return build([&split](std::uint64_t r) { return split[r] != 0; });
}

// Records carry no errors (full refinement never computes them): the cut's records are chosen
// here, by the range data's exact errors (made first when no run has made them), one lookup
// per record, in parallel. Every diamond's error is then from one source, and nested, so the
// cut is parent-closed whatever mix of runs made the records.
triangle_mesh surface_snapshot::mesh_cut(double max_error) const {
  PROGISO_ASSERT(valid());
  if (root_->base_stride > 0) refuse_uniform("mesh_cut", root_->base_stride);
  const range_data& rd = owner_->ranges();
  const hierarchy& hier = owner_->hierarchy_of();
  std::vector<std::uint8_t> coarse(published_, 0);  // per record: error > max_error
  const auto mark = [&](std::uint64_t lo, std::uint64_t hi) {
    for (std::uint64_t r = std::max<std::uint64_t>(lo, 1); r < hi; ++r) {
      const detail::engine_record& rec = root_->records[r];
      const ipoint c = hier.point(rec.diamond);
      coarse[r] = rd.get(c, hier.scale_of(c)).error > max_error ? 1 : 0;
    }
  };
  constexpr std::uint64_t chunk = 4096;
  if (owner_->threads() <= 1 || published_ <= chunk) {
    mark(0, published_);
  } else {
    tbb::task_arena arena(static_cast<int>(owner_->threads()));
    arena.execute([&] {
      tbb::parallel_for(std::uint64_t{0}, (published_ + chunk - 1) / chunk, [&](std::uint64_t i) {
        mark(i * chunk, std::min(published_, (i + 1) * chunk));
      });
    });
  }
  return build([&coarse](std::uint64_t r) { return coarse[r] != 0; });
}

void surface_snapshot::mesh_into(render_buffers& out, vertex_normals normals) const {
  if (root_->base_stride > 0) {
    // The uniform cut's mesh is final: written as it is, normals from its positions alone.
    fill_render_buffers(root_->base, out);
    if (normals == vertex_normals::gradient) {
      triangle_mesh points;
      points.vertices = root_->base.vertices;
      owner_->add_normals(points);
      out.normals.resize(3 * points.normals.size());
      float* n = out.normals.data();
      for (const vec3& v : points.normals) {
        for (const double x : v) *n++ = static_cast<float>(x);
      }
    }
    return;
  }
  triangle_mesh m = mesh();
  if (normals == vertex_normals::gradient) owner_->add_normals(m);
  fill_render_buffers(m, out);
}

void surface_snapshot::mesh_cut_into(double max_error, render_buffers& out,
                                     vertex_normals normals) const {
  triangle_mesh m = mesh_cut(max_error);
  if (normals == vertex_normals::gradient) owner_->add_normals(m);
  fill_render_buffers(m, out);
}

// ---------------------------------------------------------------------------------------------
// engine::add_normals

// In pieces of 16 K vertices on the engine's thread count, in a fresh arena (as the meshes
// above): the same normals for every thread count, each computed from the vertex alone.
void engine::add_normals(triangle_mesh& mesh) const {
  const std::size_t threads = this->threads();
  if (threads <= 1 || mesh.vertices.size() <= 16384) {
    add_vertex_normals(mesh, field());
    return;
  }
  tbb::task_arena arena(static_cast<int>(threads));
  arena.execute([&] { add_vertex_normals(mesh, field(), detail::tbb_loop); });
}

bool surface_snapshot::check_integrity() const noexcept {
  if (root_ == nullptr) return false;
  if (root_->magic != detail::root_alive || !std::isfinite(root_->isovalue)) return false;
  const std::uint64_t vertices = owner_->hierarchy_of().vertex_count();
  if (root_->base_stride > 0) {
    return published_ == 1 && root_->records[0].count == 0 &&
           root_->records[0].cut_triangles == root_->base.triangles.size();
  }
  for (std::uint64_t r = 0; r < published_; ++r) {
    const detail::engine_record& rec = root_->records[r];
    if (r == 0) {
      if (rec.diamond != no_owner || rec.count != root_->root_triangles.size()) return false;
      for (const owned_triangle& t : root_->root_triangles) {
        if (t.owner != no_owner && t.owner >= vertices) return false;
      }
      continue;
    }
    if (rec.diamond >= vertices || root_->record_index(rec.diamond) != r) return false;
    // At most one group per child tetrahedron: 2 per ring tetrahedron, 8 of those.
    if (rec.count > 16) return false;
    const std::int32_t scale = detail::record_scale(owner_->hierarchy_of(), rec);
    for (std::uint32_t k = 0; k < rec.count; ++k) {
      const packed_group& g = rec.groups[k];
      const unsigned code = g.owner_code();
      if (code != packed_group::no_owner_code &&
          (code >= 125 || group_owner(owner_->hierarchy_of(), rec.diamond, scale, g) >= vertices)) {
        return false;
      }
      if (g.count() != 1 && g.count() != 2) return false;
    }
  }
  return true;
}

}  // namespace progiso
