// progiso/concurrent/epoch.hpp — epoch-based reclamation whose garbage stays bounded while a
// reader stalls: interval-based reclamation (2GEIBR of Wen, Izraelevitz, Cai, Beadle and Scott,
// "Interval-Based Memory Reclamation", PPoPP 2018) in the shape of crossbeam-epoch.
//
// What it is. Lock-free structures unlink objects that other threads may still be reading. A
// reader pins its participant (`epoch_guard g = participant.pin();`) and reads every shared
// pointer through `g.protect(source)`; a writer unlinks an object and hands it to
// `participant.retire(object)`; the object is destroyed once no guard can reach it. The domain
// keeps a clock of eras. A managed object records its birth era (make_managed, epoch_object),
// retire() records its retire era, and a pinned participant publishes the eras it may be
// reading, [lower, upper]: lower is the era at pin(), and protect() raises upper to the current
// era when it reads a pointer. A retired object is freed once [birth, retire] meets no published
// interval. Plain EBR is the special case birth = 0: then every object retired after the oldest
// pin is kept.
//
// When to use it: readers that walk pointer-linked shared data while writers replace parts of it
// (versioned roots, snapshots, lock-free maps). Every pointer loaded from a location that a
// writer may change must go through protect(). A pointer stored in a protected object and never
// changed needs no protect() only if its target was born no later and is retired no earlier than
// the object holding it (e.g. an immutable tree built before its root was published, retired
// with it). Not for objects that must be destroyed at a known moment (use ownership), nor for
// readers that must not publish anything (a guard writes its participant's reservation).
//
// Bound on garbage. Let P be the number of participants, T = reclaim_threshold and
// F = era_frequency. A participant stamps at most F retirements with one era (its F-th advances
// the clock) and runs flush() at least every T retirements, after which its list holds only
// objects that some published reservation keeps. A participant stalled inside a guard with
// reservation [L, U] keeps exactly the retired objects whose [birth, retire] meets [L, U]:
//     kept ≤ (U − L + 1) · P · F    objects retired while the clock read an era in [L, U]
//          + live(U)                 objects born but not yet retired when the clock left U.
// So a stalled reader pins only the versions it reads plus the objects alive when it last raised
// its reservation; everything born later is reclaimed as if it did not exist. In all,
//     pending ≤ Σ kept over pinned participants + P · (T − 1)
// plus, until the next flush() of any participant, what exited participants left behind.
// Example (tests/concurrent/epoch_bounded_garbage_test.cpp): one writer publishes and retires
// 100 000 versions of one pointer while a reader that pinned and protected the first one
// stalls (U = L, live = 1): pending ≤ F + 1 + T − 1 = T + F (80 with the defaults; the test
// reaches it, so the bound is tight), and after the reader resumes everything is reclaimed.
// Plain EBR (interval_based = false) kept all 100 000 versions retired during the stall. The
// bound assumes the stalled thread is not preempted inside protect()'s fallback (two loads long,
// entered only after the clock moved protect_attempts + 1 times during one call), where its
// reservation briefly covers every era.
//
// Thread safety: an epoch_domain is shared by all threads. An epoch_participant and its guards
// belong to one thread at a time (one participant per thread per domain); pin(), protect(),
// retire() and flush() of different participants run concurrently. Registration takes the
// domain's mutex. Deleters run on the thread that calls flush() or drain(), pinned or not, and
// may retire more objects.
//
// Progress: pin() and unpin are wait-free (no loop). protect() is wait-free: at most
// protect_attempts + 2 loads of the source, then a fallback without a loop. retire() is
// wait-free amortised: O(1) plus a flush() every T retirements. flush() is wait-free apart from
// the deleters it runs: one pass over the registry (P records) and over its own list.
// Registration (constructing or destroying an epoch_participant) takes a mutex.
//
// Memory ordering: a pointer must be published with a release-store (or stronger) after its
// object is stamped, and unlinked before retire() by a modification that happens before it.
// pin() and protect() store the reservation and then run a seq_cst fence before loading a
// source; retire() and flush() run a seq_cst fence after the unlink and before reading the clock
// or any reservation. Either the reader's fence precedes the writer's in the total order S, and
// then the writer sees the reservation (and a retire era ≥ lower), or the reader's load of the
// source sees the unlink and the reader never reaches the object. A reader's accesses happen
// before the deleter runs through the release-store of `lower` at unpin and the acquire-load in
// the scan. Under PROGISO_TSAN the fences become seq_cst accesses (detail/memory_order.hpp); that
// variant's argument also needs the unlink to be seq_cst, the default of std::atomic.
//
// Cost: pin() one load, two stores and a fence; protect() two loads when the clock has not
// moved since the last pin() or protect() (else one store and a fence per attempt); unpin one
// store; retire() a fence and an append; flush() O((T + kept) · P).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <type_traits>
#include <utility>
#include <vector>

