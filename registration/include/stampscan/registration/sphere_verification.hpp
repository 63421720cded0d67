// Verification of the digitizer on a calibrated reference sphere, in the manner of ISO 10360-8
// (acceptance and reverification tests for CMMs with optical distance sensors), clause "probing
// errors": a sphere is fitted by unconstrained least squares to all the points measured on the
// artefact, and two figures are compared with their maximum permissible errors (MPE):
//
//   probing form error  P[Form.Sph.All]  the range of the points' radial deviations from the fitted
//                                        sphere (largest minus smallest), mm
//   probing size error  P[Size.Sph.All]  the fitted sphere's diameter minus the certified one, mm
//
// "All" is the standard's evaluation with every point, no outliers removed: the only points left out
// are those not on the sphere at all (the table it stands on, the stem), by a shell around the
// sphere located first (SphereVerificationParams::evaluation_shell_mm). The length check between two
// spheres (the standard's length measurement error E) is not done here yet.
//
// Thread safety: pure functions on their arguments.
#pragma once

#include "stampscan/registration/laser_geometry.hpp"

#include <cstddef>
#include <span>
#include <vector>

namespace stampscan::registration {

// A sphere fitted by least squares, and the points' radial deviations from it (distance to the
// centre minus the radius, positive outside).
struct SphereFit {
  Vec3 centre = Vec3::Zero();
  double radius = 0;              // mm
  double rms_mm = 0;              // of the radial deviations
  double min_deviation_mm = 0;    // the smallest (most negative) radial deviation
  double max_deviation_mm = 0;    // the largest
  std::size_t points = 0;
  int iterations = 0;
};

// The geometric least-squares sphere (the sum of squared radial deviations is least): the algebraic
// fit as the start, then Gauss-Newton. Throws std::invalid_argument with fewer than 4 points or
// points that do not determine a sphere (all on a plane or a line).
SphereFit fitSphere(std::span<const Vec3> points);

struct SphereVerificationParams {
  double certified_diameter_mm = 25.4;  // from the sphere's certificate
  // Maximum permissible errors, until the cell config carries the manufacturer's stated values.
  // P[Form.Sph.All] is the full range over every point, so it grows with the number of points:
  // about 10 sigma for the few million returns of eight sweeps, 0.06 mm for a line scanner of the
  // digitizer's class (6 um noise). The size error averages the noise out and is held tighter.
  double form_mpe_mm = 0.100;  // MPE for P[Form.Sph.All]
  double size_mpe_mm = 0.030;  // MPE for |P[Size.Sph.All]|
  // Points further than this from the located sphere of certified radius are not on the artefact
  // (the table, the stem, stray returns) and are left out before the fit. Wider than any form error
  // that could pass, so that no point on the sphere is lost to it.
  double evaluation_shell_mm = 1.0;
  std::size_t min_points = 100;  // fewer points on the sphere and the verification is refused
};

struct SphereVerification {
  SphereFit fit;
  double form_error_mm = 0;  // P[Form.Sph.All]
  double size_error_mm = 0;  // P[Size.Sph.All]
  bool form_passed = false, size_passed = false;
  std::size_t points_measured = 0;  // all the points given
  std::size_t points_on_sphere = 0; // within the evaluation shell, used for the fit
  bool passed() const { return form_passed && size_passed; }
};

// Locates the sphere among the points (robust fit of a sphere of the certified radius), keeps the
// points within the evaluation shell, fits the least-squares sphere to them and computes the probing
// errors. Throws std::runtime_error when fewer than params.min_points lie on the sphere.
SphereVerification verifySphere(std::span<const Vec3> points, const SphereVerificationParams& params);

// The returns of the sphere sweeps' profiles in the machine frame with the given calibration;
// overexposed profiles and profiles outside the head track are left out.
std::vector<Vec3> spherePoints(const std::vector<Profile>& profiles, const HeadTrack& track,
                               const DigitizerCalibration& calibration);

}  // namespace stampscan::registration
