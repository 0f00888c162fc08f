// progiso/core/base/config.hpp — what every progiso header needs from the compiler.
//
// progiso's headers use C++20 (concepts, std::span, std::bit_cast, make_unique_for_overwrite).
// A consumer compiled with an older standard gets this one clear error instead of a cascade of
// missing names from deep inside the headers. Every public header includes this file.
#pragma once

#if !defined(__cplusplus) || __cplusplus < 202002L
#error \
    "progiso requires C++20 or later: compile with -std=c++20 (CMake: cxx_std_20, which progiso's targets already require of their consumers)"
#endif