#include <progiso/concurrent/detail/epoch_record.hpp>
#include <progiso/concurrent/detail/memory_order.hpp>
#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/config.hpp>

namespace progiso {

class epoch_domain;
class epoch_participant;

/// Tuning of an epoch_domain. Zero thresholds are treated as 1.
struct epoch_options {
  /// A participant runs flush() after this many retire() calls (T in the bound).
  std::size_t reclaim_threshold = 64;
  /// A participant advances the era clock after this many retire() calls (F in the bound).
  std::size_t era_frequency = 16;
  /// How often protect() republishes its reservation and re-reads before its fallback.
  unsigned protect_attempts = 3;
  /// false: ignore birth eras, i.e. plain epoch-based reclamation (for measurements only).
  bool interval_based = true;
};

/// A closed interval of eras.
struct era_interval {
  std::uint64_t lower;
  std::uint64_t upper;
};

/// Counts over the whole domain: exact when no thread is working, approximate otherwise.
struct epoch_statistics {
  std::uint64_t retired = 0;    ///< objects passed to retire()
  std::uint64_t reclaimed = 0;  ///< deleters run
  std::uint64_t pending = 0;    ///< retired − reclaimed
  std::uint64_t era = 0;        ///< the clock
};

/// Base of objects that carry their birth era. An object whose birth was never stamped (0), or
/// that does not derive from epoch_object, is kept like in plain EBR: safe, but a stalled reader
/// keeps it.
class epoch_object {
 public:
  [[nodiscard]] std::uint64_t birth_era() const noexcept { return birth_era_; }

 protected:
  epoch_object() noexcept = default;
  epoch_object(const epoch_object&) noexcept = default;  // an older birth is still safe
  epoch_object& operator=(const epoch_object&) noexcept { return *this; }  // keeps its own birth
  ~epoch_object() = default;

 private:
  friend class epoch_domain;
  std::uint64_t birth_era_ = 0;
};

/// The default deleter of retire(): `delete object`.
struct delete_object {
  template <class T>
  void operator()(T* object) const noexcept {
    delete object;
  }
};

/// The era clock, the registry of participants and the objects exited participants left.
class epoch_domain {
 public:
  explicit epoch_domain(epoch_options options = {});
  /// Precondition: every participant of this domain is destroyed. Drains.
  ~epoch_domain();
  epoch_domain(const epoch_domain&) = delete;
  epoch_domain& operator=(const epoch_domain&) = delete;

  /// The clock. Progress: wait-free.
  [[nodiscard]] std::uint64_t era() const noexcept {
    // relaxed: a reading for statistics and tests; no other access is ordered by it.
    return era_.load(std::memory_order_relaxed);
  }

  /// Sets `object`'s birth to the current era. Call it after constructing and before publishing
  /// (make_managed does both). Thread safety: any thread. Progress: wait-free.
  void stamp_birth(epoch_object& object) const noexcept {
    // relaxed: a reader needs its upper era ≥ this birth. The object is published by a
    // release-store that the reader's acquire-load (2) in protect() reads, so by write-read
    // coherence every later load of the clock in the reader returns at least this value.
    object.birth_era_ = era_.load(std::memory_order_relaxed);
  }

