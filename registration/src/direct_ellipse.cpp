#include "stampscan/registration/direct_ellipse.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <cmath>

namespace stampscan::registration {

std::optional<CentredEllipse> fitDirectEllipse(const std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 6) return std::nullopt;
  // Centred and scaled to unit spread, so that the quartic sums stay well conditioned.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& q : points) mean += q;
  mean /= static_cast<double>(points.size());
  double spread = 0;
  for (const Eigen::Vector2d& q : points) spread += (q - mean).squaredNorm();
  spread = std::sqrt(spread / static_cast<double>(points.size()));
  if (!(spread > 0)) return std::nullopt;
  // The conic a1 . (x^2, xy, y^2) + a2 . (x, y, 1) = 0. S1, S2 and S3 are the scatter of the
  // quadratic and the linear terms; for a given a1 the best a2 is T a1, and a1 is the eigenvector of
  // C1^-1 (S1 + S2 T) with 4ac - b^2 > 0 (C1 the constraint's matrix; Halir & Flusser, section 3).
  Eigen::Matrix3d S1 = Eigen::Matrix3d::Zero(), S2 = Eigen::Matrix3d::Zero(), S3 = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector2d& q : points) {
    const Eigen::Vector2d u = (q - mean) / spread;
    const Eigen::Vector3d quadratic(u.x() * u.x(), u.x() * u.y(), u.y() * u.y()), linear(u.x(), u.y(), 1);
    S1.noalias() += quadratic * quadratic.transpose();
    S2.noalias() += quadratic * linear.transpose();
    S3.noalias() += linear * linear.transpose();
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> S3_lu(S3);
  if (!S3_lu.isInvertible()) return std::nullopt;
  const Eigen::Matrix3d T = -S3_lu.solve(S2.transpose());
  const Eigen::Matrix3d M = S1 + S2 * T;
  Eigen::Matrix3d reduced;  // C1^-1 M, C1^-1 = [0 0 1/2; 0 -1 0; 1/2 0 0]
  reduced.row(0) = 0.5 * M.row(2);
  reduced.row(1) = -M.row(1);
  reduced.row(2) = 0.5 * M.row(0);
  const Eigen::EigenSolver<Eigen::Matrix3d> eig(reduced);
  if (eig.info() != Eigen::Success) return std::nullopt;
  // The one eigenvector that is an ellipse; the largest margin when rounding leaves more than one.
  Eigen::Vector3d a1 = Eigen::Vector3d::Zero();
  double best = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d v = eig.eigenvectors().col(k).real();
    const double margin = (4 * v(0) * v(2) - v(1) * v(1)) / v.squaredNorm();
    if (margin > best) {
      best = margin;
      a1 = v;
    }
  }
  if (!(best > 0)) return std::nullopt;
  const Eigen::Vector3d a2 = T * a1;
  // The centre, where the conic's gradient vanishes; there (x - c)^T Q (x - c) = -(its value at c).
  Eigen::Matrix2d Q;
  Q << a1(0), 0.5 * a1(1), 0.5 * a1(1), a1(2);
  const Eigen::Vector2d c = -0.5 * Q.inverse() * a2.head<2>();
  const double at_centre = c.dot(Q * c) + a2.head<2>().dot(c) + a2(2);
  if (!(std::abs(at_centre) > 0)) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> axes(Q / -at_centre);
  if (!(axes.eigenvalues().minCoeff() > 0)) return std::nullopt;
  // M = (Q / -value)^(-1/2), in the points' own units.
  CentredEllipse e;
  e.centre = mean + spread * c;
  e.shape = spread * axes.eigenvectors() * axes.eigenvalues().cwiseSqrt().cwiseInverse().asDiagonal() *
            axes.eigenvectors().transpose();
  if (!e.centre.allFinite() || !e.shape.allFinite()) return std::nullopt;
  return e;
}

}  // namespace stampscan::registration
