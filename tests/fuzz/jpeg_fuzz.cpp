// Fuzz harness: lossless JPEG frames alone (io/detail/jpeg_lossless.hpp: our header checks, then
// DCMTK's decoder), faster than through DICOM files. Input layout: rows and columns (one byte
// each, 1 to 256), the maximum precision (one byte: 8 or 16 by its low bit), then the stream,
// decoded from its first byte.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/jpeg_lossless.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 3) return 0;
  const std::uint32_t rows = std::uint32_t{data[0]} + 1;
  const std::uint32_t columns = std::uint32_t{data[1]} + 1;
  const unsigned precision = (data[2] & 1u) != 0 ? 16 : 8;
  std::vector<std::uint16_t> out(std::size_t{rows} * columns);
  try {
    (void)progiso::detail::decode_lossless_jpeg(std::span<const std::uint8_t>(data + 3, size - 3),
                                                0, rows, columns, precision, out);
  } catch (const progiso::error&) {
  }
  return 0;
}
