// A smooth stamped pan with a punch-stretched dome in its floor, known analytically: height, normal,
// closest point and thickness strain at every (x, y). It is the ground truth the fitting tests and
// the benchmark measure against.
#pragma once

#include "stampscan/fitting/cloud.hpp"

namespace stampscan::sim {

using fitting::Vec3;

struct PanParams {
  double half_length = 80;  // mm, x extent of the blank
  double half_width = 60;   // mm, y extent
  double pocket_a = 45;     // mm, x half-size of the pocket at mid-wall
  double pocket_b = 30;     // mm, y half-size
  double depth = 25;        // mm
  double wall_width = 14;   // mm, horizontal run of the wall (steeper when smaller)
  double dome_radius = 14;  // mm, dome in the pocket floor
  double dome_height = 6;   // mm
  double max_thinning_strain = 0.35;  // |eps3| at the steepest wall
};

class PanPart {
 public:
  explicit PanPart(const PanParams& params = {});

  double height(double x, double y) const;
  // The pocket's normalised radius: 1 on the outline at mid-wall, a rounded rectangle (a
  // superellipse of order 4) around the centre.
  double pocketRadius(double x, double y) const;
  // The height of the flange-wall-floor profile at pocket radius s, without the floor's dome.
  double wallHeight(double s) const;
  Eigen::Vector2d gradient(double x, double y) const;
  Vec3 surfacePoint(double x, double y) const { return {x, y, height(x, y)}; }
  Vec3 normal(double x, double y) const;  // unit, facing +z
  // Thickness true strain eps3 (negative: thinning) of the formed sheet at (x, y): a smooth field
  // that grows with the wall slope and peaks on the dome.
  double thicknessStrain(double x, double y) const;
  // The point of the surface closest to p (Gauss-Newton on the height field).
  Vec3 closestPoint(const Vec3& p) const;
  // Unsigned orthogonal distance from p to the surface.
  double distance(const Vec3& p) const { return (p - closestPoint(p)).norm(); }
  const PanParams& params() const { return params_; }

 private:
  PanParams params_;
};

}  // namespace stampscan::sim
