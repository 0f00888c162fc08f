// progiso/core/field/analytic.hpp — analytic scalar fields sampled onto a grid.
//
// These build f32 volumes whose isosurfaces are known in advance, for tests with exact
// expectations (a sphere is closed with Euler characteristic 2, a torus has 0), for benchmarks
// that must not depend on data files, and as the command-line tool's built-in input. Every
// field is evaluated at the grid points i = 0 … dims − 1 per axis in double precision and
// rounded once to float; spacing is 1 and origin 0, so grid units are physical units.
//
// Marschner–Lobb (S. R. Marschner and R. J. Lobb, "An evaluation of reconstruction filters for
// volume rendering", IEEE Visualization 1994) is the classic hard case for reconstruction: a
// slowly varying signal in z modulated by a radial ripple whose frequency approaches the grid's
// Nyquist limit, so coarse levels of the hierarchy miss detail that finer levels recover.
//
// Determinism: the pseudo-random blob parameters come from splitmix64 and arithmetic on them, so
// the same seed gives the same centres, widths and heights on every platform; the samples then
// agree up to the last bit of the platform's std::exp.
//
// Cost: one evaluation per voxel, 4 bytes of memory per voxel. Invalid arguments throw
// progiso::error.
#pragma once

#include <array>
#include <cstdint>

#include <progiso/core/base/config.hpp>
#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>

namespace progiso {

/// Distance field of a point: f(p) = |p − centre| / radius_scale, p and centre in grid units.
/// Isovalue r gives the sphere of radius r · radius_scale around `centre`. Throws
/// progiso::error when a dim is < 2 or too large for a volume, or when radius_scale is not
/// finite and positive.
[[nodiscard]] volume make_sphere_field(index3 dims, std::array<double, 3> centre,
                                       double radius_scale = 1.0);

/// Distance to the circle of radius `major_radius` around `centre` in the plane z = centre_z:
/// f(p) = sqrt((sqrt((x − cx)² + (y − cy)²) − R)² + (z − cz)²). Isovalue r < R gives a torus
/// with tube radius r (genus 1). Throws progiso::error on bad dims or a major_radius that is
/// not finite and non-negative.
[[nodiscard]] volume make_torus_field(index3 dims, std::array<double, 3> centre,
                                      double major_radius);

/// Gyroid: f(p) = sin(kx) cos(ky) + sin(ky) cos(kz) + sin(kz) cos(kx) with k = 2π / period
/// (grid units). Values lie in [−1.5, 1.5]; isovalue 0 gives the triply periodic minimal
/// surface, which reaches every face of the box. Throws progiso::error on bad dims or a period
/// that is not finite and positive.
[[nodiscard]] volume make_gyroid_field(index3 dims, double period);

/// The Marschner–Lobb signal on [−1, 1]³, mapped onto the grid (grid index 0 → −1,
/// dims − 1 → +1 on each axis):
///   ρ(x, y, z) = (1 − sin(πz/2) + α (1 + ρ_r(√(x² + y²)))) / (2 (1 + α)),
///   ρ_r(r) = cos(2π f_M cos(πr / 2)).
/// Values lie in [0, 1]; the usual isovalue is 0.5. Throws progiso::error on bad dims or a
/// non-finite alpha (alpha must also be > −1) or f_M.
[[nodiscard]] volume make_marschner_lobb(index3 dims, double alpha = 0.25, double f_M = 6.0);

/// A sum of `count` isotropic Gaussians (grid units) with pseudo-random centres (inside the
/// middle 70% of each axis), widths (5%–15% of the shortest extent) and heights (0.5–1),
/// drawn from splitmix64(seed); the sum is divided by its largest sample, so values lie in
/// [0, 1] with maximum exactly 1. Same seed, same field on every platform (see the header
/// comment). Throws progiso::error on bad dims or count < 1.
[[nodiscard]] volume make_gaussian_blobs(index3 dims, int count, std::uint32_t seed);

/// Suggested isovalue for make_demo_volume().
inline constexpr double demo_isovalue = 0.5;

/// The command-line tool's built-in input: Marschner–Lobb (default parameters) on n³ samples;
/// its suggested isovalue is demo_isovalue. Throws progiso::error when n is < 2 or too large.
[[nodiscard]] volume make_demo_volume(std::int64_t n = 129);

}  // namespace progiso
