// progiso/core/surface/hierarchy_stream.hpp — the output hierarchy as a byte stream (paper §7:
// the display side traverses the isocontour hierarchy without the volume).
//
// A stream holds one isovalue's published split records, in publication order (every record
// after its parents'), with what a consumer needs to make any cut of them without the volume:
// per record the diamond, its pieces (packed groups, split_record.hpp), its crossed new edges,
// the sample at its centre (every vertex of a cut is on an edge between centres of split
// diamonds or root corners, so these samples and the root corners' are all the field a cut
// reads) and its nested error (for cuts by error and by triangle budget). A cut of a stream
// equals the engine's cut of the same split set vertex for vertex: the same cut_mesher, fed the
// same doubles. Byte layout (version 1, little-endian): docs/formats.md, "Hierarchy streams".
//
// The writer makes chunks: a header, the root surface, then batches of records, then an end
// mark. Each chunk carries its length and a CRC-32, so a consumer reading a stream as it is
// written (a pipe, a socket) takes it chunk by chunk, and any prefix that ends at a chunk
// boundary is a stream of its own (a coarser cut: records are in parent-before-child order).
// decode() validates everything a cut relies on (grid, parents before children, nested errors,
// group codes, crossed edges) and throws progiso::error with the byte offset and what was
// expected for a truncated or corrupt stream.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/detail/flat_map.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>
#include <progiso/core/surface/mesh.hpp>
#include <progiso/core/surface/split_record.hpp>

namespace progiso {

/// The stream's first bytes and its version.
inline constexpr std::array<char, 8> hierarchy_stream_magic{'P', 'R', 'O', 'G', 'I', 'S', 'O', 'H'};
inline constexpr std::uint32_t hierarchy_stream_version = 1;
/// The file extension the command writes and reads.
inline constexpr const char* hierarchy_stream_extension = ".pgh";

namespace detail {
/// The root corners a stream's root chunk holds samples of: every root cube's corners, in grid
/// order (x fastest), at multiples of the root size.
[[nodiscard]] inline std::uint64_t root_corner_count(const hierarchy& h) noexcept {
  const ipoint& c = h.cubes();
  return static_cast<std::uint64_t>(c[0] + 1) * static_cast<std::uint64_t>(c[1] + 1) *
         static_cast<std::uint64_t>(c[2] + 1);
}
/// Root corner i of that order.
[[nodiscard]] inline ipoint root_corner(const hierarchy& h, std::uint64_t i) noexcept {
  const ipoint& c = h.cubes();
  const auto nx = static_cast<std::uint64_t>(c[0] + 1);
  const auto ny = static_cast<std::uint64_t>(c[1] + 1);
  const std::int32_t n = h.root_size();
  return {static_cast<std::int32_t>(i % nx) * n, static_cast<std::int32_t>(i / nx % ny) * n,
          static_cast<std::int32_t>(i / (nx * ny)) * n};
}
}  // namespace detail

/// What a stream is of: the field's grid and geometry, its sample type, and the isovalue.
struct hierarchy_stream_header {
  index3 dims{};                        ///< samples per axis of the field refined (each ≥ 2)
  sample_type type = sample_type::f64;  ///< how centre samples are stored (exact)
  std::array<double, 3> spacing{1.0, 1.0, 1.0};
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  double isovalue = 0.0;
};

/// One split record as the writer takes it.
struct hierarchy_stream_record {
  std::uint64_t diamond = 0;  ///< grid index of its centre
  std::uint32_t crossed = 0;  ///< split_summary::crossed
  double value = 0.0;         ///< the field at its centre (volume::value())
  double error = 0.0;         ///< its nested error (range_data)
  std::span<const packed_group> groups;
};

/// Encodes a stream into chunks handed to `sink` as they are complete. Not thread-safe.
class hierarchy_stream_writer {
 public:
  using sink = std::function<void(std::span<const std::byte>)>;
  /// Records per chunk: a chunk is handed over when it holds this many (or on flush()).
  static constexpr std::size_t chunk_records = 16384;

  /// Writes the magic, the header and the root chunk: the root corners' samples (in grid order:
  /// x fastest over the corners at multiples of the root size) and the root surface's triangles.
  /// Throws progiso::error when the header is not one a reader accepts.
  hierarchy_stream_writer(sink out, const hierarchy_stream_header& header,
                          std::span<const double> root_corner_values,
                          std::span<const owned_triangle> root_triangles);
  /// Appends a record (after its parents').
  void add(const hierarchy_stream_record& r);
  /// Hands over the records added since the last chunk.
  void flush();
  /// flush(), then the end mark. Nothing may be added afterwards.
  void finish();
  [[nodiscard]] std::uint64_t records() const noexcept { return records_; }
  [[nodiscard]] std::uint64_t bytes() const noexcept { return bytes_; }

