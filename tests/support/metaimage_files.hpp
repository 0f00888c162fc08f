// tests/support/metaimage_files.hpp — writing MetaImage test files (.mha / .mhd and their data)
// for the reader's tests and its comparison with MetaIO.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"

namespace progiso::test {

/// The MetaImage element types progiso reads, with the sample type each gives.
struct metaimage_type {
  const char* name;
  sample_type type;
};
inline constexpr std::array<metaimage_type, 10> metaimage_types{{
    {"MET_UCHAR", sample_type::u8},
    {"MET_CHAR", sample_type::i8},
    {"MET_USHORT", sample_type::u16},
    {"MET_SHORT", sample_type::i16},
    {"MET_UINT", sample_type::u32},
    {"MET_INT", sample_type::i32},
    {"MET_ULONG", sample_type::u32},
    {"MET_LONG", sample_type::i32},
    {"MET_FLOAT", sample_type::f32},
    {"MET_DOUBLE", sample_type::f64},
}};

/// One MetaImage volume to write: its samples (host order) and how the file lays them out.
struct metaimage_file {
  enum class layout { local, detached, list, pattern };
  std::string type_name = "MET_UCHAR";
  std::size_t item = 1;
  std::array<int, 3> dims{5, 4, 3};
  int volumes = 1;                 ///< above 1: NDims 4, the volumes one after the other
  std::vector<std::byte> samples;  ///< host byte order, x fastest
  bool msb = false;
  bool msb_by_element_key = true;  ///< ElementByteOrderMSB, else BinaryDataByteOrderMSB
  bool compressed = false;
  bool ascii = false;
  layout where = layout::local;
  int header_size = 0;         ///< written when non-zero
  std::string skipped = "";    ///< bytes before the data (HeaderSize > 0) or after it (-1)
  std::string extra_fields;    ///< lines written before ElementDataFile
  std::string pattern_digits;  ///< "%03d" for the pattern layout

  /// The samples in the file's byte order.
  [[nodiscard]] std::string payload_bytes(std::size_t first, std::size_t count) const {
    std::string out(reinterpret_cast<const char*>(samples.data()) + first * item, count * item);
    if (msb && item > 1) {
      for (std::size_t i = 0; i + item <= out.size(); i += item) {
        std::reverse(out.begin() + static_cast<std::ptrdiff_t>(i),
                     out.begin() + static_cast<std::ptrdiff_t>(i + item));
      }
    }
    return out;
  }

  /// Samples [first, first + count) as the file holds them: text, compressed or raw, with the
  /// skipped bytes placed where HeaderSize says.
  [[nodiscard]] std::string data(std::size_t first, std::size_t count) const {
    std::string body;
    if (ascii) {
      for (std::size_t i = first; i < first + count; ++i) {
        body += ascii_value(i);
        body += i + 1 < first + count ? " " : "\n";
      }
    } else {
      body = payload_bytes(first, count);
      if (compressed) body = gzip(body, 6, true);
    }
    if (header_size > 0) return skipped + body;
    if (header_size < 0) return skipped + body;  // -1: the data is the file's last bytes
    return body;
  }

