// Unit tests of progiso/concurrent/epoch.hpp: what a guard keeps alive, when flush() frees,
// the interval rule (objects born after a reservation are not kept), protect()'s reservation and
// fallback, nesting, orphans of exited participants, and drain(): every retired object is
// destroyed exactly once (destructor calls counted per object id).
#include <progiso/concurrent/epoch.hpp>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

// An object that counts its destructions in a vector indexed by id.
struct tracked : epoch_object {
  tracked(std::vector<std::atomic<int>>* counts, std::size_t number)
      : destroyed(counts), id(number) {}
  tracked(const tracked&) = delete;
  tracked& operator=(const tracked&) = delete;
  ~tracked() { (*destroyed)[id].fetch_add(1, std::memory_order_relaxed); }

  std::vector<std::atomic<int>>* destroyed;
  std::size_t id;
};

std::vector<std::atomic<int>> counters(std::size_t n) { return std::vector<std::atomic<int>>(n); }

// Advances the clock by `eras` through retirements of unpublished objects (era_frequency 1).
void advance_clock(epoch_participant& p, std::vector<std::atomic<int>>& destroyed,
                   std::size_t first_id, std::size_t eras) {
  for (std::size_t i = 0; i < eras; ++i) {
    p.retire(make_managed<tracked>(p.domain(), &destroyed, first_id + i));
  }
}

TEST(EpochGuard, protected_object_survives_until_the_guard_ends_and_a_flush_runs) {
  auto destroyed = counters(2);
  epoch_domain domain;
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, 0u)};
  {
    epoch_guard guard = reader.pin();
    tracked* seen = guard.protect(shared);
    writer.retire(shared.exchange(make_managed<tracked>(domain, &destroyed, 1u)));
    EXPECT_EQ(writer.flush(), 0u);
    EXPECT_EQ(destroyed[0].load(), 0);
    EXPECT_EQ(seen->id, 0u);
    EXPECT_EQ(writer.pending(), 1u);
  }
  EXPECT_EQ(destroyed[0].load(), 0) << "the guard's end alone frees nothing";
  EXPECT_EQ(writer.flush(), 1u);
  EXPECT_EQ(destroyed[0].load(), 1);
  const epoch_statistics s = domain.statistics();
  EXPECT_EQ(s.retired, 1u);
  EXPECT_EQ(s.reclaimed, 1u);
  EXPECT_EQ(s.pending, 0u);
  writer.retire(shared.exchange(nullptr));
  EXPECT_EQ(writer.flush(), 1u);
  EXPECT_EQ(destroyed[1].load(), 1);
}

TEST(EpochParticipant, flush_runs_by_itself_every_reclaim_threshold_retirements) {
  auto destroyed = counters(8);
  epoch_domain domain({.reclaim_threshold = 4});
  epoch_participant p(domain);
  for (std::size_t i = 0; i < 3; ++i) p.retire(make_managed<tracked>(domain, &destroyed, i));
  EXPECT_EQ(p.pending(), 3u);
  EXPECT_EQ(domain.statistics().pending, 3u);
  p.retire(make_managed<tracked>(domain, &destroyed, 3u));
  EXPECT_EQ(p.pending(), 0u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(destroyed[i].load(), 1) << i;
  for (std::size_t i = 4; i < 7; ++i) p.retire(make_managed<tracked>(domain, &destroyed, i));
  EXPECT_EQ(p.pending(), 3u);
  const epoch_statistics s = domain.statistics();
  EXPECT_EQ(s.retired, 7u);
  EXPECT_EQ(s.reclaimed, 4u);
  EXPECT_EQ(s.pending, 3u);
}

TEST(EpochGuard, objects_born_after_a_reservation_are_freed_while_it_lasts) {
  auto destroyed = counters(16);
  epoch_domain domain({.era_frequency = 1});
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, 0u)};
  auto* older = make_managed<tracked>(domain, &destroyed, 1u);  // born before the reservation

  epoch_guard guard = reader.pin();
  EXPECT_NE(guard.protect(shared), nullptr);
  const era_interval reserved = guard.reservation();
  EXPECT_EQ(reserved.lower, reserved.upper);

  advance_clock(writer, destroyed, 2, 3);
  auto* younger = make_managed<tracked>(domain, &destroyed, 5u);
  EXPECT_GT(younger->birth_era(), reserved.upper);
  writer.retire(older);    // lifetime [≤ upper, > lower]: meets the reservation
  writer.retire(younger);  // born after upper: does not
  writer.flush();
  EXPECT_EQ(destroyed[5].load(), 1) << "born after the reservation, freed at once";
  EXPECT_EQ(destroyed[1].load(), 0) << "alive during the reservation, kept";
  for (std::size_t i = 2; i < 5; ++i) {
    EXPECT_EQ(destroyed[i].load(), i == 2 ? 0 : 1) << "only the one retired in the reserved era";
  }
  guard.unpin();
  writer.flush();
  EXPECT_EQ(destroyed[1].load(), 1);
  EXPECT_EQ(destroyed[2].load(), 1);
  writer.retire(shared.exchange(nullptr));
}

