#include <progiso/core/field/analytic.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>

namespace progiso {
namespace {

constexpr std::int64_t max_dim = (std::int64_t{1} << 15) + 1;  // the limit volume enforces

void check_dims(const char* who, const index3& dims) {
  for (const std::int64_t d : dims) {
    if (d < 2 || d > max_dim) {
      throw error(std::string(who) + ": every dim must be in [2, " + std::to_string(max_dim) +
                  "], found " + std::to_string(dims[0]) + "," + std::to_string(dims[1]) + "," +
                  std::to_string(dims[2]));
    }
  }
}

void check_parameter(bool ok, const char* who, const char* name, const char* expected,
                     double found) {
  if (!ok) {
    throw error(std::string(who) + ": " + name + " must be " + expected + ", found " +
                std::to_string(found));
  }
}

// Evaluates field(x, y, z) at every grid point (grid units, x fastest) and stores it as f32.
template <class Field>
volume sample_field(const char* who, const index3& dims, Field&& field) {
  check_dims(who, dims);
  const auto count = static_cast<std::size_t>(dims[0] * dims[1] * dims[2]);
  std::vector<std::byte> bytes(count * sizeof(float));
  std::byte* out = bytes.data();
  for (std::int64_t z = 0; z < dims[2]; ++z) {
    for (std::int64_t y = 0; y < dims[1]; ++y) {
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        const auto v = static_cast<float>(
            field(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
        std::memcpy(out, &v, sizeof v);
        out += sizeof v;
      }
    }
  }
  return volume(dims, sample_type::f32, std::move(bytes));
}

// splitmix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", 2014):
// a counter passed through a fixed mixing function, so its output is the same everywhere.
class splitmix64 {
 public:
  explicit splitmix64(std::uint64_t seed) noexcept : state_(seed) {}

  std::uint64_t next() noexcept {
    state_ += 0x9e3779b97f4a7c15u;
    std::uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
  }

  /// Uniform in [lo, hi): the top 53 bits as a double in [0, 1), scaled (exact arithmetic up to
  /// the final multiply-add, which IEEE 754 rounds the same way everywhere).
  double uniform(double lo, double hi) noexcept {
    const double unit = static_cast<double>(next() >> 11) * 0x1.0p-53;
    return lo + unit * (hi - lo);
  }

 private:
  std::uint64_t state_;
};

}  // namespace

volume make_sphere_field(index3 dims, std::array<double, 3> centre, double radius_scale) {
  constexpr const char* who = "make_sphere_field";
  check_parameter(std::isfinite(radius_scale) && radius_scale > 0.0, who, "radius_scale",
                  "finite and positive", radius_scale);
  for (const double c : centre) check_parameter(std::isfinite(c), who, "centre", "finite", c);
  return sample_field(who, dims, [&](double x, double y, double z) {
    const double dx = x - centre[0];
    const double dy = y - centre[1];
    const double dz = z - centre[2];
    return std::sqrt(dx * dx + dy * dy + dz * dz) / radius_scale;
  });
}

volume make_torus_field(index3 dims, std::array<double, 3> centre, double major_radius) {
  constexpr const char* who = "make_torus_field";
  check_parameter(std::isfinite(major_radius) && major_radius >= 0.0, who, "major_radius",
                  "finite and non-negative", major_radius);
  for (const double c : centre) check_parameter(std::isfinite(c), who, "centre", "finite", c);
  return sample_field(who, dims, [&](double x, double y, double z) {
    const double dx = x - centre[0];
    const double dy = y - centre[1];
    const double dz = z - centre[2];
    const double ring = std::sqrt(dx * dx + dy * dy) - major_radius;
    return std::sqrt(ring * ring + dz * dz);
  });
}

volume make_gyroid_field(index3 dims, double period) {
  constexpr const char* who = "make_gyroid_field";
  check_parameter(std::isfinite(period) && period > 0.0, who, "period", "finite and positive",
                  period);
  const double k = 2.0 * std::numbers::pi / period;
  return sample_field(who, dims, [k](double x, double y, double z) {
    return std::sin(k * x) * std::cos(k * y) + std::sin(k * y) * std::cos(k * z) +
           std::sin(k * z) * std::cos(k * x);
  });
}

volume make_marschner_lobb(index3 dims, double alpha, double f_M) {
  constexpr const char* who = "make_marschner_lobb";
  check_parameter(std::isfinite(alpha) && alpha > -1.0, who, "alpha", "finite and > -1", alpha);
  check_parameter(std::isfinite(f_M), who, "f_M", "finite", f_M);
  check_dims(who, dims);
  // Grid index i on an axis of n samples maps to -1 + 2 i / (n - 1).
  std::array<double, 3> to_unit{};
  for (std::size_t a = 0; a < 3; ++a) to_unit[a] = 2.0 / static_cast<double>(dims[a] - 1);
  constexpr double pi = std::numbers::pi;
  return sample_field(who, dims, [&](double i, double j, double k) {
    const double x = -1.0 + i * to_unit[0];
    const double y = -1.0 + j * to_unit[1];
    const double z = -1.0 + k * to_unit[2];
    const double r = std::sqrt(x * x + y * y);
    const double rho_r = std::cos(2.0 * pi * f_M * std::cos(pi * r / 2.0));
    return (1.0 - std::sin(pi * z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha));
  });
}

volume make_gaussian_blobs(index3 dims, int count, std::uint32_t seed) {
  constexpr const char* who = "make_gaussian_blobs";
  check_parameter(count >= 1, who, "count", "at least 1", count);
  check_dims(who, dims);

  struct blob {
    std::array<double, 3> centre;
    double inv_two_sigma2;
    double height;
  };
  const double shortest = static_cast<double>(std::min({dims[0], dims[1], dims[2]}) - 1);
  splitmix64 rng(seed);
  std::vector<blob> blobs(static_cast<std::size_t>(count));
  for (blob& b : blobs) {
    for (std::size_t a = 0; a < 3; ++a) {
      const double extent = static_cast<double>(dims[a] - 1);
      b.centre[a] = rng.uniform(0.15 * extent, 0.85 * extent);
    }
    const double sigma = rng.uniform(0.05, 0.15) * shortest;
    b.inv_two_sigma2 = 1.0 / (2.0 * sigma * sigma);
    b.height = rng.uniform(0.5, 1.0);
  }

  // Two passes: the sum first (double), then normalised by its largest sample.
  std::vector<double> sum(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]));
  std::size_t next = 0;
  double largest = 0.0;
  for (std::int64_t z = 0; z < dims[2]; ++z) {
    for (std::int64_t y = 0; y < dims[1]; ++y) {
      for (std::int64_t x = 0; x < dims[0]; ++x) {
        const std::array<double, 3> p{static_cast<double>(x), static_cast<double>(y),
                                      static_cast<double>(z)};
        double s = 0.0;
        for (const blob& b : blobs) {
          double d2 = 0.0;
          for (std::size_t a = 0; a < 3; ++a) d2 += (p[a] - b.centre[a]) * (p[a] - b.centre[a]);
          s += b.height * std::exp(-d2 * b.inv_two_sigma2);
        }
        largest = std::max(largest, s);
        sum[next++] = s;
      }
    }
  }
  // Every blob centre lies inside the box and its height is >= 0.5, so largest > 0.
  next = 0;
  return sample_field(who, dims, [&](double, double, double) { return sum[next++] / largest; });
}

volume make_demo_volume(std::int64_t n) { return make_marschner_lobb({n, n, n}); }

}  // namespace progiso