  /// Writes the file(s) into `dir` as `stem` + .mha (local) or .mhd; returns the header's path.
  std::filesystem::path write(const std::filesystem::path& dir, const std::string& stem) const {
    const auto count = static_cast<std::size_t>(dims[0] * dims[1] * dims[2] * volumes);
    // A file of the list and pattern layouts holds a slice, or in a series (MetaIO's default
    // piece: NDims − 1 dimensions) a volume.
    const auto slice = static_cast<std::size_t>(dims[0] * dims[1] * (volumes > 1 ? dims[2] : 1));
    const int files = volumes > 1 ? volumes : dims[2];
    std::string h = "ObjectType = Image\nNDims = " + std::string(volumes > 1 ? "4" : "3") +
                    "\nDimSize = " + std::to_string(dims[0]) + " " + std::to_string(dims[1]) + " " +
                    std::to_string(dims[2]) +
                    (volumes > 1 ? " " + std::to_string(volumes) : std::string()) + "\n";
    if (ascii) h += "BinaryData = False\n";
    if (compressed) {
      h += "CompressedData = True\n";
      // MetaIO writes the compressed size, and needs it for data after the header.
      if (where == layout::local || where == layout::detached) {
        h += "CompressedDataSize = " + std::to_string(data(0, count).size()) + "\n";
      }
    }
    h += std::string(msb_by_element_key ? "ElementByteOrderMSB" : "BinaryDataByteOrderMSB") +
         (msb ? " = True\n" : " = False\n");
    if (header_size != 0) h += "HeaderSize = " + std::to_string(header_size) + "\n";
    h += extra_fields;
    h += "ElementType = " + type_name + "\n";
    const std::filesystem::path header = dir / (stem + (where == layout::local ? ".mha" : ".mhd"));
    switch (where) {
      case layout::local:
        h += "ElementDataFile = LOCAL\n";
        if (header_size > 0) {
          // MetaIO reads LOCAL data from byte HeaderSize of the file.
          write_file(header, pad_to(h, static_cast<std::size_t>(header_size)) + data(0, count));
          return header;
        }
        write_file(header, header_size < 0 ? h + "junk" + data(0, count) : h + data(0, count));
        return header;
      case layout::detached:
        h += "ElementDataFile = " + stem + ".raw\n";
        write_file(dir / (stem + ".raw"), data(0, count));
        break;
      case layout::list:
        h += "ElementDataFile = LIST\n";
        for (int z = 0; z < files; ++z) {
          const std::string name = stem + "_slice" + std::to_string(z) + ".raw";
          h += name + "\n";
          write_file(dir / name, data(static_cast<std::size_t>(z) * slice, slice));
        }
        break;
      case layout::pattern: {
        // Files numbered 1, 2, … with the digits given, e.g. stem_001.raw.
        h += "ElementDataFile = " + stem + "_" + pattern_digits + ".raw 1 " +
             std::to_string(files) + " 1\n";
        for (int z = 0; z < files; ++z) {
          char number[32];
          std::snprintf(number, sizeof number, pattern_digits.c_str(), z + 1);
          write_file(dir / (stem + "_" + number + ".raw"),
                     data(static_cast<std::size_t>(z) * slice, slice));
        }
        break;
      }
    }
    write_file(header, h);
    return header;
  }

 private:
  [[nodiscard]] std::string ascii_value(std::size_t i) const {
    const std::byte* p = samples.data() + i * item;
    char text[64];
    const auto load = [p](auto x) {
      std::memcpy(&x, p, sizeof x);
      return x;
    };
    if (type_name == "MET_UCHAR") return std::to_string(load(std::uint8_t{}));
    if (type_name == "MET_CHAR") return std::to_string(load(std::int8_t{}));
    if (type_name == "MET_USHORT") return std::to_string(load(std::uint16_t{}));
    if (type_name == "MET_SHORT") return std::to_string(load(std::int16_t{}));
    if (type_name == "MET_UINT" || type_name == "MET_ULONG")
      return std::to_string(load(std::uint32_t{}));
    if (type_name == "MET_INT" || type_name == "MET_LONG")
      return std::to_string(load(std::int32_t{}));
    if (type_name == "MET_FLOAT") {
      std::snprintf(text, sizeof text, "%.9g", static_cast<double>(load(float{})));
      return text;
    }
    std::snprintf(text, sizeof text, "%.17g", load(double{}));
    return text;
  }

  /// `h` padded with a comment-free filler line to exactly `size` bytes (the test keeps the
  /// header shorter than that).
  [[nodiscard]] static std::string pad_to(const std::string& h, std::size_t size) {
    std::string out = h;
    if (out.size() < size) out += std::string(size - out.size(), '#');
    return out.substr(0, size);
  }
};

/// A file of `volumes` volumes of 5 × 4 × 3 random samples of `t` (seeded), laid out as
/// `where` (`digits` naming a pattern's files) in `encoding` (0 raw, 1 zlib, 2 ASCII), most
/// significant byte first for even seeds.
inline metaimage_file make_metaimage_file(const metaimage_type& t, int volumes, unsigned seed,
                                          metaimage_file::layout where, int encoding,
                                          const char* digits) {
  metaimage_file f;
  f.type_name = t.name;
  f.item = sample_size(t.type);
  f.volumes = volumes;
  f.samples = random_samples(t.type, 60 * static_cast<std::size_t>(volumes), seed);
  f.where = where;
  f.pattern_digits = digits;
  f.msb = seed % 2 == 0;
  f.compressed = encoding == 1;
  f.ascii = encoding == 2;
  return f;
}

}  // namespace progiso::test