TEST(EpochGuard, plain_epochs_keep_objects_born_after_the_reservation) {
  auto destroyed = counters(8);
  epoch_domain domain({.era_frequency = 1, .interval_based = false});
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  epoch_guard guard = reader.pin();
  advance_clock(writer, destroyed, 0, 3);
  writer.retire(make_managed<tracked>(domain, &destroyed, 3u));
  writer.flush();
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(destroyed[i].load(), 0) << i;
  guard.unpin();
  writer.flush();
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(destroyed[i].load(), 1) << i;
}

TEST(EpochGuard, objects_without_a_birth_era_are_kept_like_in_plain_epochs) {
  epoch_domain domain({.era_frequency = 1});
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  epoch_guard guard = reader.pin();
  static std::atomic<int> deleted{0};
  struct counting_delete {
    void operator()(int* p) const noexcept {
      deleted.fetch_add(1, std::memory_order_relaxed);
      delete p;
    }
  };
  writer.retire(new int(1));  // moves the clock past the reservation (era_frequency 1)
  writer.flush();
  writer.retire<counting_delete>(new int(2));  // born "at 0": overlaps every reservation
  writer.flush();
  EXPECT_EQ(deleted.load(), 0);
  guard.unpin();
  writer.flush();
  EXPECT_EQ(deleted.load(), 1);
}

TEST(EpochGuard, protect_raises_the_reservation_to_the_current_era) {
  auto destroyed = counters(8);
  epoch_domain domain({.era_frequency = 1});
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, 0u)};
  epoch_guard guard = reader.pin();
  const std::uint64_t pinned = guard.reservation().lower;
  EXPECT_EQ(pinned, domain.era());
  advance_clock(writer, destroyed, 1, 4);
  auto* fresh = make_managed<tracked>(domain, &destroyed, 5u);
  writer.retire(shared.exchange(fresh));
  EXPECT_EQ(guard.protect(shared), fresh);
  const era_interval reserved = guard.reservation();
  EXPECT_EQ(reserved.lower, pinned);
  EXPECT_EQ(reserved.upper, domain.era());
  EXPECT_GE(reserved.upper, fresh->birth_era());
  guard.unpin();
  writer.retire(shared.exchange(nullptr));
}

TEST(EpochGuard, protect_fallback_ends_with_a_finite_reservation) {
  auto destroyed = counters(8);
  epoch_domain domain({.era_frequency = 1, .protect_attempts = 0});
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, 0u)};
  epoch_guard guard = reader.pin();
  advance_clock(writer, destroyed, 1, 3);
  tracked* seen = guard.protect(shared);  // the clock moved: straight to the fallback
  EXPECT_EQ(seen->id, 0u);
  EXPECT_EQ(guard.reservation().upper, domain.era());
  // A later object is not kept by the narrowed reservation.
  advance_clock(writer, destroyed, 4, 1);
  writer.retire(make_managed<tracked>(domain, &destroyed, 5u));
  writer.flush();
  EXPECT_EQ(destroyed[5].load(), 1);
  guard.unpin();
  writer.retire(shared.exchange(nullptr));
}

TEST(EpochGuard, nested_guards_keep_the_reservation_until_the_outermost_ends) {
  auto destroyed = counters(2);
  epoch_domain domain;
  epoch_participant writer(domain);
  epoch_participant reader(domain);
  std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, 0u)};
  epoch_guard outer = reader.pin();
  {
    epoch_guard inner = reader.pin();
    EXPECT_NE(inner.protect(shared), nullptr);
  }
  EXPECT_TRUE(reader.is_pinned());
  writer.retire(shared.exchange(make_managed<tracked>(domain, &destroyed, 1u)));
  writer.flush();
  EXPECT_EQ(destroyed[0].load(), 0);
  outer.unpin();
  EXPECT_FALSE(reader.is_pinned());
  writer.flush();
  EXPECT_EQ(destroyed[0].load(), 1);
  writer.retire(shared.exchange(nullptr));
}

