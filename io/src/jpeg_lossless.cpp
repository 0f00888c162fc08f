#include <progiso/io/detail/jpeg_lossless.hpp>

#include <array>
#include <mutex>
#include <string>
#include <vector>

// DCMTK's configuration header comes first, as its headers require.
#include <dcmtk/config/osconfig.h>
// Then its decoders (dcmjpeg, on the IJG libraries).
#include <dcmtk/dcmjpeg/djcparam.h>
#include <dcmtk/dcmjpeg/djdijg12.h>
#include <dcmtk/dcmjpeg/djdijg16.h>
#include <dcmtk/dcmjpeg/djdijg8.h>
#include <dcmtk/dcmjpeg/djutils.h>

#include <progiso/core/base/error.hpp>

namespace progiso::detail {
namespace {

[[noreturn]] void fail(const std::string& what) { throw error("JPEG stream " + what); }

/// Walks a lossless JPEG stream's headers and checks them (see the header), and finds the end
/// of its scan: the decoding itself is DCMTK's.
class stream_check {
 public:
  stream_check(std::span<const std::uint8_t> data, std::size_t at) : data_(data), pos_(at) {}

  /// Returns the offset just past the EOI marker.
  std::size_t run(std::uint32_t rows, std::uint32_t columns, unsigned max_precision) {
    if (marker() != 0xd8) fail("does not start with SOI (FF D8)");
    bool frame = false;
    for (;;) {
      const int m = marker();
      if (m == 0xc3) {
        if (frame) fail("holds more than one frame header");
        read_frame(rows, columns, max_precision);
        frame = true;
      } else if (m == 0xc4) {
        read_tables();
      } else if (m == 0xdd) {
        const std::size_t end = segment();
        if (end - pos_ != 2) fail("holds a DRI segment of the wrong length");
        pos_ = end;
      } else if (m == 0xda) {
        if (!frame) fail("holds a scan before its frame header (SOF3)");
        scan_header();
        skip_entropy_coded_data();
        // After the scan: fill bytes, then EOI.
        const int next = marker();
        if (next == 0xd9) return pos_;
        fail("holds more than one scan, or no EOI after its scan (found marker FF " + hex(next) +
             ")");
      } else if ((m >= 0xe0 && m <= 0xef) || m == 0xfe || m == 0xdb) {
        pos_ = segment();  // APPn, COM, DQT (unused by lossless coding)
      } else if (m == 0xc0 || m == 0xc1 || m == 0xc2 ||
                 (m >= 0xc5 && m <= 0xcf && m != 0xc8 && m != 0xcc)) {
        fail("uses the JPEG process of marker FF " + hex(m) +
             " (expected lossless process 14, SOF3: FF C3)");
      } else if (m == 0xd9) {
        fail("ends (EOI) before its scan");
      } else {
        fail("holds the marker FF " + hex(m) + " where lossless JPEG has none");
      }
    }
  }

  [[nodiscard]] unsigned precision() const noexcept { return precision_; }

 private:
  static std::string hex(int v) {
    static constexpr char digits[] = "0123456789ABCDEF";
    return {digits[(v >> 4) & 15], digits[v & 15]};
  }
  std::uint32_t u16(std::size_t at) const {
    if (at + 2 > data_.size()) fail("ends inside a segment");
    return (std::uint32_t{data_[at]} << 8) | data_[at + 1];
  }
  /// The next marker's code, after any fill bytes (FF); fails at the end of the data or at a
  /// byte that is not a marker.
  int marker() {
    if (pos_ >= data_.size()) fail("ends before its EOI marker");
    if (data_[pos_] != 0xff) {
      fail("holds byte " + hex(data_[pos_]) + " at " + std::to_string(pos_) +
           " where a marker belongs");
    }
    while (pos_ < data_.size() && data_[pos_] == 0xff) ++pos_;
    if (pos_ >= data_.size()) fail("ends before its EOI marker");
    return data_[pos_++];
  }
  /// The end of the segment whose length field is at pos_; pos_ moves past the length.
  std::size_t segment() {
    const std::uint32_t length = u16(pos_);
    if (length < 2 || pos_ + length > data_.size()) {
      fail("holds a segment of " + std::to_string(length) + " bytes at " + std::to_string(pos_) +
           " that does not fit in its " + std::to_string(data_.size()) + " bytes");
    }
    const std::size_t end = pos_ + length;
    pos_ += 2;
    return end;
  }

