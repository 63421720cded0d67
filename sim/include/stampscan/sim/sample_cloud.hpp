// A scanned-looking cloud of the sample pan (or another shape), with the defects of real scans that the paper describes:
// laser sweeps that overlap at small angles (density doubles where they meet), stereo observations
// repeated 1-12 times per grid element, Gaussian noise, dropouts on steep walls, a hole and a few
// outliers. Deterministic for a given seed.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <cstdint>
#include <functional>

namespace stampscan::sim {

struct SampleCloudParams {
  std::size_t target_points = 100000;  // approximate; laser density is scaled to reach it
  double noise_sigma = 0.05;           // mm, standard deviation per coordinate
  double grid_pitch = 2.54;            // mm, stereo grid element spacing
  int max_repeats = 12;                // stereo observations per element: uniform in 1..max_repeats
  double stereo_fraction = 0.25;       // share of the part's x range seen only by the stereo pair
  double hole_radius = 6;              // mm; 0 for no hole
  double outlier_fraction = 0.002;     // points displaced along z by 0.3..1.5 mm
  double steep_dropout = 0.5;          // chance of losing a laser point where the wall is steepest
  std::uint64_t seed = 1;
};

struct SampleCloud {
  fitting::Cloud cloud;             // positions and thickness strain (true strain + measurement noise)
  std::vector<double> true_strain;  // at the closest surface point of each sample
  std::size_t laser_points = 0, stereo_points = 0, outliers = 0;
};

// What the sample scan needs of a shape: its height, slope and thickness strain over a rectangle
// |x| <= half_length, |y| <= half_width, and the distance of any point to it (the ground truth).
struct SampleShape {
  std::function<double(double, double)> height;
  std::function<double(double, double)> slope;  // |grad height|
  std::function<double(double, double)> thickness_strain;
  std::function<double(const Vec3&)> distance;
  double half_length = 0, half_width = 0;
};
// The sample pan (tight radii, steep walls) and any formed part centred on the origin (for example
// the smooth punch-stretched dome). The part must outlive the shape.
SampleShape sampleShape(const PanPart& part);
SampleShape sampleShape(const FormedPart& part);

SampleCloud makeSampleCloud(const SampleShape& shape, const SampleCloudParams& params = {});
inline SampleCloud makeSampleCloud(const PanPart& part, const SampleCloudParams& params = {}) {
  return makeSampleCloud(sampleShape(part), params);
}

// Root-mean-square orthogonal distance of `points` to the part surface, and the largest distance.
struct SurfaceError {
  double rms = 0;
  double max = 0;
};
SurfaceError surfaceError(const SampleShape& shape, const std::vector<Vec3>& points);
inline SurfaceError surfaceError(const PanPart& part, const std::vector<Vec3>& points) {
  return surfaceError(sampleShape(part), points);
}

}  // namespace stampscan::sim
