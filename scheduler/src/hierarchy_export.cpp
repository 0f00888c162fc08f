// The engine's records into a hierarchy stream.

#include <progiso/scheduler/hierarchy_export.hpp>

#include "engine_impl.hpp"

namespace progiso {

hierarchy_exporter::hierarchy_exporter(const engine& e, hierarchy_stream_writer::sink out)
    : engine_(e), out_(std::move(out)) {}

void hierarchy_exporter::write(const surface_snapshot& s) {
  PROGISO_ASSERT(s.valid());
  if (s.owner_ != &engine_) throw error("hierarchy stream: a snapshot of another engine");
  if (s.root_->base_stride > 0) {
    throw error(
        "hierarchy stream: the snapshot is a uniform cut made by streaming passes, which "
        "has no split records to write (engine_options::uniform_cuts = false)");
  }
  const volume& field = engine_.field();
  const hierarchy& hier = engine_.hierarchy_of();
  if (!writer_) {
    hierarchy_stream_header h;
    h.dims = field.dims();
    // A smoothed field's samples are computed doubles; a volume's are of its type.
    h.type = field.subdivided() != nullptr ? sample_type::f64 : field.type();
    h.spacing = field.spacing();
    h.origin = field.origin();
    h.isovalue = s.isovalue();
    std::vector<double> corners(detail::root_corner_count(hier));
    for (std::uint64_t i = 0; i < corners.size(); ++i) {
      const ipoint p = detail::root_corner(hier, i);
      corners[i] = field.value(p[0], p[1], p[2]);
    }
    writer_.emplace(out_, h, corners, s.root_->root_triangles);
    generation_ = s.generation();
    root_ = s.root_->serial;
    written_ = 1;
  } else if (s.generation() != generation_) {
    throw error("hierarchy stream: a snapshot of another isovalue (" +
                std::to_string(s.isovalue()) + ") than the stream's");
  } else if (s.root_->serial != root_) {
    throw error("hierarchy stream: a snapshot of another refinement of the stream's isovalue");
  }
  if (s.published_ <= written_) return;
  const range_data& rd = engine_.ranges();
  for (std::uint64_t r = written_; r < s.published_; ++r) {
    const detail::engine_record& rec = s.root_->records[r];
    const ipoint c = hier.point(rec.diamond);
    hierarchy_stream_record out;
    out.diamond = rec.diamond;
    out.crossed = rec.crossed;
    out.value = field.value(c[0], c[1], c[2]);
    out.error = rd.get(c, hier.scale_of(c)).error;
    out.groups = std::span<const packed_group>(rec.groups, rec.count);
    writer_->add(out);
  }
  written_ = s.published_;
  writer_->flush();
}

void hierarchy_exporter::finish() {
  if (writer_) writer_->finish();
}

}  // namespace progiso
