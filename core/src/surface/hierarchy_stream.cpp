// Hierarchy streams: the encoder, the validating decoder and the cuts of a decoded stream.

#include <progiso/core/surface/hierarchy_stream.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <utility>

#include <progiso/core/surface/detail/cut_mesher.hpp>

namespace progiso {

namespace {

// Chunk types.
constexpr char chunk_header = 'H';
constexpr char chunk_root = 'R';
constexpr char chunk_splits = 'S';
constexpr char chunk_end = 'E';
// The header chunk's payload: dims (3 u32), type (u8), spacing, origin (6 f64), isovalue.
constexpr std::size_t header_payload = 12 + 1 + 48 + 8;
// Record head byte: groups in bits 0-4, bit 5 set when the error is stored as a double.
constexpr unsigned head_double_error = 0x20;
constexpr unsigned max_groups = 16;  // one per child tetrahedron with surface: 2 × 8
// Doubled coordinates of edge keys stay below 2^21 (edge_key_bits), so grids below 2^20.
constexpr std::int64_t max_axis = std::int64_t{1} << 20;

// CRC-32 (ISO 3309 / zlib: reflected polynomial 0xEDB88320), by a table made at compile time.
constexpr std::array<std::uint32_t, 256> crc_table = [] {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[i] = c;
  }
  return t;
}();

std::uint32_t crc32(std::uint32_t crc, const std::byte* p, std::size_t n) noexcept {
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) {
    crc = crc_table[(crc ^ static_cast<std::uint32_t>(p[i])) & 0xFFu] ^ (crc >> 8);
  }
  return ~crc;
}

// Little-endian appends.
template <class T>
void put(std::vector<std::byte>& out, T v) {
  static_assert(std::is_trivially_copyable_v<T>);
  std::array<std::byte, sizeof(T)> b{};
  std::memcpy(b.data(), &v, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(b.begin(), b.end());
  // resize and copy rather than insert(): gcc 12 at -O3 reports a false bounds overflow in
  // vector::insert of a small array (-Wstringop-overflow).
  const std::size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, b.data(), sizeof(T));
}
void put_varint(std::vector<std::byte>& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<std::byte>((v & 0x7Fu) | 0x80u));
    v >>= 7;
  }
  out.push_back(static_cast<std::byte>(v));
}
// A sample in the stream's type (exact: the value came from a sample of that type).
void put_sample(std::vector<std::byte>& out, sample_type t, double v) {
  switch (t) {
    case sample_type::u8:
      return put(out, static_cast<std::uint8_t>(v));
    case sample_type::i8:
      return put(out, static_cast<std::int8_t>(v));
    case sample_type::u16:
      return put(out, static_cast<std::uint16_t>(v));
    case sample_type::i16:
      return put(out, static_cast<std::int16_t>(v));
    case sample_type::u32:
      return put(out, static_cast<std::uint32_t>(v));
    case sample_type::i32:
      return put(out, static_cast<std::int32_t>(v));
    case sample_type::f32:
      return put(out, static_cast<float>(v));
    case sample_type::f64:
      return put(out, v);
  }
}
// Whether v is a value of type t (so that put_sample keeps it exactly).
bool fits_sample(sample_type t, double v) {
  if (!std::isfinite(v)) return false;
  const auto in = [v](double lo, double hi) { return v >= lo && v <= hi && v == std::floor(v); };
  switch (t) {
    case sample_type::u8:
      return in(0, 255);
    case sample_type::i8:
      return in(-128, 127);
    case sample_type::u16:
      return in(0, 65535);
    case sample_type::i16:
      return in(-32768, 32767);
    case sample_type::u32:
      return in(0, 4294967295.0);
    case sample_type::i32:
      return in(-2147483648.0, 2147483647.0);
    case sample_type::f32:  // range first: a cast out of float's range is undefined
      return std::fabs(v) <= static_cast<double>(std::numeric_limits<float>::max()) &&
             static_cast<double>(static_cast<float>(v)) == v;
    case sample_type::f64:
      return true;
  }
  return false;
}

std::uint64_t zigzag(std::int64_t v) noexcept {
  return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63);
}
std::int64_t unzigzag(std::uint64_t v) noexcept {
  return static_cast<std::int64_t>(v >> 1) ^ -static_cast<std::int64_t>(v & 1);
}

