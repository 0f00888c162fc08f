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
// it and its place among that record's triangles, so the same triangle has the same id in every
// cut that holds it, and a change names what it removes by the ids it added earlier. Where the
// hierarchy reaches past the data box a triangle is clipped to the box: into up to four pieces,
// which share its id (consecutive entries of `added`), or none (its id is then in `hidden`, so
// that a later change may name it in `gone` like any other).
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

namespace progiso {

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
  /// piece into a free slot (and remembers the ids of `hidden`, which take none) (the most recently
  /// freed first, so the pool stays as small as the largest surface it held), or into a new slot at
  /// the end. A rebuilt change first empties the pool (slot_count() starts again from 0). Returns
  /// the number of slots written. Throws progiso::error when `gone` names a triangle the pool does
  /// not hold or `added` one it already holds (a change applied out of order, or to another
  /// surface's pool); the pool is then unchanged.
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
  // Open addressing by linear probing, with backward-shift deletion (no tombstones, so a pool
  // that has seen millions of removals probes as short runs as a fresh one): id → first slot,
  // or none for a hidden triangle.
  struct id_table {
    std::vector<std::uint64_t> keys;
    std::vector<std::uint32_t> values;
    std::size_t size = 0;
    [[nodiscard]] std::size_t find(std::uint64_t id) const noexcept;  // place, or keys.size()
    void insert(std::uint64_t id, std::uint32_t slot);
    void erase_at(std::size_t place) noexcept;
    void clear() noexcept;
    void grow();
  };
  void free_slot_at(std::uint32_t s) noexcept;

  std::vector<float> positions_;
  std::vector<float> normals_;
  std::vector<std::uint64_t> owner_;  // per slot: the id, or free_slot
  std::vector<std::uint32_t> next_;   // per slot: the next piece of the same id, or none
  std::vector<std::uint32_t> free_;   // free slots, most recently freed last
  std::vector<std::uint32_t> written_;
  id_table ids_;
  std::size_t live_ = 0;
};

}  // namespace progiso
