// A run's own failure: refinement that needs more memory than the process may have. Each engine
// runs on its driver thread, so what a split throws there must reach wait() / refine() (not
// std::terminate), the published cut must stay readable, and the root, which may hold a split
// begun and not ended, must refuse further runs with one clear error. Each case runs in a child
// process of its own (a death test, "threadsafe": the binary re-executed for that test alone, so
// no thread pool is inherited) under an RLIMIT_DATA a little above what it holds before the run;
// a terminate() there would end the child by SIGABRT, which the test reports.
#include <progiso/core/base/error.hpp>
#include <progiso/scheduler/contour_engine.hpp>
#include <progiso/scheduler/engine.hpp>

#include <sys/resource.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <string>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

#if !defined(PROGISO_SANITIZER_BUILD)  // sanitizer builds skip the test: no helper unused

/// Noise: a surface through nearly every cell, so full refinement needs far more than the cap.
volume noise(const index3& dims) {
  std::vector<std::byte> bytes(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]));
  std::uint32_t x = 12345;
  for (std::byte& b : bytes) {
    x = x * 1664525u + 1013904223u;
    b = static_cast<std::byte>(x >> 24);
  }
  return volume(dims, sample_type::u8, std::move(bytes));
}

/// Caps the data segment at what it holds now plus `more` bytes (the soft limit: lifted again by
/// lift_cap()).
void cap_data(std::uint64_t more) {
  std::ifstream status("/proc/self/status");
  std::string key;
  std::uint64_t kib = 0;
  while (status >> key) {
    if (key == "VmData:") {
      status >> kib;
      break;
    }
  }
  rlimit r{};
  if (getrlimit(RLIMIT_DATA, &r) != 0) std::exit(3);
  r.rlim_cur = static_cast<rlim_t>(kib * 1024 + more);
  if (setrlimit(RLIMIT_DATA, &r) != 0) std::exit(3);
}

void lift_cap() {
  rlimit r{};
  if (getrlimit(RLIMIT_DATA, &r) != 0) std::exit(3);
  r.rlim_cur = r.rlim_max;
  if (setrlimit(RLIMIT_DATA, &r) != 0) std::exit(3);
}

template <class Engine>
void refine_past_the_cap(Engine& e) {
  bool rethrown = false;
  try {
    (void)e.refine(refine_goal::full());
  } catch (const std::bad_alloc&) {
    rethrown = true;
  }
  if (!rethrown) std::exit(4);  // the cap was never reached: the test proves nothing
  std::fputs("rethrown\n", stderr);
  lift_cap();  // memory is there again: what stays must still work
  // The published cut stays readable.
  if constexpr (std::is_same_v<Engine, engine>) {
    (void)e.snapshot().mesh();
  } else {
    (void)e.snapshot().extract();
  }
  bool refused = false;
  try {
    (void)e.refine(refine_goal::full());
  } catch (const error& m) {
    refused =
        std::string(m.what()).find("an earlier run on this isovalue failed") != std::string::npos;
  }
  if (!refused) std::exit(5);
  // A new isovalue makes a fresh root, which refines.
  e.set_isovalue(100.5);
  if (!e.refine(refine_goal::triangles(2000))) std::exit(6);
  std::fputs("refused afresh\n", stderr);
  std::exit(0);
}

void engine_past_the_cap(unsigned threads) {
  auto v = std::make_shared<const volume>(noise({160, 160, 160}));
  engine_options o;
  o.threads = threads;
  o.uniform_cuts = false;  // refinement by records (a full goal's passes fail without harm)
  engine e(v, 127.5, o);
  cap_data(std::uint64_t{64} << 20);
  refine_past_the_cap(e);
}

void contour_engine_past_the_cap() {
  auto image = std::make_shared<const volume>(noise({2048, 2048, 1}));
  contour_engine e(image, 127.5);
  cap_data(std::uint64_t{32} << 20);
  refine_past_the_cap(e);
}

#endif

TEST(EngineFailure, a_run_out_of_memory_is_rethrown_and_its_root_refines_no_further) {
#if defined(PROGISO_SANITIZER_BUILD)
  GTEST_SKIP() << "sanitizer builds run without memory limits (their shadow memory)";
#else
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(engine_past_the_cap(1), ::testing::ExitedWithCode(0), "rethrown\nrefused afresh");
  EXPECT_EXIT(engine_past_the_cap(2), ::testing::ExitedWithCode(0), "rethrown\nrefused afresh");
  EXPECT_EXIT(contour_engine_past_the_cap(), ::testing::ExitedWithCode(0),
              "rethrown\nrefused afresh");
#endif
}

}  // namespace
}  // namespace progiso
