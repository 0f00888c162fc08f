// progiso/concurrent/detail/epoch_record.hpp — the shared state behind one epoch_participant.
//
// A record is owned by the domain and never freed before it: a participant claims a free record
// when it registers and hands it back when it leaves, so scans may walk the registry without
// locks. The reservation (lower, upper) is written by the owning participant and read by every
// scan; the retired list and counters are written only by the owner (and by
// epoch_domain::drain() at shutdown, when nobody else runs). Not a public type.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

namespace progiso::detail {

/// `lower` of a participant that is not pinned; `upper` of a reservation that covers every era.
inline constexpr std::uint64_t no_era = ~std::uint64_t{0};

/// A retired object with its lifetime in eras, [birth, retire].
struct retired_object {
  void* object;
  void (*deleter)(void*) noexcept;
  std::uint64_t birth;
  std::uint64_t retire;
};

/// Where a record is shared and where it is private are on different cache lines: scans read
/// the reservation of every record, and only the owner touches the rest.
struct epoch_record {
  alignas(64) std::atomic<std::uint64_t> lower{no_era};
  std::atomic<std::uint64_t> upper{no_era};

  alignas(64) std::vector<retired_object> retired;
  // Single writer (the owner); read by epoch_domain::statistics().
  std::atomic<std::uint64_t> retired_count{0};
  std::atomic<std::uint64_t> reclaimed_count{0};
  epoch_record* next = nullptr;  // set before the record is published, immutable afterwards
  bool in_use = false;           // guarded by the domain's registry mutex
};

/// The objects an exited participant could not free yet, waiting for another participant.
struct orphan_batch {
  std::vector<retired_object> objects;
  orphan_batch* next = nullptr;
};

static_assert(std::atomic<std::uint64_t>::is_always_lock_free);

}  // namespace progiso::detail
