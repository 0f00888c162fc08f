#include <progiso/io/detail/dicom_reader.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/dicom_jpeg2000.hpp>
#include <progiso/io/detail/dicom_rle.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/header_text.hpp>
#include <progiso/io/detail/jpeg_lossless.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t undefined_length = 0xffffffffu;
constexpr std::size_t max_value_bytes = 1024;  // of an element progiso reads
// GridFrameOffsetVector: one decimal string (at most 16 characters and a backslash) per frame.
constexpr std::size_t max_offsets_bytes = 17 * dicom_max_slices;
constexpr int max_depth = 16;  // of nested sequences
constexpr std::size_t max_directory_entries = 1u << 20;
// Per-frame functional groups (each about 150 bytes) and RT dose offsets kept over a directory's
// multi-frame images: four series of the most frames one volume may have.
constexpr std::size_t max_frame_groups = 4 * dicom_max_slices;

constexpr std::uint32_t tag(std::uint16_t group, std::uint16_t element) noexcept {
  return (std::uint32_t{group} << 16) | element;
}
constexpr std::uint32_t transfer_syntax_tag = tag(0x0002, 0x0010);
constexpr std::uint32_t series_uid_tag = tag(0x0020, 0x000e);
constexpr std::uint32_t instance_tag = tag(0x0020, 0x0013);
constexpr std::uint32_t position_tag = tag(0x0020, 0x0032);
constexpr std::uint32_t orientation_tag = tag(0x0020, 0x0037);
constexpr std::uint32_t samples_tag = tag(0x0028, 0x0002);
constexpr std::uint32_t photometric_tag = tag(0x0028, 0x0004);
constexpr std::uint32_t frames_tag = tag(0x0028, 0x0008);
constexpr std::uint32_t rows_tag = tag(0x0028, 0x0010);
constexpr std::uint32_t columns_tag = tag(0x0028, 0x0011);
constexpr std::uint32_t pixel_spacing_tag = tag(0x0028, 0x0030);
constexpr std::uint32_t bits_allocated_tag = tag(0x0028, 0x0100);
constexpr std::uint32_t bits_stored_tag = tag(0x0028, 0x0101);
constexpr std::uint32_t pixel_representation_tag = tag(0x0028, 0x0103);
constexpr std::uint32_t intercept_tag = tag(0x0028, 0x1052);
constexpr std::uint32_t slope_tag = tag(0x0028, 0x1053);
constexpr std::uint32_t float_pixel_tag = tag(0x7fe0, 0x0008);
constexpr std::uint32_t double_pixel_tag = tag(0x7fe0, 0x0009);
constexpr std::uint32_t pixel_data_tag = tag(0x7fe0, 0x0010);
constexpr std::uint32_t shared_groups_tag = tag(0x5200, 0x9229);
constexpr std::uint32_t per_frame_groups_tag = tag(0x5200, 0x9230);
constexpr std::uint32_t pixel_measures_tag = tag(0x0028, 0x9110);
constexpr std::uint32_t plane_position_tag = tag(0x0020, 0x9113);
constexpr std::uint32_t frame_content_tag = tag(0x0020, 0x9111);
constexpr std::uint32_t temporal_index_tag = tag(0x0020, 0x9128);
constexpr std::uint32_t plane_orientation_tag = tag(0x0020, 0x9116);
constexpr std::uint32_t value_transformation_tag = tag(0x0028, 0x9145);
constexpr std::uint32_t grid_offsets_tag = tag(0x3004, 0x000c);
constexpr std::uint32_t dose_scaling_tag = tag(0x3004, 0x000e);
constexpr std::uint32_t item_tag = tag(0xfffe, 0xe000);
constexpr std::uint32_t item_end_tag = tag(0xfffe, 0xe00d);
constexpr std::uint32_t sequence_end_tag = tag(0xfffe, 0xe0dd);

std::string tag_text(std::uint32_t t) {
  static constexpr char hex[] = "0123456789ABCDEF";
  std::string out = "(";
  for (int shift = 28; shift >= 0; shift -= 4) {
    out += hex[(t >> static_cast<unsigned>(shift)) & 15u];
    if (shift == 16) out += ',';
  }
  return out + ")";
}

/// The transfer syntaxes progiso reads, and the names of those it refuses.
struct syntax {
  bool explicit_vr = true;
  bool big_endian = false;
  dicom_codec codec = dicom_codec::native;  ///< how the pixel data is stored
};
std::optional<syntax> syntax_of(std::string_view uid, std::string& refused) {
  if (uid == "1.2.840.10008.1.2") return syntax{false, false, dicom_codec::native};
  if (uid == "1.2.840.10008.1.2.1") return syntax{true, false, dicom_codec::native};
  if (uid == "1.2.840.10008.1.2.2") return syntax{true, true, dicom_codec::native};
  // JPEG Lossless, Non-Hierarchical (Process 14), and its First-Order Prediction subset.
  if (uid == "1.2.840.10008.1.2.4.57" || uid == "1.2.840.10008.1.2.4.70") {
    return syntax{true, false, dicom_codec::jpeg_lossless};
  }
  if (uid == "1.2.840.10008.1.2.5") return syntax{true, false, dicom_codec::rle};
  // JPEG 2000 Image Compression (Lossless Only), and the one that allows lossy frames.
  if (uid == "1.2.840.10008.1.2.4.90" || uid == "1.2.840.10008.1.2.4.91") {
    return syntax{true, false, dicom_codec::jpeg2000};
  }
  if (uid == "1.2.840.10008.1.2.1.99") {
    refused = "deflated explicit VR little endian";
  } else if (uid.rfind("1.2.840.10008.1.2.4.8", 0) == 0) {
    refused = "JPEG-LS";
  } else if (uid.rfind("1.2.840.10008.1.2.4.9", 0) == 0) {
    refused = "JPEG 2000 multi-component or JPIP";
  } else if (uid.rfind("1.2.840.10008.1.2.4.20", 0) == 0) {
    refused = "High-Throughput JPEG 2000";
  } else if (uid.rfind("1.2.840.10008.1.2.4.", 0) == 0) {
    refused = "JPEG";
  } else {
    refused = "an unknown transfer syntax";
  }
  return std::nullopt;
}

/// VRs whose length field is 4 bytes after 2 reserved ones in explicit VR.
bool long_vr(std::string_view vr) noexcept {
  static constexpr std::array<std::string_view, 13> vrs{"OB", "OD", "OF", "OL", "OV", "OW", "SQ",
                                                        "SV", "UC", "UN", "UR", "UT", "UV"};
  return std::find(vrs.begin(), vrs.end(), vr) != vrs.end();
}

/// Where a frame lies and how its values scale: the dataset's own elements, or those of an
/// enhanced image's functional groups (shared by every frame, or one frame's).
struct frame_fields {
  std::optional<std::array<double, 3>> position;
  std::optional<std::array<double, 6>> orientation;
  std::optional<std::array<double, 2>> pixel_spacing;
  std::optional<double> slope;
  std::optional<double> intercept;
  std::optional<std::uint32_t> temporal;  ///< Frame Content's TemporalPositionIndex

