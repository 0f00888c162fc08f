// tests/support/dicom_files.hpp — writing DICOM Part 10 test files (one CT-like slice each) in
// the three uncompressed transfer syntaxes, for the DICOM reader's tests.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "support/io_test_helpers.hpp"

namespace progiso::test {

inline constexpr const char* dicom_implicit_le = "1.2.840.10008.1.2";
inline constexpr const char* dicom_explicit_le = "1.2.840.10008.1.2.1";
inline constexpr const char* dicom_explicit_be = "1.2.840.10008.1.2.2";
inline constexpr const char* dicom_jpeg_lossless = "1.2.840.10008.1.2.4.70";

/// One slice file: its header fields and its stored pixel values (host order).
struct dicom_slice_file {
  std::string transfer_syntax = dicom_explicit_le;
  std::string series_uid = "1.2.826.0.1.3680043.2.1125.1";
  int instance = 1;
  std::array<double, 3> position{0, 0, 0};
  std::array<double, 6> orientation{1, 0, 0, 0, 1, 0};
  std::array<double, 2> pixel_spacing{0.5, 0.75};  ///< row spacing, column spacing
  int rows = 4;
  int columns = 5;
  int bits_allocated = 16;
  int bits_stored = 12;
  int pixel_representation = 1;
  int samples = 1;
  std::string photometric = "MONOCHROME2";
  std::string slope = "1";
  std::string intercept = "-1024";
  bool with_sequences = true;     ///< nested sequences of undefined and defined length to skip
  std::vector<std::byte> pixels;  ///< rows × columns samples of bits_allocated, host order
  std::string extra_meta;         ///< more bytes at the end of the file meta (tests)
  /// Non-empty: an enhanced multi-frame image of one frame per position (pixels holds them in
  /// this order), placed by PerFrameFunctionalGroupsSequence; orientation, pixel spacing and the
  /// rescale go to SharedFunctionalGroupsSequence instead of the top level.
  std::vector<std::array<double, 3>> frame_positions;
  std::string number_of_frames;  ///< written instead of the frames' count when set
  /// Non-empty: an RT dose grid of one frame per offset (GridFrameOffsetVector, relative to
  /// `position` along the normal when the first is 0), scaled by `dose_scaling`.
  std::vector<double> grid_offsets;
  std::string dose_scaling = "1";
  /// Non-empty: encapsulated pixel data of these fragments (with transfer_syntax
  /// dicom_jpeg_lossless), instead of `pixels`.
  std::vector<std::string> fragments;

  [[nodiscard]] bool explicit_vr() const { return transfer_syntax != dicom_implicit_le; }
  [[nodiscard]] bool big() const { return transfer_syntax == dicom_explicit_be; }