 private:
  void emit(char type, const std::vector<std::byte>& payload);

  sink out_;
  hierarchy_stream_header header_;
  std::vector<std::byte> batch_;
  std::uint32_t batch_records_ = 0;
  std::uint64_t previous_ = 0;  // the last record's diamond (deltas are coded)
  std::uint64_t records_ = 0;
  std::uint64_t bytes_ = 0;
  bool finished_ = false;
};

/// A decoded, validated stream, and its cuts. Records are numbered 1 … records() (0 is the root
/// surface), as the engine numbers them.
class hierarchy_stream {
 public:
  static constexpr std::uint64_t all_records = std::numeric_limits<std::uint64_t>::max();

  hierarchy_stream(hierarchy_stream&&) noexcept = default;
  hierarchy_stream& operator=(hierarchy_stream&&) noexcept = default;
  hierarchy_stream(const hierarchy_stream&) = delete;  // records point into groups_
  hierarchy_stream& operator=(const hierarchy_stream&) = delete;
  ~hierarchy_stream() = default;

  /// Decodes `bytes`, keeping at most `max_records` records (a prefix). Throws progiso::error
  /// ("byte N: expected …, found …") for a stream that is corrupt or ends inside a chunk.
  [[nodiscard]] static hierarchy_stream decode(std::span<const std::byte> bytes,
                                               std::uint64_t max_records = all_records);

  [[nodiscard]] const hierarchy_stream_header& header() const noexcept { return header_; }
  [[nodiscard]] const hierarchy& grid() const noexcept { return hier_; }
  [[nodiscard]] std::uint64_t records() const noexcept { return records_.size() - 1; }
  /// Whether the stream ended with its end mark (else it is a prefix of a longer one).
  [[nodiscard]] bool complete() const noexcept { return complete_; }

  /// A split set: entry r (1 … records()) says whether record r is split; entry 0 is unused.
  using split_set = std::vector<std::uint8_t>;
  /// Every record.
  [[nodiscard]] split_set all() const;
  /// The records whose nested error exceeds max_error (engine: surface_snapshot::mesh_cut).
  [[nodiscard]] split_set by_error(double max_error) const;
  /// The largest cut by error (by_error(e) for the smallest error e that the stream's records
  /// take, or all of them) whose triangles before clipping number at most max_triangles; the
  /// root surface when none is that small. `threshold`, when given, receives e (−1 for all).
  [[nodiscard]] split_set by_triangles(std::uint64_t max_triangles,
                                       double* threshold = nullptr) const;
  /// The records whose diamond meets the box [lo, hi] (grid coordinates, inclusive) and their
  /// ancestors: full resolution inside the box, the least refinement outside that keeps the cut
  /// closed under parents.
  [[nodiscard]] split_set in_box(const std::array<double, 3>& lo,
                                 const std::array<double, 3>& hi) const;
  /// Triangles of a split set's cut before clipping (engine: surface_snapshot::triangle_count).
  [[nodiscard]] std::uint64_t triangle_count(const split_set& split) const;
  /// The cut's surface, as the engine's snapshot meshes it (canonical order, clipped to the
  /// data box, physical coordinates). Precondition: `split` is closed under parents (every set
  /// above is); throws progiso::error otherwise.
  [[nodiscard]] triangle_mesh mesh(const split_set& split) const;

  /// The grid index of record r's diamond, its nested error.
  [[nodiscard]] std::uint64_t diamond(std::uint64_t r) const noexcept {
    return records_[r].diamond;
  }
  [[nodiscard]] double error_of(std::uint64_t r) const noexcept { return records_[r].error; }

  /// A record as cut_mesher reads it (public for it; not an interface to rely on).
  struct record {
    std::uint64_t diamond;
    const packed_group* groups;
    std::uint32_t count;
    std::int32_t scale;
    std::uint32_t crossed;
    double error;
    std::uint32_t parents[4];
    std::uint32_t parent_count;
  };

 private:
  friend struct stream_decoder;
  explicit hierarchy_stream(const hierarchy_stream_header& h) : header_(h), hier_(h.dims) {}

  hierarchy_stream_header header_;
  hierarchy hier_;
  bool complete_ = false;
  std::vector<record> records_;       // [0] is the root surface
  std::vector<packed_group> groups_;  // records point into it (filled before pointing)
  std::vector<owned_triangle> root_triangles_;
  detail::flat_map vertex_slot_{16};  // edge_key(p, p) of a centre or root corner → value
  std::vector<double> values_;
  std::vector<std::uint32_t> removed_;  // per record: triangles its split removes
};

}  // namespace progiso