  /// Each field of `over` where it has one, else this one's.
  [[nodiscard]] frame_fields under(const frame_fields& over) const {
    return {over.position ? over.position : position,
            over.orientation ? over.orientation : orientation,
            over.pixel_spacing ? over.pixel_spacing : pixel_spacing,
            over.slope ? over.slope : slope,
            over.intercept ? over.intercept : intercept,
            over.temporal ? over.temporal : temporal};
  }
};

/// What one file's header says.
struct file_header {
  bool image = false;  ///< holds pixel data
  bool big_endian = false;
  std::string series;
  std::optional<double> instance;       ///< InstanceNumber (0020,0013)
  frame_fields own;                     ///< the dataset's top-level elements
  frame_fields shared;                  ///< SharedFunctionalGroupsSequence
  std::vector<frame_fields> per_frame;  ///< PerFrameFunctionalGroupsSequence, one per item
  std::uint32_t rows = 0, columns = 0, bits_allocated = 0, bits_stored = 0;
  std::uint32_t pixel_representation = 0, samples = 1;
  std::int64_t frames = 1;
  std::string photometric = "MONOCHROME2";
  std::uint64_t pixel_offset = 0;
  std::uint64_t pixel_length = 0;
  dicom_codec codec = dicom_codec::native;  ///< encapsulated: fragments from pixel_offset
  std::vector<double> grid_offsets;         ///< an RT dose's GridFrameOffsetVector (3004,000C)
  std::optional<double> dose_scaling;       ///< an RT dose's DoseGridScaling (3004,000E)

  /// Frame k's fields: its own functional groups, else the shared ones, else the dataset's.
  [[nodiscard]] frame_fields frame(std::size_t k) const {
    frame_fields f = own.under(shared);
    return k < per_frame.size() ? f.under(per_frame[k]) : f;
  }
};

/// Reads the elements of one DICOM Part 10 file up to its pixel data.
class file_parser {
 public:
  explicit file_parser(input_file& in) : in_(in), name_(in.path().string()) {}

  /// nullopt for a file that is not DICOM Part 10 (no "DICM" at byte 128).
  std::optional<file_header> run() {
    if (in_.size() < 132) return std::nullopt;
    std::array<char, 132> head{};
    read(head.data(), head.size());
    if (std::string_view(head.data() + 128, 4) != "DICM") return std::nullopt;
    file_header h;
    // File meta information: group 0002, explicit VR little endian.
    std::string uid;
    for (;;) {
      if (pos_ + 8 > in_.size()) fail("ends in the file meta information");
      const std::uint64_t at = pos_;
      const std::uint32_t t = read_tag(false);
      if ((t >> 16) != 0x0002) {
        seek(at);
        break;
      }
      const element e = read_header(t, true, false);
      if (e.length == undefined_length) fail("holds a file meta element of undefined length");
      if (t == transfer_syntax_tag) {
        uid = std::string(trim_value(read_value(e)));
      } else {
        skip(e.length);
      }
    }
    if (uid.empty()) fail("has no transfer syntax (0002,0010) in its file meta information");
    std::string refused;
    const std::optional<syntax> s = syntax_of(uid, refused);
    if (!s) {
      fail("uses the transfer syntax " + detail::quoted(uid) + " (" + refused +
           "): not supported (expected uncompressed pixel data: implicit or explicit VR)");
    }
    syntax_ = *s;
    h.big_endian = s->big_endian;
    parse_dataset(h);
    return h;
  }

 private:
  struct element {
    std::uint32_t tag = 0;
    std::string vr;  // empty in implicit VR
    std::uint32_t length = 0;
  };

  [[noreturn]] void fail(const std::string& what) const {
    throw error(name_ + ": DICOM file " + what);
  }

