// progiso/core/field/volume.hpp — a scalar field sampled on a regular 3D grid.
//
// A volume owns its samples in their native type (u8 … f64, host byte order), with x varying
// fastest, then y, then z, together with the grid spacing and origin that map a grid index to
// physical coordinates (origin + index * spacing). Any dims ≥ 2 per axis are accepted; the
// diamond hierarchy embeds them in the smallest covering hierarchy (see hierarchy.hpp). A 2D
// image is a volume one sample thick (dims w, h, 1: x = column, y = row); the 3D hierarchy
// rejects those, the 2D one (hierarchy2d.hpp) takes them.
//
// value() reads one sample as double and clamps the index to the data box, which is how the
// hierarchy's padding vertices outside the data get their values (the nearest data vertex).
// Reading costs one predictable switch on the sample type; code that scans every voxel uses
// visit_samples() to run on the typed array instead.
//
// A volume is also the field refinement reads: either data, or the smoothed field of another
// volume (smooth(), smoothing.hpp), whose samples are computed on demand by the 4-point rule.
// Everything that refines or extracts reads samples through at(), value() or
// detail::visit_field(), so both kinds run through the same code.
//
// Samples are owned (the constructor takes a vector) or borrowed (borrow(): another owner's
// memory, such as a numpy array, read in place, kept alive through a keeper the caller passes).
// Copies of a volume share its samples: they are immutable either way.
//
// Thread safety: a volume is immutable after construction; concurrent reads are safe.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/base/parallel_loop.hpp>

namespace progiso {

/// Sample types a volume may hold.
enum class sample_type : std::uint8_t { u8, i8, u16, i16, u32, i32, f32, f64 };

/// Bytes per sample.
[[nodiscard]] std::size_t sample_size(sample_type type) noexcept;
/// "u8", "i16", … as used by the command line.
[[nodiscard]] std::string_view to_string(sample_type type) noexcept;
/// Parses "u8", "i8", "u16", "i16", "u32", "i32", "f32", "f64"; nullopt otherwise.
[[nodiscard]] std::optional<sample_type> parse_sample_type(std::string_view name) noexcept;

using index3 = std::array<std::int64_t, 3>;

namespace detail {
class subdivision;
// The fine sample at a linear index of a smoothed volume (subdivision.hpp), out of line so that
// volume.hpp does not need the subdivision's definition.
[[nodiscard]] double subdivided_at(const subdivision& s, std::size_t linear) noexcept;
}  // namespace detail

struct smoothing;
class volume;
[[nodiscard]] volume smooth(std::shared_ptr<const volume> data, const smoothing& s);

/// A scalar field on a regular grid.
class volume {
 public:
  /// Takes ownership of `samples` (host byte order, x fastest). Throws progiso::error when
  /// dims[0] or dims[1] is < 2 or dims[2] < 1 or a dim is above 32769, when the byte count
  /// differs from dims × sample_size(type), when a spacing is not finite and positive, when
  /// origin + (dims − 1) × spacing is not finite (coordinates would overflow), or when a
  /// floating-point sample is NaN or infinite (the message gives the first one's position):
  /// colours, ranges and vertex positions are only meaningful for finite samples.
  volume(index3 dims, sample_type type, std::vector<std::byte> samples,
         std::array<double, 3> spacing = {1.0, 1.0, 1.0},
         std::array<double, 3> origin = {0.0, 0.0, 0.0});
  /// A volume reading `samples` in place, without a copy (host byte order, x fastest). `keeper`
  /// owns that memory and is held by the volume and its copies (null: the caller keeps it alive
  /// and unchanged while any of them is in use). Checked as the constructor checks, except that
  /// integer samples are not scanned here: no integer is NaN, and their range is found by the
  /// first call of value_range(). So a borrowed integer volume is ready in O(1); a
  /// floating-point one costs one pass, which rejects NaN and infinite samples, in pieces
  /// through `run` when it is given (core/base/parallel_loop.hpp).
  [[nodiscard]] static volume borrow(index3 dims, sample_type type,
                                     std::span<const std::byte> samples,
                                     std::shared_ptr<const void> keeper,
                                     std::array<double, 3> spacing = {1.0, 1.0, 1.0},
                                     std::array<double, 3> origin = {0.0, 0.0, 0.0},
                                     const parallel_loop& run = {});

  /// borrow() for samples that the caller checks itself, possibly not all readable yet: no
  /// sample is read here or by value_range(), which returns `range` (a bound on the samples the
  /// caller will let be read). A plane window (io's volume_source::window()) makes its planes
  /// readable as a pass reaches them, checking each for non-finite samples as it decodes it.
  [[nodiscard]] static volume borrow_unscanned(index3 dims, sample_type type,
                                               std::span<const std::byte> samples,
                                               std::shared_ptr<const void> keeper,
                                               std::array<double, 3> spacing,
                                               std::array<double, 3> origin,
                                               std::array<double, 2> range);

