#include <progiso/core/volume_io.hpp>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <teem/nrrd.h>

#include <progiso/core/detail/file_output.hpp>
#include <progiso/core/error.hpp>

namespace progiso {
namespace {

namespace fs = std::filesystem;

std::string dims_text(const index3& dims) {
  return std::to_string(dims[0]) + "," + std::to_string(dims[1]) + "," + std::to_string(dims[2]);
}

using detail::lower_extension;

/// Throws unless `file` names an existing regular file; returns its size in bytes.
std::uintmax_t require_regular_file(const fs::path& file) {
  std::error_code ec;
  const fs::file_status st = fs::status(file, ec);
  if (ec || !fs::exists(st)) {
    const std::string why = ec ? ec.message() : "no such file";
    throw error(file.string() + ": cannot open volume file (" + why + ")");
  }
  if (!fs::is_regular_file(st)) {
    throw error(file.string() + ": expected a regular volume file, found a directory or device");
  }
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec) throw error(file.string() + ": cannot read the file size (" + ec.message() + ")");
  return size;
}

/// a × b, or nullopt when it does not fit in 64 bits.
std::optional<std::uint64_t> checked_mul(std::uint64_t a, std::uint64_t b) {
  if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a) return std::nullopt;
  return a * b;
}

/// Builds the volume, prefixing the volume's own complaints (bad spacing, dims too large) with
/// the file name so that every message names its file.
volume make_volume(const fs::path& file, const index3& dims, sample_type type,
                   std::vector<std::byte> samples, const std::array<double, 3>& spacing,
                   const std::array<double, 3>& origin) {
  try {
    return volume(dims, type, std::move(samples), spacing, origin);
  } catch (const error& e) {
    throw error(file.string() + ": " + e.what());
  }
}

struct file_closer {
  void operator()(std::FILE* f) const noexcept { std::fclose(f); }
};

// ---------------------------------------------------------------------------------------------
// NRRD through Teem.

// Teem reports errors through biff, whose message store is process-wide and unsynchronised, and
// reads its verbosity from a global: every call that touches either holds this mutex.
std::mutex teem_mutex;

struct nrrd_deleter {
  void operator()(Nrrd* n) const noexcept { nrrdNuke(n); }
};

/// Takes (and frees) Teem's accumulated NRRD error message and returns its innermost entry,
/// the actual cause, without the "[nrrd] function: " prefix. Teem stacks one line per call
/// level, outermost first ("nrrdLoad: trouble reading …", "nrrdRead: trouble", …).
/// Precondition: teem_mutex is held.
std::string take_teem_message() {
  char* raw = biffGetDone(NRRD);
  const std::string text = raw != nullptr ? raw : "";
  std::free(raw);
  std::string cause;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    start = end + 1;
    if (line.starts_with('[')) {
      const std::size_t close = line.find("] ");
      if (close != std::string_view::npos) line.remove_prefix(close + 2);
    }
    const std::size_t colon = line.find(": ");
    const bool is_name = [&] {
      if (colon == std::string_view::npos || colon == 0) return false;
      return std::all_of(
          line.begin(), line.begin() + static_cast<std::ptrdiff_t>(colon),
          [](char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; });
    }();
    if (is_name) line.remove_prefix(colon + 2);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\r' || line.back() == ':')) {
      line.remove_suffix(1);
    }
    if (!line.empty()) cause = line;
  }
  return cause.empty() ? "no details" : cause;
}

std::optional<sample_type> from_teem_type(int type) {
  switch (type) {
    case nrrdTypeUChar:
      return sample_type::u8;
    case nrrdTypeChar:
      return sample_type::i8;
    case nrrdTypeUShort:
      return sample_type::u16;
    case nrrdTypeShort:
      return sample_type::i16;
    case nrrdTypeUInt:
      return sample_type::u32;
    case nrrdTypeInt:
      return sample_type::i32;
    case nrrdTypeFloat:
      return sample_type::f32;
    case nrrdTypeDouble:
      return sample_type::f64;
    default:
      return std::nullopt;
  }
}

