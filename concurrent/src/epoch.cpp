// Interval-based reclamation: registration, retire(), the scan of flush(), orphans and drain().
// The numbered synchronisation points are listed at the end of progiso/concurrent/epoch.hpp.
#include <progiso/concurrent/epoch.hpp>

#include <algorithm>

namespace progiso {

namespace {

// Whether some published reservation may still reach `object`: its lifetime [birth, retire]
// meets a reserved [lower, upper].
bool is_reserved(const detail::retired_object& object,
                 const std::vector<era_interval>& reservations) noexcept {
  return std::any_of(reservations.begin(), reservations.end(), [&](const era_interval& r) {
    return object.birth <= r.upper && object.retire >= r.lower;
  });
}

// Single-writer counter: only the owner adds, statistics() reads.
void add(std::atomic<std::uint64_t>& counter, std::uint64_t amount) noexcept {
  // relaxed: counts for statistics; no access is ordered by them.
  counter.store(counter.load(std::memory_order_relaxed) + amount, std::memory_order_relaxed);
}

}  // namespace

// =============================================================================================
// epoch_domain

epoch_domain::epoch_domain(epoch_options options) : options_(options) {
  options_.reclaim_threshold = std::max<std::size_t>(options_.reclaim_threshold, 1);
  options_.era_frequency = std::max<std::size_t>(options_.era_frequency, 1);
}

epoch_domain::~epoch_domain() {
  drain();
  // relaxed: the precondition (every participant destroyed) orders every use before this.
  detail::epoch_record* record = records_.load(std::memory_order_relaxed);
  while (record != nullptr) {
    PROGISO_ASSERT(!record->in_use);
    delete std::exchange(record, record->next);
  }
}

detail::epoch_record* epoch_domain::claim_record() {
  const std::lock_guard lock(registry_mutex_);
  // relaxed: the registry only grows under the mutex, which orders this load after every push.
  detail::epoch_record* head = records_.load(std::memory_order_relaxed);
  for (detail::epoch_record* r = head; r != nullptr; r = r->next) {
    if (!r->in_use) {
      r->in_use = true;
      return r;
    }
  }
  auto* record = new detail::epoch_record;
  record->in_use = true;
  record->next = head;
  // (9) release-store (seq_cst under TSan), pairs with acquire-loads (10) in flush() and
  // statistics(): a scan that reaches the record sees it initialised. A scan that misses it
  // frees nothing this participant can reach: this store precedes the participant's first fence
  // (1), so the argument of fences (1) and (6) applies to it as to the reservation.
  records_.store(record, detail::fenced_release);
  return record;
}

void epoch_domain::release_record(detail::epoch_record* record) noexcept {
  const std::lock_guard lock(registry_mutex_);
  record->in_use = false;
}

void epoch_domain::push_orphans(std::vector<detail::retired_object>&& objects) {
  auto* batch = new detail::orphan_batch{std::move(objects), nullptr};
  // relaxed: the CAS below re-reads on failure, and the batch is published only by it.
  batch->next = orphans_.load(std::memory_order_relaxed);
  // (11) release-CAS, pairs with acquire-exchange (12) in take_orphans(): the adopter sees the
  // batch's contents, and this thread's retire fences (5) happen before the adopter's scan.
  // On failure relaxed: nothing was published; the loop retries with the value read.
  while (!orphans_.compare_exchange_weak(batch->next, batch, std::memory_order_release,
                                         std::memory_order_relaxed)) {
  }
}

detail::orphan_batch* epoch_domain::take_orphans() noexcept {
  // relaxed: a cheap emptiness test; the exchange below is what synchronises.
  if (orphans_.load(std::memory_order_relaxed) == nullptr) return nullptr;
  // (12) acquire-exchange, pairs with release-CAS (11) in push_orphans(). Taking the whole
  // stack at once leaves no ABA problem: a node is never popped alone.
  return orphans_.exchange(nullptr, std::memory_order_acquire);
}

std::size_t epoch_domain::drain() noexcept {
  std::size_t freed = 0;
  bool found = true;
  // Deleters may retire more objects: repeat until a pass finds nothing.
  while (found) {
    found = false;
    // acquire (10): as in flush(); the precondition already orders every participant's work
    // before this call.
    for (detail::epoch_record* r = records_.load(std::memory_order_acquire); r != nullptr;
         r = r->next) {
      // acquire: pairs with (8) like (7); checks the precondition.
      PROGISO_ASSERT(r->lower.load(std::memory_order_acquire) == detail::no_era);
      std::vector<detail::retired_object> objects;
      objects.swap(r->retired);
      for (const detail::retired_object& o : objects) o.deleter(o.object);
      freed += objects.size();
      found = found || !objects.empty();
    }
    for (detail::orphan_batch* batch = take_orphans(); batch != nullptr;) {
      for (const detail::retired_object& o : batch->objects) o.deleter(o.object);
      freed += batch->objects.size();
      found = found || !batch->objects.empty();
      delete std::exchange(batch, batch->next);
    }
  }
  // relaxed: a count for statistics.
  drained_.fetch_add(freed, std::memory_order_relaxed);
  return freed;
}

epoch_statistics epoch_domain::statistics() const noexcept {
  epoch_statistics s;
  // (10) acquire-load, pairs with release-store (9) in claim_record().
  for (const detail::epoch_record* r = records_.load(detail::fenced_acquire); r != nullptr;
       r = r->next) {
    // relaxed: counts; the file comment says they are exact only when nobody works.
    s.retired += r->retired_count.load(std::memory_order_relaxed);
    s.reclaimed += r->reclaimed_count.load(std::memory_order_relaxed);
  }
  s.reclaimed += drained_.load(std::memory_order_relaxed);  // relaxed: as above
  s.pending = s.retired > s.reclaimed ? s.retired - s.reclaimed : 0;
  s.era = era();
  return s;
}

// =============================================================================================
// epoch_participant

epoch_participant::epoch_participant(epoch_domain& domain)
    : domain_(&domain), record_(domain.claim_record()) {}

epoch_participant::~epoch_participant() {
  PROGISO_ASSERT(nesting_ == 0);
  flush();
  if (!record_->retired.empty()) {
    std::vector<detail::retired_object> left;
    left.swap(record_->retired);
    domain_->push_orphans(std::move(left));
  }
  domain_->release_record(record_);
}

void epoch_participant::retire(void* object, void (*deleter)(void*) noexcept,
                               std::uint64_t birth_era) {
  if (object == nullptr) return;
  if (!domain_->options_.interval_based) birth_era = 0;
  std::vector<detail::retired_object>& list = record_->retired;
  if (list.size() == list.capacity()) list.reserve(std::max<std::size_t>(16, 2 * list.size()));
  // (5) seq_cst fence, then the retire era; pairs with fence (1) in pin(). The unlink happens
  // before this fence. If a reader's fence (1) precedes it in S, this load returns at least the
  // era that reader loaded before (1), its `lower`; otherwise that reader's loads of the source
  // see the unlink and it never reaches the object. Under TSan the loads and the clock's
  // increments are seq_cst and the unlink must be too (std::atomic's default).
  detail::seq_cst_fence();
  const std::uint64_t now = domain_->era_.load(detail::fenced_relaxed);
  PROGISO_ASSERT(birth_era <= now);
  list.push_back({object, deleter, birth_era, now});  // no allocation: reserved above
  add(record_->retired_count, 1);
  if (++since_advance_ >= domain_->options_.era_frequency) {
    since_advance_ = 0;
    // relaxed (seq_cst under TSan, where the argument at (5) needs the increments in S): when
    // the clock moves only decides how soon objects become free, never whether it is safe.
    domain_->era_.fetch_add(1, detail::fenced_relaxed);
  }
  if (++since_flush_ >= domain_->options_.reclaim_threshold) flush();
}

void epoch_participant::adopt_orphans() noexcept {
  for (detail::orphan_batch* batch = domain_->take_orphans(); batch != nullptr;) {
    record_->retired.insert(record_->retired.end(), batch->objects.begin(), batch->objects.end());
    delete std::exchange(batch, batch->next);
  }
}

std::size_t epoch_participant::flush() noexcept {
  if (flushing_) return 0;
  flushing_ = true;
  since_flush_ = 0;
  adopt_orphans();

  // ---- snapshot the reservations -------------------------------------------------------
  // (6) seq_cst fence before the scan; pairs with fences (1), (3) and (4) in pin() and
  // protect(): for every object in the list, unlinked before this fence, a reader either
  // published the reservation that covers it before its own fence, and then the loads below
  // see that reservation (or a later one of the same participant), or its loads of the
  // source see the unlink. Adopted objects were unlinked before their retirer's fence (5),
  // which happens before this one through (11)/(12).
  detail::seq_cst_fence();
  reservations_.clear();
  // (10) acquire-load, pairs with release-store (9) in claim_record().
  for (const detail::epoch_record* r = domain_->records_.load(detail::fenced_acquire); r != nullptr;
       r = r->next) {
    // (7) acquire-load (seq_cst under TSan), pairs with release-store (8) in unpin() and with
    // the release-store of `lower` (1) in pin(): a guard that ended before the value read
    // did all its reads before the deleters below.
    const std::uint64_t lower = r->lower.load(detail::fenced_acquire);
    if (lower == detail::no_era) continue;
    // relaxed (seq_cst under TSan): visibility comes from fence (6), ordering from (7). Within
    // one guard `upper` only grows (the fallback's `no_era` covers everything), and a later
    // guard's value is larger still, so any value read covers what the guard read at (7) holds.
    const std::uint64_t upper = r->upper.load(detail::fenced_relaxed);
    reservations_.push_back({lower, upper});
  }

  // ---- free what no reservation keeps, compacting the list in place --------------------
  // Indices, not iterators: a deleter may retire into this list (appending past `count`).
  std::vector<detail::retired_object>& list = record_->retired;
  const std::size_t count = list.size();
  std::size_t kept = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const detail::retired_object object = list[i];
    if (is_reserved(object, reservations_)) {
      list[kept++] = object;
    } else {
      object.deleter(object.object);
    }
  }
  list.erase(list.begin() + static_cast<std::ptrdiff_t>(kept),
             list.begin() + static_cast<std::ptrdiff_t>(count));
  add(record_->reclaimed_count, count - kept);
  flushing_ = false;
  return count - kept;
}

}  // namespace progiso
