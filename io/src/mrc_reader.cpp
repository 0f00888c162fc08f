#include <progiso/io/detail/mrc_reader.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/detail/gzip_input.hpp>
#include <progiso/io/detail/header_bytes.hpp>
#include <progiso/io/detail/nrrd_reader.hpp>

namespace progiso::detail {
namespace {

namespace fs = std::filesystem;

// Field offsets of the 1024-byte header (MRC2014; CCP4 and IMOD agree on these).
constexpr std::size_t at_n = 0;       // NX, NY, NZ: int32 × 3
constexpr std::size_t at_mode = 12;   // int32
constexpr std::size_t at_start = 16;  // NXSTART, NYSTART, NZSTART: int32 × 3
constexpr std::size_t at_m = 28;      // MX, MY, MZ: int32 × 3
constexpr std::size_t at_cella = 40;  // float × 3 (Å)
constexpr std::size_t at_cellb = 52;  // float × 3 (degrees)
constexpr std::size_t at_map = 64;    // MAPC, MAPR, MAPS: int32 × 3
constexpr std::size_t at_ispg = 88;
constexpr std::size_t at_nsymbt = 92;
constexpr std::size_t at_imod_stamp = 152;
constexpr std::size_t at_imod_flags = 156;
constexpr std::size_t at_origin = 196;  // float × 3
constexpr std::size_t at_identifier = 208;
constexpr std::size_t at_machst = 212;
constexpr std::int32_t imod_stamp = 1146047817;  // "IMOD" read as a little-endian int32

std::string_view refused_mode_name(std::int32_t mode) noexcept {
  switch (mode) {
    case 3:
      return "complex 16-bit integers";
    case 4:
      return "complex 32-bit floats";
    case 16:
      return "RGB bytes";
    case 101:
      return "4-bit integers packed two to a byte";
    default:
      return "an unknown mode";
  }
}

/// Whether a header read in one byte order makes sense: a known mode and a positive NX.
bool plausible(const header_bytes& f) noexcept {
  const auto mode = f.get<std::int32_t>(at_mode);
  const auto nx = f.get<std::int32_t>(at_n);
  return ((mode >= 0 && mode <= 16) || mode == 101) && nx > 0 && nx <= (1 << 30);
}

const char* axis_name(int a) noexcept { return a == 0 ? "X" : a == 1 ? "Y" : "Z"; }

}  // namespace

float half_to_float(std::uint16_t bits) noexcept {
  const std::uint32_t sign = (std::uint32_t{bits} & 0x8000u) << 16;
  const std::uint32_t exponent = (bits >> 10) & 0x1fu;
  std::uint32_t mantissa = bits & 0x3ffu;
  std::uint32_t out = 0;
  if (exponent == 0x1f) {  // infinity or NaN
    out = sign | 0x7f800000u | (mantissa << 13);
  } else if (exponent != 0) {  // normal: rebias 15 → 127
    out = sign | ((exponent + 112u) << 23) | (mantissa << 13);
  } else if (mantissa != 0) {  // subnormal: normalise
    std::uint32_t e = 113;     // 2^-14 is exponent 113 in float32
    while ((mantissa & 0x400u) == 0) {
      mantissa <<= 1;
      --e;
    }
    out = sign | (e << 23) | ((mantissa & 0x3ffu) << 13);
  } else {
    out = sign;  // ±0
  }
  return std::bit_cast<float>(out);
}

bool has_mrc_name(const fs::path& file) {
  std::string ext = lower_extension(file);
  if (ext == ".gz") ext = lower_extension(file.stem());
  return ext == ".mrc" || ext == ".mrcs" || ext == ".map" || ext == ".ccp4" || ext == ".rec";
}

bool has_mrc_identifier(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return false;
  try {
    input_file in(file, "MRC");
    std::array<char, at_identifier + 4> head{};
    return in.read(head.data(), head.size()) == head.size() &&
           std::string_view(head.data() + at_identifier, 4) == "MAP ";
  } catch (const error&) {
    return false;
  }
}

mrc_header read_mrc_header(const fs::path& file) {
  sequential_input in(file, "MRC", "MRC gzip data");
  const std::string name = file.string();
  std::array<std::byte, mrc_header_bytes> raw{};
  const std::size_t got = in.read(raw);
  if (got < raw.size()) {
    throw error(name + ": file ends after " + std::to_string(got) +
                " bytes, inside the 1024-byte MRC header");
  }
  mrc_header h;
  // Byte order: the machine stamp, else the order in which the header makes sense.
  const auto stamp = std::to_integer<unsigned>(raw[at_machst]);
  bool file_big = false;
  if (stamp == 0x44) {
    file_big = false;
  } else if (stamp == 0x11) {
    file_big = true;
  } else {
    const bool host_big = std::endian::native == std::endian::big;
    const header_bytes little(raw.data(), host_big);
    const header_bytes big(raw.data(), !host_big);
    if (plausible(little)) {
      file_big = false;
    } else if (plausible(big)) {
      file_big = true;
    } else {
      throw error(name + ": not an MRC file: the machine stamp at byte 212 is " +
                  std::to_string(stamp) + " (expected 0x44 or 0x11), and MODE reads " +
                  std::to_string(little.get<std::int32_t>(at_mode)) + " little endian, " +
                  std::to_string(big.get<std::int32_t>(at_mode)) +
                  " big endian (expected 0 to 16 or 101, with NX > 0)");
    }
  }
  h.big_endian = file_big;
  const header_bytes f(raw.data(), file_big != (std::endian::native == std::endian::big));

  // Mode.
  h.mode = f.get<std::int32_t>(at_mode);
  switch (h.mode) {
    case 0: {
      // MRC2014 bytes are signed; IMOD's stamp with its "signed" flag clear says unsigned.
      const bool imod_unsigned = f.get<std::int32_t>(at_imod_stamp) == imod_stamp &&
                                 (f.get<std::int32_t>(at_imod_flags) & 1) == 0;
      h.stored = imod_unsigned ? sample_type::u8 : sample_type::i8;
      break;
    }
    case 1:
      h.stored = sample_type::i16;
      break;
    case 2:
      h.stored = sample_type::f32;
      break;
    case 6:
      h.stored = sample_type::u16;
      break;
    case 12:
      h.stored = sample_type::f32;
      h.half = true;
      break;
    default:
      throw error(name + ": MODE " + std::to_string(h.mode) + " (" +
                  std::string(refused_mode_name(h.mode)) +
                  ") is not supported (expected 0: 8-bit integers, 1: int16, 2: float32, "
                  "6: uint16 or 12: float16)");
  }

  // Axes: columns, rows and sections run along MAPC, MAPR, MAPS.
  std::array<std::int32_t, 3> map{};
  for (std::size_t i = 0; i < 3; ++i) map[i] = f.get<std::int32_t>(at_map + 4 * i);
  if (map != std::array<std::int32_t, 3>{0, 0, 0}) {
    std::array<std::int32_t, 3> sorted = map;
    std::sort(sorted.begin(), sorted.end());
    if (sorted != std::array<std::int32_t, 3>{1, 2, 3}) {
      throw error(name + ": MAPC, MAPR, MAPS are " + std::to_string(map[0]) + ", " +
                  std::to_string(map[1]) + ", " + std::to_string(map[2]) +
                  " (expected a permutation of 1, 2, 3: the axes X, Y, Z of columns, rows "
                  "and sections)");
    }
    for (std::size_t i = 0; i < 3; ++i) h.axis[i] = map[i] - 1;
  }

  // Sizes: NX, NY, NZ as stored; a volume stack holds NZ / MZ sections per volume.
  std::array<std::int64_t, 3> n{};
  constexpr std::array<std::string_view, 3> n_names{"NX", "NY", "NZ"};
  for (std::size_t i = 0; i < 3; ++i) {
    n[i] = f.get<std::int32_t>(at_n + 4 * i);
    if (n[i] < 1) {
      throw error(name + ": " + std::string(n_names[i]) + " is " + std::to_string(n[i]) +
                  ", expected at least 1");
    }
  }
  std::array<std::int64_t, 3> m{};
  for (std::size_t i = 0; i < 3; ++i) m[i] = f.get<std::int32_t>(at_m + 4 * i);
  const std::int32_t ispg = f.get<std::int32_t>(at_ispg);
  std::int64_t sections = n[2];
  if (ispg >= 401 && ispg <= 630 && m[2] >= 1 && m[2] != n[2]) {
    if (n[2] % m[2] != 0) {
      throw error(name + ": a volume stack (ISPG " + std::to_string(ispg) +
                  ") of NZ = " + std::to_string(n[2]) +
                  " sections that is not a whole number of volumes of MZ = " +
                  std::to_string(m[2]) + " sections");
    }
    if (h.axis != std::array<int, 3>{0, 1, 2}) {
      throw error(name + ": a volume stack (ISPG " + std::to_string(ispg) +
                  ") whose axes are not in the order X, Y, Z (MAPC, MAPR, MAPS are " +
                  std::to_string(map[0]) + ", " + std::to_string(map[1]) + ", " +
                  std::to_string(map[2]) + "): not supported");
    }
    sections = m[2];
    h.volumes = n[2] / m[2];
  }
  h.stored_dims = {n[0], n[1], sections};
  if (sections == 1) {
    throw error(name + ": a single image (" +
                std::string(h.volumes > 1 ? "MZ = 1 section per volume" : "NZ = 1") +
                "): expected a volume of at least 2 sections");
  }
  for (std::size_t i = 0; i < 3; ++i) {
    const std::int64_t d = h.stored_dims[i];
    if (d < 2 || d > mrc_max_axis_size) {
      throw error(name + ": " + std::string(n_names[i]) + " is " + std::to_string(n[i]) +
                  (i == 2 && h.volumes > 1 ? " (MZ " + std::to_string(sections) + " per volume)"
                                           : std::string()) +
                  ", expected 2 to " + std::to_string(mrc_max_axis_size) + " samples along " +
                  axis_name(h.axis[i]));
    }
    h.dims[static_cast<std::size_t>(h.axis[i])] = d;
  }

  // Where the samples start.
  const std::int32_t nsymbt = f.get<std::int32_t>(at_nsymbt);
  if (nsymbt < 0) {
    throw error(name + ": NSYMBT (the extended header's bytes) is " + std::to_string(nsymbt) +
                ", expected at least 0");
  }
  h.data_offset = mrc_header_bytes + static_cast<std::uint64_t>(nsymbt);

  // Geometry: steps along X, Y, Z from the unit cell and its samples.
  std::array<double, 3> cell_angles{};
  for (std::size_t a = 0; a < 3; ++a) {
    const auto length = static_cast<double>(f.get<float>(at_cella + 4 * a));
    const double step = m[a] > 0 ? length / static_cast<double>(m[a]) : 0.0;
    h.spacing[a] = std::isfinite(step) && step > 0.0 ? step : 1.0;
    cell_angles[a] = static_cast<double>(f.get<float>(at_cellb + 4 * a));
  }
  // The cell's axes (a along x, b in the xy plane), one step each: right angles unless CELLB
  // gives a valid oblique cell.
  std::array<std::array<double, 3>, 3> steps{};  // steps[axis] = the vector of one step
  for (std::size_t a = 0; a < 3; ++a) steps[a][a] = h.spacing[a];
  const bool angles_valid = std::all_of(cell_angles.begin(), cell_angles.end(), [](double d) {
    return std::isfinite(d) && d > 0.0 && d < 180.0;
  });
  const bool right = std::all_of(cell_angles.begin(), cell_angles.end(),
                                 [](double d) { return std::abs(d - 90.0) < 1e-4; });
  if (angles_valid && !right) {
    const double rad = std::numbers::pi / 180.0;
    const double ca = std::cos(cell_angles[0] * rad);
    const double cb = std::cos(cell_angles[1] * rad);
    const double cg = std::cos(cell_angles[2] * rad);
    const double sg = std::sin(cell_angles[2] * rad);
    const double cy = (ca - cb * cg) / sg;
    const double cz2 = 1.0 - cb * cb - cy * cy;
    if (cz2 > 1e-12) {
      steps[1] = {h.spacing[1] * cg, h.spacing[1] * sg, 0.0};
      steps[2] = {h.spacing[2] * cb, h.spacing[2] * cy, h.spacing[2] * std::sqrt(cz2)};
    }
  }
  // The origin: ORIGIN when given, else the start indices (along X, Y, Z) × the steps.
  std::array<double, 3> given{};
  for (std::size_t a = 0; a < 3; ++a) {
    given[a] = static_cast<double>(f.get<float>(at_origin + 4 * a));
  }
  const bool origin_given =
      std::all_of(given.begin(), given.end(), [](double v) { return std::isfinite(v); }) &&
      std::any_of(given.begin(), given.end(), [](double v) { return v != 0.0; });
  std::array<double, 3> start{};
  for (std::size_t i = 0; i < 3; ++i) {
    start[static_cast<std::size_t>(h.axis[i])] =
        static_cast<double>(f.get<std::int32_t>(at_start + 4 * i));
  }
  std::array<double, 3> translation{};
  for (std::size_t r = 0; r < 3; ++r) {
    if (origin_given) {
      translation[r] = given[r];
      h.origin[r] = given[r];
    } else {
      for (std::size_t a = 0; a < 3; ++a) translation[r] += start[a] * steps[a][r];
      h.origin[r] = start[r] * h.spacing[r];
    }
  }
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t a = 0; a < 3; ++a) h.world.m[r][a] = steps[a][r];
    h.world.m[r][3] = translation[r];
  }
  return h;
}

