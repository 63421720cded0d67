// A scanned-looking cloud of the sample pan, with the defects of real scans that the paper describes:
// laser sweeps that overlap at small angles (density doubles where they meet), stereo observations
// repeated 1-12 times per grid element, Gaussian noise, dropouts on steep walls, a hole and a few
// outliers. Deterministic for a given seed.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <cstdint>

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

SampleCloud makeSampleCloud(const PanPart& part, const SampleCloudParams& params = {});

// Root-mean-square orthogonal distance of `points` to the part surface, and the largest distance.
struct SurfaceError {
  double rms = 0;
  double max = 0;
};
SurfaceError surfaceError(const PanPart& part, const std::vector<Vec3>& points);

}  // namespace stampscan::sim