using detail::root_corner;
using detail::root_corner_count;

std::uint64_t point_key(const ipoint& p) noexcept { return edge_key(p, p); }

// The header as a reader accepts it, or the reason it does not.
std::string header_problem(const hierarchy_stream_header& h) {
  for (std::size_t q = 0; q < 3; ++q) {
    if (h.dims[q] < 2 || h.dims[q] >= max_axis) {
      return "dims between 2 and " + std::to_string(max_axis - 1) + ", found " +
             std::to_string(h.dims[0]) + "x" + std::to_string(h.dims[1]) + "x" +
             std::to_string(h.dims[2]);
    }
    if (!std::isfinite(h.spacing[q]) || !(h.spacing[q] > 0.0) || !std::isfinite(h.origin[q])) {
      return "a finite positive spacing and a finite origin";
    }
  }
  if (static_cast<unsigned>(h.type) > static_cast<unsigned>(sample_type::f64)) {
    return "a sample type code from 0 to 7";
  }
  if (!std::isfinite(h.isovalue)) return "a finite isovalue";
  return {};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Writer

hierarchy_stream_writer::hierarchy_stream_writer(sink out, const hierarchy_stream_header& header,
                                                 std::span<const double> root_corner_values,
                                                 std::span<const owned_triangle> root_triangles)
    : out_(std::move(out)), header_(header) {
  if (const std::string why = header_problem(header); !why.empty()) {
    throw error("hierarchy stream: expected " + why);
  }
  const hierarchy hier(header.dims);
  if (hier.grid_max()[0] >= max_axis || hier.grid_max()[1] >= max_axis ||
      hier.grid_max()[2] >= max_axis) {
    throw error("hierarchy stream: the grid of " + std::to_string(header.dims[0]) + "x" +
                std::to_string(header.dims[1]) + "x" + std::to_string(header.dims[2]) +
                " is too large for edge keys");
  }
  if (root_corner_values.size() != root_corner_count(hier)) {
    throw error("hierarchy stream: expected " + std::to_string(root_corner_count(hier)) +
                " root corner samples, found " + std::to_string(root_corner_values.size()));
  }
  std::vector<std::byte> magic(8);
  std::memcpy(magic.data(), hierarchy_stream_magic.data(), 8);
  put(magic, hierarchy_stream_version);
  out_(magic);
  bytes_ += magic.size();

  std::vector<std::byte> p;
  for (const std::int64_t d : header.dims) put(p, static_cast<std::uint32_t>(d));
  put(p, static_cast<std::uint8_t>(header.type));
  for (const double s : header.spacing) put(p, s);
  for (const double o : header.origin) put(p, o);
  put(p, header.isovalue);
  emit(chunk_header, p);

  p.clear();
  put(p, static_cast<std::uint32_t>(root_corner_values.size()));
  for (const double v : root_corner_values) {
    if (!fits_sample(header.type, v)) {
      throw error("hierarchy stream: a root corner sample " + std::to_string(v) +
                  " is not a value of the stream's sample type");
    }
    put_sample(p, header.type, v);
  }
  put(p, static_cast<std::uint32_t>(root_triangles.size()));
  for (const owned_triangle& t : root_triangles) {
    put(p, t.owner);
    for (const std::uint64_t k : t.keys) put(p, k);
  }
  emit(chunk_root, p);
}

void hierarchy_stream_writer::add(const hierarchy_stream_record& r) {
  PROGISO_ASSERT(!finished_);
  PROGISO_ASSERT(r.groups.size() <= max_groups);
  if (!fits_sample(header_.type, r.value)) {
    throw error("hierarchy stream: the sample " + std::to_string(r.value) + " at diamond " +
                std::to_string(r.diamond) + " is not a value of the stream's sample type");
  }
  put_varint(batch_, zigzag(static_cast<std::int64_t>(r.diamond - previous_)));
  previous_ = r.diamond;
  // Most errors of integer data (half-integers) and many others are floats exactly.
  const bool as_float = fits_sample(sample_type::f32, r.error);
  put(batch_, static_cast<std::uint8_t>(r.groups.size() | (as_float ? 0u : head_double_error)));
  put_varint(batch_, r.crossed);
  put_sample(batch_, header_.type, r.value);
  if (as_float) {
    put(batch_, static_cast<float>(r.error));
  } else {
    put(batch_, r.error);
  }
  for (const packed_group& g : r.groups) put(batch_, g.bits);
  ++records_;
  if (++batch_records_ == chunk_records) flush();
}

void hierarchy_stream_writer::flush() {
  if (batch_records_ == 0) return;
  std::vector<std::byte> p;
  p.reserve(batch_.size() + 4);
  put(p, batch_records_);
  p.insert(p.end(), batch_.begin(), batch_.end());
  emit(chunk_splits, p);
  batch_.clear();
  batch_records_ = 0;
}

void hierarchy_stream_writer::finish() {
  if (finished_) return;
  flush();
  std::vector<std::byte> p;
  put(p, records_);
  emit(chunk_end, p);
  finished_ = true;
}

void hierarchy_stream_writer::emit(char type, const std::vector<std::byte>& payload) {
  if (payload.size() > std::numeric_limits<std::uint32_t>::max()) {
    throw error("hierarchy stream: a chunk of " + std::to_string(payload.size()) +
                " bytes is larger than 4 GiB");
  }
  std::vector<std::byte> c;
  c.reserve(payload.size() + 9);
  c.push_back(static_cast<std::byte>(type));
  put(c, static_cast<std::uint32_t>(payload.size()));
  c.insert(c.end(), payload.begin(), payload.end());
  put(c, crc32(0, c.data(), c.size()));
  out_(c);
  bytes_ += c.size();
}

// ---------------------------------------------------------------------------------------------
// Decoder

// Reads one chunk's payload (or the magic) with bounds checks; every error names the byte.
class byte_reader {
 public:
  byte_reader(std::span<const std::byte> b, std::size_t base) : b_(b), base_(base) {}
  [[noreturn]] void fail(const std::string& expected, const std::string& found) const {
    throw error("hierarchy stream: byte " + std::to_string(base_ + at_) + ": expected " + expected +
                ", found " + found);
  }
  [[nodiscard]] std::size_t left() const noexcept { return b_.size() - at_; }
  [[nodiscard]] std::size_t offset() const noexcept { return base_ + at_; }
  void need(std::size_t n, const char* what) const {
    if (left() < n) fail(what, "the chunk's end");
  }
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    std::array<std::byte, sizeof(T)> v{};
    std::memcpy(v.data(), b_.data() + at_, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) std::reverse(v.begin(), v.end());
    at_ += sizeof(T);
    return std::bit_cast<T>(v);
  }
  std::uint64_t varint(const char* what) {
    std::uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const auto b = static_cast<std::uint64_t>(get<std::uint8_t>(what));
      if (shift == 63 && b > 1) break;
      v |= (b & 0x7Fu) << shift;
      if ((b & 0x80u) == 0) return v;
    }
    fail(what, "a variable-length integer of more than 64 bits");
  }
  double sample(sample_type t) {
    switch (t) {
      case sample_type::u8:
        return get<std::uint8_t>("a sample");
      case sample_type::i8:
        return get<std::int8_t>("a sample");
      case sample_type::u16:
        return get<std::uint16_t>("a sample");
      case sample_type::i16:
        return get<std::int16_t>("a sample");
      case sample_type::u32:
        return get<std::uint32_t>("a sample");
      case sample_type::i32:
        return get<std::int32_t>("a sample");
      case sample_type::f32:
        return static_cast<double>(get<float>("a sample"));
      case sample_type::f64:
        return get<double>("a sample");
    }
    return 0.0;
  }

 private:
  std::span<const std::byte> b_;
  std::size_t base_;
  std::size_t at_ = 0;
};

