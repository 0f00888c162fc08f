// progiso/io/detail/header_bytes.hpp — fixed-offset fields of a binary header in either
// byte order, shared by the NIfTI and MRC readers.
//
// Reads copy the bytes (no alignment or aliasing assumptions) and reverse them when the file's
// byte order differs from the host's. The caller bounds the offsets by the header's size.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstring>
#include <string_view>

namespace progiso::detail {

/// Fields of a header held in memory, in the file's byte order (`swap`: not the host's).
class header_bytes {
 public:
  header_bytes(const std::byte* data, bool swap) : data_(data), swap_(swap) {}
  template <class T>
  [[nodiscard]] T get(std::size_t offset) const noexcept {
    std::array<std::byte, sizeof(T)> b{};
    std::memcpy(b.data(), data_ + offset, sizeof(T));
    if (swap_) std::reverse(b.begin(), b.end());
    return std::bit_cast<T>(b);
  }
  [[nodiscard]] std::string_view text(std::size_t offset, std::size_t n) const noexcept {
    return {reinterpret_cast<const char*>(data_ + offset), n};
  }

 private:
  const std::byte* data_;
  bool swap_;
};

}  // namespace progiso::detail
