#include <progiso/io/detail/plane_window.hpp>

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/error.hpp>

namespace progiso {

/// The reservation, the planes held [lo, hi) and what hold() has seen.
struct detail::plane_window_state {
  std::filesystem::path name;
  index3 dims{};
  sample_type type = sample_type::u8;
  std::int64_t chunk_planes = 1;
  std::uint64_t plane_bytes = 0;
  std::uint64_t page = 4096;
  std::byte* base = nullptr;
  std::shared_ptr<const void> mapping;  // unmaps the reservation when the last volume copy goes
  plane_loader load;
  std::optional<volume> field;
  std::int64_t lo = 0, hi = 0;  // planes held
  std::array<double, 2> seen{std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity()};
  std::uint64_t peak = 0;

  [[nodiscard]] std::uint64_t floor_page(std::uint64_t b) const noexcept { return b / page * page; }
  [[nodiscard]] std::uint64_t ceil_page(std::uint64_t b) const noexcept {
    return (b + page - 1) / page * page;
  }
  [[nodiscard]] std::uint64_t at(std::int64_t z) const noexcept {
    return static_cast<std::uint64_t>(z) * plane_bytes;
  }
  [[nodiscard]] std::uint64_t total() const noexcept { return at(dims[2]); }

  // Gives back the pages wholly below byte `end`, from those of plane lo: no longer readable, and
  // their memory (and its count against the process's data limit) returned at once.
  void release_below(std::uint64_t end) {
    const std::uint64_t from = floor_page(at(lo)), to = floor_page(end);
    if (to <= from) return;
    (void)madvise(base + from, to - from, MADV_DONTNEED);
    (void)mprotect(base + from, to - from, PROT_NONE);
  }

  // Planes [hi, z_end) made readable and decoded, a chunk row at a time.
  void extend(std::int64_t z_end, const parallel_loop& run) {
    while (hi < z_end) {
      const std::int64_t row_end = std::min(dims[2], (hi / chunk_planes + 1) * chunk_planes);
      const std::uint64_t from = floor_page(at(hi));
      const std::uint64_t to = std::min(ceil_page(at(row_end)), ceil_page(total()));
      if (mprotect(base + from, to - from, PROT_READ | PROT_WRITE) != 0) {
        const int e = errno;
        throw error(name.string() + ": cannot hold planes " + std::to_string(hi) + " to " +
                    std::to_string(row_end - 1) + " (" + std::to_string(to - from) +
                    " bytes) in memory: " + std::strerror(e));
      }
      const std::span<std::byte> out(base + at(hi), static_cast<std::size_t>(at(row_end) - at(hi)));
      load(hi, row_end, out, run);
      check(hi, row_end, out, run);
      hi = row_end;
      peak = std::max(peak, ceil_page(at(hi)) - floor_page(at(lo)));
    }
  }

