// progiso/core/surface/surface_change.hpp — what changed between two cuts of one surface, and
// a renderer's slot pool that follows those changes.
//
// A progressive cut changes locally: a split replaces the triangles its diamond owned by those
// of its children. A renderer that re-extracts the whole cut every frame pays for the whole
// surface; one that applies the change pays for what changed. surface_change is that change,
// renderer-ready (float positions, optional normals), and render_slots keeps a surface in
// storage that stays put between frames, so that an update writes only the slots it touches.
//
// Triangle ids. A triangle of a cut is named by where it was made: the record (split) that made
// it and its place k among that record's triangles, `record << 5 | k` (k < 32), or for the root
// surface's triangle k, `root_triangle_bit | k`. The same triangle has the same id in every cut
// that holds it, and a change names what it removes by the ids it added earlier. Every triangle
// of a record is added by the one change whose window holds the record, so a change lists its
// added record triangles by increasing id. Where the hierarchy reaches past the data box a
// triangle is clipped to the box: into up to four pieces, which share its id (consecutive entries
// of `added`), or none (its id is then in `hidden`, so that a later change may name it in `gone`
// like any other).
//
// Slots. render_slots gives each live piece one slot of three vertices (slot s: vertices 3s,
// 3s + 1, 3s + 2), so the index buffer is the identity and never changes; a removed piece's slot
// is collapsed to a point (a zero-area triangle a rasteriser draws nothing of) and reused by a
// later piece. Vertices are not shared between slots: which triangles share a vertex changes
// from cut to cut, and keeping shared vertices would cost reference counts and a lookup per
// corner on every update, against three times the vertex storage.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <progiso/core/base/error.hpp>

namespace progiso {

/// The top bit of a root surface triangle's id (see the file comment).
inline constexpr std::uint64_t root_triangle_bit = std::uint64_t{1} << 63;

/// The triangles that differ between an earlier cut and a later one of the same surface.
struct surface_change {
  /// True when the change is the whole later cut (the earlier cut was of another isovalue, or
  /// there was none): a consumer drops everything it holds first. `gone` is then empty.
  bool rebuilt = false;
  /// Ids of the triangles of the earlier cut that the later one no longer holds (every piece
  /// of each).
  std::vector<std::uint64_t> gone;
  /// One id per added piece: pieces of one triangle are consecutive.
  std::vector<std::uint64_t> added;
  /// Ids of the triangles added that lie wholly past the data box: no piece, no slot.
  std::vector<std::uint64_t> hidden;
  /// 9 per added piece: three corners, x y z each, in the orientation of triangle_mesh.
  std::vector<float> positions;
  /// 9 per added piece when normals were asked for, else empty.
  std::vector<float> normals;

  [[nodiscard]] std::size_t added_count() const noexcept { return added.size(); }
  void clear() noexcept {
    rebuilt = false;
    gone.clear();
    added.clear();
    hidden.clear();
    positions.clear();
    normals.clear();
  }
};

/// A surface kept as a pool of triangle slots that follows surface_change updates (see the file
/// comment). One thread at a time.
class render_slots {
 public:
  /// Applies a change: frees the slots of `gone` (collapsing them), then writes each added
  /// piece into a free slot, the most recently freed first (so the pool stays as small as the
  /// largest surface it held), or into a new slot at the end, and remembers the ids of `hidden`,
  /// which take none. A rebuilt change first empties the pool (slot_count() starts again from
  /// 0). Returns the number of slots written. Throws progiso::error, leaving the pool unchanged,
  /// when `gone` names a triangle the pool does not hold or `added` or `hidden` one it already
  /// holds (a change applied twice, out of order, or to another surface's pool), or when the
  /// change is malformed (record ids not increasing, positions or normals not 9 per piece).
  std::size_t apply(const surface_change& change);
  /// Empties the pool: no slot, no id (storage is kept).
  void clear() noexcept;

  /// Slots below the high-water mark, live or free: draw 3 × slot_count() vertices.
  [[nodiscard]] std::size_t slot_count() const noexcept { return owner_.size(); }
  /// Live pieces.
  [[nodiscard]] std::size_t triangle_count() const noexcept { return live_; }
  /// 9 floats per slot (a free slot's three corners are equal).
  [[nodiscard]] std::span<const float> positions() const noexcept { return positions_; }
  /// 9 floats per slot once a change with normals was applied, else empty.
  [[nodiscard]] std::span<const float> normals() const noexcept { return normals_; }
  /// The slots written by the last apply(), in the order written (a slot may repeat: freed,
  /// then reused): what a renderer uploads.
  [[nodiscard]] std::span<const std::uint32_t> written() const noexcept { return written_; }
  /// The id of the piece in slot s, or free_slot.
  [[nodiscard]] std::uint64_t id_of(std::size_t s) const noexcept { return owner_[s]; }
  static constexpr std::uint64_t free_slot = ~std::uint64_t{0};

 private:
  static constexpr std::uint32_t none = ~std::uint32_t{0};
  // Where each id's pieces are, by record rather than by hash: the triangles of a record are
  // added together, so record r gets a block of entries (one per k up to its largest) when its
  // triangles arrive, written in sequence, and a lookup is two array reads. A hash table of ids
  // cost a cache miss per insertion. An entry is 0 (no piece held), hidden_entry, or first slot
  // + 1; the top bit marks an entry named by the change being checked.
  std::uint32_t* entry(std::uint64_t id) noexcept;  // null when the id was never added
  std::vector<std::uint32_t> base_;                 // per record: its block's first entry, or none
  std::vector<std::uint8_t> span_;                  // per record: its block's size
  std::vector<std::uint32_t> entries_;              // the blocks
  std::vector<std::uint32_t> root_;                 // the root surface's triangles, by k
  struct run {  // one record's triangles in the change being applied
    std::uint64_t record;
    std::uint32_t size;
  };
  std::vector<run> runs_;
  void free_slot_at(std::uint32_t s) noexcept;

  std::vector<float> positions_;
  std::vector<float> normals_;
  std::vector<std::uint64_t> owner_;  // per slot: the id, or free_slot
  std::vector<std::uint32_t> next_;   // per slot: the next piece of the same id, or none
  std::vector<std::uint32_t> free_;   // free slots, most recently freed last
  std::vector<std::uint32_t> written_;
  std::size_t live_ = 0;
};

}  // namespace progiso
