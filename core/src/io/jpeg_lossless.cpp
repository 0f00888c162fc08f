#include <progiso/core/io/detail/jpeg_lossless.hpp>

#include <array>
#include <string>

#include <progiso/core/base/error.hpp>

namespace progiso::detail {
namespace {

[[noreturn]] void fail(const std::string& what) { throw error("JPEG stream " + what); }

/// A Huffman table (T.81 Annex C): codes of each length in canonical order.
struct huffman_table {
  bool defined = false;
  std::array<std::int32_t, 17> mincode{};  // by length 1..16
  std::array<std::int32_t, 17> maxcode{};  // −1: no code of that length
  std::array<std::int32_t, 17> first{};    // index of the length's first value
  std::array<std::uint8_t, 256> values{};
  // Codes of up to 9 bits by their next 9 bits: (length << 8) | value, 0 for a longer code.
  std::array<std::uint16_t, 512> fast{};
};

constexpr int fast_bits = 9;

/// The entropy-coded bits of a scan: byte stuffing (FF 00) removed, stopping at the first
/// marker. Past the data it supplies zero bits and counts them, so that a scan that needed them
/// is found out.
class bit_reader {
 public:
  bit_reader(std::span<const std::uint8_t> data, std::size_t at) : data_(data), pos_(at) {}

  std::uint32_t peek(int n) {
    if (bits_ < n) fill();
    return static_cast<std::uint32_t>(acc_ >> (64 - n));
  }
  void skip(int n) {
    acc_ <<= n;
    bits_ -= n;
  }
  std::uint32_t get(int n) {
    const std::uint32_t v = peek(n);
    skip(n);
    return v;
  }
  /// Whether the scan used bits beyond its data.
  [[nodiscard]] bool overran() const noexcept {
    return phantom_ > static_cast<std::uint64_t>(bits_);
  }
  /// Where the bytes after the scan start (its marker, or the end of the data).
  [[nodiscard]] std::size_t position() const noexcept { return pos_; }

 private:
  void fill() {
    while (bits_ <= 56) {
      std::uint8_t b = 0;
      if (!stopped_ && pos_ < data_.size()) {
        b = data_[pos_];
        if (b == 0xff) {
          if (pos_ + 1 < data_.size() && data_[pos_ + 1] == 0x00) {
            pos_ += 2;
          } else {
            stopped_ = true;  // a marker: the scan's end
            b = 0;
            phantom_ += 8;
          }
        } else {
          ++pos_;
        }
      } else {
        stopped_ = true;
        phantom_ += 8;
      }
      acc_ |= static_cast<std::uint64_t>(b) << (56 - bits_);
      bits_ += 8;
    }
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_;
  std::uint64_t acc_ = 0;
  int bits_ = 0;
  bool stopped_ = false;
  std::uint64_t phantom_ = 0;  // zero bits supplied past the scan's data
};

int decode_symbol(bit_reader& in, const huffman_table& t) {
  const std::uint16_t e = t.fast[in.peek(fast_bits)];
  if (e != 0) {
    in.skip(e >> 8);
    return e & 0xff;
  }
  for (int len = fast_bits + 1; len <= 16; ++len) {
    const auto code = static_cast<std::int32_t>(in.peek(len));
    if (t.maxcode[static_cast<std::size_t>(len)] >= code &&
        code >= t.mincode[static_cast<std::size_t>(len)]) {
      in.skip(len);
      const auto len_index = static_cast<std::size_t>(len);
      return t.values[static_cast<std::size_t>(t.first[len_index] + code - t.mincode[len_index])];
    }
  }
  fail("holds a Huffman code that its table does not define");
}

class decoder {
 public:
  decoder(std::span<const std::uint8_t> data, std::size_t at) : data_(data), pos_(at) {}

  std::size_t run(std::uint32_t rows, std::uint32_t columns, unsigned max_precision,
                  std::span<std::uint16_t> out) {
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
        if (u16(pos_) != 0) fail("uses restart intervals: not supported");
        pos_ = end;
      } else if (m == 0xda) {
        if (!frame) fail("holds a scan before its frame header (SOF3)");
        scan(out);
        // After the scan: fill bytes, then EOI.
        const int next = marker();
        if (next == 0xd9) return pos_;
        if (next >= 0xd0 && next <= 0xd7) fail("holds a restart marker: not supported");
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
    rows_ = rows;
    columns_ = columns;
    pos_ = end;
  }

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
      std::array<std::uint8_t, 16> counts{};
      std::size_t total = 0;
      for (std::size_t i = 0; i < 16; ++i) {
        counts[i] = data_[pos_ + 1 + i];
        total += counts[i];
      }
      if (total > 256 || end - pos_ - 17 < total) fail("holds a Huffman table cut short");
      const std::uint8_t* values = data_.data() + pos_ + 17;
      if (tc == 0) build(tables_[th], counts, values, total);  // lossless uses the DC tables
      pos_ += 17 + total;
    }
  }