/// Teem's nrrdLoad also accepts PNM, VTK, text and other formats by their magic; progiso
/// promises NRRD only, so the magic is checked first (which also gives garbage files a clear
/// message instead of whatever the text reader makes of them).
void require_nrrd_magic(const fs::path& file) {
  std::unique_ptr<std::FILE, file_closer> f(std::fopen(file.string().c_str(), "rb"));
  if (!f) {
    throw error(file.string() + ": cannot open volume file (" +
                std::error_code(errno, std::generic_category()).message() + ")");
  }
  char magic[8] = {};
  const std::size_t got = std::fread(magic, 1, sizeof magic, f.get());
  const bool ok = got >= 7 && std::memcmp(magic, "NRRD000", 7) == 0;
  if (!ok) {
    std::string found;
    for (std::size_t i = 0; i < got; ++i) {
      const auto u = static_cast<unsigned char>(magic[i]);
      found += std::isprint(u) != 0 ? magic[i] : '?';
    }
    throw error(file.string() + ": not a NRRD file (expected the magic \"NRRD000x\", found \"" +
                found + "\")");
  }
}

/// Spacing of axis `ax`: direction length, else |spacings entry|, else 1.
double axis_spacing(const Nrrd* n, unsigned ax) {
  double spacing = std::numeric_limits<double>::quiet_NaN();
  double direction[NRRD_SPACE_DIM_MAX];
  const int status = nrrdSpacingCalculate(n, ax, &spacing, direction);
  // A negative "spacings" entry means the axis runs backwards in world space; progiso keeps
  // index order and uses the magnitude.
  const bool known = status == nrrdSpacingStatusScalarNoSpace ||
                     status == nrrdSpacingStatusScalarWithSpace ||
                     status == nrrdSpacingStatusDirection;
  if (!known) return 1.0;
  spacing = std::fabs(spacing);
  return std::isfinite(spacing) && spacing > 0.0 ? spacing : 1.0;
}

