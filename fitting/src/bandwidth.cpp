#include "stampscan/fitting/bandwidth.hpp"

#include "stampscan/fitting/kernels.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace stampscan::fitting {

namespace {
template <class Fn>
void forEachPoint(std::size_t n, Fn&& fn) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) fn(i);
  });
}
}  // namespace

std::vector<double> rthNeighborDistances(const std::vector<Vec3>& points, const KdTree& tree, int r) {
  const int rank = std::max(1, r);
  std::vector<double> d(points.size(), 0.0);
  forEachPoint(points.size(), [&](std::size_t i) {
    thread_local std::vector<Neighbor> near;
    // +1: the query point is its own nearest neighbour at distance 0.
    tree.knn(points[i], static_cast<std::size_t>(rank) + 1, near);
    d[i] = near.size() > 1 ? std::sqrt(near.back().distance_sq) : 0.0;
  });
  return d;
}

std::vector<double> gaussianDataBandwidths(const std::vector<Vec3>& points, const KdTree& tree, double h0) {
  std::vector<double> h(points.size(), h0);
  const double h0_sq = h0 * h0;
  forEachPoint(points.size(), [&](std::size_t i) {
    thread_local std::vector<Neighbor> near;
    tree.radius(points[i], kGaussianCutoff * h0, near);
    double sum_w = 0, sum_wd = 0;
    for (const Neighbor& nb : near) {
      if (nb.index == i) continue;  // Eq. (12): i != j
      const double w = gaussianWeightSq(nb.distance_sq, h0_sq);  // Eq. (10)
      sum_w += w;
      sum_wd += w * std::sqrt(nb.distance_sq);  // Eq. (11)
    }
    if (sum_w > 0) h[i] = sum_wd / sum_w;  // Eq. (12)
  });
  return h;
}

BandwidthField::BandwidthField(const std::vector<Vec3>& points, const KdTree& tree, std::vector<double> values, Mean mean)
    : points_(points), tree_(tree), values_(std::move(values)), mean_(mean) {}

double BandwidthField::interpolate(const Vec3& /*x*/, const std::vector<Neighbor>& near) const {
  double sum_s = 0, sum_sh = 0;
  for (const Neighbor& nb : near) {
    const double hi = values_[nb.index];
    if (!(hi > 0)) continue;
    const double hi_sq = hi * hi;
    const double w = gaussianWeightSq(nb.distance_sq, hi_sq);  // Eq. (14)
    const double s = w / (nb.distance_sq + 0.01 * hi_sq);      // Shepard weight, see header
    sum_s += s;
    sum_sh += mean_ == Mean::Arithmetic ? s * hi : s / hi;
  }
  if (sum_s > 0) return mean_ == Mean::Arithmetic ? sum_sh / sum_s : sum_s / sum_sh;  // Eqs. (9), (13)
  // Far from every point: fall back to the nearest point's value.
  return near.empty() ? 0.0 : values_[near.front().index];
}

double BandwidthField::at(const Vec3& x, int neighbors, std::uint32_t* nearest) const {
  thread_local std::vector<Neighbor> near;
  tree_.knn(x, static_cast<std::size_t>(std::max(1, neighbors)), near);
  if (nearest && !near.empty()) *nearest = near.front().index;
  return interpolate(x, near);
}

double BandwidthField::interpolateOther(const Vec3& x, const std::vector<double>& other, int neighbors) const {
  return atAndOther(x, other, neighbors).second;
}

std::pair<double, double> BandwidthField::atAndOther(const Vec3& x, const std::vector<double>& other, int neighbors) const {
  thread_local std::vector<Neighbor> near;
  tree_.knn(x, static_cast<std::size_t>(std::max(1, neighbors)), near);
  double sum_s = 0, sum_v = 0;
  for (const Neighbor& nb : near) {
    const double hi = values_[nb.index];
    if (!(hi > 0)) continue;
    const double hi_sq = hi * hi;
    const double s = gaussianWeightSq(nb.distance_sq, hi_sq) / (nb.distance_sq + 0.01 * hi_sq);
    sum_s += s;
    sum_v += s * other[nb.index];
  }
  const double value = sum_s > 0 ? sum_v / sum_s : (near.empty() ? 0.0 : other[near.front().index]);
  return {interpolate(x, near), value};
}

std::vector<double> BandwidthField::smoothedAtPoints(int neighbors) const {
  std::vector<double> h(points_.size(), 0.0);
  forEachPoint(points_.size(), [&](std::size_t i) {
    thread_local std::vector<Neighbor> near;
    tree_.knn(points_[i], static_cast<std::size_t>(std::max(1, neighbors)), near);
    h[i] = interpolate(points_[i], near);
  });
  return h;
}

std::vector<double> robustScales(const std::vector<Vec3>& points, const KdTree& tree, const RobustScaleParams& params) {
  std::vector<double> h = rthNeighborDistances(points, tree, params.rank);
  for (double& v : h) v *= params.factor;
  return h;
}

BandwidthSummary summarize(std::vector<double> values) {
  BandwidthSummary s;
  if (values.empty()) return s;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  s.median = *mid;
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  s.min = *lo;
  s.max = *hi;
  return s;
}

}  // namespace stampscan::fitting