  /// Reclaims every retired object, whatever the reservations, and returns how many.
  /// Precondition: no participant is pinned and no other thread uses this domain during the
  /// call (e.g. its workers are joined). Deleters may retire more objects; those are reclaimed
  /// too. Every retired object is reclaimed exactly once over flush() and drain() calls.
  std::size_t drain() noexcept;

  /// Sums over all participants, past and present. Thread safety: any thread. Progress:
  /// wait-free (one pass over the registry).
  [[nodiscard]] epoch_statistics statistics() const noexcept;

  [[nodiscard]] const epoch_options& options() const noexcept { return options_; }

 private:
  friend class epoch_participant;

  detail::epoch_record* claim_record();
  void release_record(detail::epoch_record* record) noexcept;
  void push_orphans(std::vector<detail::retired_object>&& objects);
  [[nodiscard]] detail::orphan_batch* take_orphans() noexcept;

  alignas(64) std::atomic<std::uint64_t> era_{1};
  alignas(64) std::atomic<detail::epoch_record*> records_{nullptr};
  std::atomic<detail::orphan_batch*> orphans_{nullptr};
  std::atomic<std::uint64_t> drained_{0};  // objects reclaimed by drain()
  epoch_options options_;
  std::mutex registry_mutex_;  // registration only
};

/// A critical section of one participant, from pin() to destruction (or unpin()). Move-only.
/// While it lives, objects loaded through protect() stay valid.
class [[nodiscard]] epoch_guard {
 public:
  epoch_guard() noexcept = default;  ///< not pinned
  epoch_guard(epoch_guard&& other) noexcept
      : participant_(std::exchange(other.participant_, nullptr)) {}
  epoch_guard& operator=(epoch_guard&& other) noexcept;
  epoch_guard(const epoch_guard&) = delete;
  epoch_guard& operator=(const epoch_guard&) = delete;
  ~epoch_guard() { unpin(); }

  /// Loads `source` and reserves the era of the object it points to; the object stays valid
  /// while this guard lives. The source must be published with a release-store after the
  /// object was stamped (make_managed). Precondition: pinned.
  /// Progress: wait-free, at most options().protect_attempts + 2 loads of `source`.
  template <class T>
  [[nodiscard]] T* protect(const std::atomic<T*>& source) noexcept;

  /// The eras this guard's participant reserves now (for tests and diagnostics).
  [[nodiscard]] era_interval reservation() const noexcept;

  [[nodiscard]] bool is_pinned() const noexcept { return participant_ != nullptr; }

  /// Ends the critical section now; pointers obtained through this guard become invalid.
  void unpin() noexcept;

 private:
  friend class epoch_participant;
  explicit epoch_guard(epoch_participant* participant) noexcept : participant_(participant) {}

  epoch_participant* participant_ = nullptr;
};

/// A thread's registration in a domain, with its own retired list. Neither copyable nor
/// movable (guards point to it). Destroying it flushes, and hands what is still reserved to
/// the domain, where the next flush() of any participant (or drain()) picks it up.
class epoch_participant {
 public:
  /// Registers; takes the domain's mutex. Throws std::bad_alloc.
  explicit epoch_participant(epoch_domain& domain);
  /// Precondition: no guard of this participant is alive.
  ~epoch_participant();
  epoch_participant(const epoch_participant&) = delete;
  epoch_participant& operator=(const epoch_participant&) = delete;

  /// Enters a critical section. Guards nest: the reservation ends with the last one.
  /// Progress: wait-free.
  epoch_guard pin() noexcept;

  /// Hands over an unlinked object: `Deleter{}(object)` runs once no guard can reach it. The
  /// birth is object->birth_era() when T derives from epoch_object, else 0 (kept as in plain
  /// EBR). Deleter must be stateless and noexcept. Null is ignored. Precondition: `object` is
  /// unreachable for guards pinned from now on, retired once. Throws std::bad_alloc (before
  /// anything changes: the caller still owns the object). Progress: wait-free amortised.
  template <class Deleter = delete_object, class T>
  void retire(T* object);