  // The decoded planes [z0, z1): their range into seen, and no NaN or infinity (as volume's
  // constructor refuses them), named by position. Plane by plane through `run`, in the samples'
  // own type (integer compares and a float's exponent bits vectorise; a double per sample
  // does not), the position searched only when a plane has a non-finite sample.
  void check(std::int64_t z0, std::int64_t z1, std::span<const std::byte> bytes,
             const parallel_loop& run) {
    const index3 d{dims[0], dims[1], z1 - z0};
    const volume planes =
        volume::borrow_unscanned(d, type, bytes, nullptr, {1.0, 1.0, 1.0}, {0.0, 0.0, 0.0}, {});
    const auto n_planes = static_cast<std::size_t>(z1 - z0);
    const auto plane = static_cast<std::size_t>(dims[0] * dims[1]);
    planes.visit_samples([&](const auto* s) {
      using T = std::remove_cv_t<std::remove_pointer_t<decltype(s)>>;
      std::vector<std::array<T, 2>> range(n_planes);
      std::vector<std::uint8_t> finite(n_planes, 1);
      run_loop(run, n_planes, [&](std::size_t p) {
        const T* q = s + p * plane;
        if constexpr (std::is_floating_point_v<T>) {
          using bits_t = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>;
          constexpr auto exponent = static_cast<bits_t>(
              sizeof(T) == 4 ? std::uint64_t{0x7f800000u} : std::uint64_t{0x7ff0000000000000u});
          bits_t any = 0;
          for (std::size_t i = 0; i < plane; ++i) {
            bits_t b;
            std::memcpy(&b, q + i, sizeof b);
            any |= static_cast<bits_t>((b & exponent) == exponent);
          }
          if (any != 0) {
            finite[p] = 0;
            return;
          }
        }
        T least = q[0], most = q[0];
        for (std::size_t i = 1; i < plane; ++i) {
          least = q[i] < least ? q[i] : least;
          most = q[i] > most ? q[i] : most;
        }
        range[p] = {least, most};
      });
      for (std::size_t p = 0; p < n_planes; ++p) {
        if (finite[p] == 0) {
          const T* q = s + p * plane;
          for (std::size_t i = 0; i < plane; ++i) {
            if (std::isfinite(static_cast<double>(q[i]))) continue;
            const auto k = static_cast<std::int64_t>(i);
            throw error(name.string() + ": expected finite samples, found " +
                        std::to_string(static_cast<double>(q[i])) + " at x " +
                        std::to_string(k % dims[0]) + ", y " + std::to_string(k / dims[0]) +
                        ", z " + std::to_string(z0 + static_cast<std::int64_t>(p)));
          }
        }
        seen[0] = std::min(seen[0], static_cast<double>(range[p][0]));
        seen[1] = std::max(seen[1], static_cast<double>(range[p][1]));
      }
    });
  }
};

plane_window::plane_window(std::unique_ptr<detail::plane_window_state> state) noexcept
    : state_(std::move(state)) {}
plane_window::plane_window(plane_window&&) noexcept = default;
plane_window& plane_window::operator=(plane_window&&) noexcept = default;
plane_window::~plane_window() = default;

const volume& plane_window::field() const noexcept { return *state_->field; }
std::int64_t plane_window::chunk_planes() const noexcept { return state_->chunk_planes; }
std::array<double, 2> plane_window::range_seen() const noexcept { return state_->seen; }
std::uint64_t plane_window::peak_bytes() const noexcept { return state_->peak; }

void plane_window::hold(std::int64_t z_begin, std::int64_t z_end, const parallel_loop& run) {
  detail::plane_window_state& w = *state_;
  PROGISO_ASSERT(0 <= z_begin && z_begin <= z_end && z_end <= w.dims[2]);
  if (z_begin < w.lo || z_begin > w.hi) {
    // Not forward, or past what is held: nothing held is of use.
    w.release_below(w.total());
    w.lo = w.hi = z_begin;
  }
  w.release_below(w.at(z_begin));
  w.lo = z_begin;
  w.extend(z_end, run);
}

namespace detail {

plane_window make_plane_window(const std::filesystem::path& name, const index3& dims,
                               sample_type type, std::int64_t chunk_planes,
                               const std::array<double, 3>& spacing,
                               const std::array<double, 3>& origin, plane_loader load) {
  PROGISO_ASSERT(chunk_planes > 0);
  auto w = std::make_unique<plane_window_state>();
  w->name = name;
  w->dims = dims;
  w->type = type;
  w->chunk_planes = chunk_planes;
  w->plane_bytes = static_cast<std::uint64_t>(dims[0] * dims[1]) * sample_size(type);
  const long page = sysconf(_SC_PAGESIZE);
  if (page > 0) w->page = static_cast<std::uint64_t>(page);
  w->load = std::move(load);
  const std::uint64_t bytes = w->ceil_page(w->total());
  // Address space only: PROT_NONE pages are neither memory nor data against RLIMIT_DATA until
  // hold() makes them writable.
  void* p = mmap(nullptr, static_cast<std::size_t>(bytes), PROT_NONE,
                 MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) {
    const int e = errno;
    throw error(name.string() + ": cannot reserve " + std::to_string(bytes) +
                " bytes of address space for the level: " + std::strerror(e));
  }
  w->base = static_cast<std::byte*>(p);
  w->mapping = std::shared_ptr<const void>(
      p, [bytes](const void* q) { munmap(const_cast<void*>(q), static_cast<std::size_t>(bytes)); });
  // The type's bounds: a pass over windows reads no range from the field (range_seen() has it).
  const auto bounds = [type]() -> std::array<double, 2> {
    switch (type) {
      case sample_type::u8:
        return {0.0, 255.0};
      case sample_type::i8:
        return {-128.0, 127.0};
      case sample_type::u16:
        return {0.0, 65535.0};
      case sample_type::i16:
        return {-32768.0, 32767.0};
      case sample_type::u32:
        return {0.0, 4294967295.0};
      case sample_type::i32:
        return {-2147483648.0, 2147483647.0};
      case sample_type::f32:
        return {-static_cast<double>(std::numeric_limits<float>::max()),
                static_cast<double>(std::numeric_limits<float>::max())};
      case sample_type::f64:
        break;
    }
    return {-std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  }();
  try {
    w->field = volume::borrow_unscanned(
        dims, type, std::span<const std::byte>(w->base, static_cast<std::size_t>(w->total())),
        w->mapping, spacing, origin, bounds);
  } catch (const error& e) {
    throw error(name.string() + ": " + e.what());
  }
  return plane_window(std::move(w));
}

}  // namespace detail
}  // namespace progiso
