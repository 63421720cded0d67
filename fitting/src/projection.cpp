#include "stampscan/fitting/projection.hpp"

#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/median.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stampscan::fitting {

namespace {
// Tukey's biweight: full weight near the fit, zero beyond c robust standard deviations.
constexpr double kTukeyC = 4.685;
// Robust weights are re-estimated during the first iterations, then frozen so the iteration settles.
constexpr int kRobustIterations = 2;

struct Candidate {
  std::uint32_t index;
  double base_weight;  // fixed weight (data-to-data, graph kernels), unused for Euclidean
  double robust = 1.0;
  double weight = 0;   // weight of the last fit
};

}  // namespace

WlsSurface::WlsSurface(const SurfaceData& data, const ProjectionParams& params) : data_(data), params_(params) {
  if (!data_.points || !data_.tree || !data_.bandwidths) throw std::invalid_argument("WlsSurface: points, tree and bandwidths are required");
  if (params_.weights == WeightScheme::GraphDistance && !data_.graph)
    throw std::invalid_argument("WlsSurface: the graph-distance kernel needs the r-SIG graph");
}

Projection WlsSurface::projectPoint(std::size_t i) const {
  return run((*data_.points)[i], static_cast<std::uint32_t>(i), data_.bandwidths->values()[i]);
}

double WlsSurface::bandwidthAt(const Vec3& x) const { return data_.bandwidths->at(x); }

Projection WlsSurface::project(const Vec3& x) const {
  // h(x) by Shepard's interpolant of the per-point bandwidths (Eqs. (9), (13)); the nearest data
  // point anchors the data-to-data and graph kernels.
  std::uint32_t nearest = 0;
  const double h = data_.bandwidths->at(x, 8, &nearest);
  if (!(h > 0)) return Projection{x, Vec3::UnitZ(), std::numeric_limits<double>::quiet_NaN(), 0, 0, false, false, 0};
  return run(x, nearest, h);
}

double ImplicitSurface::signedDistance(const Vec3& x, Projection* out) const {
  const Projection p = project(x);
  if (out) *out = p;
  if (!p.valid) return std::numeric_limits<double>::quiet_NaN();
  return p.normal.dot(x - p.point);
}

namespace {

// One projection's neighbourhood and fits (Sec. 3 of the paper): the candidates gathered once, the
// local surface fitted at the moving point, robust weights re-estimated in the first iterations.
class ProjectionRun {
 public:
  ProjectionRun(const SurfaceData& data, const ProjectionParams& params, double h)
      : data_(data), params_(params), points_(*data.points), h_(h), h_sq_(h * h),
        support_(kernelSupport(params.kernel, h)), margin_(0.5 * h),
        euclidean_(params.weights == WeightScheme::Euclidean), sphere_(params.model == SurfaceModel::Sphere) {
    candidates_.clear();
  }

  // The neighbourhood: by graph distance or data-to-data distance from the anchor (fixed weights),
  // or for the Euclidean kernel around the start (the weights move with P*).
  void gather(const Vec3& start, std::uint32_t anchor) {
    if (params_.weights == WeightScheme::GraphDistance) {
      data_.graph->distancesFrom(anchor, support_, reached_);
      for (const auto& r : reached_) candidates_.push_back({r.vertex, kernelWeight(params_.kernel, r.distance, h_)});
    } else if (params_.weights == WeightScheme::DataToData) {
      data_.tree->radius(points_[anchor], support_, near_);
      for (const Neighbor& nb : near_)
        candidates_.push_back({nb.index, kernelWeight(params_.kernel, std::sqrt(nb.distance_sq), h_)});  // Eqs. (10)-(11)
    } else {
      gatherEuclidean(start);
    }
  }

  // For the Euclidean kernel the centre moves with P*: the query radius carries a margin and is
  // refreshed once P* wanders farther than that.
  void followPoint(const Vec3& x) {
    if (euclidean_ && (x - query_centre_).norm() > margin_) gatherEuclidean(x);
  }

  std::optional<LocalSurface> fitAt(const Vec3& centre) {
    WeightedSums plane_sums(centre, h_);
    AlgebraicMoments sphere_sums(centre, h_);
    for (Candidate& c : candidates_) {
      const Vec3& p = points_[c.index];
      double w = c.base_weight;
      if (euclidean_) {
        const double r_sq = (p - centre).squaredNorm();
        w = params_.kernel == KernelType::Gaussian ? (r_sq < support_ * support_ ? gaussianWeightSq(r_sq, h_sq_) : 0.0)
                                                   : cubicWeight(std::sqrt(r_sq), h_);  // Eqs. (3)-(5)
      }
      w *= c.robust;
      c.weight = w;
      if (w <= 0) continue;
      if (sphere_)
        sphere_sums.add(p, w);
      else
        plane_sums.add(p, w);  // Eqs. (2), (6), (7)
    }
    return sphere_ ? LocalSurface::fitPrattSphere(sphere_sums) : LocalSurface::fitPlane(plane_sums);
  }

