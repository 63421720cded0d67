// Local weighted fits at the heart of the WLS projection: the paper's plane (Eqs. (1), (2), (6), (7))
// and, beyond the paper, an algebraic sphere (Pratt 1987; as used by Guennebaud & Gross, "Algebraic
// Point Set Surfaces", 2007) that follows curvature and so removes the plane fit's shrinkage at peaks.
//
// All fits work in a local frame centred at `origin` and scaled by 1/scale, which keeps the sums well
// conditioned whatever the part's coordinates.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <optional>

namespace stampscan::fitting {

// Weighted sums over a neighbourhood, accumulated point by point.
class WeightedSums {
 public:
  WeightedSums(const Vec3& origin, double scale) : origin_(origin), inv_scale_(1.0 / scale) {}

  // Adds point p with weight w.
  void add(const Vec3& p, double w);
  // Adds a cell of points by their total weight w, weighted centroid and covariance about it: the
  // same sums as adding each point (cell_pyramid.hpp).
  void addCell(const Vec3& mean, const Eigen::Matrix3d& covariance, double w);

  double weightSum() const { return w_; }
  std::size_t count() const { return count_; }
  const Vec3& origin() const { return origin_; }
  double scale() const { return 1.0 / inv_scale_; }

 private:
  friend class LocalSurface;
  Vec3 origin_;
  double inv_scale_;
  std::size_t count_ = 0;
  double w_ = 0;           // sum w
  Vec3 wp_ = Vec3::Zero();  // sum w q          (q = local coordinates)
  Eigen::Matrix3d wpp_ = Eigen::Matrix3d::Zero();  // sum w q q^T
};

// Weighted moments of v = (1, q, |q|^2) over a neighbourhood, for fitting an algebraic sphere to
// positions alone (no normals needed).
class AlgebraicMoments {
 public:
  AlgebraicMoments(const Vec3& origin, double scale) : origin_(origin), inv_scale_(1.0 / scale) {}
  void add(const Vec3& p, double w);
  double weightSum() const { return s_[0]; }
  std::size_t count() const { return count_; }
  // The symmetric 5x5 moment matrix sum w v v^T.
  Eigen::Matrix<double, 5, 5> matrix() const;

 private:
  friend class LocalSurface;
  Vec3 origin_;
  double inv_scale_;
  std::size_t count_ = 0;
  // The 15 distinct entries: w, wx, wy, wz, wr, wxx, wxy, wxz, wxr, wyy, wyz, wyr, wzz, wzr, wrr
  // (r = |q|^2), kept as plain sums so the hot loop vectorises.
  double s_[15] = {};
};

// A fitted local surface: the zero set of s(x) = u0 + ul.q + uq |q|^2 in the local frame
// (uq = 0 is the plane n.(x - a) = 0 of Eq. (1)).
class LocalSurface {
 public:
  enum class Kind { Plane, Sphere };

  // Eq. (2): a = weighted mean; Eqs. (6)-(7): n = eigenvector of the smallest eigenvalue of the
  // weighted covariance. Returns nothing when the weights sum to zero or all weighted points
  // coincide (no plane is defined by repeated observations of one spot).
  static std::optional<LocalSurface> fitPlane(const WeightedSums& sums);

  // Algebraic sphere s(q) = u0 + ul.q + uq |q|^2 minimising sum w s(q_i)^2 under Pratt's
  // normalisation |ul|^2 - 4 u0 uq = 1 (so s is close to the signed distance and planes are the
  // uq = 0 limit). The sign is arbitrary until oriented with flip(). Nothing when degenerate.
  static std::optional<LocalSurface> fitPrattSphere(const AlgebraicMoments& moments);

  // Reverses the orientation (the surface stays the same).
  void flip() {
    u0_ = -u0_;
    ul_ = -ul_;
    uq_ = -uq_;
  }
  const Vec3& origin() const { return origin_; }
  double scale() const { return scale_; }

  Kind kind() const { return kind_; }
  // Orthogonal projection of x onto the fitted surface (world coordinates).
  Vec3 project(const Vec3& x) const;
  // Unit normal at (or near) x: the gradient of s (its sign is arbitrary until oriented).
  Vec3 normal(const Vec3& x) const;
  // Signed distance of x from the surface along the normal (first-order for the sphere); for the
  // plane this is -f of Eq. (1): n.(x - a).
  double signedDistance(const Vec3& x) const;
  // Plane only: the weighted mean a(P*) of Eq. (2); for the sphere, the weighted mean too.
  const Vec3& weightedMean() const { return mean_; }
  // Mean curvature of the fitted sphere (1/radius, signed), 0 for a plane.
  double curvature() const;
  // Smallest eigenvalue over the sum of eigenvalues of the weighted covariance (plane fits):
  // 0 on a perfect plane, 1/3 for isotropic scatter.
  double surfaceVariation() const { return variation_; }
  // Plane fits: the middle eigenvalue of the weighted covariance in units of scale^2, i.e. how far
  // the neighbours spread in the plane's second direction (about 0.5 for a disk evenly covered
  // under a Gaussian of bandwidth scale; near 0 for a row of points or one cluster of repeats).
  double tangentSpread() const { return spread_; }

 private:
  Vec3 origin_ = Vec3::Zero();
  double scale_ = 1;
  Kind kind_ = Kind::Plane;
  double u0_ = 0;
  Vec3 ul_ = Vec3::UnitZ();
  double uq_ = 0;
  Vec3 mean_ = Vec3::Zero();
  double variation_ = 0;
  double spread_ = 0;
  Vec3 toLocal(const Vec3& x) const { return (x - origin_) / scale_; }
};

}  // namespace stampscan::fitting
