#include "surface_distance.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

namespace progiso::bench {
namespace {

using kernel = CGAL::Simple_cartesian<double>;
using point = kernel::Point_3;
using triangle = kernel::Triangle_3;
using primitive = CGAL::AABB_triangle_primitive<kernel, std::vector<triangle>::const_iterator>;
using tree = CGAL::AABB_tree<CGAL::AABB_traits<kernel, primitive>>;

point to_point(const vec3& v) { return {v[0], v[1], v[2]}; }

double area_of(const triangle_mesh& m, const std::array<std::uint32_t, 3>& t) {
  const vec3& a = m.vertices[t[0]];
  const vec3& b = m.vertices[t[1]];
  const vec3& c = m.vertices[t[2]];
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
  const double x = uy * vz - uz * vy, y = uz * vx - ux * vz, z = ux * vy - uy * vx;
  return 0.5 * std::sqrt(x * x + y * y + z * z);
}

}  // namespace

area_coverage area_within(const triangle_mesh& reference, const triangle_mesh& cut, double radius,
                          std::size_t samples, std::uint64_t seed) {
  area_coverage r;
  r.samples = samples;
  std::vector<double> cumulative;
  cumulative.reserve(reference.triangles.size());
  double total = 0.0;
  for (const auto& t : reference.triangles) cumulative.push_back(total += area_of(reference, t));
  if (total <= 0.0) {
    r.fraction = 1.0;
    return r;
  }
  if (cut.triangles.empty()) return r;
  std::vector<triangle> tris;
  tris.reserve(cut.triangles.size());
  for (const auto& t : cut.triangles) {
    tris.emplace_back(to_point(cut.vertices[t[0]]), to_point(cut.vertices[t[1]]),
                      to_point(cut.vertices[t[2]]));
  }
  tree aabb(tris.cbegin(), tris.cend());
  aabb.accelerate_distance_queries();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double r2 = radius * radius;
  std::size_t near = 0;
  for (std::size_t k = 0; k < samples; ++k) {
    const double u = unit(rng) * total;
    const auto i = static_cast<std::size_t>(std::min<std::ptrdiff_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin(),
        static_cast<std::ptrdiff_t>(cumulative.size()) - 1));
    // A uniform point of the triangle: (1 − √s, √s (1 − t), √s t).
    const double s = std::sqrt(unit(rng));
    const double t = unit(rng);
    const auto& tri = reference.triangles[i];
    const vec3& a = reference.vertices[tri[0]];
    const vec3& b = reference.vertices[tri[1]];
    const vec3& c = reference.vertices[tri[2]];
    const double wa = 1.0 - s, wb = s * (1.0 - t), wc = s * t;
    const point p(wa * a[0] + wb * b[0] + wc * c[0], wa * a[1] + wb * b[1] + wc * c[1],
                  wa * a[2] + wb * b[2] + wc * c[2]);
    if (aabb.squared_distance(p) <= r2) ++near;
  }
  r.fraction = static_cast<double>(near) / static_cast<double>(samples);
  return r;
}

}  // namespace progiso::bench
