// Compiled with -std=c++17 by ctest: must stop at progiso/core/base/config.hpp's #error.
#include <progiso/scheduler/engine.hpp>