std::optional<mapped_bytes> map_mrc_samples(const mrc_header& h, const fs::path& file,
                                            std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < h.volumes);
  if (h.half || h.axis != std::array<int, 3>{0, 1, 2} || h.volume_type() != h.stored) {
    return std::nullopt;
  }
  const std::size_t item = sample_size(h.stored);
  if (item > 1 && h.big_endian != (std::endian::native == std::endian::big)) return std::nullopt;
  const std::uint64_t bytes = static_cast<std::uint64_t>(h.stored_dims[0]) *
                              static_cast<std::uint64_t>(h.stored_dims[1]) *
                              static_cast<std::uint64_t>(h.stored_dims[2]) * item;
  if (bytes < map_min_bytes) return std::nullopt;
  const sequential_input in(file, "MRC", "MRC gzip data");
  if (in.plain() == nullptr) return std::nullopt;
  const auto volumes = static_cast<std::uint64_t>(h.volumes);
  if (h.data_offset > in.size() || volumes > (in.size() - h.data_offset) / bytes) {
    return std::nullopt;
  }
  return map_bytes(*in.plain(), h.data_offset + static_cast<std::uint64_t>(volume) * bytes, bytes);
}

std::vector<std::byte> read_mrc_samples(const mrc_header& h, const fs::path& file,
                                        std::int64_t volume) {
  PROGISO_ASSERT(volume >= 0 && volume < h.volumes);
  sequential_input in(file, "MRC", "MRC gzip data");
  const std::string name = file.string();
  const std::size_t item = h.half ? 2 : sample_size(h.stored);
  const auto columns = static_cast<std::uint64_t>(h.stored_dims[0]);
  const auto rows = static_cast<std::uint64_t>(h.stored_dims[1]);
  const auto sections = static_cast<std::uint64_t>(h.stored_dims[2]);
  const std::uint64_t count = columns * rows * sections;
  const std::uint64_t bytes = count * item;  // ≤ 32769³ × 4 < 2^47
  const std::string shape = std::to_string(columns) + "x" + std::to_string(rows) + "x" +
                            std::to_string(sections) +
                            (h.volumes > 1 ? "x" + std::to_string(h.volumes) : std::string());
  const std::string type_name = h.half ? std::string("float16") : std::string(to_string(h.stored));
  // Every declared volume after the extended header: columns × rows × NZ × 4 bytes at most
  // (NZ < 2^31), under 2^64.
  const std::uint64_t all = bytes * static_cast<std::uint64_t>(h.volumes);
  const std::string declared = std::to_string(all) + " bytes (" + shape + " of MODE " +
                               std::to_string(h.mode) + ", " + type_name + ")";
  if (in.gzipped()) {
    if (!gzip_can_hold(in.size(), h.data_offset + all)) {
      throw error(name + ": " + std::to_string(in.size()) +
                  " bytes of gzip data cannot hold the declared " + declared +
                  " after byte offset " + std::to_string(h.data_offset) +
                  " (gzip expands at most " + std::to_string(gzip_max_ratio) + ":1)");
    }
  } else if (in.size() < h.data_offset || in.size() - h.data_offset < all) {
    throw error(name + ": MRC data ends: the file has " + std::to_string(in.size()) +
                " bytes, too few for the declared " + declared + " after the header and " +
                std::to_string(h.data_offset - mrc_header_bytes) +
                " bytes of extended header (NSYMBT)");
  }
  const std::uint64_t first = h.data_offset + static_cast<std::uint64_t>(volume) * bytes;
  if (!in.skip_to(first)) {
    throw error(name + ": MRC data ends before " +
                (volume == 0 ? "byte " + std::to_string(first) + ", where the samples start"
                             : "volume " + std::to_string(volume) + " (byte " +
                                   std::to_string(first) + ")"));
  }
  const auto ends = [&](std::uint64_t got) {
    return error(name + ": MRC data ends after " + std::to_string(got) + " of the " +
                 std::to_string(bytes) + " bytes of " +
                 (h.volumes > 1 ? "volume " + std::to_string(volume) + " of the declared "
                                : std::string("the declared ")) +
                 declared);
  };
  const bool swap = item > 1 && h.big_endian != (std::endian::native == std::endian::big);
  const std::size_t out_item = sample_size(h.volume_type());
  std::vector<std::byte> out(static_cast<std::size_t>(count) * out_item);

  if (h.axis == std::array<int, 3>{0, 1, 2}) {
    // Stored x fastest: read in place (half floats into the tail, widened front to back:
    // float i is written over halves before i + 1, since 4(i + 1) ≤ 2·count + 2(i + 1)).
    const std::size_t tail = out.size() - static_cast<std::size_t>(bytes);
    const std::span<std::byte> stored(out.data() + tail, static_cast<std::size_t>(bytes));
    const std::size_t got = in.read(stored);
    if (got < stored.size()) throw ends(got);
    if (swap) swap_sample_bytes(stored, item);
    if (h.half) {
      for (std::size_t i = 0; i < static_cast<std::size_t>(count); ++i) {
        std::uint16_t bits = 0;
        std::memcpy(&bits, stored.data() + 2 * i, 2);
        const float v = half_to_float(bits);
        std::memcpy(out.data() + 4 * i, &v, 4);
      }
    }
    return out;
  }

  // Stored in another order: one section at a time, each sample to its place x fastest.
  std::array<std::uint64_t, 3> stride_of_axis{
      1, static_cast<std::uint64_t>(h.dims[0]),
      static_cast<std::uint64_t>(h.dims[0]) * static_cast<std::uint64_t>(h.dims[1])};
  const std::uint64_t sc = stride_of_axis[static_cast<std::size_t>(h.axis[0])];
  const std::uint64_t sr = stride_of_axis[static_cast<std::size_t>(h.axis[1])];
  const std::uint64_t ss = stride_of_axis[static_cast<std::size_t>(h.axis[2])];
  std::vector<std::byte> section(static_cast<std::size_t>(columns * rows) * item);
  std::uint64_t total = 0;
  for (std::uint64_t s = 0; s < sections; ++s) {
    const std::size_t got = in.read(section);
    total += got;
    if (got < section.size()) throw ends(total);
    if (swap) swap_sample_bytes(section, item);
    const std::byte* from = section.data();
    for (std::uint64_t r = 0; r < rows; ++r) {
      std::byte* row = out.data() + (s * ss + r * sr) * out_item;
      for (std::uint64_t c = 0; c < columns; ++c, from += item) {
        std::byte* to = row + c * sc * out_item;
        if (h.half) {
          std::uint16_t bits = 0;
          std::memcpy(&bits, from, 2);
          const float v = half_to_float(bits);
          std::memcpy(to, &v, 4);
        } else {
          std::memcpy(to, from, item);
        }
      }
    }
  }
  return out;
}

}  // namespace progiso::detail