  std::string bytes() const {
    std::string meta;
    const auto meta_element = [&](std::uint16_t g, std::uint16_t e, const char* vr,
                                  std::string value) {
      if (value.size() % 2 == 1) value += std::string(vr) == "UI" ? '\0' : ' ';
      put16(meta, g, false);
      put16(meta, e, false);
      meta += vr;
      if (std::string(vr) == "OB") {
        meta += std::string(2, '\0');
        put32(meta, static_cast<std::uint32_t>(value.size()), false);
      } else {
        put16(meta, static_cast<std::uint16_t>(value.size()), false);
      }
      meta += value;
    };
    meta_element(0x0002, 0x0001, "OB", std::string("\0\1", 2));
    meta_element(0x0002, 0x0002, "UI", "1.2.840.10008.5.1.4.1.1.2");
    meta_element(0x0002, 0x0003, "UI", series_uid + "." + std::to_string(instance));
    meta_element(0x0002, 0x0010, "UI", transfer_syntax);
    meta_element(0x0002, 0x0012, "UI", "1.2.826.0.1.3680043.2.1125.99");
    meta += extra_meta;
    std::string group_length;
    put16(group_length, 0x0002, false);
    put16(group_length, 0x0000, false);
    group_length += "UL";
    put16(group_length, 4, false);
    put32(group_length, static_cast<std::uint32_t>(meta.size()), false);

    std::string d;
    element(d, 0x0008, 0x0016, "UI", "1.2.840.10008.5.1.4.1.1.2");
    element(d, 0x0008, 0x0018, "UI", series_uid + "." + std::to_string(instance));
    element(d, 0x0008, 0x0060, "CS", "CT");
    if (with_sequences) {
      // ReferencedImageSequence of undefined length: an item of undefined length holding a
      // nested sequence, and an item of defined length.
      std::string inner;
      element(inner, 0x0008, 0x1150, "UI", "1.2.840.10008.5.1.4.1.1.2");
      std::string nested;
      element(nested, 0x0008, 0x0100, "SH", "T-D1100");
      std::string nested_seq;
      item(nested_seq, nested, true);
      sequence(inner, 0x0008, 0x2218, nested_seq, true);
      std::string items;
      item(items, inner, true);
      item(items, inner, false);
      sequence(d, 0x0008, 0x1140, items, true);
      // A sequence of defined length.
      std::string defined;
      item(defined, inner, false);
      sequence(d, 0x0008, 0x1150 + 1, defined, false);
    }
    const bool enhanced = !frame_positions.empty();
    element(d, 0x0020, 0x000e, "UI", series_uid);
    element(d, 0x0020, 0x0013, "IS", std::to_string(instance));
    if (!enhanced) {
      element(d, 0x0020, 0x0032, "DS", ds(position.data(), 3));
      element(d, 0x0020, 0x0037, "DS", ds(orientation.data(), 6));
    }
    element(d, 0x0028, 0x0002, "US", us(samples));
    element(d, 0x0028, 0x0004, "CS", photometric);
    if (enhanced) {
      element(d, 0x0028, 0x0008, "IS",
              number_of_frames.empty() ? std::to_string(frame_positions.size()) : number_of_frames);
    } else if (!grid_offsets.empty()) {
      element(d, 0x0028, 0x0008, "IS",
              number_of_frames.empty() ? std::to_string(grid_offsets.size()) : number_of_frames);
    }
    element(d, 0x0028, 0x0010, "US", us(rows));
    element(d, 0x0028, 0x0011, "US", us(columns));
    if (!enhanced) element(d, 0x0028, 0x0030, "DS", ds(pixel_spacing.data(), 2));
    element(d, 0x0028, 0x0100, "US", us(bits_allocated));
    element(d, 0x0028, 0x0101, "US", us(bits_stored));
    element(d, 0x0028, 0x0102, "US", us(bits_stored - 1));
    element(d, 0x0028, 0x0103, "US", us(pixel_representation));
    if (!enhanced) {
      element(d, 0x0028, 0x1052, "DS", intercept);
      element(d, 0x0028, 0x1053, "DS", slope);
    } else {
      // Shared groups (items of undefined length): Plane Orientation, Pixel Measures, Pixel
      // Value Transformation; per frame (defined length): Frame Content, Plane Position.
      const auto group = [&](std::uint16_t g, std::uint16_t e, const std::string& content,
                             bool undefined) {
        std::string items;
        item(items, content, undefined);
        std::string out;
        sequence(out, g, e, items, undefined);
        return out;
      };
      std::string measures, plane, transform;
      element(measures, 0x0028, 0x0030, "DS", ds(pixel_spacing.data(), 2));
      element(plane, 0x0020, 0x0037, "DS", ds(orientation.data(), 6));
      element(transform, 0x0028, 0x1052, "DS", intercept);
      element(transform, 0x0028, 0x1053, "DS", slope);
      const std::string shared = group(0x0020, 0x9116, plane, true) +
                                 group(0x0028, 0x9110, measures, true) +
                                 group(0x0028, 0x9145, transform, true);
      std::string shared_items;
      item(shared_items, shared, true);
      sequence(d, 0x5200, 0x9229, shared_items, true);
      std::string frames;
      for (std::size_t k = 0; k < frame_positions.size(); ++k) {
        std::string content, place;
        element(content, 0x0020, 0x9057, "UL", std::string(4, '\0'));
        element(place, 0x0020, 0x0032, "DS", ds(frame_positions[k].data(), 3));
        item(frames, group(0x0020, 0x9111, content, false) + group(0x0020, 0x9113, place, false),
             false);
      }
      sequence(d, 0x5200, 0x9230, frames, false);
    }
    if (!grid_offsets.empty()) {
      element(d, 0x3004, 0x000c, "DS",
              ds(grid_offsets.data(), static_cast<int>(grid_offsets.size())));
      element(d, 0x3004, 0x000e, "DS", dose_scaling);
    }
    std::string px(reinterpret_cast<const char*>(pixels.data()), pixels.size());
    const std::size_t item_bytes = static_cast<std::size_t>(bits_allocated / 8);
    if (big() && item_bytes > 1) {
      for (std::size_t i = 0; i + item_bytes <= px.size(); i += item_bytes) {
        std::reverse(px.begin() + static_cast<std::ptrdiff_t>(i),
                     px.begin() + static_cast<std::ptrdiff_t>(i + item_bytes));
      }
    }
    if (!fragments.empty()) {
      // Encapsulated: undefined length, an empty offsets table, the fragments, the delimiter.
      put16(d, 0x7fe0, false);
      put16(d, 0x0010, false);
      d += std::string("OB") + std::string(2, '\0');
      put32(d, 0xffffffffu, false);
      item(d, "", false);
      for (const std::string& f : fragments) item(d, f, false);
      put16(d, 0xfffe, false);
      put16(d, 0xe0dd, false);
      put32(d, 0, false);
    } else {
      element(d, 0x7fe0, 0x0010, bits_allocated == 8 ? "OB" : "OW", px);
    }
    return std::string(128, '\0') + "DICM" + group_length + meta + d;
  }

