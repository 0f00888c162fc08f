# Warning flags and sanitizer switches shared by every progiso target.
add_library(progiso_warnings INTERFACE)
target_compile_options(progiso_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion -Wnon-virtual-dtor
  -Wold-style-cast -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion
  $<$<BOOL:${PROGISO_WERROR}>:-Werror>)

# GCC 12 at -O2 and -O3 reports -Wrestrict inside std::string's operator+ (libstdc++'s
# char_traits, sizes of exabytes at negative offsets): a false positive of the compiler (GCC bug
# 105329, fixed in GCC 13). A release build printed 26 of them (the NRRD, NIfTI, MRC and PLY
# readers, 16 test files), so the warning is off for every target under GCC < 13.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  add_compile_options(-Wno-restrict)
endif()

# With clang, an address-undefined build also instruments for libFuzzer's coverage and builds the
# fuzz harnesses as libFuzzer binaries beside the tests (PROGISO_FUZZ_BINARIES), so that CI's
# fuzzing stage reuses the sanitizer build instead of compiling the libraries a third time.
set(PROGISO_FUZZ_BINARIES OFF)
if(PROGISO_SANITIZE STREQUAL "address-undefined")
  # -fno-sanitize=vptr: with gcc, UBSan's vptr check aborts inside oneTBB's flow-graph headers.
  add_compile_options(-fsanitize=address,undefined -fno-sanitize=vptr
                      -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
  add_compile_definitions(PROGISO_SANITIZER_BUILD=1)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    add_compile_options(-fsanitize=fuzzer-no-link)
    set(PROGISO_FUZZ_BINARIES ON)
  endif()
elseif(PROGISO_SANITIZE STREQUAL "thread")
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  add_link_options(-fsanitize=thread)
  add_compile_definitions(PROGISO_SANITIZER_BUILD=1 PROGISO_TSAN=1)
elseif(PROGISO_SANITIZE STREQUAL "fuzzer")
  # libFuzzer builds (clang only): everything instrumented for coverage, ASan and UBSan; the
  # harnesses in tests/fuzz/ link the fuzzer's main with -fsanitize=fuzzer.
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "PROGISO_SANITIZE=fuzzer needs clang (the fuzz preset sets it)")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
  add_compile_definitions(PROGISO_SANITIZER_BUILD=1)
  set(PROGISO_FUZZ_BINARIES ON)
elseif(NOT PROGISO_SANITIZE STREQUAL "")
  message(FATAL_ERROR "PROGISO_SANITIZE must be empty, address-undefined, thread or fuzzer")
endif()

# Shared surface vertices must be bit-identical however they are computed (a + t (b - a),
# origin + p * spacing): forbid fused multiply-add contraction, which clang applies by default.
add_compile_options(-ffp-contract=off)
