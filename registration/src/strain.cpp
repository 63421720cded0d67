#include "stampscan/registration/strain.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <stdexcept>
#include <utility>

namespace stampscan::registration {

PrincipalStrains strainsFromEllipse(double a, double b, double r0) {
  if (!(a > 0) || !(b > 0) || !(r0 > 0))
    throw std::invalid_argument("strain: ellipse axes and printed radius must be positive");
  if (b > a) std::swap(a, b);
  PrincipalStrains s;
  s.major = std::log(a / r0);
  s.minor = std::log(b / r0);
  s.thickness = -(s.major + s.minor);
  return s;
}

PrincipalStrains strainsFromSquareCell(const std::array<Vec3, 4>& c, double pitch) {
  if (!(pitch > 0)) throw std::invalid_argument("strain: grid pitch must be positive");
  // Bilinear map X(u, v) through the corners; its derivatives averaged over the cell = at the centre.
  Eigen::Matrix<double, 3, 2> F;
  F.col(0) = ((c[1] - c[0]) + (c[2] - c[3])) / (2 * pitch);
  F.col(1) = ((c[3] - c[0]) + (c[2] - c[1])) / (2 * pitch);
  const Eigen::Matrix2d C = F.transpose() * F;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(C);
  if (!(eig.eigenvalues()(0) > 0)) throw std::invalid_argument("strain: degenerate square cell");
  PrincipalStrains s;
  s.major = 0.5 * std::log(eig.eigenvalues()(1));
  s.minor = 0.5 * std::log(eig.eigenvalues()(0));
  s.thickness = -(s.major + s.minor);
  s.major_direction = (F * eig.eigenvectors().col(1)).normalized();
  return s;
}

double thinningPercent(double thickness_strain) { return (1 - std::exp(thickness_strain)) * 100; }
double engineeringStrain(double true_strain) { return std::expm1(true_strain); }

}  // namespace stampscan::registration
