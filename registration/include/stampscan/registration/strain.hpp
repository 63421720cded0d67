// Strain from what the grid shows: a printed circle's ellipse, or a printed square's four corners.
// True (logarithmic) strains unless a name says engineering. Volume constancy gives the thickness
// strain: eps3 = -(eps1 + eps2).
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <Eigen/Core>

#include <array>

namespace stampscan::registration {

using fitting::Vec3;

struct PrincipalStrains {
  double major = 0;      // eps1 = ln(a / r0), the larger
  double minor = 0;      // eps2 = ln(b / r0)
  double thickness = 0;  // eps3 = -(eps1 + eps2)
  Vec3 major_direction = Vec3::UnitX();  // unit, in the surface (square cells); unset for ellipses
};

// From an ellipse's semi-axes (any order) and the printed circle's radius r0. Throws
// std::invalid_argument for non-positive lengths.
PrincipalStrains strainsFromEllipse(double semi_axis_1, double semi_axis_2, double printed_radius);

// From the four deformed corners of a printed square of side `pitch`, in order around the cell
// (material (0,0), (p,0), (p,p), (0,p)): the deformation gradient at the cell's centre of the bilinear
// map through the corners, then the principal stretches of C = F^T F.
PrincipalStrains strainsFromSquareCell(const std::array<Vec3, 4>& corners, double pitch);

// Thinning in percent: (1 - t / t0) * 100 = (1 - exp(eps3)) * 100.
double thinningPercent(double thickness_strain);
// Engineering strain from true strain: exp(eps) - 1.
double engineeringStrain(double true_strain);

}  // namespace stampscan::registration