  /// retire() without types: `deleter(object)` with the given birth era.
  void retire(void* object, void (*deleter)(void*) noexcept, std::uint64_t birth_era);

  /// Frees every object of this participant's list that no reservation keeps, adopting first
  /// what exited participants left; returns how many it freed. Runs by itself every
  /// reclaim_threshold retirements. Calls from within a deleter return 0. Terminates if memory
  /// for its list runs out (no retired object is ever lost). Progress: see the file comment.
  std::size_t flush() noexcept;

  /// Objects in this participant's list (retired, not yet freed).
  [[nodiscard]] std::size_t pending() const noexcept { return record_->retired.size(); }
  [[nodiscard]] bool is_pinned() const noexcept { return nesting_ != 0; }
  [[nodiscard]] epoch_domain& domain() const noexcept { return *domain_; }
  /// How many times protect() re-read a source because the era clock had moved (each is one
  /// more bounded step, never a wait). Any thread (a recent value).
  [[nodiscard]] std::uint64_t protect_retries() const noexcept {
    // relaxed: a statistic.
    return retries_.load(std::memory_order_relaxed);
  }

 private:
  friend class epoch_guard;

  template <class T>
  T* protect(const std::atomic<T*>& source) noexcept;
  void unpin() noexcept;
  void adopt_orphans() noexcept;

