// tests/support/vti_files.hpp — writing VTK XML image data (.vti) test files by hand, in every
// data mode VTK's writer has (ascii, inline base64, appended raw or base64; zlib blocks or none;
// UInt32 or UInt64 headers; either byte order), for the reader's tests and the fuzz seeds.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"

namespace progiso::test {

/// The VTK XML data types progiso reads, with the sample type each gives.
struct vti_type {
  const char* name;
  sample_type type;
};
inline constexpr std::array<vti_type, 8> vti_types{{
    {"Int8", sample_type::i8},
    {"UInt8", sample_type::u8},
    {"Int16", sample_type::i16},
    {"UInt16", sample_type::u16},
    {"Int32", sample_type::i32},
    {"UInt32", sample_type::u32},
    {"Float32", sample_type::f32},
    {"Float64", sample_type::f64},
}};

/// `bytes` in base64 (RFC 4648, padded).
inline std::string base64(const std::string& bytes) {
  static constexpr char digits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const auto v = (static_cast<unsigned>(static_cast<unsigned char>(bytes[i])) << 16) |
                   (static_cast<unsigned>(static_cast<unsigned char>(bytes[i + 1])) << 8) |
                   static_cast<unsigned>(static_cast<unsigned char>(bytes[i + 2]));
    for (int s = 18; s >= 0; s -= 6) out += digits[(v >> s) & 63];
  }
  if (i < bytes.size()) {
    unsigned v = static_cast<unsigned>(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size())
      v |= static_cast<unsigned>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    out += digits[(v >> 18) & 63];
    out += digits[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? digits[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

/// One .vti file: a point array of `samples` (host order, x fastest) over `extent`, with a
/// decoy array beside it, written the way `mode` says.
struct vti_file {
  enum class mode { ascii, binary, appended_raw, appended_base64 };
  const char* type_name = "UInt8";
  sample_type type = sample_type::u8;
  std::array<int, 6> extent{0, 4, 0, 3, 0, 2};  ///< 5 × 4 × 3 points
  std::vector<std::byte> samples;
  mode how = mode::appended_raw;
  bool zlib = false;
  std::uint64_t block_bytes = 32;  ///< uncompressed bytes per zlib block
  bool uint64_headers = false;
  bool big_endian = false;
  /// Where the array lies among the point arrays: after a Float32 decoy named by nothing
  /// (Scalars names the array), or first with no Scalars attribute.
  bool decoy_first = true;
  std::string origin = "-3 4.5 100";
  std::string spacing = "0.5 2 1.25";
  std::string direction;  ///< nine numbers, or none
  std::string version = "1.0";

  [[nodiscard]] std::size_t count() const {
    std::size_t n = 1;
    for (std::size_t a = 0; a < 3; ++a) {
      n *= static_cast<std::size_t>(extent[2 * a + 1] - extent[2 * a] + 1);
    }
    return n;
  }

  /// A header word (UInt32 or UInt64) in the file's byte order.
  [[nodiscard]] std::string word(std::uint64_t v) const {
    std::string out(uint64_headers ? 8 : 4, '\0');
    for (std::size_t b = 0; b < out.size(); ++b) {
      const std::size_t shift = 8 * (big_endian ? out.size() - 1 - b : b);
      out[b] = static_cast<char>((v >> shift) & 0xff);
    }
    return out;
  }

  /// `payload` (host-order samples of `item` bytes) as one array's binary block: header and
  /// data, compressed or not. `encode` turns each of the two runs into what the file holds.
  template <class Encode>
  [[nodiscard]] std::string block(const std::vector<std::byte>& payload, std::size_t item,
                                  Encode encode) const {
    std::string data(reinterpret_cast<const char*>(payload.data()), payload.size());
    for (std::size_t i = 0; big_endian && item > 1 && i + item <= data.size(); i += item) {
      std::reverse(data.begin() + static_cast<std::ptrdiff_t>(i),
                   data.begin() + static_cast<std::ptrdiff_t>(i + item));
    }
    if (!zlib) return encode(word(data.size()) + data);  // one run, as VTK writes it
    std::string header;
    std::string packed;
    const std::size_t n = (data.size() + block_bytes - 1) / block_bytes;
    header = word(n) + word(block_bytes) + word(data.size() % block_bytes);
    for (std::size_t b = 0; b < n; ++b) {
      const std::string piece = gzip(data.substr(b * block_bytes, block_bytes), 6, true);
      header += word(piece.size());
      packed += piece;
    }
    return encode(header) + encode(packed);  // two runs
  }

  [[nodiscard]] std::string text() const {
    const std::size_t item = sample_size(type);
    std::vector<std::byte> decoy(count() * 4);
    for (std::size_t i = 0; i < count(); ++i) {
      const float v = -0.25f * static_cast<float>(i);
      std::memcpy(decoy.data() + 4 * i, &v, 4);
    }
    const auto raw = [](const std::string& s) { return s; };
    const auto b64 = [](const std::string& s) { return base64(s); };
    std::string appended;
    const auto array = [&](const char* name, const char* type_text, const std::vector<std::byte>& p,
                           std::size_t size, sample_type t) {
      std::string a = "      <DataArray type=\"" + std::string(type_text) + "\" Name=\"" + name +
                      "\" NumberOfComponents=\"1\" format=\"";
      switch (how) {
        case mode::ascii: {
          a += "ascii\">\n        ";
          for (std::size_t i = 0; i < p.size() / size; ++i) {
            a += sample_text(t, p, i);
            a += (i + 1) % 6 == 0 ? "\n        " : " ";
          }
          return a + "\n      </DataArray>\n";
        }
        case mode::binary:
          return a + "binary\">\n        " + block(p, size, b64) + "\n      </DataArray>\n";
        case mode::appended_raw:
        case mode::appended_base64: {
          a += "appended\" offset=\"" + std::to_string(appended.size()) + "\"/>\n";
          appended += how == mode::appended_raw ? block(p, size, raw) : block(p, size, b64);
          return a;
        }
      }
      return a;
    };
    std::string h = "<?xml version=\"1.0\"?>\n<!-- written by progiso's tests -->\n";
    h += "<VTKFile type=\"ImageData\" version=\"" + version + "\" byte_order=\"" +
         (big_endian ? "BigEndian" : "LittleEndian") + "\" header_type=\"" +
         (uint64_headers ? "UInt64" : "UInt32") + "\"" +
         (zlib ? " compressor=\"vtkZLibDataCompressor\"" : "") + ">\n";
    std::string ext;
    for (int e : extent) ext += (ext.empty() ? "" : " ") + std::to_string(e);
    h += "  <ImageData WholeExtent=\"" + ext + "\" Origin=\"" + origin + "\" Spacing=\"" + spacing +
         "\"" + (direction.empty() ? "" : " Direction=\"" + direction + "\"") + ">\n";
    h += "  <Piece Extent=\"" + ext + "\">\n";
    h += std::string("    <PointData") + (decoy_first ? " Scalars=\"density\"" : "") + ">\n";
    if (decoy_first) h += array("decoy", "Float32", decoy, 4, sample_type::f32);
    h += array("density", type_name, samples, item, type);
    if (!decoy_first) h += array("decoy", "Float32", decoy, 4, sample_type::f32);
    h += "    </PointData>\n    <CellData>\n    </CellData>\n  </Piece>\n  </ImageData>\n";
    if (how == mode::appended_raw || how == mode::appended_base64) {
      h += std::string("  <AppendedData encoding=\"") +
           (how == mode::appended_raw ? "raw" : "base64") + "\">\n   _" + appended +
           "\n  </AppendedData>\n";
    }
    return h + "</VTKFile>\n";
  }

  std::filesystem::path write(const std::filesystem::path& dir, const std::string& stem) const {
    const std::filesystem::path file = dir / (stem + ".vti");
    write_file(file, text());
    return file;
  }
};

/// Writes `whole` as a .pvti of pieces with the given extents (each a .vti of the samples it
/// covers, in mode `how`), the pieces' Source names relative; returns the .pvti.
inline std::filesystem::path write_pvti(const std::filesystem::path& dir, const std::string& stem,
                                        const vti_file& whole,
                                        const std::vector<std::array<int, 6>>& pieces,
                                        vti_file::mode how, const std::string& extra_piece = "") {
  const auto& w = whole.extent;
  const std::size_t item = sample_size(whole.type);
  const auto nx = static_cast<std::size_t>(w[1] - w[0] + 1);
  const auto ny = static_cast<std::size_t>(w[3] - w[2] + 1);
  std::string ext;
  for (int e : w) ext += (ext.empty() ? "" : " ") + std::to_string(e);
  std::string text =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"PImageData\" version=\"1.0\" "
      "byte_order=\"LittleEndian\" header_type=\"UInt32\">\n"
      "  <PImageData WholeExtent=\"" +
      ext + "\" GhostLevel=\"0\" Origin=\"" + whole.origin + "\" Spacing=\"" + whole.spacing +
      "\">\n"
      "    <PPointData Scalars=\"density\">\n"
      "      <PDataArray type=\"Float32\" Name=\"decoy\"/>\n"
      "      <PDataArray type=\"" +
      std::string(whole.type_name) + "\" Name=\"density\"/>\n    </PPointData>\n";
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    vti_file f = whole;
    f.extent = pieces[k];
    f.how = how;
    f.samples.clear();
    for (int z = f.extent[4]; z <= f.extent[5]; ++z) {
      for (int y = f.extent[2]; y <= f.extent[3]; ++y) {
        for (int x = f.extent[0]; x <= f.extent[1]; ++x) {
          // A piece reaching past the whole grid (a hostile .pvti) holds zeros there.
          if (x < w[0] || x > w[1] || y < w[2] || y > w[3] || z < w[4] || z > w[5]) {
            f.samples.insert(f.samples.end(), item, std::byte{0});
            continue;
          }
          const std::size_t at =
              static_cast<std::size_t>(x - w[0]) +
              nx * (static_cast<std::size_t>(y - w[2]) + ny * static_cast<std::size_t>(z - w[4]));
          f.samples.insert(f.samples.end(), whole.samples.begin() + static_cast<long>(at * item),
                           whole.samples.begin() + static_cast<long>((at + 1) * item));
        }
      }
    }
    const std::string name = stem + "_" + std::to_string(k);
    f.write(dir, name);
    std::string pe;
    for (int e : f.extent) pe += (pe.empty() ? "" : " ") + std::to_string(e);
    text += "    <Piece Extent=\"" + pe + "\" Source=\"" + name + ".vti\"/>\n";
  }
  text += extra_piece + "  </PImageData>\n</VTKFile>\n";
  const std::filesystem::path file = dir / (stem + ".pvti");
  write_file(file, text);
  return file;
}

}  // namespace progiso::test