struct stream_decoder {
  static hierarchy_stream decode(std::span<const std::byte> bytes, std::uint64_t max_records);
};

hierarchy_stream hierarchy_stream::decode(std::span<const std::byte> bytes,
                                          std::uint64_t max_records) {
  return stream_decoder::decode(bytes, max_records);
}

namespace {

// The offset codes of a diamond's points that are its new edges' far ends (spine ends and ring
// vertices in the grid): the bits split_summary::crossed may hold.
std::uint32_t new_edge_codes(const diamond& d) noexcept {
  const auto code = [&d](const ipoint& p) {
    return edge_offset_code({(p[0] - d.centre[0]) / d.scale, (p[1] - d.centre[1]) / d.scale,
                             (p[2] - d.centre[2]) / d.scale});
  };
  std::uint32_t m = (1u << code(d.spine[0])) | (1u << code(d.spine[1]));
  for (int k = 0; k < d.ring_size; ++k) {
    if (((d.ring_in_grid >> k) & 1u) != 0) m |= 1u << code(d.ring[static_cast<std::size_t>(k)]);
  }
  return m;
}

}  // namespace

hierarchy_stream stream_decoder::decode(std::span<const std::byte> bytes,
                                        std::uint64_t max_records) {
  byte_reader top(bytes, 0);
  top.need(12, "the 8-byte magic PROGISOH and a version");
  if (std::memcmp(bytes.data(), hierarchy_stream_magic.data(), 8) != 0) {
    top.fail("the magic PROGISOH", "other bytes (not a progiso hierarchy stream)");
  }
  (void)top.get<std::uint64_t>("the magic");
  const auto version = top.get<std::uint32_t>("a version");
  if (version != hierarchy_stream_version) {
    byte_reader(bytes, 8).fail("version " + std::to_string(hierarchy_stream_version),
                               "version " + std::to_string(version));
  }
  std::size_t at = 12;

  // The next chunk: its type and payload, after checking its length and CRC.
  const auto next_chunk = [&](char& type) -> std::span<const std::byte> {
    byte_reader r(bytes.subspan(at), at);
    r.need(5, "a chunk's type and length");
    type = static_cast<char>(r.get<std::uint8_t>("a chunk type"));
    const auto length = r.get<std::uint32_t>("a chunk length");
    if (r.left() < std::size_t{length} + 4) {
      r.fail("a chunk of " + std::to_string(length) + " bytes and its CRC",
             "the stream's end after " + std::to_string(r.left()) + " bytes (truncated)");
    }
    const std::span<const std::byte> payload = bytes.subspan(at + 5, length);
    byte_reader crc_at(bytes.subspan(at + 5 + length, 4), at + 5 + length);
    const auto stored = crc_at.get<std::uint32_t>("a CRC");
    const std::uint32_t computed = crc32(0, bytes.data() + at, 5 + std::size_t{length});
    if (stored != computed) {
      crc_at.fail("the chunk's CRC-32 " + std::to_string(computed),
                  std::to_string(stored) + " (corrupt chunk)");
    }
    at += 5 + std::size_t{length} + 4;
    return payload;
  };

  char type = 0;
  std::size_t chunk_at = at;
  std::span<const std::byte> p = next_chunk(type);
  if (type != chunk_header) {
    byte_reader(bytes, chunk_at).fail("the header chunk 'H'", std::string("chunk '") + type + "'");
  }
  byte_reader hr(p, chunk_at + 5);
  if (p.size() != header_payload) {
    hr.fail("a header of " + std::to_string(header_payload) + " bytes",
            std::to_string(p.size()) + " bytes");
  }
  hierarchy_stream_header h;
  for (std::int64_t& d : h.dims) d = hr.get<std::uint32_t>("dims");
  const auto type_code = hr.get<std::uint8_t>("a sample type");
  h.type = static_cast<sample_type>(type_code);
  for (double& s : h.spacing) s = hr.get<double>("a spacing");
  for (double& o : h.origin) o = hr.get<double>("an origin");
  h.isovalue = hr.get<double>("an isovalue");
  if (type_code > static_cast<unsigned>(sample_type::f64)) {
    hr.fail("a sample type code from 0 to 7", std::to_string(type_code));
  }
  if (const std::string why = header_problem(h); !why.empty()) hr.fail(why, "other values");
  hierarchy_stream s(h);
  const hierarchy& hier = s.hier_;
  if (hier.grid_max()[0] >= max_axis || hier.grid_max()[1] >= max_axis ||
      hier.grid_max()[2] >= max_axis) {
    hr.fail("a grid below 2^20 per axis", "dims that pad beyond it");
  }
  const std::int32_t n = hier.root_size();

  // Root chunk.
  chunk_at = at;
  p = next_chunk(type);
  if (type != chunk_root) {
    byte_reader(bytes, chunk_at).fail("the root chunk 'R'", std::string("chunk '") + type + "'");
  }
  byte_reader rr(p, chunk_at + 5);
  const std::uint64_t corners = root_corner_count(hier);
  const auto stored_corners = rr.get<std::uint32_t>("a root corner count");
  if (stored_corners != corners) {
    rr.fail(std::to_string(corners) + " root corners for these dims",
            std::to_string(stored_corners));
  }
  rr.need(corners * sample_size(h.type), "the root corners' samples");
  s.values_.reserve(corners);
  s.vertex_slot_ = detail::flat_map(corners + 16);
  for (std::uint64_t i = 0; i < corners; ++i) {
    const double v = rr.sample(h.type);
    if (!std::isfinite(v)) rr.fail("a finite sample", "a non-finite one");
    s.vertex_slot_.try_emplace(point_key(root_corner(hier, i)),
                               static_cast<std::uint32_t>(s.values_.size()));
    s.values_.push_back(v);
  }
  const auto triangles = rr.get<std::uint32_t>("a root triangle count");
  if (rr.left() != std::size_t{triangles} * 32) {
    rr.fail(std::to_string(triangles) + " root triangles of 32 bytes",
            std::to_string(rr.left()) + " bytes");
  }
  s.root_triangles_.reserve(triangles);
  for (std::uint32_t i = 0; i < triangles; ++i) {
    owned_triangle t{};
    t.owner = rr.get<std::uint64_t>("a root triangle's owner");
    for (std::uint64_t& k : t.keys) k = rr.get<std::uint64_t>("an edge key");
    // The owner: the root diamond of the triangle's cube (none when the root cubes are cells).
    ipoint lo{};
    if (n == 1) {
      if (t.owner != no_owner) rr.fail("no owner (root cubes of one cell)", "an owner");
    } else {
      const ipoint c = t.owner < hier.vertex_count() ? hier.point(t.owner) : ipoint{-1, -1, -1};
      const std::int32_t half = n / 2;
      for (std::size_t q = 0; q < 3; ++q) {
        if (c[q] < 0 || c[q] % n != half || c[q] > hier.grid_max()[q]) {
          rr.fail("a root cube's centre as a root triangle's owner",
                  "grid index " + std::to_string(t.owner));
        }
        lo[q] = c[q] - half;
      }
    }
    for (const std::uint64_t k : t.keys) {
      bool ok = k < (std::uint64_t{1} << (3 * edge_key_bits));
      if (ok) {
        const auto ends = hier.edge_ends(k);
        ok = ends[0] != ends[1] && edge_key(ends[0], ends[1]) == k;
        for (const ipoint& e : ends) {
          for (std::size_t q = 0; q < 3 && ok; ++q) {
            ok = n == 1 ? (e[q] >= 0 && e[q] <= hier.grid_max()[q])
                        : (e[q] == lo[q] || e[q] == lo[q] + n);
          }
        }
      }
      if (!ok)
        rr.fail("an edge between two corners of the owner's root cube", "key " + std::to_string(k));
    }
    s.root_triangles_.push_back(t);
  }
  s.records_.push_back(hierarchy_stream::record{no_owner,
                                                nullptr,
                                                static_cast<std::uint32_t>(triangles),
                                                0,
                                                0,
                                                std::numeric_limits<double>::infinity(),
                                                {},
                                                0});

  // Record chunks, then the end mark.
  std::vector<std::uint64_t> group_at{0};  // per record: its first group in groups_
  std::uint64_t previous = 0;
  while (at < bytes.size()) {
    chunk_at = at;
    p = next_chunk(type);
    if (type == chunk_end) {
      byte_reader er(p, chunk_at + 5);
      const auto total = er.get<std::uint64_t>("the record count");
      if (er.left() != 0) er.fail("an end chunk of 8 bytes", std::to_string(p.size()) + " bytes");
      const std::uint64_t seen = s.records_.size() - 1;
      if (seen < max_records && total != seen) {
        er.fail(std::to_string(seen) + " records (as the chunks hold)", std::to_string(total));
      }
      if (at != bytes.size()) {
        byte_reader(bytes, at).fail("the stream's end after its end mark", "more bytes");
      }
      s.complete_ = seen < max_records || total == seen;
      break;
    }
    if (type != chunk_splits) {
      byte_reader(bytes, chunk_at)
          .fail("a record chunk 'S' or the end mark 'E'", std::string("chunk '") + type + "'");
    }
    byte_reader r(p, chunk_at + 5);
    const auto count = r.get<std::uint32_t>("a record count");
    if (count == 0) r.fail("at least one record", "0");
    // Every record takes at least 3 bytes plus its sample and a float error.
    if (r.left() / (7 + sample_size(h.type)) < count) {
      r.fail(std::to_string(count) + " records", "a chunk too short for them");
    }
    for (std::uint32_t i = 0; i < count; ++i) {
      if (s.records_.size() - 1 >= max_records) break;
      const std::size_t record_at = r.offset();
      const std::uint64_t diamond_index =
          previous + static_cast<std::uint64_t>(unzigzag(r.varint("a diamond delta")));
      previous = diamond_index;
      const auto head = r.get<std::uint8_t>("a record head");
      const std::uint32_t groups = head & 0x1Fu;
      if (groups > max_groups || (head & ~0x3Fu) != 0) {
        r.fail("a record head with at most 16 groups", "byte " + std::to_string(head));
      }
      const std::uint64_t crossed = r.varint("crossed edges");
      const double value = r.sample(h.type);
      const double err = (head & head_double_error) != 0
                             ? r.get<double>("an error")
                             : static_cast<double>(r.get<float>("an error"));
      const auto bad = [&](const std::string& expected, const std::string& found) {
        byte_reader(bytes, record_at)
            .fail(expected + " (record " + std::to_string(s.records_.size()) + ")", found);
      };
      if (diamond_index >= hier.vertex_count()) {
        bad("a diamond in the grid", "grid index " + std::to_string(diamond_index));
      }
      const ipoint c = hier.point(diamond_index);
      if (!hier.is_diamond(c))
        bad("a diamond centre", "grid index " + std::to_string(diamond_index));
      const std::uint64_t key = point_key(c);
      if (s.vertex_slot_.find(key) != nullptr) {
        bad("each diamond once", "grid index " + std::to_string(diamond_index) + " again");
      }
      if (!std::isfinite(value)) bad("a finite sample", "a non-finite one");
      if (!(err >= 0.0) || !std::isfinite(err))
        bad("a finite non-negative error", std::to_string(err));
      const diamond d = hier.make_diamond(c);
      hierarchy_stream::record rec{
          diamond_index, nullptr, groups, d.scale, static_cast<std::uint32_t>(crossed), err, {}, 0};
      // Parents first, errors nested.
      std::array<ipoint, 4> parents{};
      const int np = hier.parents(d, parents);
      for (int k = 0; k < np; ++k) {
        const std::uint32_t* slot =
            s.vertex_slot_.find(point_key(parents[static_cast<std::size_t>(k)]));
        if (slot == nullptr || *slot < corners) {
          bad("its parents' records before it", "a record whose parent is not in the stream yet");
        }
        const std::uint32_t pr = *slot - static_cast<std::uint32_t>(corners) + 1;
        if (err > s.records_[pr].error) {
          bad("an error at most its parent's (" + std::to_string(s.records_[pr].error) + ")",
              std::to_string(err));
        }
        rec.parents[rec.parent_count++] = pr;
      }
      const std::uint32_t allowed = new_edge_codes(d);
      if ((crossed & ~std::uint64_t{allowed}) != 0) {
        bad("crossed edges among the diamond's new edges", "mask " + std::to_string(crossed));
      }
      r.need(std::size_t{groups} * 8, "the record's groups");
      const group_edge_table& edges = group_edges(c, d.scale);
      for (std::uint32_t g = 0; g < groups; ++g) {
        const packed_group pg{r.get<std::uint64_t>("a group")};
        if (pg.count() != 1 && pg.count() != 2) {
          bad("a group of 1 or 2 triangles", std::to_string(pg.count()));
        }
        const unsigned oc = pg.owner_code();
        if (oc != packed_group::no_owner_code) {
          bool ok = oc < 125;
          if (ok) {
            const std::array<int, 3> o = half_offset_of(oc);
            // The owner is c + (h/2)·o, a grid vertex; cuts look it up by grid index
            // (group_owner()), which must be that vertex's.
            ipoint w{};
            for (std::size_t q = 0; q < 3; ++q) {
              const std::int32_t ho = d.scale * o[q];
              ok = ok && (ho % 2) == 0;
              w[q] = c[q] + ho / 2;
            }
            ok = ok && hier.in_grid(w) &&
                 group_owner(hier, diamond_index, d.scale, pg) == hier.index(w);
          }
          if (!ok) {
            bad("a group owner inside the grid",
                "code " + std::to_string(oc) + " at diamond (" + std::to_string(c[0]) + ", " +
                    std::to_string(c[1]) + ", " + std::to_string(c[2]) + ") of scale " +
                    std::to_string(d.scale));
          }
        }
        for (std::size_t t = 0; t < pg.count(); ++t) {
          for (std::size_t v = 0; v < 3; ++v) {
            const unsigned e = pg.edge(t, v);
            if (e >= 125 || edges[e][1] == centre_offset_code ||
                (edges[e][0] == centre_offset_code && ((crossed >> edges[e][1]) & 1u) == 0)) {
              bad("a group's edges among the diamond's crossed edges",
                  "edge code " + std::to_string(e));
            }
          }
        }
        s.groups_.push_back(pg);
      }
      s.vertex_slot_.try_emplace(key, static_cast<std::uint32_t>(s.values_.size()));
      s.values_.push_back(value);
      s.records_.push_back(rec);
      group_at.push_back(s.groups_.size() - groups);
    }
    if (s.records_.size() - 1 >= max_records) break;
    if (r.left() != 0)
      r.fail("the chunk's end after its records", std::to_string(r.left()) + " more bytes");
  }
  for (std::size_t i = 1; i < s.records_.size(); ++i) {
    s.records_[i].groups = s.records_[i].count != 0 ? s.groups_.data() + group_at[i] : nullptr;
  }
  // Triangles each split removes: those its parents' records (and the root surface) gave it.
  s.removed_.assign(s.records_.size(), 0);
  const auto owner_record = [&s, corners](std::uint64_t owner) -> std::uint32_t {
    if (owner == no_owner) return 0;
    const std::uint32_t* slot = s.vertex_slot_.find(point_key(s.hier_.point(owner)));
    if (slot == nullptr || *slot < corners) return 0;
    return *slot - static_cast<std::uint32_t>(corners) + 1;
  };
  for (const owned_triangle& t : s.root_triangles_) s.removed_[owner_record(t.owner)] += 1;
  for (std::size_t i = 1; i < s.records_.size(); ++i) {
    const hierarchy_stream::record& rec = s.records_[i];
    for (std::uint32_t g = 0; g < rec.count; ++g) {
      s.removed_[owner_record(group_owner(hier, rec.diamond, rec.scale, rec.groups[g]))] +=
          static_cast<std::uint32_t>(rec.groups[g].count());
    }
  }
  s.removed_[0] = 0;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Cuts

hierarchy_stream::split_set hierarchy_stream::all() const {
  split_set s(records_.size(), 1);  // records_ holds the root surface at least
  if (!s.empty()) s[0] = 0;
  return s;
}

hierarchy_stream::split_set hierarchy_stream::by_error(double max_error) const {
  split_set s(records_.size(), 0);
  for (std::size_t r = 1; r < records_.size(); ++r) s[r] = records_[r].error > max_error ? 1 : 0;
  return s;
}

std::uint64_t hierarchy_stream::triangle_count(const split_set& split) const {
  std::uint64_t n = root_triangles_.size();
  for (std::size_t r = 1; r < records_.size() && r < split.size(); ++r) {
    if (split[r] == 0) continue;
    for (std::uint32_t g = 0; g < records_[r].count; ++g) n += records_[r].groups[g].count();
    n -= removed_[r];
  }
  return n;
}

hierarchy_stream::split_set hierarchy_stream::by_triangles(std::uint64_t max_triangles,
                                                           double* threshold) const {
  // Records by decreasing error; the cut by error e holds those above e, so the candidates are
  // the prefixes that end where the error changes.
  std::vector<std::uint32_t> order(records_.size() - 1);
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i + 1);
  std::stable_sort(order.begin(), order.end(), [this](std::uint32_t a, std::uint32_t b) {
    return records_[a].error > records_[b].error;
  });
  std::int64_t count = static_cast<std::int64_t>(root_triangles_.size());
  std::size_t best = 0;  // records taken
  double best_threshold = order.empty() ? -1.0 : records_[order[0]].error;
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    const double e = records_[order[i]].error;
    while (j < order.size() && records_[order[j]].error == e) {
      const record& rec = records_[order[j]];
      for (std::uint32_t g = 0; g < rec.count; ++g)
        count += static_cast<std::int64_t>(rec.groups[g].count());
      count -= removed_[order[j]];
      ++j;
    }
    if (count > static_cast<std::int64_t>(max_triangles)) break;
    best = j;
    best_threshold = j < order.size() ? records_[order[j]].error : -1.0;
    i = j;
  }
  split_set s(records_.size(), 0);
  for (std::size_t i = 0; i < best; ++i) s[order[i]] = 1;
  if (threshold != nullptr) *threshold = best_threshold;
  return s;
}

