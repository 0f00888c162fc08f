#include <progiso/io/detail/dicom_rle.hpp>

#include <bit>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso::detail {
namespace {

[[noreturn]] void fail(const std::string& what) { throw error("RLE frame " + what); }

std::uint32_t u32_le(std::span<const std::uint8_t> d, std::size_t at) {
  return std::uint32_t{d[at]} | (std::uint32_t{d[at + 1]} << 8) | (std::uint32_t{d[at + 2]} << 16) |
         (std::uint32_t{d[at + 3]} << 24);
}

}  // namespace

void decode_dicom_rle(std::span<const std::uint8_t> fragment, std::size_t bytes,
                      std::span<std::byte> out) {
  if (fragment.size() < 64) fail("is shorter than its 64-byte header");
  const std::uint32_t segments = u32_le(fragment, 0);
  if (segments != bytes) {
    fail("has " + std::to_string(segments) + " segments, expected " + std::to_string(bytes) +
         " (one per byte of a sample)");
  }
  const std::size_t samples = out.size() / bytes;
  const bool host_big = std::endian::native == std::endian::big;
  for (std::size_t s = 0; s < segments; ++s) {
    const std::uint32_t begin = u32_le(fragment, 4 + 4 * s);
    const std::uint32_t end = s + 1 < segments ? u32_le(fragment, 8 + 4 * s)
                                               : static_cast<std::uint32_t>(fragment.size());
    if (begin < 64 || begin > end || end > fragment.size()) {
      fail("has segment " + std::to_string(s + 1) + " at bytes " + std::to_string(begin) + " to " +
           std::to_string(end) + ", outside its " + std::to_string(fragment.size()) + " bytes");
    }
    // Segment s holds byte s of every sample, most significant first.
    const std::size_t shift = bytes - 1 - s;  // significance of this byte
    const std::size_t lane = host_big ? s : shift;
    std::size_t at = begin;
    std::size_t i = 0;  // samples written
    while (i < samples) {
      if (at >= end) fail("has segment " + std::to_string(s + 1) + " ending before its samples");
      const auto n = static_cast<std::int8_t>(fragment[at++]);
      if (n >= 0) {
        const std::size_t count = static_cast<std::size_t>(n) + 1;
        if (count > end - at || count > samples - i) {
          fail("has a literal run past its segment or its samples");
        }
        for (std::size_t k = 0; k < count; ++k) {
          out[(i + k) * bytes + lane] = static_cast<std::byte>(fragment[at + k]);
        }
        at += count;
        i += count;
      } else if (n != -128) {
        const std::size_t count = static_cast<std::size_t>(1 - n);
        if (at >= end || count > samples - i) fail("has a repeat run past its segment or samples");
        const auto value = static_cast<std::byte>(fragment[at++]);
        for (std::size_t k = 0; k < count; ++k) out[(i + k) * bytes + lane] = value;
        i += count;
      }
    }
  }
}

}  // namespace progiso::detail