  void read_frame(std::uint32_t rows, std::uint32_t columns, unsigned max_precision) {
    const std::size_t end = segment();
    if (end - pos_ < 6) fail("holds a frame header (SOF3) too short");
    precision_ = data_[pos_];
    const std::uint32_t lines = u16(pos_ + 1);
    const std::uint32_t samples = u16(pos_ + 3);
    const unsigned components = data_[pos_ + 5];
    if (precision_ < 2 || precision_ > 16 || precision_ > max_precision) {
      fail("has precision " + std::to_string(precision_) + ", expected 2 to " +
           std::to_string(max_precision) + " bits");
    }
    if (components != 1) {
      fail("has " + std::to_string(components) + " components, expected 1 (a grey image)");
    }
    if (end - pos_ != 9) fail("holds a frame header (SOF3) of the wrong length");
    if (lines != rows || samples != columns) {
      fail("holds an image of " + std::to_string(samples) + "x" + std::to_string(lines) +
           " samples, expected " + std::to_string(columns) + "x" + std::to_string(rows));
    }
    component_ = data_[pos_ + 6];
    pos_ = end;
  }

  /// Huffman tables: each must fit its segment and hold no more codes of a length than there
  /// are; the DC tables (the ones lossless coding uses) are noted as defined.
  void read_tables() {
    const std::size_t end = segment();
    while (pos_ < end) {
      const unsigned tc_th = data_[pos_];
      const unsigned tc = tc_th >> 4;
      const unsigned th = tc_th & 15u;
      if (tc > 1 || th > 3)
        fail("holds a Huffman table of class " + std::to_string(tc) + " and destination " +
             std::to_string(th));
      if (end - pos_ < 17) fail("holds a Huffman table cut short");
      std::size_t total = 0;
      std::uint32_t code = 0;
      for (std::size_t len = 1; len <= 16; ++len) {
        const std::uint32_t c = data_[pos_ + len];
        total += c;
        if (code + c > (std::uint32_t{1} << len)) {
          fail("holds a Huffman table with more codes of " + std::to_string(len) +
               " bits than there are");
        }
        code = (code + c) << 1;
      }
      if (total > 256 || end - pos_ - 17 < total) fail("holds a Huffman table cut short");
      if (tc == 0) defined_[th] = true;
      pos_ += 17 + total;
    }
  }

  void scan_header() {
    const std::size_t end = segment();
    if (end - pos_ < 1) fail("holds a scan header (SOS) too short");
    const unsigned ns = data_[pos_];
    if (ns != 1) fail("holds a scan of " + std::to_string(ns) + " components, expected 1");
    if (end - pos_ != 6) fail("holds a scan header (SOS) of the wrong length");
    if (data_[pos_ + 1] != component_) fail("scans a component its frame does not have");
    const unsigned td = data_[pos_ + 2] >> 4;
    const unsigned predictor = data_[pos_ + 3];
    const unsigned pt = data_[pos_ + 5] & 15u;
    if (td > 3 || !defined_[td]) {
      fail("uses Huffman table " + std::to_string(td) + ", which it does not define");
    }
    if (predictor < 1 || predictor > 7) {
      fail("uses predictor " + std::to_string(predictor) + ", expected 1 to 7");
    }
    if (pt >= precision_) {
      fail("has point transform " + std::to_string(pt) + " at precision " +
           std::to_string(precision_));
    }
    pos_ = end;
  }