TEST(EpochGuard, a_moved_guard_ends_the_critical_section_once) {
  epoch_domain domain;
  epoch_participant p(domain);
  epoch_guard a = p.pin();
  epoch_guard b = std::move(a);
  EXPECT_FALSE(
      a.is_pinned());  // NOLINT(bugprone-use-after-move): the moved-from state is specified
  EXPECT_TRUE(b.is_pinned());
  epoch_guard c;
  c = std::move(b);
  EXPECT_TRUE(p.is_pinned());
  c.unpin();
  c.unpin();
  EXPECT_FALSE(p.is_pinned());
}

TEST(EpochParticipant, objects_left_by_an_exited_participant_are_freed_by_another) {
  auto destroyed = counters(3);
  epoch_domain domain;
  epoch_participant reader(domain);
  epoch_participant survivor(domain);
  epoch_guard guard = reader.pin();
  {
    epoch_participant leaving(domain);
    for (std::size_t i = 0; i < 3; ++i) {
      leaving.retire(make_managed<tracked>(domain, &destroyed, i));
    }
  }  // flushes, keeps all three (reserved), hands them over
  EXPECT_EQ(domain.statistics().pending, 3u);
  guard.unpin();
  EXPECT_EQ(survivor.flush(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(destroyed[i].load(), 1) << i;
  EXPECT_EQ(domain.statistics().pending, 0u);
}

// A deleter that retires the object's child through the participant running the flush.
struct parent : epoch_object {
  tracked* child = nullptr;
  static inline thread_local epoch_participant* reclaimer = nullptr;
};
struct retire_child_then_delete {
  void operator()(parent* p) const noexcept {
    parent::reclaimer->retire(p->child);
    delete p;
  }
};

TEST(EpochParticipant, a_deleter_may_retire_more_objects) {
  auto destroyed = counters(16);
  epoch_domain domain({.reclaim_threshold = 3});
  epoch_participant p(domain);
  parent::reclaimer = &p;
  for (std::size_t i = 0; i < 8; ++i) {
    auto* node = make_managed<parent>(domain);
    node->child = make_managed<tracked>(domain, &destroyed, i);
    p.retire<retire_child_then_delete>(node);
  }
  while (p.pending() != 0) p.flush();
  parent::reclaimer = nullptr;
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(destroyed[i].load(), 1) << i;
  const epoch_statistics s = domain.statistics();
  EXPECT_EQ(s.retired, 16u);
  EXPECT_EQ(s.reclaimed, 16u);
}

TEST(EpochDomain, drain_reclaims_every_retired_object_exactly_once) {
  constexpr std::size_t writers = 3;
  constexpr std::size_t per_writer = 5000;
  auto destroyed = counters(writers * per_writer + 1);
  {
    epoch_domain domain({.reclaim_threshold = 32, .era_frequency = 4});
    std::atomic<tracked*> shared{make_managed<tracked>(domain, &destroyed, writers * per_writer)};
    std::atomic<bool> stop{false};
    std::thread reader([&] {
      epoch_participant p(domain);
      while (!stop.load(std::memory_order_acquire)) {
        epoch_guard g = p.pin();
        const tracked* seen = g.protect(shared);
        EXPECT_EQ((*seen->destroyed)[seen->id].load(std::memory_order_relaxed), 0);
      }
    });
    // Participants stay registered (quiescent) during drain(): their lists are drained too.
    std::vector<std::unique_ptr<epoch_participant>> participants;
    for (std::size_t w = 0; w < writers; ++w) {
      participants.push_back(std::make_unique<epoch_participant>(domain));
    }
    std::vector<std::thread> threads;
    for (std::size_t w = 0; w < writers; ++w) {
      threads.emplace_back([&, w] {
        epoch_participant& p = *participants[w];
        epoch_guard hold = p.pin();  // own reservation keeps part of the garbage until drain
        for (std::size_t i = 0; i < per_writer; ++i) {
          p.retire(shared.exchange(make_managed<tracked>(domain, &destroyed, w * per_writer + i)));
        }
      });
    }
    for (std::thread& t : threads) t.join();
    stop.store(true, std::memory_order_release);
    reader.join();
    participants.front()->retire(shared.exchange(nullptr));
    const epoch_statistics before = domain.statistics();
    EXPECT_EQ(before.retired, writers * per_writer + 1);
    EXPECT_GT(before.pending, 0u) << "the test must leave something for drain()";
    EXPECT_EQ(domain.drain(), before.pending);
    const epoch_statistics after = domain.statistics();
    EXPECT_EQ(after.reclaimed, after.retired);
    EXPECT_EQ(after.pending, 0u);
    EXPECT_EQ(domain.drain(), 0u);
  }  // participants, then the domain: nothing more may be freed
  for (std::size_t id = 0; id < destroyed.size(); ++id) {
    ASSERT_EQ(destroyed[id].load(), 1) << "object " << id;
  }
}

}  // namespace
}  // namespace progiso
