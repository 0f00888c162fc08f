#include <progiso/mpi/detail/messages.hpp>

#include <chrono>
#include <thread>

namespace progiso::detail {

void send_bytes(MPI_Comm comm, const void* bytes, std::uint64_t n, int to, int tag) {
  MPI_Send(&n, 1, MPI_UINT64_T, to, tag, comm);
  const auto* b = static_cast<const char*>(bytes);
  for (std::uint64_t at = 0; at < n; at += mpi_message_bytes) {
    const auto count = static_cast<int>(std::min(mpi_message_bytes, n - at));
    MPI_Send(b + at, count, MPI_BYTE, to, tag, comm);
  }
}

void wait_politely(MPI_Request& request) {
  std::chrono::microseconds pause{1};
  for (;;) {
    int done = 0;
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done != 0) return;
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::microseconds{1000});
  }
}

}  // namespace progiso::detail