  void read(void* data, std::size_t n) {
    if (in_.read(data, n) != n)
      fail("ends after " + std::to_string(pos_) + " bytes, inside an element");
    pos_ += n;
  }
  void seek(std::uint64_t at) {
    in_.seek(at);
    pos_ = at;
  }
  void skip(std::uint64_t n) {
    if (n > in_.size() - pos_) {
      fail("holds an element of " + std::to_string(n) + " bytes at byte " + std::to_string(pos_) +
           ", past its end (" + std::to_string(in_.size()) + " bytes)");
    }
    seek(pos_ + n);
  }
  std::uint16_t read_u16(bool big) {
    std::array<unsigned char, 2> b{};
    read(b.data(), 2);
    return big ? static_cast<std::uint16_t>(b[0] << 8 | b[1])
               : static_cast<std::uint16_t>(b[1] << 8 | b[0]);
  }
  std::uint32_t read_u32(bool big) {
    const std::uint32_t a = read_u16(big);
    const std::uint32_t b = read_u16(big);
    return big ? (a << 16) | b : (b << 16) | a;
  }
  std::uint32_t read_tag(bool big) {
    const std::uint32_t group = read_u16(big);
    const std::uint32_t elem = read_u16(big);
    return (group << 16) | elem;
  }
  /// The VR and length after a tag (items and delimiters have no VR).
  element read_header(std::uint32_t t, bool explicit_vr, bool big) {
    element e;
    e.tag = t;
    if (!explicit_vr || (t >> 16) == 0xfffe) {
      e.length = read_u32(big);
      return e;
    }
    std::array<char, 2> vr{};
    read(vr.data(), 2);
    e.vr.assign(vr.data(), 2);
    if (long_vr(e.vr)) {
      skip(2);
      e.length = read_u32(big);
    } else {
      e.length = read_u16(big);
    }
    return e;
  }
  std::string read_value(const element& e, std::size_t limit = max_value_bytes) {
    if (e.length > limit) {
      fail("element " + tag_text(e.tag) + " holds " + std::to_string(e.length) +
           " bytes, expected at most " + std::to_string(limit));
    }
    std::string v(e.length, '\0');
    read(v.data(), v.size());
    return v;
  }
  static std::string_view trim_value(std::string_view v) noexcept {
    while (!v.empty() && (v.back() == '\0' || v.back() == ' ')) v.remove_suffix(1);
    while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
    return v;
  }
  /// Backslash-separated decimal strings (DS, IS).
  template <std::size_t N>
  std::array<double, N> numbers(const element& e, std::string_view v) const {
    std::array<double, N> out{};
    std::size_t k = 0;
    std::size_t start = 0;
    for (std::size_t i = 0; i <= v.size(); ++i) {
      if (i < v.size() && v[i] != '\\') continue;
      const std::string_view part = trim_value(v.substr(start, i - start));
      const auto x = to_real<double>(part);
      if (k >= N || !x || !std::isfinite(*x)) {
        fail("element " + tag_text(e.tag) + " holds " + detail::quoted(v) + ", expected " +
             std::to_string(N) + " finite number" + (N > 1 ? "s" : ""));
      }
      out[k++] = *x;
      start = i + 1;
    }
    if (k != N) {
      fail("element " + tag_text(e.tag) + " holds " + detail::quoted(v) + ", expected " +
           std::to_string(N) + " numbers");
    }
    return out;
  }
  /// Backslash-separated decimal strings, as many as there are (at most dicom_max_slices).
  std::vector<double> number_list(const element& e, std::string_view v) const {
    std::vector<double> out;
    std::size_t start = 0;
    for (std::size_t i = 0; i <= v.size(); ++i) {
      if (i < v.size() && v[i] != '\\') continue;
      const auto x = to_real<double>(trim_value(v.substr(start, i - start)));
      if (!x || !std::isfinite(*x) || out.size() == dicom_max_slices) {
        fail("element " + tag_text(e.tag) + " holds " + detail::quoted(v) + ", expected 1 to " +
             std::to_string(dicom_max_slices) + " finite numbers");
      }
      out.push_back(*x);
      start = i + 1;
    }
    return out;
  }
  std::uint32_t unsigned_long(const element& e, std::string_view v) const {
    if (v.size() != 4)
      fail("element " + tag_text(e.tag) + " has " + std::to_string(v.size()) +
           " bytes, expected 4 (UL)");
    std::uint32_t out = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      const auto b = static_cast<unsigned char>(v[syntax_.big_endian ? i : 3 - i]);
      out = (out << 8) | b;
    }
    return out;
  }
  std::uint32_t unsigned_short(const element& e, std::string_view v) const {
    if (v.size() != 2)
      fail("element " + tag_text(e.tag) + " has " + std::to_string(v.size()) +
           " bytes, expected 2 (US)");
    const auto b0 = static_cast<unsigned char>(v[0]);
    const auto b1 = static_cast<unsigned char>(v[1]);
    return syntax_.big_endian ? (std::uint32_t{b0} << 8) | b1 : (std::uint32_t{b1} << 8) | b0;
  }

  void parse_dataset(file_header& h) {
    const bool big = syntax_.big_endian;
    while (pos_ < in_.size()) {
      const std::uint32_t t = read_tag(big);
      if ((t >> 16) == 0xfffe)
        fail("holds an item tag " + tag_text(t) + " outside a sequence at byte " +
             std::to_string(pos_ - 4));
      const element e = read_header(t, syntax_.explicit_vr, big);
      if (t == pixel_data_tag) {
        const bool encapsulated = syntax_.codec != dicom_codec::native;
        if ((e.length == undefined_length) != encapsulated) {
          fail(encapsulated ? "holds native pixel data in a compressed transfer syntax"
                            : "holds encapsulated (compressed) pixel data in an uncompressed "
                              "transfer syntax");
        }
        h.image = true;
        h.codec = syntax_.codec;
        h.pixel_offset = pos_;
        // Encapsulated: the fragments run to the file's end at most.
        h.pixel_length = encapsulated ? in_.size() - pos_ : e.length;
        return;
      }
      if (t == float_pixel_tag || t == double_pixel_tag) {
        fail("holds floating-point pixel data " + tag_text(t) + ": not supported");
      }
      if (t == shared_groups_tag || t == per_frame_groups_tag) {
        functional_groups(e, t == per_frame_groups_tag, h);
        continue;
      }
      if (e.length == undefined_length) {
        // A sequence (SQ; UN of undefined length is an implicit VR little endian sequence).
        skip_value(e, syntax_.explicit_vr, big, 1);
        continue;
      }
      if (frame_value(e, h.own)) continue;
      switch (t) {
        case series_uid_tag:
          h.series = std::string(trim_value(read_value(e)));
          break;
        case instance_tag: {
          // Only an order among frames at one position: an empty or odd value is no order.
          const std::string v = read_value(e);
          const auto x = to_real<double>(trim_value(v));
          if (x && std::isfinite(*x)) h.instance = *x;
          break;
        }
        case frames_tag: {
          const std::string v = read_value(e);
          const double frames = numbers<1>(e, trim_value(v))[0];
          if (!(frames >= 1 && frames <= static_cast<double>(dicom_max_slices)) ||
              frames != std::floor(frames)) {
            fail("has NumberOfFrames (0028,0008) " + detail::quoted(trim_value(v)) +
                 ", expected 1 to " + std::to_string(dicom_max_slices));
          }
          h.frames = static_cast<std::int64_t>(frames);
          break;
        }
        case grid_offsets_tag:
          h.grid_offsets = number_list(e, trim_value(read_value(e, max_offsets_bytes)));
          break;
        case dose_scaling_tag: {
          const std::string v = read_value(e);
          h.dose_scaling = numbers<1>(e, trim_value(v))[0];
          break;
        }
        case photometric_tag:
          h.photometric = std::string(trim_value(read_value(e)));
          break;
        case samples_tag:
          h.samples = unsigned_short(e, read_value(e));
          break;
        case rows_tag:
          h.rows = unsigned_short(e, read_value(e));
          break;
        case columns_tag:
          h.columns = unsigned_short(e, read_value(e));
          break;
        case bits_allocated_tag:
          h.bits_allocated = unsigned_short(e, read_value(e));
          break;
        case bits_stored_tag:
          h.bits_stored = unsigned_short(e, read_value(e));
          break;
        case pixel_representation_tag:
          h.pixel_representation = unsigned_short(e, read_value(e));
          break;
        default:
          skip(e.length);
          break;
      }
    }
  }

  /// Reads `e` into `f` when it is one of the fields that place or scale a frame (at the top
  /// level or in a functional group); false, with nothing read, for any other element.
  bool frame_value(const element& e, frame_fields& f) {
    if (e.length == undefined_length) return false;
    switch (e.tag) {
      case position_tag:
        f.position = numbers<3>(e, trim_value(read_value(e)));
        return true;
      case orientation_tag:
        f.orientation = numbers<6>(e, trim_value(read_value(e)));
        return true;
      case pixel_spacing_tag:
        f.pixel_spacing = numbers<2>(e, trim_value(read_value(e)));
        return true;
      case intercept_tag:
        f.intercept = numbers<1>(e, trim_value(read_value(e)))[0];
        return true;
      case slope_tag:
        f.slope = numbers<1>(e, trim_value(read_value(e)))[0];
        return true;
      case temporal_index_tag: {
        // Only an order among frames at one position: a value of another size is no order.
        const std::string v = read_value(e);
        if (v.size() == 4) f.temporal = unsigned_long(e, v);
        return true;
      }
      default:
        return false;
    }
  }

  /// Skips an element's value: by its length, or a sequence of undefined length item by item
  /// (an item of undefined length element by element), at most max_depth deep.
  void skip_value(const element& e, bool explicit_vr, bool big, int depth) {
    if (e.length != undefined_length) {
      skip(e.length);
      return;
    }
    for_each_item(e, explicit_vr, big, depth, [&](std::uint32_t length, bool ex, bool bg) {
      if (length != undefined_length) {
        skip(length);
        return;
      }
      for_each_element(length, ex, bg,
                       [&](const element& inner) { skip_value(inner, ex, bg, depth + 1); });
    });
  }

  /// The end of a value of `length` bytes starting here; fails when it runs past the file.
  std::uint64_t end_of(std::uint32_t length, const char* what) {
    if (length > in_.size() - pos_) {
      fail("holds " + std::string(what) + " of " + std::to_string(length) + " bytes at byte " +
           std::to_string(pos_) + ", past its end (" + std::to_string(in_.size()) + " bytes)");
    }
    return pos_ + length;
  }

  /// Calls f(length, explicit_vr, big) at each item of the sequence `e` (of defined or undefined
  /// length), after the item's tag and length; f consumes the item.
  template <class F>
  void for_each_item(const element& e, bool explicit_vr, bool big, int depth, F&& f) {
    if (depth > max_depth) fail("nests sequences more than " + std::to_string(max_depth) + " deep");
    // A UN sequence holds implicit VR little endian.
    const bool ex = explicit_vr && e.vr != "UN";
    const bool bg = e.vr == "UN" ? false : big;
    const bool undefined = e.length == undefined_length;
    const std::uint64_t end = undefined ? 0 : end_of(e.length, "a sequence");
    while (undefined || pos_ < end) {
      const std::uint32_t t = read_tag(bg);
      const std::uint32_t length = read_u32(bg);
      if (undefined && t == sequence_end_tag) return;
      if (t != item_tag) {
        fail("holds " + tag_text(t) + " inside a sequence at byte " + std::to_string(pos_ - 8) +
             " (expected an item or the sequence's end)");
      }
      f(length, ex, bg);
      if (!undefined && pos_ > end) fail("holds an item that runs past its sequence's end");
    }
  }

  /// Calls f(element) for each element of an item of `length` bytes (or up to its end tag), f
  /// consuming the element's value.
  template <class F>
  void for_each_element(std::uint32_t length, bool explicit_vr, bool big, F&& f) {
    const bool undefined = length == undefined_length;
    const std::uint64_t end = undefined ? 0 : end_of(length, "an item");
    while (undefined || pos_ < end) {
      const std::uint32_t t = read_tag(big);
      const element e = read_header(t, explicit_vr, big);
      if (undefined && t == item_end_tag) return;
      if ((t >> 16) == 0xfffe) {
        fail("holds " + tag_text(t) + " inside an item at byte " + std::to_string(pos_ - 8));
      }
      f(e);
      if (!undefined && pos_ > end) fail("holds an element that runs past its item's end");
    }
  }

  /// An enhanced image's SharedFunctionalGroupsSequence (5200,9229) or
  /// PerFrameFunctionalGroupsSequence (5200,9230): from each item, the frame's fields in the
  /// functional groups that hold them (Pixel Measures, Plane Position, Plane Orientation, Pixel
  /// Value Transformation); every other group skipped.
  void functional_groups(const element& seq, bool per_frame, file_header& h) {
    for_each_item(seq, syntax_.explicit_vr, syntax_.big_endian, 1,
                  [&](std::uint32_t length, bool ex, bool big) {
                    frame_fields fields;
                    for_each_element(length, ex, big, [&](const element& group) {
                      if (group.tag != pixel_measures_tag && group.tag != plane_position_tag &&
                          group.tag != plane_orientation_tag &&
                          group.tag != value_transformation_tag && group.tag != frame_content_tag) {
                        skip_value(group, ex, big, 2);
                        return;
                      }
                      for_each_item(group, ex, big, 2, [&](std::uint32_t n, bool ex2, bool big2) {
                        for_each_element(n, ex2, big2, [&](const element& v) {
                          if (!frame_value(v, fields)) skip_value(v, ex2, big2, 3);
                        });
                      });
                    });
                    if (!per_frame) {
                      h.shared = h.shared.under(fields);
                      return;
                    }
                    if (h.per_frame.size() == dicom_max_slices) {
                      fail("holds more than " + std::to_string(dicom_max_slices) +
                           " items in PerFrameFunctionalGroupsSequence (5200,9230)");
                    }
                    h.per_frame.push_back(fields);
                  });
  }

  input_file& in_;
  std::string name_;
  std::uint64_t pos_ = 0;
  syntax syntax_;
};