  epoch_domain* domain_;
  detail::epoch_record* record_;
  std::uint64_t lower_ = detail::no_era;  // owner's copies of the published reservation
  std::uint64_t upper_ = detail::no_era;
  unsigned nesting_ = 0;
  std::size_t since_advance_ = 0;
  std::size_t since_flush_ = 0;
  bool flushing_ = false;
  std::vector<era_interval> reservations_;  // scratch of flush()
  std::atomic<std::uint64_t> retries_{0};   // protect() re-reads (statistics)
};

/// `new T(args...)` with its birth stamped: the way to allocate objects for protect()/retire().
/// Publish the result with a release-store (or stronger). Throws what `new T` throws.
template <class T, class... Args>
[[nodiscard]] T* make_managed(epoch_domain& domain, Args&&... args) {
  static_assert(std::is_base_of_v<epoch_object, T>, "T must derive from progiso::epoch_object");
  T* object = new T(std::forward<Args>(args)...);
  domain.stamp_birth(*object);
  return object;
}

// ---------------------------------------------------------------------------------------------
// Inline bodies of the hot paths. Numbered synchronisation points:
//   (1) pin()         reservation stores, then a seq_cst fence
//   (2) protect()     acquire-load of the source
//   (3) protect()     raised upper, then a seq_cst fence
//   (4) protect()     fallback: upper = every era, then a seq_cst fence
//   (5) retire()      seq_cst fence, then the retire era            (epoch.cpp)
//   (6) flush()       seq_cst fence, then the scan                  (epoch.cpp)
//   (7) flush()       acquire-load of each `lower`                  (epoch.cpp)
//   (8) unpin()       release-store of lower = no_era
//   (9)/(10)          registry head: release-store in claim_record(), acquire-loads in
//                     flush() and statistics()                     (epoch.cpp)
//   (11)/(12)         orphan batches: release-CAS in push_orphans(), acquire-exchange in
//                     take_orphans()                                (epoch.cpp)

inline epoch_guard epoch_participant::pin() noexcept {
  if (nesting_++ == 0) {
    // relaxed (seq_cst under TSan): fence (1) orders this load before the loads of sources;
    // retire()'s stamp is ≥ it by the argument at (5).
    const std::uint64_t now = domain_->era_.load(detail::fenced_relaxed);
    lower_ = upper_ = now;
    // (1) stores of the reservation, then a seq_cst fence; pairs with fence (5) in retire() and
    // fence (6) in flush(): a writer whose unlink this pin's later loads miss sees both stores.
    // `lower` is a release-store: whichever guard's `lower` a scan reads, acquire-load (7)
    // then orders every earlier guard's reads before the deleters.
    record_->upper.store(now, detail::fenced_relaxed);
    record_->lower.store(now, detail::fenced_release);
    detail::seq_cst_fence();
  }
  return epoch_guard(this);
}

inline void epoch_participant::unpin() noexcept {
  PROGISO_ASSERT(nesting_ > 0);
  if (--nesting_ == 0) {
    lower_ = upper_ = detail::no_era;
    // (8) release-store, pairs with acquire-load (7) in flush(): this guard's reads happen
    // before any deleter that a scan reading this value runs.
    record_->lower.store(detail::no_era, std::memory_order_release);
  }
}

template <class T>
T* epoch_participant::protect(const std::atomic<T*>& source) noexcept {
  PROGISO_ASSERT(nesting_ > 0);
  // (2) acquire-load (seq_cst under TSan), pairs with the writer's release-store that published
  // the pointer: the object's birth was read from the clock before that store, so the clock
  // load below returns at least the birth (write-read coherence), and the object's fields are
  // visible. Fence (1), (3) or (4) of this guard precedes it.
  T* object = source.load(detail::fenced_acquire);
  // relaxed: `now` only has to be ≥ the birth of `object`, which (2) provides.
  std::uint64_t now = domain_->era_.load(std::memory_order_relaxed);
  for (unsigned attempt = 0; now > upper_; ++attempt) {
    // relaxed: a statistic with one writer (this participant's thread).
    retries_.store(retries_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    if (attempt == domain_->options_.protect_attempts) {
      // (4) fallback: reserve every era, fence, load, then narrow to the current era. Pairs
      // with fence (6) in flush() like (3). The narrowing store is relaxed (seq_cst under TSan):
      // every value a scan can read from here on covers the births of all objects this guard
      // holds, so the narrowing needs no ordering of its own.
      record_->upper.store(detail::no_era, detail::fenced_relaxed);
      detail::seq_cst_fence();
      object = source.load(detail::fenced_acquire);
      upper_ = domain_->era_.load(std::memory_order_relaxed);  // relaxed: as above
      record_->upper.store(upper_, detail::fenced_relaxed);
      return object;
    }
    upper_ = now;
    // (3) raised upper, then a seq_cst fence; pairs with fence (6) in flush(): a writer whose
    // unlink the re-load below misses sees this upper bound.
    record_->upper.store(now, detail::fenced_relaxed);
    detail::seq_cst_fence();
    object = source.load(detail::fenced_acquire);         // (2) again
    now = domain_->era_.load(std::memory_order_relaxed);  // relaxed: as above
  }
  return object;
}

template <class Deleter, class T>
void epoch_participant::retire(T* object) {
  static_assert(std::is_empty_v<Deleter> && std::is_default_constructible_v<Deleter>,
                "the deleter of retire() must be stateless");
  static_assert(std::is_nothrow_invocable_v<Deleter, T*>, "the deleter must be noexcept");
  if (object == nullptr) return;
  std::uint64_t birth = 0;
  if constexpr (std::is_base_of_v<epoch_object, T>) birth = object->birth_era();
  retire(
      const_cast<std::remove_cv_t<T>*>(object),
      [](void* erased) noexcept { Deleter{}(static_cast<T*>(erased)); }, birth);
}

inline epoch_guard& epoch_guard::operator=(epoch_guard&& other) noexcept {
  if (this != &other) {
    unpin();
    participant_ = std::exchange(other.participant_, nullptr);
  }
  return *this;
}

template <class T>
T* epoch_guard::protect(const std::atomic<T*>& source) noexcept {
  PROGISO_ASSERT(participant_ != nullptr);
  return participant_->protect(source);
}

inline era_interval epoch_guard::reservation() const noexcept {
  PROGISO_ASSERT(participant_ != nullptr);
  return {participant_->lower_, participant_->upper_};
}

inline void epoch_guard::unpin() noexcept {
  if (participant_ != nullptr) std::exchange(participant_, nullptr)->unpin();
}

}  // namespace progiso
