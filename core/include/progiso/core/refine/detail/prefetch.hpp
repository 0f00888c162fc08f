// progiso/core/refine/detail/prefetch.hpp — asking the cache for a diamond's samples ahead of
// its split, shared by the sequential refiner and the engine's compute tasks.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/hierarchy/hierarchy.hpp>

namespace progiso::detail {

// Volumes this small stay in the cache: prefetching their samples only costs instructions.
inline constexpr std::size_t prefetch_min_bytes = std::size_t{1} << 20;

// Every point of the diamond centred at c with scale h lies in c + h·{-1, 0, 1}³: nine rows of
// the volume, each asked for at both ends (a row's span is at most 2h + 1 samples).
inline void prefetch_diamond_samples(const volume& vol, const ipoint& c, std::int32_t h) noexcept {
  const index3& dims = vol.dims();
  const std::size_t size = sample_size(vol.type());
  const std::byte* base = vol.bytes();
  const auto clamp = [](std::int64_t v, std::int64_t hi) {
    return std::clamp<std::int64_t>(v, 0, hi);
  };
  const std::int64_t x0 = clamp(c[0] - h, dims[0] - 1);
  const std::int64_t x1 = clamp(c[0] + h, dims[0] - 1);
  for (int dz = -1; dz <= 1; ++dz) {
    const std::int64_t z = clamp(c[2] + dz * h, dims[2] - 1);
    for (int dy = -1; dy <= 1; ++dy) {
      const std::int64_t y = clamp(c[1] + dy * h, dims[1] - 1);
      __builtin_prefetch(base + vol.linear(x0, y, z) * size);
      __builtin_prefetch(base + vol.linear(x1, y, z) * size);
    }
  }
}

}  // namespace progiso::detail