  std::filesystem::path write(const std::filesystem::path& dir, const std::string& name) const {
    const std::filesystem::path file = dir / name;
    write_file(file, bytes());
    return file;
  }

 private:
  static void put16(std::string& s, std::uint16_t v, bool big_endian) {
    if (big_endian) {
      s += static_cast<char>(v >> 8);
      s += static_cast<char>(v & 0xff);
    } else {
      s += static_cast<char>(v & 0xff);
      s += static_cast<char>(v >> 8);
    }
  }
  static void put32(std::string& s, std::uint32_t v, bool big_endian) {
    if (big_endian) {
      put16(s, static_cast<std::uint16_t>(v >> 16), true);
      put16(s, static_cast<std::uint16_t>(v & 0xffff), true);
    } else {
      put16(s, static_cast<std::uint16_t>(v & 0xffff), false);
      put16(s, static_cast<std::uint16_t>(v >> 16), false);
    }
  }
  std::string us(int v) const {
    std::string s;
    put16(s, static_cast<std::uint16_t>(v), big());
    return s;
  }
  static std::string ds(const double* v, int n) {
    std::string s;
    for (int i = 0; i < n; ++i) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.6g", v[i]);
      if (i > 0) s += '\\';
      s += buf;
    }
    return s;
  }
  static bool long_vr(const std::string& vr) {
    return vr == "OB" || vr == "OW" || vr == "SQ" || vr == "UN" || vr == "UT";
  }
  void element(std::string& d, std::uint16_t g, std::uint16_t e, const std::string& vr,
               std::string value) const {
    if (value.size() % 2 == 1) value += vr == "UI" || vr == "OB" ? '\0' : ' ';
    put16(d, g, big());
    put16(d, e, big());
    if (explicit_vr()) {
      d += vr;
      if (long_vr(vr)) {
        d += std::string(2, '\0');
        put32(d, static_cast<std::uint32_t>(value.size()), big());
      } else {
        put16(d, static_cast<std::uint16_t>(value.size()), big());
      }
    } else {
      put32(d, static_cast<std::uint32_t>(value.size()), big());
    }
    d += value;
  }
  void item(std::string& d, const std::string& content, bool undefined) const {
    put16(d, 0xfffe, big());
    put16(d, 0xe000, big());
    put32(d, undefined ? 0xffffffffu : static_cast<std::uint32_t>(content.size()), big());
    d += content;
    if (undefined) {
      put16(d, 0xfffe, big());
      put16(d, 0xe00d, big());
      put32(d, 0, big());
    }
  }
  void sequence(std::string& d, std::uint16_t g, std::uint16_t e, const std::string& items,
                bool undefined) const {
    put16(d, g, big());
    put16(d, e, big());
    if (explicit_vr()) {
      d += "SQ";
      d += std::string(2, '\0');
    }
    put32(d, undefined ? 0xffffffffu : static_cast<std::uint32_t>(items.size()), big());
    d += items;
    if (undefined) {
      put16(d, 0xfffe, big());
      put16(d, 0xe0dd, big());
      put32(d, 0, big());
    }
  }
};

/// Slice k of a plain stack: `bits`-bit unsigned samples (all bits stored, no rescale), `rows` ×
/// `columns` pixels, positions `step` apart along z, instance k + 1; pixels left to the caller.
inline dicom_slice_file plain_slice(int k, int rows, int columns, int bits, double step) {
  dicom_slice_file f;
  f.rows = rows;
  f.columns = columns;
  f.bits_allocated = bits;
  f.bits_stored = bits;
  f.pixel_representation = 0;
  f.slope = "1";
  f.intercept = "0";
  f.position = {0.0, 0.0, step * k};
  f.instance = k + 1;
  return f;
}

}  // namespace progiso::test
