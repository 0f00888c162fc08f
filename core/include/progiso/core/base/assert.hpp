// progiso/core/base/assert.hpp — precondition and invariant checks.
//
// PROGISO_ASSERT(cond) checks a condition that only a bug can break (a broken precondition of
// an internal function, a violated invariant). It is active when PROGISO_ENABLE_ASSERTS is
// defined (the `default` and sanitizer presets) and compiles to nothing otherwise, so it may
// sit on hot paths. Recoverable failures (bad files, bad arguments) never use it: they throw
// progiso::error (see error.hpp).
#pragma once

#include <cstdio>
#include <cstdlib>

#include <progiso/core/base/config.hpp>

#if defined(PROGISO_ENABLE_ASSERTS)
#define PROGISO_ASSERT(cond)                                                                    \
  do {                                                                                          \
    if (!(cond)) {                                                                              \
      std::fprintf(stderr, "%s:%d: progiso assertion failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                             \
    }                                                                                           \
  } while (false)
#else
#define PROGISO_ASSERT(cond) \
  do {                       \
  } while (false)
#endif