  [[nodiscard]] const index3& dims() const noexcept { return dims_; }
  [[nodiscard]] sample_type type() const noexcept { return type_; }
  [[nodiscard]] const std::array<double, 3>& spacing() const noexcept { return spacing_; }
  [[nodiscard]] const std::array<double, 3>& origin() const noexcept { return origin_; }
  [[nodiscard]] std::size_t voxel_count() const noexcept {
    return static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]);
  }
  /// Bytes of sample storage.
  [[nodiscard]] std::size_t byte_size() const noexcept { return size_; }
  [[nodiscard]] const std::byte* bytes() const noexcept { return data_; }
  /// Whether the samples are another owner's (borrow()).
  [[nodiscard]] bool borrowed() const noexcept { return borrowed_; }

  /// Linear index of an in-box grid point.
  [[nodiscard]] std::size_t linear(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    return static_cast<std::size_t>(x + dims_[0] * (y + dims_[1] * z));
  }
  /// Sample at a linear index, as double.
  [[nodiscard]] double at(std::size_t i) const noexcept;
  /// Sample at grid point (x, y, z), clamped into the data box.
  [[nodiscard]] double value(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    const auto c = [](std::int64_t v, std::int64_t hi) { return v < 0 ? 0 : (v > hi ? hi : v); };
    return at(linear(c(x, dims_[0] - 1), c(y, dims_[1] - 1), c(z, dims_[2] - 1)));
  }
  /// Smallest and largest sample (a borrowed integer volume scans its samples on the first
  /// call, once, whichever thread calls).
  [[nodiscard]] std::array<double, 2> value_range() const noexcept;
  /// The subdivision behind a smoothed volume (smooth(), smoothing.hpp), or null for data. A
  /// smoothed volume has no sample array: bytes() is null, byte_size() 0, type() f64, its
  /// samples are computed by at() and value(), value_range() is a bound on them, and
  /// visit_samples() must not be called (detail::visit_field() serves both kinds).
  [[nodiscard]] const detail::subdivision* subdivided() const noexcept { return sub_.get(); }

  /// Calls f(const T* samples) with the typed sample array.
  template <class F>
  decltype(auto) visit_samples(F&& f) const;

 private:
  friend volume smooth(std::shared_ptr<const volume> data, const smoothing& s);
  volume(std::shared_ptr<const detail::subdivision> sub, const volume& data, index3 dims,
         std::array<double, 2> range);

  // The range of samples not scanned at construction (borrowed integers), found once.
  struct deferred_range {
    std::once_flag once;
    std::array<double, 2> range{};
  };
  volume(index3 dims, sample_type type, std::shared_ptr<const void> keeper, const std::byte* data,
         std::size_t size, bool borrowed, std::array<double, 3> spacing,
         std::array<double, 3> origin);
  void check_layout() const;
  // range_, and rejects non-finite samples (pieces through run, when not empty).
  void scan_samples(const parallel_loop& run = {});

  std::shared_ptr<const detail::subdivision> sub_;
  index3 dims_;
  sample_type type_;
  std::shared_ptr<const void> keeper_;  // owns the samples (an owned vector, or the caller's)
  const std::byte* data_ = nullptr;
  std::size_t size_ = 0;
  bool borrowed_ = false;
  std::array<double, 3> spacing_;
  std::array<double, 3> origin_;
  std::array<double, 2> range_{};
  std::shared_ptr<deferred_range> deferred_;  // null: range_ holds the range
};

// ---------------------------------------------------------------------------------------------
// Implementation of the inline parts.

inline double volume::at(std::size_t i) const noexcept {
  if (sub_ != nullptr) [[unlikely]] {
    return detail::subdivided_at(*sub_, i);
  }
  const std::byte* p = data_;
  switch (type_) {
    case sample_type::u8:
      return static_cast<double>(reinterpret_cast<const std::uint8_t*>(p)[i]);
    case sample_type::i8:
      return static_cast<double>(reinterpret_cast<const std::int8_t*>(p)[i]);
    case sample_type::u16:
      return static_cast<double>(reinterpret_cast<const std::uint16_t*>(p)[i]);
    case sample_type::i16:
      return static_cast<double>(reinterpret_cast<const std::int16_t*>(p)[i]);
    case sample_type::u32:
      return static_cast<double>(reinterpret_cast<const std::uint32_t*>(p)[i]);
    case sample_type::i32:
      return static_cast<double>(reinterpret_cast<const std::int32_t*>(p)[i]);
    case sample_type::f32:
      return static_cast<double>(reinterpret_cast<const float*>(p)[i]);
    case sample_type::f64:
      return reinterpret_cast<const double*>(p)[i];
  }
  return 0.0;
}

template <class F>
decltype(auto) volume::visit_samples(F&& f) const {
  PROGISO_ASSERT(sub_ == nullptr);
  const std::byte* p = data_;
  switch (type_) {
    case sample_type::u8:
      return f(reinterpret_cast<const std::uint8_t*>(p));
    case sample_type::i8:
      return f(reinterpret_cast<const std::int8_t*>(p));
    case sample_type::u16:
      return f(reinterpret_cast<const std::uint16_t*>(p));
    case sample_type::i16:
      return f(reinterpret_cast<const std::int16_t*>(p));
    case sample_type::u32:
      return f(reinterpret_cast<const std::uint32_t*>(p));
    case sample_type::i32:
      return f(reinterpret_cast<const std::int32_t*>(p));
    case sample_type::f32:
      return f(reinterpret_cast<const float*>(p));
    case sample_type::f64:
      break;
  }
  return f(reinterpret_cast<const double*>(p));
}

}  // namespace progiso
