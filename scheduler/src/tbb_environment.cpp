#include <progiso/scheduler/tbb_environment.hpp>

#include <tbb/info.h>

namespace progiso::scheduler {

int default_concurrency() noexcept { return tbb::info::default_concurrency(); }

}  // namespace progiso::scheduler
