// progiso/scheduler/hierarchy_export.hpp — an engine's published records as a hierarchy stream
// (core/surface/hierarchy_stream.hpp), written as they are published.
//
// A caller that follows a run (the command's --hierarchy, a server) takes a snapshot now and
// then and calls write(snapshot): the records published since the last call go out, in the
// engine's publication order and numbering, so that a consumer's cut of records 1 … k is the
// engine's snapshot of k + 1 records. Errors come from the engine's range data (engine::ranges():
// the first write makes the exact errors if no run has), as surface_snapshot::mesh_cut() takes
// them, so a consumer's cut by error equals the engine's. One isovalue per stream.
#pragma once

#include <cstdint>
#include <optional>

#include <progiso/core/base/error.hpp>
#include <progiso/core/surface/hierarchy_stream.hpp>
#include <progiso/scheduler/engine.hpp>

namespace progiso {

class hierarchy_exporter {
 public:
  /// Chunks go to `out` (see hierarchy_stream_writer). Nothing is written before write().
  hierarchy_exporter(const engine& e, hierarchy_stream_writer::sink out);

  /// Writes the header and root surface (first call), then the records of `s` not yet written,
  /// and flushes them as a chunk. Throws progiso::error for a snapshot of another engine or
  /// isovalue than the first call's. Not from the engine's progress callback (see ranges()).
  void write(const surface_snapshot& s);
  /// The end mark (after a last write()). A stream without it is a prefix.
  void finish();

  [[nodiscard]] std::uint64_t records() const noexcept { return written_ == 0 ? 0 : written_ - 1; }
  [[nodiscard]] std::uint64_t bytes() const noexcept { return writer_ ? writer_->bytes() : 0; }

 private:
  const engine& engine_;
  hierarchy_stream_writer::sink out_;
  std::optional<hierarchy_stream_writer> writer_;
  std::uint64_t generation_ = 0;
  std::uint64_t root_ = 0;     // the engine's root (cut_mark::root) the stream's records are of
  std::uint64_t written_ = 0;  // records written, counting the root surface
};

}  // namespace progiso
