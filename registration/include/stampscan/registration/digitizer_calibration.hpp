// Digitizer-to-head (hand-eye) transform and the digitizer's latency from sweeps over a reference
// sphere of known radius. Sweeps in opposite directions and at different speeds make the latency
// visible (a late stamp shifts the points along the sweep by speed x latency); sweeps with the head
// turned and tilted make the mount's translation separable from the sphere's position.
#pragma once

#include "stampscan/registration/laser_geometry.hpp"

#include <cstddef>
#include <vector>

namespace stampscan::registration {

struct SphereCalibrationParams {
  double sphere_radius = 12.7;                   // mm, the artefact's certified radius
  DigitizerCalibration nominal;                  // mount from the drawing, clock offset from sync pairs, latency 0
  std::size_t max_points = 40000;                // spread evenly over the sweeps
  int max_iterations = 50;
  double tukey_constant = 4.685;                 // robust weights, in units of the residual scale
};

struct SphereCalibrationResult {
  DigitizerCalibration calibration;
  Vec3 sphere_centre = Vec3::Zero();  // machine frame
  double rms_mm = 0;                  // radial residual RMS of the inliers
  std::size_t points = 0, inliers = 0;
  int iterations = 0;
};

// Throws std::runtime_error when too few points fall on the sphere.
SphereCalibrationResult calibrateDigitizer(const std::vector<Profile>& sphere_profiles, const HeadTrack& track,
                                           const SphereCalibrationParams& params);

}  // namespace stampscan::registration