sample_type stored_type(std::uint32_t bits, bool is_signed) {
  switch (bits) {
    case 8:
      return is_signed ? sample_type::i8 : sample_type::u8;
    case 16:
      return is_signed ? sample_type::i16 : sample_type::u16;
    default:
      return is_signed ? sample_type::i32 : sample_type::u32;
  }
}

double dot(const std::array<double, 3>& a, const std::array<double, 3>& b) noexcept {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/// The stored value `raw` (BitsAllocated wide, host order) masked to BitsStored and
/// sign-extended when signed.
template <class U>
std::int64_t stored_value(U raw, unsigned bits_stored, bool is_signed) noexcept {
  const std::uint64_t mask =
      bits_stored >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits_stored) - 1;
  std::uint64_t v = static_cast<std::uint64_t>(raw) & mask;
  if (is_signed && bits_stored > 0 && ((v >> (bits_stored - 1)) & 1u) != 0) v |= ~mask;
  return static_cast<std::int64_t>(v);
}

}  // namespace

dicom_series read_dicom_series(const fs::path& input, const std::optional<std::string>& chosen,
                               const std::optional<std::int64_t>& volume) {
  const std::string dir_name = input.string();
  std::error_code ec;
  const bool one_file = !fs::is_directory(input, ec);
  std::vector<fs::path> names;
  if (one_file) {
    names.push_back(input);
  } else {
    for (fs::directory_iterator it(input, ec), end; !ec && it != end; it.increment(ec)) {
      if (names.size() == max_directory_entries) {
        throw error(dir_name + ": holds more than " + std::to_string(max_directory_entries) +
                    " entries, expected one DICOM series");
      }
      std::error_code type_ec;
      if (it->is_regular_file(type_ec)) names.push_back(it->path());
    }
    if (ec) throw error(dir_name + ": cannot list the directory (" + ec.message() + ")");
    std::sort(names.begin(), names.end());
  }

  struct found {
    fs::path file;
    file_header header;
  };
  struct series_files {
    std::vector<found> files;
    std::size_t frames = 0;
  };
  std::map<std::string, series_files> series;
  std::size_t per_frame_items = 0;  // enhanced images' per-frame groups, over every file
  for (const fs::path& file : names) {
    input_file in(file, "DICOM");
    std::optional<file_header> h = file_parser(in).run();
    if (one_file && !h) {
      throw error(dir_name + ": not a DICOM Part 10 file (no \"DICM\" at byte 128)");
    }
    if (!h || !h->image) continue;
    per_frame_items += h->per_frame.size() + h->grid_offsets.size();
    if (per_frame_items > max_frame_groups) {
      throw error(dir_name + ": holds more than " + std::to_string(max_frame_groups) +
                  " frames placed one by one (per-frame functional groups, RT dose offsets) in "
                  "its multi-frame DICOM images");
    }
    series_files& list = series[h->series];
    list.frames += static_cast<std::size_t>(h->frames);
    if (list.frames > dicom_max_slices) {
      throw error(dir_name + ": holds more than " + std::to_string(dicom_max_slices) +
                  " DICOM images (frames) of one series");
    }
    list.files.push_back({file, std::move(*h)});
  }
  if (series.empty()) {
    throw error(dir_name + (one_file ? ": DICOM file holds no pixel data"
                                     : ": holds no DICOM image (expected DICOM Part 10 files "
                                       "with pixel data)"));
  }
  // The series: the only one, or the one chosen by UID or by number in UID order.
  const auto listing = [&] {
    std::string list;
    std::size_t number = 0;
    for (const auto& [uid, files] : series) {
      if (++number > 8) {
        list += ", …";
        break;
      }
      if (!list.empty()) list += ", ";
      list += std::to_string(number) + ": " + detail::quoted(uid, 64) + " (" +
              std::to_string(files.frames) + " images)";
    }
    return list;
  };
  auto picked = series.begin();
  if (chosen) {
    picked = series.find(*chosen);
    const auto number = to_integer<std::size_t>(*chosen);
    if (picked == series.end() && number && *number >= 1 && *number <= series.size()) {
      picked = std::next(series.begin(), static_cast<std::ptrdiff_t>(*number - 1));
    }
    if (picked == series.end()) {
      throw error(dir_name + ": holds no DICOM series " + detail::quoted(*chosen, 64) +
                  " (its series: " + listing() + ")");
    }
  } else if (series.size() > 1) {
    throw error(dir_name + ": holds " + std::to_string(series.size()) + " DICOM series (" +
                listing() + "), expected one: choose one by its number or UID");
  }
  std::vector<found>& files = picked->second.files;
  const file_header& first = files.front().header;
  const std::string first_name = files.front().file.string();
  const auto refuse = [](const std::string& name, const std::string& what) {
    throw error(name + ": " + what);
  };
  if (picked->second.frames < 2) {
    if (one_file) {
      refuse(dir_name,
             "one DICOM file is one slice: give the directory of its series instead (a file "
             "alone must be an enhanced multi-frame image)");
    }
    refuse(first_name, "the only DICOM image in " + dir_name +
                           ": a 2-D image, expected a series of at least 2 slices");
  }
  // What every file must share.
  for (const found& f : files) {
    const file_header& h = f.header;
    const std::string name = f.file.string();
    const auto frames = static_cast<std::size_t>(h.frames);
    if (h.frames > 1 && h.per_frame.empty() && !h.grid_offsets.empty() &&
        h.grid_offsets.size() != frames) {
      refuse(name, "an RT dose grid of " + std::to_string(h.frames) + " frames with " +
                       std::to_string(h.grid_offsets.size()) +
                       " offsets in GridFrameOffsetVector (3004,000C): expected one per frame");
    }
    if (h.frames > 1 && h.per_frame.size() != frames && h.grid_offsets.empty()) {
      refuse(name, "a multi-frame image of " + std::to_string(h.frames) + " frames with " +
                       std::to_string(h.per_frame.size()) +
                       " items in PerFrameFunctionalGroupsSequence (5200,9230): expected an "
                       "enhanced image that places each of its frames, or an RT dose grid "
                       "(GridFrameOffsetVector)");
    }
    if (h.samples != 1) {
      refuse(name, "has " + std::to_string(h.samples) + " samples per pixel (" + h.photometric +
                       "): expected 1 (MONOCHROME1 or MONOCHROME2)");
    }
    if (h.bits_allocated != 8 && h.bits_allocated != 16 && h.bits_allocated != 32) {
      refuse(name, "allocates " + std::to_string(h.bits_allocated) +
                       " bits per pixel, expected 8, 16 or 32");
    }
    if (h.bits_stored == 0 || h.bits_stored > h.bits_allocated) {
      refuse(name, "stores " + std::to_string(h.bits_stored) + " bits in " +
                       std::to_string(h.bits_allocated) + ", expected 1 to " +
                       std::to_string(h.bits_allocated));
    }
    if (h.pixel_representation > 1) {
      refuse(name, "has pixel representation " + std::to_string(h.pixel_representation) +
                       ", expected 0 (unsigned) or 1 (signed)");
    }
    if (h.rows < 2 || h.columns < 2) {
      refuse(name, "has " + std::to_string(h.rows) + " rows and " + std::to_string(h.columns) +
                       " columns, expected at least 2 of each");
    }
    const bool same = h.rows == first.rows && h.columns == first.columns &&
                      h.bits_allocated == first.bits_allocated &&
                      h.bits_stored == first.bits_stored &&
                      h.pixel_representation == first.pixel_representation;
    if (!same) {
      refuse(name, "differs from " + first_name + " in its rows, columns or bits (" +
                       std::to_string(h.columns) + "x" + std::to_string(h.rows) + ", " +
                       std::to_string(h.bits_allocated) + " bits, against " +
                       std::to_string(first.columns) + "x" + std::to_string(first.rows) + ", " +
                       std::to_string(first.bits_allocated) + ")");
    }
    const std::uint64_t frame = std::uint64_t{h.rows} * h.columns * (h.bits_allocated / 8);
    const std::uint64_t need = frame * static_cast<std::uint64_t>(h.frames);
    if (h.codec == dicom_codec::jpeg_lossless) {
      // Lossless JPEG codes every sample in at least one bit: the fragments bound the frames.
      const std::uint64_t samples =
          std::uint64_t{h.rows} * h.columns * static_cast<std::uint64_t>(h.frames);
      if (h.bits_allocated > 16) {
        refuse(name, "holds lossless JPEG of " + std::to_string(h.bits_allocated) +
                         "-bit pixels, expected 8 or 16 (JPEG holds at most 16 bits)");
      }
      if (h.pixel_length < samples / 8) {
        refuse(name, "holds " + std::to_string(h.pixel_length) +
                         " bytes of lossless JPEG data, too few for " + std::to_string(h.frames) +
                         " frames of " + std::to_string(h.columns) + "x" + std::to_string(h.rows) +
                         " (at least a bit a sample)");
      }
    } else if (h.codec == dicom_codec::jpeg2000) {
      // JPEG 2000 has no smallest code per sample; a codestream decoding to more than 4096
      // times its size is refused (jpeg2000_largest_expansion), so the fragments bound the
      // frames here as well.
      if (h.pixel_length < need / jpeg2000_largest_expansion) {
        refuse(name, "holds " + std::to_string(h.pixel_length) +
                         " bytes of JPEG 2000 data, too few for " + std::to_string(h.frames) +
                         " frames of " + std::to_string(h.columns) + "x" + std::to_string(h.rows) +
                         " (at most " + std::to_string(jpeg2000_largest_expansion) +
                         " bytes from each)");
      }
    } else if (h.codec == dicom_codec::rle) {
      // RLE's longest run, two bytes, makes 128: the fragments bound the frames.
      if (h.pixel_length < need / 64) {
        refuse(name, "holds " + std::to_string(h.pixel_length) +
                         " bytes of RLE data, too few for " + std::to_string(h.frames) +
                         " frames of " + std::to_string(h.columns) + "x" + std::to_string(h.rows) +
                         " (at most 64 bytes from each)");
      }
    } else if (h.pixel_length < need) {
      refuse(name, "holds " + std::to_string(h.pixel_length) + " bytes of pixel data, expected " +
                       std::to_string(need) + " (" +
                       (h.frames > 1 ? std::to_string(h.frames) + " frames of " : std::string()) +
                       std::to_string(h.columns) + "x" + std::to_string(h.rows) + " of " +
                       std::to_string(h.bits_allocated) + " bits)");
    }
  }
  // Every frame: placed, and placed like the first.
  struct placed {
    dicom_slice slice;
    frame_fields fields;
    double dose_scaling = 1.0;
    // The order among frames at one position (time points, echoes, stacks): TemporalPositionIndex,
    // else InstanceNumber, then the file (in name order) and the frame.
    std::array<double, 3> order{};
  };
  std::vector<placed> frames;
  frames.reserve(picked->second.frames);
  for (std::size_t file_index = 0; file_index < files.size(); ++file_index) {
    const found& f = files[file_index];
    const file_header& h = f.header;
    const std::uint64_t frame_bytes = std::uint64_t{h.rows} * h.columns * (h.bits_allocated / 8);
    for (std::int64_t k = 0; k < h.frames; ++k) {
      placed p;
      p.fields = h.frame(static_cast<std::size_t>(k));
      p.order = {
          p.fields.temporal ? static_cast<double>(*p.fields.temporal) : h.instance.value_or(0.0),
          static_cast<double>(file_index), static_cast<double>(k)};
      p.slice.file = f.file;
      p.slice.frame = h.frames > 1 ? k : -1;
      p.slice.pixel_offset = h.codec != dicom_codec::native
                                 ? h.pixel_offset
                                 : h.pixel_offset + static_cast<std::uint64_t>(k) * frame_bytes;
      p.slice.big_endian = h.big_endian;
      p.slice.codec = h.codec;
      p.dose_scaling = h.dose_scaling.value_or(1.0);
      frames.push_back(std::move(p));
    }
  }
  // An RT dose grid's frames: ImagePositionPatient moved along the normal by each offset of
  // GridFrameOffsetVector, relative when the first offset is 0, else (axial grids only) z
  // coordinates starting at ImagePositionPatient's; DoseGridScaling gives the dose.
  std::size_t at = 0;
  for (const found& f : files) {
    const file_header& h = f.header;
    const std::size_t count = static_cast<std::size_t>(h.frames);
    if (!h.per_frame.empty() || h.grid_offsets.empty()) {
      at += count;
      continue;
    }
    const frame_fields& g = frames[at].fields;
    if (!g.position || !g.orientation) {
      refuse(f.file.string(),
             "an RT dose grid without ImagePositionPatient (0020,0032) or "
             "ImageOrientationPatient (0020,0037): its frames cannot be placed");
    }
    const std::array<double, 6>& o = *g.orientation;
    const std::array<double, 3> n{o[1] * o[5] - o[2] * o[4], o[2] * o[3] - o[0] * o[5],
                                  o[0] * o[4] - o[1] * o[3]};
    const double first_offset = h.grid_offsets.front();
    const bool axial = std::abs(n[0]) < 1e-6 && std::abs(n[1]) < 1e-6 && n[2] > 1.0 - 1e-6;
    double base = 0.0;
    if (first_offset != 0.0) {
      if (!axial || std::abs(first_offset - (*g.position)[2]) > 1e-3) {
        refuse(f.file.string(),
               "an RT dose grid whose first GridFrameOffsetVector (3004,000C) "
               "offset " +
                   std::to_string(first_offset) +
                   " is neither 0 (relative offsets) nor, on an axial grid, "
                   "ImagePositionPatient's z (absolute ones)");
      }
      base = first_offset;
    }
    for (std::size_t k = 0; k < count; ++k) {
      std::array<double, 3> p = *g.position;
      for (std::size_t i = 0; i < 3; ++i) p[i] += n[i] * (h.grid_offsets[k] - base);
      frames[at + k].fields.position = p;
    }
    at += count;
  }
  const frame_fields& lead = frames.front().fields;
  const std::string lead_name = frames.front().slice.name();
  for (placed& p : frames) {
    const frame_fields& g = p.fields;
    const std::string name = p.slice.name();
    if (!g.position || !g.orientation) {
      refuse(name,
             "has no ImagePositionPatient (0020,0032) or ImageOrientationPatient "
             "(0020,0037): the slices cannot be placed");
    }
    if (!g.pixel_spacing || (*g.pixel_spacing)[0] <= 0.0 || (*g.pixel_spacing)[1] <= 0.0) {
      refuse(name, "has no positive PixelSpacing (0028,0030)");
    }
    if (g.slope.value_or(1.0) == 0.0) refuse(name, "has RescaleSlope 0");
    if (p.dose_scaling == 0.0) refuse(name, "has DoseGridScaling 0");
    for (std::size_t i = 0; i < 6; ++i) {
      if (std::abs((*g.orientation)[i] - (*lead.orientation)[i]) > 1e-4) {
        refuse(name, "has another ImageOrientationPatient than " + lead_name);
      }
    }
    for (std::size_t i = 0; i < 2; ++i) {
      if (std::abs((*g.pixel_spacing)[i] - (*lead.pixel_spacing)[i]) >
          1e-6 * (*lead.pixel_spacing)[i]) {
        refuse(name, "has another PixelSpacing than " + lead_name);
      }
    }
    p.slice.position = *g.position;
    p.slice.slope = g.slope.value_or(1.0) * p.dose_scaling;
    p.slice.intercept = g.intercept.value_or(0.0);
  }
  // Directions: DICOM gives the row direction (along a row: x), then the column direction.
  const std::array<double, 6>& o = *lead.orientation;
  const std::array<double, 3> row{o[0], o[1], o[2]};
  const std::array<double, 3> col{o[3], o[4], o[5]};
  std::array<double, 3> normal{row[1] * col[2] - row[2] * col[1], row[2] * col[0] - row[0] * col[2],
                               row[0] * col[1] - row[1] * col[0]};
  const double n = std::sqrt(dot(normal, normal));
  if (!(n > 0.5))
    refuse(lead_name, "has ImageOrientationPatient without two independent directions");
  for (double& v : normal) v /= n;

  for (placed& p : frames) p.slice.along = dot(p.slice.position, normal);
  std::sort(frames.begin(), frames.end(), [](const placed& a, const placed& b) {
    return a.slice.along != b.slice.along ? a.slice.along < b.slice.along : a.order < b.order;
  });
  // Several volumes in one series — time points of a 4-D CT or a cine MR, echoes, diffusion
  // directions — hold the same number of frames at every position: volume K is the K-th at each
  // (in the order above). Positions that hold different numbers are left to the spacing checks
  // below (a duplicated or missing slice).
  std::vector<std::size_t> starts;  // where each position's frames start
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (k == 0 || frames[k].slice.along - frames[starts.back()].slice.along > 1e-3) {
      starts.push_back(k);
    }
  }
  const std::size_t per_position = frames.size() / starts.size();
  bool uniform = per_position * starts.size() == frames.size();
  for (std::size_t g = 0; uniform && g < starts.size(); ++g) {
    const std::size_t end = g + 1 < starts.size() ? starts[g + 1] : frames.size();
    uniform = end - starts[g] == per_position;
  }
  const std::size_t volumes = uniform ? per_position : 1;
  const std::string last = std::to_string(volumes - 1);
  if (volume && (*volume < 0 || static_cast<std::uint64_t>(*volume) >= volumes)) {
    throw error(dir_name + ": volume " + std::to_string(*volume) + " was chosen, but the input " +
                (volumes == 1 ? std::string("holds one volume (0)")
                              : "is a time series of " + std::to_string(volumes) +
                                    " volumes (0 to " + last + ")"));
  }
  if (volumes > 1 && !volume) {
    throw error(dir_name + ": a time series of " + std::to_string(volumes) + " volumes (" +
                std::to_string(volumes) + " frames at each of " + std::to_string(starts.size()) +
                " positions): choose one by its index, 0 to " + last);
  }
  dicom_series s;
  s.slices.reserve(frames.size() / volumes);
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (volumes > 1 && (k % volumes) != static_cast<std::size_t>(*volume)) continue;
    s.scaled = s.scaled || frames[k].slice.slope != 1.0 || frames[k].slice.intercept != 0.0;
    s.slices.push_back(std::move(frames[k].slice));
  }
  if (s.slices.size() < 2) {
    refuse(s.slices.front().name(),
           "the only slice of its volume: a 2-D image, expected a "
           "series of at least 2 slices");
  }
  const double step =
      (s.slices.back().along - s.slices.front().along) / static_cast<double>(s.slices.size() - 1);
  const std::array<double, 2>& ps = *lead.pixel_spacing;
  if (!(step > 1e-6)) {
    refuse(s.slices.back().name(), "lies at the same position as " + s.slices.front().name() +
                                       ": expected slices at distinct positions along the normal");
  }
  for (std::size_t k = 1; k < s.slices.size(); ++k) {
    const double gap = s.slices[k].along - s.slices[k - 1].along;
    if (std::abs(gap - step) > std::max(1e-3, 0.01 * step)) {
      refuse(s.slices[k].name(), "lies " + std::to_string(gap) + " mm after " +
                                     s.slices[k - 1].name() + ", where the series' slices are " +
                                     std::to_string(step) +
                                     " mm apart on average: expected evenly spaced slices (a "
                                     "missing or duplicated slice?)");
    }
    // In-plane drift along the stack: a tilted gantry (positions off the normal).
    for (std::size_t i = 0; i < 3; ++i) {
      const double expected =
          s.slices[0].position[i] + normal[i] * (s.slices[k].along - s.slices[0].along);
      if (std::abs(s.slices[k].position[i] - expected) > 0.1 * std::min(ps[0], ps[1])) {
        refuse(s.slices[k].name(),
               "is offset in-plane from the slice normal (a tilted gantry?): "
               "expected positions along the normal of ImageOrientationPatient");
      }
    }
  }
  s.dims = {static_cast<std::int64_t>(first.columns), static_cast<std::int64_t>(first.rows),
            static_cast<std::int64_t>(s.slices.size())};
  s.stored = stored_type(first.bits_allocated, first.pixel_representation == 1);
  s.bits_stored = first.bits_stored;
  // PixelSpacing is (row spacing, column spacing): y then x.
  s.spacing = {ps[1], ps[0], step};
  s.origin = s.slices.front().position;
  for (std::size_t r = 0; r < 3; ++r) {
    s.world.m[r][0] = row[r] * ps[1];
    s.world.m[r][1] = col[r] * ps[0];
    s.world.m[r][2] = normal[r] * step;
    s.world.m[r][3] = s.origin[r];
  }
  return s;
}

