// Automatic bandwidths: per-point values h_i and their smooth Shepard interpolant h(P*) (Eqs. (9),
// (12)-(14)), plus the density-robust scale used by the default method.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <utility>
#include <vector>

namespace stampscan::fitting {

// d_i: distance from each point to its r-th nearest other point (r >= 1), as in the r-SIG (Eq. (8))
// and Eq. (9). Coincident duplicates count as neighbours, which is what makes small r fail on
// stereo data. Parallel; the same result for any thread count.
std::vector<double> rthNeighborDistances(const std::vector<Vec3>& points, const KdTree& tree, int r);

// Eq. (12): h_i = sum_j w_j d_j / sum_j w_j over the other points j, with d_j = |P_i - P_j| (Eq. (11))
// and w_j = exp(-d_j^2 / h0^2) (Eq. (10)) from the initial guess h0 (> 0). Points farther than
// kGaussianCutoff * h0 are left out (their weight is below 0.2 %). A point with no neighbour keeps h0.
std::vector<double> gaussianDataBandwidths(const std::vector<Vec3>& points, const KdTree& tree, double h0);

// Shepard's interpolant of per-point bandwidths, Eqs. (9) and (13), with the weights of Eq. (14),
// w_i = exp(-d_i^2 / h_i^2). The paper prints the Shepard weight as w_i^-2, which would favour far
// points; we read it as Shepard's inverse-square weighting localised by Eq. (14)'s Gaussian:
// s_i = w_i / (d_i^2 + eps^2), with eps a small fraction of h_i so the interpolant stays bounded.
class BandwidthField {
 public:
  // Arithmetic: Eqs. (9), (13) as printed. Harmonic: the same weights averaging 1/h, so that where
  // a small h meets a large one the small one wins (a narrow feature next to a flat region keeps
  // its narrow kernel rather than inheriting half of the flat region's).
  enum class Mean { Arithmetic, Harmonic };
  // `values` holds one h_i per point of `points` (same order); both must outlive the field.
  BandwidthField(const std::vector<Vec3>& points, const KdTree& tree, std::vector<double> values,
                 Mean mean = Mean::Arithmetic);

  // h(x) from the `neighbors` nearest points' h_i; `nearest`, when given, receives the index of
  // the point nearest to x.
  double at(const Vec3& x, int neighbors = 8, std::uint32_t* nearest = nullptr) const;
  // Another per-point quantity (same order as the points) interpolated with the same weights.
  double interpolateOther(const Vec3& x, const std::vector<double>& other, int neighbors = 8) const;
  // Both h(x) and the other quantity, from one neighbour search.
  std::pair<double, double> atAndOther(const Vec3& x, const std::vector<double>& other, int neighbors = 8) const;
  // h at each input point, smoothed over its neighbours (computed in parallel).
  std::vector<double> smoothedAtPoints(int neighbors = 8) const;

  const std::vector<double>& values() const { return values_; }

 private:
  double interpolate(const Vec3& x, const std::vector<Neighbor>& near) const;
  const std::vector<Vec3>& points_;
  const KdTree& tree_;
  std::vector<double> values_;
  Mean mean_;
};

// Density-robust scale for the default method: h_i = factor * d_i with d_i the distance to the
// `rank`-th neighbour. With rank above the number of near-duplicates a stereo sensor produces (up
// to 12-15 per grid element, paper Sec. 3.1), d_i measures the spacing of distinct samples, and
// factor sets how many of them fall under the Gaussian (about rank * factor^2).
struct RobustScaleParams {
  int rank = 16;
  double factor = 1.3;
};
std::vector<double> robustScales(const std::vector<Vec3>& points, const KdTree& tree, const RobustScaleParams& params);

// Summary of a set of bandwidths for reports.
struct BandwidthSummary {
  double min = 0, median = 0, max = 0;
};
BandwidthSummary summarize(std::vector<double> values);

}  // namespace stampscan::fitting
