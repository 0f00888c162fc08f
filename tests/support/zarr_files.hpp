// tests/support/zarr_files.hpp — Zarr v2 arrays written here, chunk by chunk (no compressor, C
// order, "." separator), for tests whose arrays are too large to write through Python quickly or
// that need exact bytes: a sample function gives each sample's bytes, so an array larger than the
// test's memory is written in chunk-sized pieces.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace progiso::test {

/// Writes `dir` as a Zarr v2 array of dims {x, y, z} (shape [z, y, x]) in chunks of {cx, cy, cz},
/// dtype `dtype` (such as "|u1" or "<f4") of `item` bytes, uncompressed, fill_value 0; `sample`
/// writes the bytes of the sample at (x, y, z). `skip` chunk files (their z, y, x chunk indices)
/// are left out: missing chunks, which read as fill_value.
inline void write_zarr_array(
    const std::filesystem::path& dir, const std::array<std::int64_t, 3>& dims,
    const std::array<std::int64_t, 3>& chunks, const std::string& dtype, std::size_t item,
    const std::function<void(std::int64_t, std::int64_t, std::int64_t, std::byte*)>& sample,
    const std::vector<std::array<std::int64_t, 3>>& skip = {}) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / ".zarray") << "{\"zarr_format\": 2, \"shape\": [" << dims[2] << ", "
                                 << dims[1] << ", " << dims[0] << "], \"chunks\": [" << chunks[2]
                                 << ", " << chunks[1] << ", " << chunks[0] << "], \"dtype\": \""
                                 << dtype
                                 << "\", \"compressor\": null, \"fill_value\": 0, \"order\": "
                                    "\"C\", \"filters\": null}";
  std::vector<std::byte> chunk(static_cast<std::size_t>(chunks[0] * chunks[1] * chunks[2]) * item);
  for (std::int64_t kz = 0; kz * chunks[2] < dims[2]; ++kz) {
    for (std::int64_t ky = 0; ky * chunks[1] < dims[1]; ++ky) {
      for (std::int64_t kx = 0; kx * chunks[0] < dims[0]; ++kx) {
        if (std::find(skip.begin(), skip.end(), std::array<std::int64_t, 3>{kz, ky, kx}) !=
            skip.end()) {
          continue;
        }
        // Edge chunks are padded, as Zarr writes them.
        std::fill(chunk.begin(), chunk.end(), std::byte{0});
        for (std::int64_t z = 0; z < chunks[2] && kz * chunks[2] + z < dims[2]; ++z) {
          for (std::int64_t y = 0; y < chunks[1] && ky * chunks[1] + y < dims[1]; ++y) {
            for (std::int64_t x = 0; x < chunks[0] && kx * chunks[0] + x < dims[0]; ++x) {
              sample(kx * chunks[0] + x, ky * chunks[1] + y, kz * chunks[2] + z,
                     chunk.data() +
                         static_cast<std::size_t>((z * chunks[1] + y) * chunks[0] + x) * item);
            }
          }
        }
        const std::string name =
            std::to_string(kz) + "." + std::to_string(ky) + "." + std::to_string(kx);
        std::ofstream out(dir / name, std::ios::binary);
        out.write(reinterpret_cast<const char*>(chunk.data()),
                  static_cast<std::streamsize>(chunk.size()));
        ASSERT_TRUE(out.good()) << (dir / name);
      }
    }
  }
}

}  // namespace progiso::test
