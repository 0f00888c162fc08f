#include <progiso/core/field/volume.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

#include <progiso/core/base/error.hpp>

namespace progiso {

std::size_t sample_size(sample_type type) noexcept {
  switch (type) {
    case sample_type::u8:
    case sample_type::i8:
      return 1;
    case sample_type::u16:
    case sample_type::i16:
      return 2;
    case sample_type::u32:
    case sample_type::i32:
    case sample_type::f32:
      return 4;
    case sample_type::f64:
      return 8;
  }
  return 1;
}

std::string_view to_string(sample_type type) noexcept {
  switch (type) {
    case sample_type::u8:
      return "u8";
    case sample_type::i8:
      return "i8";
    case sample_type::u16:
      return "u16";
    case sample_type::i16:
      return "i16";
    case sample_type::u32:
      return "u32";
    case sample_type::i32:
      return "i32";
    case sample_type::f32:
      return "f32";
    case sample_type::f64:
      return "f64";
  }
  return "?";
}

std::optional<sample_type> parse_sample_type(std::string_view name) noexcept {
  for (auto t : {sample_type::u8, sample_type::i8, sample_type::u16, sample_type::i16,
                 sample_type::u32, sample_type::i32, sample_type::f32, sample_type::f64}) {
    if (name == to_string(t)) return t;
  }
  return std::nullopt;
}

volume::volume(index3 dims, sample_type type, std::vector<std::byte> samples,
               std::array<double, 3> spacing, std::array<double, 3> origin)
    : dims_(dims), type_(type), spacing_(spacing), origin_(origin) {
  auto owned = std::make_shared<const std::vector<std::byte>>(std::move(samples));
  data_ = owned->data();
  size_ = owned->size();
  keeper_ = std::move(owned);
  check_layout();
  scan_samples();
}

volume::volume(index3 dims, sample_type type, std::shared_ptr<const void> keeper,
               const std::byte* data, std::size_t size, bool borrowed,
               std::array<double, 3> spacing, std::array<double, 3> origin)
    : dims_(dims),
      type_(type),
      keeper_(std::move(keeper)),
      data_(data),
      size_(size),
      borrowed_(borrowed),
      spacing_(spacing),
      origin_(origin) {}

volume volume::borrow(index3 dims, sample_type type, std::span<const std::byte> samples,
                      std::shared_ptr<const void> keeper, std::array<double, 3> spacing,
                      std::array<double, 3> origin) {
  volume v(dims, type, std::move(keeper), samples.data(), samples.size(), true, spacing, origin);
  v.check_layout();
  if (type == sample_type::f32 || type == sample_type::f64) {
    v.scan_samples();
  } else {
    v.deferred_ = std::make_shared<deferred_range>();
  }
  return v;
}

void volume::check_layout() const {
  for (std::size_t a = 0; a < 3; ++a) {
    // x and y need two samples; z may be 1 (a 2D image is a volume one sample thick).
    if (dims_[a] < (a == 2 ? 1 : 2)) {
      throw error("volume: dims must be at least 2,2,1, found " + std::to_string(dims_[0]) + "," +
                  std::to_string(dims_[1]) + "," + std::to_string(dims_[2]));
    }
    if (dims_[a] > (std::int64_t{1} << 15) + 1) {
      throw error("volume: dims above 32769 per axis are not supported, found " +
                  std::to_string(dims_[a]));
    }
    if (!(std::isfinite(spacing_[a]) && spacing_[a] > 0.0)) {
      throw error("volume: spacing must be finite and positive, found " +
                  std::to_string(spacing_[a]));
    }
    if (!std::isfinite(origin_[a])) throw error("volume: origin must be finite");
    // Every written coordinate (origin + index × spacing) must be a finite double.
    const double far = std::fabs(origin_[a]) + static_cast<double>(dims_[a] - 1) * spacing_[a];
    if (!std::isfinite(far)) {
      throw error("volume: origin + (dims - 1) × spacing overflows on axis " + std::to_string(a) +
                  " (spacing " + std::to_string(spacing_[a]) + ", " + std::to_string(dims_[a]) +
                  " samples)");
    }
  }
  const std::size_t expected = voxel_count() * sample_size(type_);
  if (size_ != expected) {
    throw error("volume: expected " + std::to_string(expected) + " bytes of samples, found " +
                std::to_string(size_));
  }
  if (data_ == nullptr) throw error("volume: expected samples, found a null pointer");
}

namespace {

// The smallest and largest sample, and the first non-finite one (n when none).
template <class T>
std::array<double, 2> sample_range(const T* s, std::size_t n, std::size_t& non_finite) {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  non_finite = n;
  for (std::size_t i = 0; i < n; ++i) {
    const auto v = static_cast<double>(s[i]);
    if (v < lo) lo = v;
    if (v > hi) hi = v;
    if constexpr (std::is_floating_point_v<T>) {
      // v − v is 0 for every finite v and NaN for a NaN or an infinity.
      if (!(v - v == 0.0) && non_finite == n) non_finite = i;
    }
  }
  return {lo, hi};
}

}  // namespace

void volume::scan_samples() {
  std::size_t non_finite = voxel_count();
  range_ = visit_samples([&](const auto* s) { return sample_range(s, voxel_count(), non_finite); });
  if (non_finite != voxel_count()) {
    const auto i = static_cast<std::int64_t>(non_finite);
    const std::int64_t x = i % dims_[0];
    const std::int64_t y = (i / dims_[0]) % dims_[1];
    const std::int64_t z = i / (dims_[0] * dims_[1]);
    throw error("volume: expected finite samples, found " + std::to_string(at(non_finite)) +
                " at sample " + std::to_string(non_finite) + " (x " + std::to_string(x) + ", y " +
                std::to_string(y) + ", z " + std::to_string(z) + ")");
  }
}

std::array<double, 2> volume::value_range() const noexcept {
  if (deferred_ == nullptr) return range_;
  std::call_once(deferred_->once, [this] {
    std::size_t unused = 0;
    deferred_->range =
        visit_samples([&](const auto* s) { return sample_range(s, voxel_count(), unused); });
  });
  return deferred_->range;
}

}  // namespace progiso
