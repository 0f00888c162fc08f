#include <progiso/core/surface/surface_change.hpp>

#include <algorithm>
#include <bit>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso {

namespace {

// Fibonacci hashing, the product's top bits: ids of one record differ in their low bits and
// records are dense, and the top bits depend on all of them (middle bits made long runs).
[[nodiscard]] std::size_t home_of(std::uint64_t id, std::size_t mask) noexcept {
  const auto bits = static_cast<int>(std::bit_width(mask));
  return static_cast<std::size_t>((id * 0x9E3779B97F4A7C15ULL) >> (64 - bits));
}

constexpr std::uint64_t empty_id = render_slots::free_slot;
// A gone id found by apply()'s check, until its slots are freed.
constexpr std::uint32_t marked = std::uint32_t{1} << 31;
// The table's value for a hidden triangle (no slot); slots stay below it.
constexpr std::uint32_t no_slot = marked - 1;

}  // namespace

std::size_t render_slots::id_table::find(std::uint64_t id) const noexcept {
  if (keys.empty()) return 0;
  const std::size_t mask = keys.size() - 1;
  for (std::size_t i = home_of(id, mask);; i = (i + 1) & mask) {
    if (keys[i] == id) return i;
    if (keys[i] == empty_id) return keys.size();
  }
}

void render_slots::id_table::grow() {
  std::vector<std::uint64_t> old_keys(std::max<std::size_t>(64, 2 * keys.size()), empty_id);
  std::vector<std::uint32_t> old_values(old_keys.size());
  old_keys.swap(keys);
  old_values.swap(values);
  const std::size_t mask = keys.size() - 1;
  for (std::size_t j = 0; j < old_keys.size(); ++j) {
    if (old_keys[j] == empty_id) continue;
    std::size_t i = home_of(old_keys[j], mask);
    while (keys[i] != empty_id) i = (i + 1) & mask;
    keys[i] = old_keys[j];
    values[i] = old_values[j];
  }
}

void render_slots::id_table::insert(std::uint64_t id, std::uint32_t slot) {
  if (2 * (size + 1) > keys.size()) grow();  // load at most one half
  const std::size_t mask = keys.size() - 1;
  std::size_t i = home_of(id, mask);
  while (keys[i] != empty_id) i = (i + 1) & mask;
  keys[i] = id;
  values[i] = slot;
  ++size;
}

// Backward shift: the entries after the hole that may sit at or before it move up, so every
// probe run stays unbroken without tombstones.
void render_slots::id_table::erase_at(std::size_t place) noexcept {
  const std::size_t mask = keys.size() - 1;
  std::size_t hole = place;
  for (std::size_t i = (hole + 1) & mask; keys[i] != empty_id; i = (i + 1) & mask) {
    const std::size_t home = home_of(keys[i], mask);
    // Entry i may fill the hole when its home is not in the cyclic interval (hole, i].
    const bool stays = hole <= i ? (home > hole && home <= i) : (home > hole || home <= i);
    if (stays) continue;
    keys[hole] = keys[i];
    values[hole] = values[i];
    hole = i;
  }
  keys[hole] = empty_id;
  --size;
}

void render_slots::id_table::clear() noexcept {
  std::fill(keys.begin(), keys.end(), empty_id);
  size = 0;
}

void render_slots::free_slot_at(std::uint32_t s) noexcept {
  float* p = positions_.data() + 9 * std::size_t{s};
  for (std::size_t k = 3; k < 9; ++k) p[k] = p[k % 3];  // all three corners at the first
  owner_[s] = free_slot;
  next_[s] = none;
  free_.push_back(s);
  written_.push_back(s);
  --live_;
}

void render_slots::clear() noexcept {
  positions_.clear();
  normals_.clear();
  owner_.clear();
  next_.clear();
  free_.clear();
  ids_.clear();
  live_ = 0;
}

std::size_t render_slots::apply(const surface_change& change) {
  if (change.positions.size() != 9 * change.added.size() ||
      (!change.normals.empty() && change.normals.size() != change.positions.size())) {
    throw error("render_slots: a surface_change with " + std::to_string(change.added.size()) +
                " added pieces has " + std::to_string(change.positions.size()) +
                " position floats and " + std::to_string(change.normals.size()) +
                " normal floats (expected 9 per piece, normals optional)");
  }
  written_.clear();
  if (change.rebuilt) clear();
  // Check before changing anything: every gone id held once, every added id new.
  std::size_t checked = 0;
  const auto unmark = [&] {
    for (std::size_t j = 0; j < checked; ++j) {
      ids_.values[ids_.find(change.gone[j])] &= ~marked;
    }
  };
  for (; checked < change.gone.size(); ++checked) {
    const std::size_t at = ids_.find(change.gone[checked]);
    if (at >= ids_.keys.size() || (ids_.values[at] & marked) != 0) {
      unmark();
      throw error("render_slots: the change removes triangle " +
                  std::to_string(change.gone[checked]) +
                  ", which the pool does not hold (a change applied out of order, twice, or "
                  "to another surface's pool)");
    }
    ids_.values[at] |= marked;
  }
  const auto check_new = [&](std::uint64_t id) {
    const std::size_t at = ids_.find(id);
    if (at < ids_.keys.size() && (ids_.values[at] & marked) == 0) {
      unmark();
      throw error("render_slots: the change adds triangle " + std::to_string(id) +
                  ", which the pool already holds (a change applied twice, or to another "
                  "surface's pool)");
    }
  };
  for (std::size_t j = 0; j < change.added.size(); ++j) {
    if (j == 0 || change.added[j] != change.added[j - 1]) check_new(change.added[j]);
  }
  for (const std::uint64_t id : change.hidden) check_new(id);
  for (const std::uint64_t id : change.gone) {
    const std::size_t at = ids_.find(id);
    const std::uint32_t first = ids_.values[at] & ~marked;
    for (std::uint32_t s = first == no_slot ? none : first; s != none;) {
      const std::uint32_t next = next_[s];
      free_slot_at(s);
      s = next;
    }
    ids_.erase_at(at);
  }
  const bool with_normals = !change.normals.empty();
  if (with_normals && normals_.size() != positions_.size()) normals_.resize(positions_.size());
  std::uint32_t previous = none;
  for (std::size_t j = 0; j < change.added.size(); ++j) {
    std::uint32_t s = 0;
    if (!free_.empty()) {
      s = free_.back();
      free_.pop_back();
    } else {
      s = static_cast<std::uint32_t>(owner_.size());
      if (s >= no_slot) throw error("render_slots: more than 2^31 - 2 slots");
      owner_.push_back(free_slot);
      next_.push_back(none);
      positions_.resize(positions_.size() + 9);
      if (with_normals || !normals_.empty()) normals_.resize(positions_.size());
    }
    const std::uint64_t id = change.added[j];
    owner_[s] = id;
    next_[s] = none;
    if (j > 0 && change.added[j - 1] == id) {
      next_[previous] = s;
    } else {
      ids_.insert(id, s);
    }
    std::copy_n(change.positions.data() + 9 * j, 9, positions_.data() + 9 * std::size_t{s});
    if (with_normals) {
      std::copy_n(change.normals.data() + 9 * j, 9, normals_.data() + 9 * std::size_t{s});
    }
    written_.push_back(s);
    previous = s;
    ++live_;
  }
  for (const std::uint64_t id : change.hidden) ids_.insert(id, no_slot);
  return written_.size();
}

}  // namespace progiso