hierarchy_stream::split_set hierarchy_stream::in_box(const std::array<double, 3>& lo,
                                                     const std::array<double, 3>& hi) const {
  split_set s(records_.size(), 0);
  for (std::size_t r = records_.size(); r-- > 1;) {
    const record& rec = records_[r];
    if (s[r] == 0) {
      const ipoint c = hier_.point(rec.diamond);
      bool meets = true;
      for (std::size_t q = 0; q < 3 && meets; ++q) {
        meets = c[q] + rec.scale >= lo[q] && c[q] - rec.scale <= hi[q];
      }
      if (!meets) continue;
      s[r] = 1;
    }
    for (std::uint32_t k = 0; k < rec.parent_count; ++k) s[rec.parents[k]] = 1;
  }
  return s;
}

namespace {

// The field a cut of a stream reads: the samples at root corners and split centres.
struct stream_field {
  const detail::flat_map& slots;
  const std::vector<double>& values;
  const hierarchy_stream_header& header;
  const hierarchy& hier;

  [[nodiscard]] double value(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    const std::uint32_t* s =
        slots.find(point_key({static_cast<std::int32_t>(x), static_cast<std::int32_t>(y),
                              static_cast<std::int32_t>(z)}));
    // Validation makes every vertex of a cut one of these; a missing one cannot arise.
    return s != nullptr ? values[*s] : 0.0;
  }
  [[nodiscard]] const std::array<double, 3>& spacing() const noexcept { return header.spacing; }
  [[nodiscard]] const std::array<double, 3>& origin() const noexcept { return header.origin; }
};

struct stream_cut {
  const std::vector<hierarchy_stream::record>& recs;
  const hierarchy_stream::split_set& split_of;
  const std::vector<owned_triangle>& roots;
  [[nodiscard]] std::uint64_t records() const noexcept { return recs.size(); }
  [[nodiscard]] const hierarchy_stream::record& record(std::uint64_t r) const noexcept {
    return recs[r];
  }
  [[nodiscard]] bool split(std::uint64_t r) const noexcept { return split_of[r] != 0; }
  [[nodiscard]] const std::vector<owned_triangle>& root_triangles() const noexcept { return roots; }
};

}  // namespace

triangle_mesh hierarchy_stream::mesh(const split_set& split) const {
  if (split.size() != records_.size()) {
    throw error("hierarchy stream: a split set of " + std::to_string(split.size()) +
                " entries for " + std::to_string(records_.size()) + " records");
  }
  for (std::size_t r = 1; r < records_.size(); ++r) {
    if (split[r] == 0) continue;
    for (std::uint32_t k = 0; k < records_[r].parent_count; ++k) {
      if (split[records_[r].parents[k]] == 0) {
        throw error("hierarchy stream: a split set that splits record " + std::to_string(r) +
                    " but not its parent, record " + std::to_string(records_[r].parents[k]));
      }
    }
  }
  const stream_field field{vertex_slot_, values_, header_, hier_};
  const stream_cut cut{records_, split, root_triangles_};
  detail::cut_mesher mesher(cut, hier_, field, header_.isovalue);
  return mesher.build({}, 1);
}

}  // namespace progiso
