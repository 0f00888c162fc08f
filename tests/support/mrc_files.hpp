// tests/support/mrc_files.hpp — MRC and CCP4 maps written field by field for the reader's
// tests, the command's tests and the fuzz seeds.
//
// Every header field a test sets is written at its MRC2014 offset, hostile values included; the
// samples are given as stored (columns fastest, in host byte order) and swapped when the file
// is big endian. Independent of the reader: nothing here calls progiso.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace progiso::test {

struct mrc_file {
  std::array<std::int32_t, 3> n{4, 3, 2};  // NX, NY, NZ
  std::int32_t mode = 2;
  std::array<std::int32_t, 3> start{0, 0, 0};
  std::array<std::int32_t, 3> m{4, 3, 2};  // MX, MY, MZ (along X, Y, Z)
  std::array<float, 3> cell{4.0f, 3.0f, 2.0f};
  std::array<float, 3> angles{90.0f, 90.0f, 90.0f};
  std::array<std::int32_t, 3> map{1, 2, 3};
  std::int32_t ispg = 1;
  std::int32_t nsymbt = 0;
  std::array<float, 3> origin{0.0f, 0.0f, 0.0f};
  bool big_endian = false;
  bool stamp = true;           ///< write MACHST (0x44 or 0x11); false leaves it zero
  bool identifier = true;      ///< write "MAP " at byte 208
  bool imod_unsigned = false;  ///< IMOD's stamp with the "signed bytes" flag clear
  /// Samples as stored, host byte order, columns fastest; `item` bytes each.
  std::vector<std::byte> samples;
  std::size_t item = 4;

  [[nodiscard]] std::string bytes() const {
    std::string h(1024, '\0');
    const bool swap = big_endian != (std::endian::native == std::endian::big);
    const auto put = [&](std::size_t at, auto value) {
      std::array<char, sizeof value> b{};
      std::memcpy(b.data(), &value, sizeof value);
      if (swap) std::reverse(b.begin(), b.end());
      std::memcpy(h.data() + at, b.data(), b.size());
    };
    for (std::size_t i = 0; i < 3; ++i) {
      put(4 * i, n[i]);
      put(16 + 4 * i, start[i]);
      put(28 + 4 * i, m[i]);
      put(40 + 4 * i, cell[i]);
      put(52 + 4 * i, angles[i]);
      put(64 + 4 * i, map[i]);
      put(196 + 4 * i, origin[i]);
    }
    put(12, mode);
    put(88, ispg);
    put(92, nsymbt);
    put(108, std::int32_t{20141});
    if (imod_unsigned) {
      put(152, std::int32_t{1146047817});
      put(156, std::int32_t{0});
    }
    if (identifier) std::memcpy(h.data() + 208, "MAP ", 4);
    if (stamp) {
      h[212] = big_endian ? '\x11' : '\x44';
      h[213] = big_endian ? '\x11' : '\x44';
    }
    std::string out = h + std::string(static_cast<std::size_t>(std::max(nsymbt, 0)), 'x');
    std::string data(reinterpret_cast<const char*>(samples.data()), samples.size());
    if (swap && item > 1) {
      for (std::size_t i = 0; i + item <= data.size(); i += item) {
        std::reverse(data.begin() + static_cast<std::ptrdiff_t>(i),
                     data.begin() + static_cast<std::ptrdiff_t>(i + item));
      }
    }
    return out + data;
  }
};

}  // namespace progiso::test