namespace {

bool is_signed_type(sample_type t) noexcept {
  return t == sample_type::i8 || t == sample_type::i16 || t == sample_type::i32;
}

/// Writes frame `raw` (BitsAllocated-wide stored values, host order) into `dst` as the volume
/// holds it: masked to BitsStored, sign-extended, and rescaled when the series is.
void convert_frame(const dicom_series& s, const dicom_slice& d, const std::vector<std::byte>& raw,
                   std::byte* dst) {
  const std::size_t count = raw.size() / sample_size(s.stored);
  const bool is_signed = is_signed_type(s.stored);
  const auto convert = [&]<class U>(U) {
    for (std::size_t i = 0; i < count; ++i) {
      U word;
      std::memcpy(&word, raw.data() + i * sizeof word, sizeof word);
      const std::int64_t v = stored_value(word, s.bits_stored, is_signed);
      if (s.scaled) {
        const auto f = static_cast<float>(d.slope * static_cast<double>(v) + d.intercept);
        std::memcpy(dst + i * sizeof f, &f, sizeof f);
      } else if (is_signed) {
        // The stored type holds every masked, sign-extended value.
        using S = std::make_signed_t<U>;
        const auto x = static_cast<S>(v);
        std::memcpy(dst + i * sizeof x, &x, sizeof x);
      } else {
        const auto x = static_cast<U>(v);
        std::memcpy(dst + i * sizeof x, &x, sizeof x);
      }
    }
  };
  switch (sample_size(s.stored)) {
    case 1:
      convert(std::uint8_t{});
      break;
    case 2:
      convert(std::uint16_t{});
      break;
    default:
      convert(std::uint32_t{});
      break;
  }
}

/// The fragments of a file's encapsulated pixel data, joined, with where each starts; the first
/// item (the basic offset table) left out. Items are read up to the sequence delimiter, each
/// within the file.
struct fragments {
  std::vector<std::uint8_t> bytes;
  std::vector<std::size_t> starts;
};
fragments read_fragments(input_file& in, std::uint64_t at, const std::string& name) {
  fragments f;
  const auto fail = [&](const std::string& what) {
    throw error(name + ": DICOM file's encapsulated pixel data " + what);
  };
  bool offsets_table = true;
  for (;;) {
    if (in.size() < at || in.size() - at < 8) fail("ends before its sequence delimiter");
    std::array<unsigned char, 8> head{};
    in.seek(at);
    if (in.read(head.data(), head.size()) != head.size()) fail("ends inside an item");
    const std::uint32_t group = head[0] | (std::uint32_t{head[1]} << 8);
    const std::uint32_t element = head[2] | (std::uint32_t{head[3]} << 8);
    const std::uint32_t length = head[4] | (std::uint32_t{head[5]} << 8) |
                                 (std::uint32_t{head[6]} << 16) | (std::uint32_t{head[7]} << 24);
    at += 8;
    if (group == 0xfffe && element == 0xe0dd) return f;
    if (group != 0xfffe || element != 0xe000 || length == undefined_length) {
      fail("holds " + tag_text((group << 16) | element) + " where an item belongs");
    }
    if (in.size() - at < length) fail("holds an item past the file's end");
    if (!offsets_table) {
      f.starts.push_back(f.bytes.size());
      const std::size_t old = f.bytes.size();
      f.bytes.resize(old + length);
      if (in.read(f.bytes.data() + old, length) != length) fail("ends inside an item");
    }
    offsets_table = false;
    at += length;
  }
}

}  // namespace

