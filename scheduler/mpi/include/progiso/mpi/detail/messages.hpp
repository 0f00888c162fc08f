// progiso/mpi/detail/messages.hpp — byte buffers and record lists between two ranks, of any size
// (MPI counts are int), and small collectives that wait without spinning.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/mpi/detail/mpi_c.hpp>

namespace progiso::detail {

/// Largest message of a buffer sent in parts.
inline constexpr std::uint64_t mpi_message_bytes = std::uint64_t{1} << 30;

/// Sends `n` bytes to rank `to` of `comm`: the size first, then messages of at most 1 GiB.
void send_bytes(MPI_Comm comm, const void* bytes, std::uint64_t n, int to, int tag);

/// Receives what send_bytes() sent and hands it to `write(const char*, size_t)` message by
/// message.
template <class Write>
void receive_bytes(MPI_Comm comm, int from, int tag, const Write& write) {
  std::uint64_t n = 0;
  MPI_Recv(&n, 1, MPI_UINT64_T, from, tag, comm, MPI_STATUS_IGNORE);
  std::vector<char> block(static_cast<std::size_t>(std::min(mpi_message_bytes, n)));
  for (std::uint64_t at = 0; at < n; at += mpi_message_bytes) {
    const auto count = static_cast<int>(std::min(mpi_message_bytes, n - at));
    MPI_Recv(block.data(), count, MPI_BYTE, from, tag, comm, MPI_STATUS_IGNORE);
    write(block.data(), static_cast<std::size_t>(count));
  }
}

/// A trivially copyable vector's elements [begin, end) to rank `to`.
template <class T>
void send_records(MPI_Comm comm, const std::vector<T>& v, std::size_t begin, std::size_t end,
                  int to, int tag) {
  static_assert(std::is_trivially_copyable_v<T>);
  send_bytes(comm, v.data() + begin, (end - begin) * sizeof(T), to, tag);
}

/// Appends what send_records() sent to `v`; a byte count that is not whole records is an error.
template <class T>
void receive_records(MPI_Comm comm, std::vector<T>& v, int from, int tag) {
  static_assert(std::is_trivially_copyable_v<T>);
  std::vector<char> b;
  receive_bytes(comm, from, tag,
                [&b](const char* p, std::size_t n) { b.insert(b.end(), p, p + n); });
  if (b.size() % sizeof(T) != 0) throw error("a rank sent a record list of a wrong size");
  const std::size_t at = v.size();
  v.resize(at + b.size() / sizeof(T));
  if (!b.empty()) std::memcpy(v.data() + at, b.data(), b.size());
}

/// Waits for `request` by testing it with growing pauses (up to a millisecond) between tests, so
/// that a rank waiting for a slower one, or for a command, leaves its cores to others.
void wait_politely(MPI_Request& request);

}  // namespace progiso::detail