  /// Moves to the first marker after the scan's entropy-coded bytes: there an FF is followed
  /// by 00 (a stuffed byte) or by a restart marker (D0 to D7), and by anything else only at a
  /// marker.
  void skip_entropy_coded_data() {
    for (;;) {
      while (pos_ < data_.size() && data_[pos_] != 0xff) ++pos_;
      if (pos_ + 1 >= data_.size()) fail("ends inside its scan, before its EOI marker");
      const std::uint8_t next = data_[pos_ + 1];
      if (next == 0x00 || (next >= 0xd0 && next <= 0xd7)) {
        pos_ += 2;
      } else if (next == 0xff) {
        ++pos_;  // a fill byte before a marker, or before FF 00
      } else {
        return;
      }
    }
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_;
  unsigned precision_ = 0;
  unsigned component_ = 0;
  std::array<bool, 4> defined_{};
};

/// DCMTK logs its decoders' complaints to stderr: a reader that refuses a file says so in its
/// one error, so dcmjpeg's log is switched off, once.
void silence_dcmjpeg_log() {
  static std::once_flag once;
  std::call_once(once, [] { DCM_dcmjpegLogger.setLogLevel(OFLogger::OFF_LOG_LEVEL); });
}

/// Decodes the checked stream with DCMTK's IJG decoder for its precision (the 8-bit library up
/// to 8 bits, the 12-bit one up to 12, the 16-bit one above), into `out`.
void decode_with_dcmtk(std::span<const std::uint8_t> stream, unsigned precision,
                       std::span<std::uint16_t> out) {
  silence_dcmjpeg_log();
  const DJCodecParameter parameters(ECC_monochrome, EDC_never, EUC_never, EPC_default);
  // DCMTK's decode() takes a mutable buffer; the stream is copied rather than cast.
  std::vector<Uint8> in(stream.begin(), stream.end());
  const auto in_size = static_cast<Uint32>(in.size());
  OFCondition result;
  if (precision <= 8) {
    std::vector<Uint8> bytes(out.size());
    DJDecompressIJG8Bit decoder(parameters, OFFalse);
    result = decoder.init();
    if (result.good()) {
      result = decoder.decode(in.data(), in_size, bytes.data(), static_cast<Uint32>(bytes.size()),
                              OFFalse);
    }
    if (result.good()) {
      for (std::size_t i = 0; i < out.size(); ++i) out[i] = bytes[i];
    }
  } else {
    auto* bytes = reinterpret_cast<Uint8*>(out.data());
    const auto size = static_cast<Uint32>(out.size_bytes());
    if (precision <= 12) {
      DJDecompressIJG12Bit decoder(parameters, OFFalse);
      result = decoder.init();
      if (result.good()) result = decoder.decode(in.data(), in_size, bytes, size, OFFalse);
    } else {
      DJDecompressIJG16Bit decoder(parameters, OFFalse);
      result = decoder.init();
      if (result.good()) result = decoder.decode(in.data(), in_size, bytes, size, OFFalse);
    }
  }
  if (result.bad()) fail(std::string("could not be decoded: ") + result.text());
}

}  // namespace

std::size_t decode_lossless_jpeg(std::span<const std::uint8_t> data, std::size_t at,
                                 std::uint32_t rows, std::uint32_t columns, unsigned max_precision,
                                 std::span<std::uint16_t> out) {
  if (out.size() != std::size_t{rows} * columns) {
    throw error("JPEG decoder given " + std::to_string(out.size()) + " samples for " +
                std::to_string(columns) + "x" + std::to_string(rows));
  }
  stream_check check(data, at);
  const std::size_t end = check.run(rows, columns, max_precision);
  decode_with_dcmtk(data.subspan(at, end - at), check.precision(), out);
  return end;
}

}  // namespace progiso::detail