  // Robust weights (Tukey's biweight) from the median absolute residual of the points that carry
  // weight. The first residuals come from a plane: a sphere fitted through outliers can bend round
  // them and make them look like inliers; a plane cannot.
  void reweigh(const Vec3& x, const LocalSurface& fit, bool first) {
    std::optional<LocalSurface> reference = fit;
    if (sphere_ && first) {
      WeightedSums plane_sums(x, h_);
      for (const Candidate& c : candidates_)
        if (c.weight > 0) plane_sums.add(points_[c.index], c.weight);
      reference = LocalSurface::fitPlane(plane_sums);
      if (!reference) reference = fit;
    }
    residuals_.clear();
    for (const Candidate& c : candidates_)
      if (c.weight > 0) residuals_.push_back(std::abs(reference->signedDistance(points_[c.index])));
    const double sigma = std::max(1.4826 * (residuals_.empty() ? 0.0 : medianInPlace(residuals_)), 1e-6 * h_);
    const double cutoff = kTukeyC * sigma;
    for (Candidate& c : candidates_) {
      const double r = std::abs(reference->signedDistance(points_[c.index])) / cutoff;
      c.robust = r < 1.0 ? (1.0 - r * r) * (1.0 - r * r) : 0.0;
    }
  }

  // The projected point's normal (oriented like the data normals when known), the points used, and
  // the scalar there (Sec. 5).
  void finish(const Vec3& x, const LocalSurface& fit, Projection& result) const {
    result.valid = true;
    result.point = x;
    Vec3 n = fit.normal(x);
    if (data_.normals) {
      Vec3 reference = Vec3::Zero();
      for (const Candidate& c : candidates_) reference += c.weight * (*data_.normals)[c.index].cast<double>();
      if (n.dot(reference) < 0) n = -n;
    }
    result.normal = n;
    std::size_t used = 0;
    for (const Candidate& c : candidates_) used += c.weight > 0;
    result.neighbors = used;
    if (data_.scalar) {
      thread_local std::vector<ScalarSample> samples;
      samples.clear();
      for (const Candidate& c : candidates_)
        if (c.weight > 0) samples.push_back({points_[c.index], (*data_.scalar)[c.index], c.weight});
      result.scalar = params_.scalar == ScalarFieldType::Smooth ? smoothScalar(x, n, samples)
                                                                : shepardScalar(x, samples, support_);
    }
  }

 private:
  void gatherEuclidean(const Vec3& centre) {
    data_.tree->radius(centre, support_ + margin_, near_);
    // Keep the robust weights of points already seen; they only make sense for the same points.
    candidates_.clear();
    for (const Neighbor& nb : near_) candidates_.push_back({nb.index, 0.0});
    query_centre_ = centre;
  }

  const SurfaceData& data_;
  const ProjectionParams& params_;
  const std::vector<Vec3>& points_;
  const double h_, h_sq_, support_, margin_;
  const bool euclidean_, sphere_;
  Vec3 query_centre_ = Vec3::Zero();
  // Reused by every projection on a thread.
  static thread_local std::vector<Candidate> candidates_;
  static thread_local std::vector<Neighbor> near_;
  static thread_local std::vector<SigGraph::Reached> reached_;
  static thread_local std::vector<double> residuals_;
};

thread_local std::vector<Candidate> ProjectionRun::candidates_;
thread_local std::vector<Neighbor> ProjectionRun::near_;
thread_local std::vector<SigGraph::Reached> ProjectionRun::reached_;
thread_local std::vector<double> ProjectionRun::residuals_;

}  // namespace

Projection WlsSurface::run(const Vec3& start, std::uint32_t anchor, double h) const {
  Projection result;
  result.point = start;
  result.bandwidth = h;
  result.scalar = std::numeric_limits<double>::quiet_NaN();
  if (!(h > 0)) return result;
  ProjectionRun projection(data_, params_, h);
  projection.gather(start, anchor);
  Vec3 x = start;
  std::optional<LocalSurface> fit;
  for (int it = 1; it <= params_.max_iterations; ++it) {
    projection.followPoint(x);
    fit = projection.fitAt(x);
    if (!fit) break;
    if (params_.robust && it <= kRobustIterations) {
      projection.reweigh(x, *fit, it == 1);
      fit = projection.fitAt(x);
      if (!fit) break;
    }
    const Vec3 next = fit->project(x);
    const double step = (next - x).norm();
    x = next;
    result.iterations = it;
    if (step < params_.tolerance * h) {
      result.converged = true;
      break;
    }
  }
  if (!fit) return result;
  projection.finish(x, *fit, result);
  return result;
}

}  // namespace stampscan::fitting