  static void build(huffman_table& t, const std::array<std::uint8_t, 16>& counts,
                    const std::uint8_t* values, std::size_t total) {
    t = huffman_table{};
    std::int32_t code = 0;
    std::int32_t k = 0;
    for (int len = 1; len <= 16; ++len) {
      const auto l = static_cast<std::size_t>(len);
      const std::int32_t c = counts[l - 1];
      if (code + c > (std::int32_t{1} << len)) {
        fail("holds a Huffman table with more codes of " + std::to_string(len) +
             " bits than there are");
      }
      t.mincode[l] = code;
      t.maxcode[l] = c > 0 ? code + c - 1 : -1;
      t.first[l] = k;
      if (len <= fast_bits) {
        const int spare = fast_bits - len;
        for (std::int32_t i = 0; i < c; ++i) {
          const auto base = static_cast<std::uint32_t>(code + i) << spare;
          const auto entry =
              static_cast<std::uint16_t>((len << 8) | values[static_cast<std::size_t>(k + i)]);
          for (std::uint32_t f = 0; f < (1u << spare); ++f) t.fast[base | f] = entry;
        }
      }
      code = (code + c) << 1;
      k += c;
    }
    for (std::size_t i = 0; i < total; ++i) t.values[i] = values[i];
    t.defined = true;
  }

  void scan(std::span<std::uint16_t> out) {
    const std::size_t end = segment();
    if (end - pos_ < 1) fail("holds a scan header (SOS) too short");
    const unsigned ns = data_[pos_];
    if (ns != 1) fail("holds a scan of " + std::to_string(ns) + " components, expected 1");
    if (end - pos_ != 6) fail("holds a scan header (SOS) of the wrong length");
    if (data_[pos_ + 1] != component_) fail("scans a component its frame does not have");
    const unsigned td = data_[pos_ + 2] >> 4;
    const unsigned predictor = data_[pos_ + 3];
    const unsigned pt = data_[pos_ + 5] & 15u;
    if (td > 3 || !tables_[td].defined) {
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
    const huffman_table& table = tables_[td];
    const unsigned bits = precision_ - pt;
    const auto mask = static_cast<std::int32_t>((std::uint32_t{1} << bits) - 1);
    const std::size_t w = columns_;
    bit_reader in(data_, pos_);
    for (std::size_t y = 0; y < rows_; ++y) {
      std::uint16_t* row = out.data() + y * w;
      const std::uint16_t* above = y > 0 ? row - w : nullptr;
      for (std::size_t x = 0; x < w; ++x) {
        std::int32_t p = 0;
        if (above == nullptr) {
          p = x == 0 ? std::int32_t{1} << (bits - 1) : row[x - 1];
        } else if (x == 0) {
          p = above[0];
        } else {
          const std::int32_t ra = row[x - 1];
          const std::int32_t rb = above[x];
          const std::int32_t rc = above[x - 1];
          switch (predictor) {
            case 1:
              p = ra;
              break;
            case 2:
              p = rb;
              break;
            case 3:
              p = rc;
              break;
            case 4:
              p = ra + rb - rc;
              break;
            case 5:
              p = ra + ((rb - rc) >> 1);
              break;
            case 6:
              p = rb + ((ra - rc) >> 1);
              break;
            default:
              p = (ra + rb) >> 1;
              break;
          }
        }
        const int ssss = decode_symbol(in, table);
        std::int32_t diff = 0;
        if (ssss == 16) {
          diff = 32768;
        } else if (ssss > 16) {
          fail("holds a difference category " + std::to_string(ssss) + ", expected 0 to 16");
        } else if (ssss > 0) {
          const auto v = static_cast<std::int32_t>(in.get(ssss));
          diff = v < (std::int32_t{1} << (ssss - 1)) ? v - (std::int32_t{1} << ssss) + 1 : v;
        }
        row[x] = static_cast<std::uint16_t>((p + diff) & 0xffff & mask);
      }
    }
    if (in.overran()) fail("ends inside its scan (the data holds fewer samples than the image)");
    pos_ = in.position();
    if (pt > 0) {
      for (std::uint16_t& v : out) v = static_cast<std::uint16_t>(v << pt);
    }
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_;
  unsigned precision_ = 0;
  unsigned component_ = 0;
  std::uint32_t rows_ = 0;
  std::uint32_t columns_ = 0;
  std::array<huffman_table, 4> tables_{};
};

}  // namespace

std::size_t decode_lossless_jpeg(std::span<const std::uint8_t> data, std::size_t at,
                                 std::uint32_t rows, std::uint32_t columns, unsigned max_precision,
                                 std::span<std::uint16_t> out) {
  if (out.size() != std::size_t{rows} * columns) {
    throw error("JPEG decoder given " + std::to_string(out.size()) + " samples for " +
                std::to_string(columns) + "x" + std::to_string(rows));
  }
  return decoder(data, at).run(rows, columns, max_precision, out);
}

}  // namespace progiso::detail