volume read_nrrd_with(const fs::path& file, const std::optional<std::array<double, 3>>& spacing) {
  const std::string name = file.string();
  require_regular_file(file);
  require_nrrd_magic(file);

  std::unique_ptr<Nrrd, nrrd_deleter> n(nrrdNew());
  if (!n) throw error(name + ": cannot allocate a Teem nrrd");
  {
    const std::lock_guard<std::mutex> lock(teem_mutex);
    // Teem prints warnings (e.g. bytes after the data) straight to stderr unless its global
    // verbosity is 0; progiso's contract is one line per error and nothing else, so it is
    // silenced for the load and restored afterwards.
    const int verbosity = nrrdStateVerboseIO;
    nrrdStateVerboseIO = 0;
    const int status = nrrdLoad(n.get(), name.c_str(), nullptr);
    nrrdStateVerboseIO = verbosity;
    if (status != 0) {
      throw error(name + ": cannot read NRRD file (" + take_teem_message() + ")");
    }
  }

  if (n->dim != 3) {
    throw error(name + ": expected a 3-D NRRD array, found dimension " + std::to_string(n->dim));
  }
  index3 dims{};
  for (unsigned a = 0; a < 3; ++a) {
    const std::size_t size = n->axis[a].size;
    if (size < 2 || size > static_cast<std::size_t>(std::numeric_limits<std::int64_t>::max())) {
      throw error(name + ": expected every axis of the NRRD array to have at least 2 samples, " +
                  "found sizes " + std::to_string(n->axis[0].size) + "," +
                  std::to_string(n->axis[1].size) + "," + std::to_string(n->axis[2].size));
    }
    dims[a] = static_cast<std::int64_t>(size);
  }
  const std::optional<sample_type> type = from_teem_type(n->type);
  if (!type) {
    const char* type_name = airEnumStr(nrrdType, n->type);
    throw error(name + ": unsupported NRRD sample type \"" +
                (type_name != nullptr ? type_name : "?") +
                "\" (expected one of u8 i8 u16 i16 u32 i32 f32 f64)");
  }

  std::array<double, 3> step{1.0, 1.0, 1.0};
  for (unsigned a = 0; a < 3; ++a) step[a] = axis_spacing(n.get(), a);
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  const unsigned space_dim = std::min(n->spaceDim, 3u);
  for (unsigned a = 0; a < space_dim; ++a) {
    if (std::isfinite(n->spaceOrigin[a])) origin[a] = n->spaceOrigin[a];
  }

  // Teem has already decoded the encoding and swapped to host order; copy the samples out.
  const std::size_t bytes = static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
                            static_cast<std::size_t>(dims[2]) * sample_size(*type);
  if (n->data == nullptr) throw error(name + ": NRRD file has no data");
  std::vector<std::byte> samples(bytes);
  std::memcpy(samples.data(), n->data, bytes);
  n.reset();
  return make_volume(file, dims, *type, std::move(samples), spacing.value_or(step), origin);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Raw files.

volume read_raw(const std::filesystem::path& file, const raw_layout& layout,
                std::array<double, 3> spacing, std::array<double, 3> origin) {
  const std::string name = file.string();
  const index3& dims = layout.dims;
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2) {
    throw error(name + ": dims must be at least 2 per axis, found " + dims_text(dims));
  }
  const std::uintmax_t size = require_regular_file(file);
  const std::size_t item = sample_size(layout.type);

  std::optional<std::uint64_t> expected = static_cast<std::uint64_t>(item);
  for (std::int64_t d : dims) {
    if (expected) expected = checked_mul(*expected, static_cast<std::uint64_t>(d));
  }
  if (!expected || *expected != size) {
    throw error(name + ": size " + std::to_string(size) + " bytes does not match dims " +
                dims_text(dims) + " × " + std::string(to_string(layout.type)) + " = " +
                (expected ? std::to_string(*expected) : std::string("more than 2^64")) + " bytes");
  }

  std::unique_ptr<std::FILE, file_closer> f(std::fopen(name.c_str(), "rb"));
  if (!f) {
    throw error(name + ": cannot open volume file (" +
                std::error_code(errno, std::generic_category()).message() + ")");
  }
  std::vector<std::byte> samples(static_cast<std::size_t>(*expected));
  const std::size_t got = std::fread(samples.data(), 1, samples.size(), f.get());
  if (got != samples.size()) {
    throw error(name + ": read only " + std::to_string(got) + " of " +
                std::to_string(samples.size()) + " bytes");
  }

  const bool host_big = std::endian::native == std::endian::big;
  if (item > 1 && layout.big_endian != host_big) {
    for (std::size_t i = 0; i < samples.size(); i += item) {
      std::reverse(samples.begin() + static_cast<std::ptrdiff_t>(i),
                   samples.begin() + static_cast<std::ptrdiff_t>(i + item));
    }
  }
  return make_volume(file, dims, layout.type, std::move(samples), spacing, origin);
}

// ---------------------------------------------------------------------------------------------
// NRRD files and dispatch.

volume read_nrrd(const std::filesystem::path& file) { return read_nrrd_with(file, std::nullopt); }

volume read_volume(const std::filesystem::path& file, const std::optional<raw_layout>& raw,
                   std::optional<std::array<double, 3>> spacing) {
  if (raw) return read_raw(file, *raw, spacing.value_or(std::array<double, 3>{1.0, 1.0, 1.0}));
  const std::string ext = lower_extension(file);
  if (ext == ".nrrd" || ext == ".nhdr") return read_nrrd_with(file, spacing);
  throw error(file.string() +
              ": unknown volume format (expected .nrrd, .nhdr, or a raw file with --dims and "
              "--type)");
}

}  // namespace progiso
