// A local quadric height field over a tangent frame: w = c0 + c1 u + c2 v + c3 u^2 + c4 uv + c5 v^2,
// with (u, v, w) the coordinates of a point in a frame (t1, t2, n) at `origin`, scaled by 1/scale;
// optionally with the cubic terms c6 u^3 + c7 u^2 v + c8 u v^2 + c9 v^3 (order 3).
//
// The cubic terms leave the height at the origin as it is for a support symmetric about it (odd
// terms average out), but a patch read away from its origin follows the surface much longer: the
// widened fits of anchored_surface.hpp, read up to a bandwidth from their centres, use them.
//
// Beyond the paper: unlike the plane of Eq. (1) it follows curvature (no shrinkage at peaks), and
// unlike a sphere it takes different curvatures in different directions, as on the cylindrical
// walls and radii of a stamped part. The frame comes from the paper's weighted plane (Eqs. (2),
// (6), (7)); the coefficients are a weighted least-squares fit of the heights above it.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/local_fit.hpp"

#include <optional>
#include <vector>

namespace stampscan::fitting {

class QuadricPatch {
 public:
  // Accumulates the weighted normal equations of the height fit in the frame of `plane`.
  class Sums {
   public:
    Sums(const LocalSurface& plane, const Vec3& origin, double scale);
    // The same in a frame of one's own (columns t1, t2, n); order 2 (quadric) or 3 (cubic).
    // `variance_rows`, when given, is cleared and receives each addCell's design row and variance
    // weight, from which fitWithOffsetVariance gets the offset's variance; it must outlive the sums.
    Sums(const Eigen::Matrix3d& frame, const Vec3& origin, double scale, int order = 2,
         std::vector<double>* variance_rows = nullptr);
    void add(const Vec3& p, double w);
    // A cell of points given by their weighted centroid and covariance (the pyramid of
    // cell_pyramid.hpp): its design row is the mean of its points' rows, which the covariance makes
    // exact for the quadratic terms, so the cell adds no curvature bias. `variance_weight` is the
    // sum of the squared weights its points carry in this fit; it feeds the offset's variance.
    // (For order 3 the cell's third central moments are taken as zero: cells are small against h.)
    void addCell(const Vec3& mean, const Eigen::Matrix3d& covariance, double w, double variance_weight);
    std::size_t count() const { return count_; }

   private:
    friend class QuadricPatch;
    int terms() const { return order_ == 3 ? 10 : 6; }
    // One design row into the sums, with the row's length fixed at compile time so that the
    // compiler unrolls the 21 or 55 products.
    template <int N>
    void accumulate(const double* phi, double w, double height) {
      int k = 0;
#pragma GCC unroll 10
      for (int i = 0; i < N; ++i) {
        const double wi = w * phi[i];
#pragma GCC unroll 10
        for (int j = 0; j <= i; ++j, ++k) ata_[k] += wi * phi[j];
        atb_[i] += wi * height;
      }
    }
    Vec3 origin_;
    double inv_scale_;
    Eigen::Matrix3d frame_;  // columns t1, t2, n
    int order_ = 2;
    // Lower triangle of sum w phi phi^T (21 entries for the quadric, 55 for the cubic, row by row;
    // the quadric's are the first 21 of the cubic's) and sum w w_height phi, kept as plain sums so
    // the accumulation loop vectorises.
    double ata_[55] = {};
    double atb_[10] = {};
    // Each addCell's row and variance weight (terms() + 1 numbers), when kept: the variance of the
    // offset needs only each row's product with M^-1 e_0, cheaper than a second set of sums.
    std::vector<double>* variance_rows_ = nullptr;
    std::size_t count_ = 0;
  };

  // Nothing when the weights sum to zero. With too little spread for curvature the quadratic
  // terms are damped towards the plane (a small ridge), never left undetermined.
  static std::optional<QuadricPatch> fit(const Sums& sums);
  // The fit and the variance of its height at the origin per unit variance of a point's residual
  // (the sandwich M^-1 B M^-1 of weighted least squares), for sums that kept their variance rows.
  struct FitWithVariance;
  static std::optional<FitWithVariance> fitWithOffsetVariance(const Sums& sums);

  // Closest point of the patch to x (Gauss-Newton on the height field, two steps).
  Vec3 project(const Vec3& x) const;
  // Unit normal at the patch point above/below x, on the side of the frame normal.
  Vec3 normal(const Vec3& x) const;
  // Signed distance from x to the patch along its normal (first order).
  double signedDistance(const Vec3& x) const;
  // Height of the patch above its origin, along the frame normal.
  double heightAtOrigin() const { return c_(0) * scale_; }
  // The larger principal curvature's magnitude at the origin (second derivatives of the height
  // field; exact where the patch is level there).
  double maxCurvatureAtOrigin() const;
  // The height field's second derivatives at the origin (1/mm), in the frame's tangent axes: the
  // second fundamental form where the patch is level there.
  Eigen::Matrix2d hessianAtOrigin() const;
  // Reverses the orientation (the surface stays the same).
  void flip();
  const Vec3& origin() const { return origin_; }

 private:
  Vec3 toLocal(const Vec3& x) const { return frame_.transpose() * (x - origin_) / scale_; }
  double height(double u, double v) const {
    return c_(0) + c_(1) * u + c_(2) * v + c_(3) * u * u + c_(4) * u * v + c_(5) * v * v +
           u * u * (c_(6) * u + c_(7) * v) + v * v * (c_(8) * u + c_(9) * v);
  }
  Eigen::Vector2d slope(double u, double v) const {
    return {c_(1) + 2 * c_(3) * u + c_(4) * v + 3 * c_(6) * u * u + 2 * c_(7) * u * v + c_(8) * v * v,
            c_(2) + c_(4) * u + 2 * c_(5) * v + c_(7) * u * u + 2 * c_(8) * u * v + 3 * c_(9) * v * v};
  }
  Vec3 origin_ = Vec3::Zero();
  double scale_ = 1;
  Eigen::Matrix3d frame_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 10, 1> c_ = Eigen::Matrix<double, 10, 1>::Zero();  // cubic terms 0 for a quadric
};

struct QuadricPatch::FitWithVariance {
  QuadricPatch patch;
  double offset_variance_factor = 0;  // infinite when it cannot be told
};

}  // namespace stampscan::fitting