std::vector<std::byte> read_dicom_samples(const dicom_series& s) {
  const std::size_t item = sample_size(s.stored);
  const auto frame_count = static_cast<std::size_t>(s.dims[0] * s.dims[1]);
  const std::size_t frame_bytes = frame_count * item;
  const std::size_t out_item = sample_size(s.volume_type());
  std::vector<std::byte> out(frame_count * s.slices.size() * out_item);
  std::vector<std::byte> frame(frame_bytes);
  const bool host_big = std::endian::native == std::endian::big;
  std::optional<input_file> in;  // the last slice's file: an enhanced image's frames share one
  const auto open = [&](const fs::path& file) -> input_file& {
    if (!in || in->path() != file) {
      in.reset();
      in.emplace(file, "DICOM");
    }
    return *in;
  };
  // Slices of compressed files, by file: (frame, slice) pairs, decoded after the others.
  std::map<fs::path, std::vector<std::pair<std::int64_t, std::size_t>>> packed;
  for (std::size_t k = 0; k < s.slices.size(); ++k) {
    const dicom_slice& d = s.slices[k];
    if (d.codec != dicom_codec::native) {
      packed[d.file].emplace_back(std::max<std::int64_t>(d.frame, 0), k);
      continue;
    }
    input_file& f = open(d.file);
    if (f.size() < d.pixel_offset || f.size() - d.pixel_offset < frame_bytes) {
      throw error(d.name() + ": DICOM file ends inside its pixel data (" +
                  std::to_string(f.size()) + " bytes, the frame needs " +
                  std::to_string(frame_bytes) + " from byte " + std::to_string(d.pixel_offset) +
                  ")");
    }
    f.seek(d.pixel_offset);
    if (f.read(frame.data(), frame.size()) != frame.size()) {
      throw error(d.name() + ": DICOM file ends inside its pixel data");
    }
    if (item > 1 && d.big_endian != host_big) swap_sample_bytes(frame, item);
    convert_frame(s, d, frame, out.data() + k * frame_count * out_item);
  }
  // Each compressed file's frames in order. JPEG: frame f starts at the first fragment at or
  // after the end of frame f − 1 (a fragment never holds two frames), so no offsets table is
  // needed. RLE: frame f is fragment f. JPEG 2000: frame f is the fragments from the f-th that
  // starts a codestream (or a JP2 file) up to the next such one.
  std::vector<std::uint16_t> decoded(frame_count);
  const auto rows = static_cast<std::uint32_t>(s.dims[1]);
  const auto columns = static_cast<std::uint32_t>(s.dims[0]);
  for (auto& [file, wanted] : packed) {
    std::sort(wanted.begin(), wanted.end());
    const std::string name = file.string();
    const dicom_slice& first = s.slices[wanted.front().second];
    const fragments data = read_fragments(open(file), first.pixel_offset, name);
    const bool rle = first.codec == dicom_codec::rle;
    const bool j2k = first.codec == dicom_codec::jpeg2000;
    std::vector<std::size_t> codestreams;  // JPEG 2000: where each frame's fragments start
    if (j2k) {
      for (const std::size_t at : data.starts) {
        if (starts_jpeg2000_frame(std::span(data.bytes).subspan(at))) codestreams.push_back(at);
      }
    }
    std::size_t end = 0;   // of the last frame decoded
    std::size_t next = 0;  // the next wanted entry
    for (std::int64_t f = 0; next < wanted.size(); ++f) {
      const std::vector<std::size_t>& starts = j2k ? codestreams : data.starts;
      const auto count = static_cast<std::int64_t>(starts.size());
      const auto start = rle || j2k ? starts.begin() + std::min(f, count)
                                    : std::lower_bound(starts.begin(), starts.end(), end);
      if (start == starts.end()) {
        throw error(name + ": DICOM file's encapsulated pixel data holds " + std::to_string(f) +
                    " frames, fewer than its NumberOfFrames");
      }
      try {
        const std::size_t stop = start + 1 == starts.end() ? data.bytes.size() : start[1];
        if (rle) {
          decode_dicom_rle(std::span(data.bytes).subspan(*start, stop - *start), item, frame);
        } else if (j2k) {
          decode_dicom_jpeg2000(std::span(data.bytes).subspan(*start, stop - *start), rows, columns,
                                item, s.bits_stored, is_signed_type(s.stored), frame);
        } else {
          end = decode_lossless_jpeg(data.bytes, *start, rows, columns,
                                     static_cast<unsigned>(item * 8), decoded);
        }
      } catch (const error& e) {
        throw error(name + " (frame " + std::to_string(f + 1) + "): " + e.what());
      }
      while (next < wanted.size() && wanted[next].first == f) {
        const std::size_t k = wanted[next++].second;
        if (!rle && !j2k) {
          for (std::size_t i = 0; i < frame_count; ++i) {
            if (item == 1) {
              frame[i] = static_cast<std::byte>(decoded[i]);
            } else {
              std::memcpy(frame.data() + 2 * i, &decoded[i], 2);
            }
          }
        }
        convert_frame(s, s.slices[k], frame, out.data() + k * frame_count * out_item);
      }
    }
  }
  return out;
}

bool has_dicom_preamble(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return false;
  try {
    input_file in(file, "DICOM");
    std::array<char, 132> head{};
    return in.read(head.data(), head.size()) == head.size() &&
           std::string_view(head.data() + 128, 4) == "DICM";
  } catch (const error&) {
    return false;
  }
}

}  // namespace progiso::detail
