// Seeded samplers of analytic surfaces with known distance functions, for the fitting tests.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <cmath>
#include <numbers>
#include <random>

namespace stampscan::fitting::test {

// Points on the plane z = 0 over [-half, half]^2 (random positions), with Gaussian noise along z.
inline Cloud samplePlane(std::size_t n, double half, double noise, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-half, half);
  std::normal_distribution<double> g(0.0, noise);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) c.positions.emplace_back(u(rng), u(rng), noise > 0 ? g(rng) : 0.0);
  return c;
}

// Points on the upper part (polar angle <= max_polar) of a sphere of radius R at the origin,
// uniformly by area, with Gaussian noise along the radius.
inline Cloud sampleSphereCap(std::size_t n, double R, double max_polar, double noise, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, noise);
  const double zmin = std::cos(max_polar);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const double z = zmin + (1.0 - zmin) * u(rng);
    const double phi = 2.0 * std::numbers::pi * u(rng);
    const double r = std::sqrt(1.0 - z * z);
    const Vec3 dir(r * std::cos(phi), r * std::sin(phi), z);
    c.positions.push_back(dir * (R + (noise > 0 ? g(rng) : 0.0)));
  }
  return c;
}

// Points on the cylinder x^2 + z^2 = R^2, z >= 0 (upper half), y in [-half, half].
inline Cloud sampleCylinder(std::size_t n, double R, double half, double noise, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> a(0.15 * std::numbers::pi, 0.85 * std::numbers::pi);
  std::uniform_real_distribution<double> y(-half, half);
  std::normal_distribution<double> g(0.0, noise);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = a(rng);
    const double r = R + (noise > 0 ? g(rng) : 0.0);
    c.positions.emplace_back(r * std::cos(t), y(rng), r * std::sin(t));
  }
  return c;
}

inline double rmsOf(const std::vector<double>& e) {
  double s = 0;
  for (double v : e) s += v * v;
  return e.empty() ? 0.0 : std::sqrt(s / static_cast<double>(e.size()));
}

}  // namespace stampscan::fitting::test
