#include <progiso/core/surface/surface_change.hpp>

#include <algorithm>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso {

namespace {

// Entries (render_slots::entries_): 0, hidden_entry, or first slot + 1; `marked` flags one named
// by the change being checked.
constexpr std::uint32_t marked = std::uint32_t{1} << 31;
constexpr std::uint32_t hidden_entry = marked - 1;
constexpr std::uint64_t max_k = 31;

[[nodiscard]] bool is_root(std::uint64_t id) noexcept { return (id & root_triangle_bit) != 0; }
[[nodiscard]] std::uint64_t record_of(std::uint64_t id) noexcept { return id >> 5; }
[[nodiscard]] std::uint64_t k_of(std::uint64_t id) noexcept {
  return is_root(id) ? id & ~root_triangle_bit : id & max_k;
}

}  // namespace

std::uint32_t* render_slots::entry(std::uint64_t id) noexcept {
  const std::uint64_t k = k_of(id);
  if (is_root(id)) return k < root_.size() ? &root_[k] : nullptr;
  const std::uint64_t r = record_of(id);
  if (r >= base_.size() || base_[r] == none || k >= span_[r]) return nullptr;
  return &entries_[base_[r] + k];
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
  base_.clear();
  span_.clear();
  entries_.clear();
  root_.clear();
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

  // 1. Check before changing anything. Gone: every id held, once (marked while checking).
  std::size_t checked = 0;
  const auto unmark = [&] {
    for (std::size_t j = 0; j < checked; ++j) *entry(change.gone[j]) &= ~marked;
  };
  const auto refuse = [&](const std::string& what) {
    unmark();
    throw error("render_slots: the change " + what +
                " (a change applied twice, out of order, or to another surface's pool)");
  };
  for (; checked < change.gone.size(); ++checked) {
    std::uint32_t* e = entry(change.gone[checked]);
    if (e == nullptr || *e == 0 || (*e & marked) != 0) {
      refuse("removes triangle " + std::to_string(change.gone[checked]) +
             ", which the pool does not hold");
    }
    *e |= marked;
  }
  // Added and hidden: new ids, record triangles by increasing id (merged, one run per record).
  runs_.clear();
  std::uint64_t last = 0;
  bool any = false;
  const auto take = [&](std::uint64_t id) {
    if (is_root(id)) {
      const std::uint32_t* e = entry(id);
      if (e != nullptr && *e != 0 && (*e & marked) == 0) {
        refuse("adds root triangle " + std::to_string(k_of(id)) + ", which the pool holds");
      }
      return;
    }
    if (any && id < last) {
      refuse("lists record triangles out of order (" + std::to_string(id) + " after " +
             std::to_string(last) + ")");
    }
    const std::uint64_t r = record_of(id);
    if (runs_.empty() || runs_.back().record != r) {
      if (r < base_.size() && base_[r] != none) {
        refuse("adds triangles of record " + std::to_string(r) + ", which the pool holds");
      }
      runs_.push_back({r, 0});
    }
    runs_.back().size = static_cast<std::uint32_t>(k_of(id) + 1);
    last = id;
    any = true;
  };
  {
    std::size_t a = 0;
    std::size_t h = 0;
    // Root ids come first in `added`; record ids of both lists merged by id.
    while (a < change.added.size() && is_root(change.added[a])) take(change.added[a++]);
    while (h < change.hidden.size() && is_root(change.hidden[h])) take(change.hidden[h++]);
    while (a < change.added.size() || h < change.hidden.size()) {
      const bool from_added = h == change.hidden.size() ||
                              (a < change.added.size() && change.added[a] <= change.hidden[h]);
      take(from_added ? change.added[a++] : change.hidden[h++]);
    }
  }

  // 2. Free what is gone.
  for (const std::uint64_t id : change.gone) {
    std::uint32_t* e = entry(id);
    const std::uint32_t v = *e & ~marked;
    *e = 0;
    if (v == hidden_entry) continue;
    for (std::uint32_t s = v - 1; s != none;) {
      const std::uint32_t next = next_[s];
      free_slot_at(s);
      s = next;
    }
  }
  // 3. Blocks for the new records, then the pieces and the hidden ids.
  for (const run& u : runs_) {
    if (u.record >= base_.size()) {
      base_.resize(u.record + 1, none);
      span_.resize(u.record + 1, 0);
    }
    base_[u.record] = static_cast<std::uint32_t>(entries_.size());
    span_[u.record] = static_cast<std::uint8_t>(u.size);
    entries_.resize(entries_.size() + u.size, 0);
  }
  const auto root_entry = [&](std::uint64_t id) {
    const std::uint64_t k = k_of(id);
    if (k >= root_.size()) root_.resize(k + 1, 0);
    return &root_[k];
  };
  const bool with_normals = !change.normals.empty();
  if (with_normals && normals_.size() != positions_.size()) normals_.resize(positions_.size());
  // The slots this change adds beyond the free ones, reserved at once (geometrically, so that
  // a run of changes moves the arrays O(log n) times, not once per change).
  if (change.added.size() > free_.size()) {
    const std::size_t slots = owner_.size() + change.added.size() - free_.size();
    const auto grow = [](auto& v, std::size_t n) {
      if (n > v.capacity()) v.reserve(std::max(n, 2 * v.capacity()));
    };
    grow(owner_, slots);
    grow(next_, slots);
    grow(positions_, 9 * slots);
    if (with_normals || !normals_.empty()) grow(normals_, 9 * slots);
  }
  std::uint32_t previous = none;
  for (std::size_t j = 0; j < change.added.size(); ++j) {
    std::uint32_t s = 0;
    if (!free_.empty()) {
      s = free_.back();
      free_.pop_back();
    } else {
      s = static_cast<std::uint32_t>(owner_.size());
      if (s + 1 >= hidden_entry) throw error("render_slots: more than 2^31 - 2 slots");
      owner_.push_back(free_slot);
      next_.push_back(none);
      positions_.resize(positions_.size() + 9);
      if (!normals_.empty() || with_normals) normals_.resize(positions_.size());
    }
    const std::uint64_t id = change.added[j];
    owner_[s] = id;
    next_[s] = none;
    if (j > 0 && change.added[j - 1] == id) {
      next_[previous] = s;
    } else {
      *(is_root(id) ? root_entry(id) : entry(id)) = s + 1;
    }
    std::copy_n(change.positions.data() + 9 * j, 9, positions_.data() + 9 * std::size_t{s});
    if (with_normals) {
      std::copy_n(change.normals.data() + 9 * j, 9, normals_.data() + 9 * std::size_t{s});
    }
    written_.push_back(s);
    previous = s;
    ++live_;
  }
  for (const std::uint64_t id : change.hidden) {
    *(is_root(id) ? root_entry(id) : entry(id)) = hidden_entry;
  }
  return written_.size();
}

}  // namespace progiso
