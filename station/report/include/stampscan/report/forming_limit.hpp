// The forming-limit curve (FLC) of a sheet material and the strain measures a press shop reads it in.
//
// Forming-limit diagrams are read in engineering strain percent (minor strain on the abscissa, major
// on the ordinate), as the shop floor and the material suppliers publish them; the rest of StampScan
// works in true strain. The conversions are here, named, so that no caller mixes the two.
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace stampscan::report {

// Engineering strain in percent from true (logarithmic) strain, and back.
inline double engineeringPercent(double true_strain) { return std::expm1(true_strain) * 100.0; }
inline double trueStrain(double engineering_percent) { return std::log1p(engineering_percent / 100.0); }
// Thinning in percent of the initial thickness from the thickness true strain eps3: (1 - exp(eps3)) * 100.
// Positive when the sheet thinned, negative when it thickened.
inline double thinningPercent(double thickness_true_strain) { return -std::expm1(thickness_true_strain) * 100.0; }

// A point of a forming-limit diagram, in engineering strain percent.
struct FldPoint {
  double minor = 0;  // e2, %
  double major = 0;  // e1, %
};

// The Keeler-Brazier FLC0, the plane-strain (minor = 0) limit, in engineering major strain percent:
//   FLC0 = (23.3 + 14.13 t) * n / 0.21,    t the sheet thickness in mm, n the strain-hardening exponent.
// Source: S. P. Keeler and W. G. Brazier, "Relationship between laboratory material characterization
// and press-shop formability", Microalloying 75, New York, 1977 (presented 1975), in the metric form the
// North American Deep Drawing Research Group (NADDRG) publishes. The thickness term is capped at
// 3 mm: the fit covers sheet up to about 3 mm and gives no further gain beyond it. n enters as
// published (the fit was made on low-carbon steels; for aluminium alloys it overestimates the limit,
// which is why aluminium entries should carry a measured curve). Throws std::invalid_argument for
// t <= 0 or n <= 0.
double keelerBrazierFlc0(double thickness_mm, double n);

// The thickness term's cap of the Keeler-Brazier formula, in mm.
inline constexpr double kKeelerBrazierMaxThicknessMm = 3.0;
// The slope of the Keeler-Brazier right branch, d(e1)/d(e2) in engineering strain.
inline constexpr double kKeelerBrazierRightSlope = 0.6;

// A forming-limit curve: the major strain at the onset of necking as a function of the minor strain.
//
// Two kinds, one interface:
//  - keelerBrazier(flc0): the standard curve shape through FLC0. Left of plane strain (e2 < 0) it
//    follows the line of constant thickness through FLC0, e1 + e2 = const in true strain, which in
//    engineering strain is (1 + e1)(1 + e2) = 1 + FLC0 (slope -1 in true strain; -(1 + FLC0) at
//    e2 = 0 in engineering strain, flattening to the left). Right of it (e2 > 0) a straight line
//    of slope +0.6 in engineering strain: e1 = FLC0 + 0.6 e2.
//  - measured(points): a curve measured on the material (Nakajima or Marciniak tests, ISO 12004),
//    piecewise linear between its points in engineering strain, extended beyond the first and the
//    last point along the end segments.
//
// Thread safety: const methods are safe to call concurrently.
class FormingLimitCurve {
 public:
  static FormingLimitCurve keelerBrazier(double flc0_percent);
  // At least two points with strictly increasing minor strain; throws std::invalid_argument otherwise.
  static FormingLimitCurve measured(std::vector<FldPoint> points);

  bool isMeasured() const { return !points_.empty(); }
  // The plane-strain limit, e1 at e2 = 0, in %.
  double flc0() const { return majorAt(0.0); }
  // The limit major strain e1 (%) at minor strain e2 (%). For the Keeler-Brazier left branch, e2 must
  // be above -100% (a sheet cannot shrink to nothing); below it the limit is +infinity.
  double majorAt(double minor_percent) const;

  // The safety margin of a point of the diagram: how far it is from the curve along its strain path,
  // in engineering strain percent; positive below the curve, negative above it.
  //
  // The path is the proportional one from the undeformed sheet through the point: a straight line in
  // true strain, eps2 / eps1 constant (in engineering strain it bends). A straight line in
  // engineering strain would be wrong on the left of the diagram: the uniaxial ray e2 = -e1/2 never
  // reaches the constant-thickness branch, while the true uniaxial path eps2 = -eps1/2 does. The
  // distance is measured in the engineering-strain diagram the operator reads, from the point to
  // where its path meets the curve. +infinity when the path never meets the curve: compression paths
  // at or beyond pure shear (eps2 <= -eps1), which never thin. The undeformed sheet is measured along
  // plane strain.
  double marginAlongPath(double minor_percent, double major_percent) const;
  // The margin curve: each point of the curve moved back along its own strain path until it is
  // `margin_percent` from the curve, so that an element lies between it and the curve exactly when its
  // margin (marginAlongPath) is between 0 and `margin_percent`. Sampled between two minor strains of
  // the FLC.
  std::vector<FldPoint> marginCurve(double margin_percent, double minor_from, double minor_to, int samples) const;

  // The curve sampled for drawing between two minor strains.
  std::vector<FldPoint> sample(double minor_from, double minor_to, int samples) const;

  // The measured points (empty for the Keeler-Brazier curve).
  const std::vector<FldPoint>& points() const { return points_; }
  std::string describe() const;

 private:
  // How far along the true-strain direction (eps2, eps1) = (du, dv), |(du, dv)| = 1, the path first
  // meets the curve, in true strain; +infinity when it does not within reach.
  double crossingDistance(double du, double dv) const;

  double flc0_ = 0;
  std::vector<FldPoint> points_;
};

}  // namespace stampscan::report
