// tests/support/vtk_legacy_files.hpp — writing legacy VTK test files (STRUCTURED_POINTS) for the
// reader's tests and its comparison with VTK's own reader.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <progiso/core/field/volume.hpp>

#include "support/io_test_helpers.hpp"

namespace progiso::test {

/// The legacy VTK data types progiso reads, with the sample type each gives.
struct vtk_type {
  const char* name;
  sample_type type;
};
inline constexpr std::array<vtk_type, 9> vtk_types{{
    {"unsigned_char", sample_type::u8},
    {"char", sample_type::i8},
    {"signed_char", sample_type::i8},
    {"unsigned_short", sample_type::u16},
    {"short", sample_type::i16},
    {"unsigned_int", sample_type::u32},
    {"int", sample_type::i32},
    {"float", sample_type::f32},
    {"double", sample_type::f64},
}};

/// One STRUCTURED_POINTS file: its samples (host order) and how the file states them.
struct vtk_legacy_file {
  std::string type_name = "unsigned_char";
  sample_type type = sample_type::u8;
  std::array<int, 3> dims{5, 4, 3};
  std::vector<std::byte> samples;  ///< host byte order, x fastest
  bool ascii = false;
  bool as_field = false;      ///< a FIELD array instead of SCALARS
  bool aspect_ratio = false;  ///< ASPECT_RATIO instead of SPACING
  std::string spacing = "0.5 2 1.25";
  std::string origin = "-3 4.5 100";
  bool upper_case = true;  ///< keywords in upper case (VTK's), else lower case
  std::string after;       ///< bytes after the data (more attributes …)

  [[nodiscard]] std::size_t count() const {
    return static_cast<std::size_t>(dims[0] * dims[1] * dims[2]);
  }

  [[nodiscard]] std::string data() const {
    const std::size_t item = sample_size(type);
    std::string out;
    if (ascii) {
      for (std::size_t i = 0; i < count(); ++i) {
        out += sample_text(type, samples, i);
        out += (i + 1) % 9 == 0 ? "\n" : " ";
      }
      return out + "\n";
    }
    out.assign(reinterpret_cast<const char*>(samples.data()), samples.size());
    for (std::size_t i = 0; item > 1 && i + item <= out.size(); i += item) {
      std::reverse(out.begin() + static_cast<std::ptrdiff_t>(i),
                   out.begin() + static_cast<std::ptrdiff_t>(i + item));
    }
    return out + "\n";
  }

  [[nodiscard]] std::string text() const {
    const auto k = [this](const std::string& keyword) {
      std::string out = keyword;
      if (!upper_case) {
        for (char& c : out) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
      }
      return out;
    };
    std::string h = "# vtk DataFile Version 3.0\nprogiso test volume\n" +
                    k(ascii ? "ASCII" : "BINARY") + "\n" + k("DATASET STRUCTURED_POINTS") + "\n" +
                    k("DIMENSIONS") + " " + std::to_string(dims[0]) + " " +
                    std::to_string(dims[1]) + " " + std::to_string(dims[2]) + "\n";
    h += k(aspect_ratio ? "ASPECT_RATIO" : "SPACING") + " " + spacing + "\n";
    h += k("ORIGIN") + " " + origin + "\n";
    h += k("POINT_DATA") + " " + std::to_string(count()) + "\n";
    if (as_field) {
      h += k("FIELD") + " FieldData 1\ndensity 1 " + std::to_string(count()) + " " + type_name +
           "\n";
    } else {
      h += k("SCALARS") + " density " + type_name + (upper_case ? " 1" : "") + "\n";
      h += k("LOOKUP_TABLE") + " default\n";
    }
    return h + data() + after;
  }

  std::filesystem::path write(const std::filesystem::path& dir, const std::string& stem) const {
    const std::filesystem::path file = dir / (stem + ".vtk");
    write_file(file, text());
    return file;
  }
};

}  // namespace progiso::test
