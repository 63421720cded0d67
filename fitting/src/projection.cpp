#include "stampscan/fitting/projection.hpp"

#include "stampscan/fitting/local_fit.hpp"

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

double medianOf(std::vector<double>& v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}
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

Projection WlsSurface::run(const Vec3& start, std::uint32_t anchor, double h) const {
  const auto& points = *data_.points;
  Projection result;
  result.point = start;
  result.bandwidth = h;
  result.scalar = std::numeric_limits<double>::quiet_NaN();
  if (!(h > 0)) return result;

  const double h_sq = h * h;
  const double support = kernelSupport(params_.kernel, h);
  const bool euclidean = params_.weights == WeightScheme::Euclidean;

  // Gather the neighbourhood once. For the Euclidean kernel the centre moves with P*; the query
  // radius carries a margin and is refreshed if P* wanders farther than that margin.
  thread_local std::vector<Candidate> candidates;
  thread_local std::vector<Neighbor> near;
  thread_local std::vector<SigGraph::Reached> reached;
  candidates.clear();
  const double margin = 0.5 * h;
  Vec3 query_centre = start;
  const auto gatherEuclidean = [&](const Vec3& centre) {
    data_.tree->radius(centre, support + margin, near);
    // Keep the robust weights of points already seen; they only make sense for the same points.
    candidates.clear();
    for (const Neighbor& nb : near) candidates.push_back({nb.index, 0.0});
    query_centre = centre;
  };
  if (params_.weights == WeightScheme::GraphDistance) {
    data_.graph->distancesFrom(anchor, support, reached);
    for (const auto& r : reached) candidates.push_back({r.vertex, kernelWeight(params_.kernel, r.distance, h)});
  } else if (params_.weights == WeightScheme::DataToData) {
    const Vec3& pa = points[anchor];
    data_.tree->radius(pa, support, near);
    for (const Neighbor& nb : near)
      candidates.push_back({nb.index, kernelWeight(params_.kernel, std::sqrt(nb.distance_sq), h)});  // Eqs. (10)-(11)
  } else {
    gatherEuclidean(start);
  }

  const bool sphere = params_.model == SurfaceModel::Sphere;
  thread_local std::vector<double> residuals;
  Vec3 x = start;
  std::optional<LocalSurface> fit;
  const auto fitAt = [&](const Vec3& centre) -> std::optional<LocalSurface> {
    WeightedSums plane_sums(centre, h);
    AlgebraicMoments sphere_sums(centre, h);
    for (Candidate& c : candidates) {
      const Vec3& p = points[c.index];
      double w = c.base_weight;
      if (euclidean) {
        const double r_sq = (p - centre).squaredNorm();
        w = params_.kernel == KernelType::Gaussian ? (r_sq < support * support ? gaussianWeightSq(r_sq, h_sq) : 0.0)
                                                   : cubicWeight(std::sqrt(r_sq), h);  // Eqs. (3)-(5)
      }
      w *= c.robust;
      c.weight = w;
      if (w <= 0) continue;
      if (sphere)
        sphere_sums.add(p, w);
      else
        plane_sums.add(p, w);  // Eqs. (2), (6), (7)
    }
    return sphere ? LocalSurface::fitPrattSphere(sphere_sums) : LocalSurface::fitPlane(plane_sums);
  };

  for (int it = 1; it <= params_.max_iterations; ++it) {
    if (euclidean && (x - query_centre).norm() > margin) gatherEuclidean(x);
    fit = fitAt(x);
    if (!fit) break;
    if (params_.robust && it <= kRobustIterations) {
      // Robust scale from the median absolute residual of the points that carry weight. The first
      // residuals come from a plane: a sphere fitted through outliers can bend round them and make
      // them look like inliers; a plane cannot.
      std::optional<LocalSurface> reference = fit;
      if (sphere && it == 1) {
        WeightedSums plane_sums(x, h);
        for (const Candidate& c : candidates)
          if (c.weight > 0) plane_sums.add(points[c.index], c.weight);
        reference = LocalSurface::fitPlane(plane_sums);
        if (!reference) reference = fit;
      }
      residuals.clear();
      for (const Candidate& c : candidates)
        if (c.weight > 0) residuals.push_back(std::abs(reference->signedDistance(points[c.index])));
      const double sigma = std::max(1.4826 * medianOf(residuals), 1e-6 * h);
      const double cutoff = kTukeyC * sigma;
      for (Candidate& c : candidates) {
        const double r = std::abs(reference->signedDistance(points[c.index])) / cutoff;
        c.robust = r < 1.0 ? (1.0 - r * r) * (1.0 - r * r) : 0.0;
      }
      fit = fitAt(x);
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

  result.valid = true;
  result.point = x;
  Vec3 n = fit->normal(x);
  // Fitted normals have no sign of their own: orient them like the data normals when known.
  if (data_.normals) {
    Vec3 reference = Vec3::Zero();
    for (const Candidate& c : candidates) reference += c.weight * (*data_.normals)[c.index].cast<double>();
    if (n.dot(reference) < 0) n = -n;
  }
  result.normal = n;
  std::size_t used = 0;
  for (const Candidate& c : candidates) used += c.weight > 0;
  result.neighbors = used;

  if (data_.scalar) {
    thread_local std::vector<ScalarSample> samples;
    samples.clear();
    for (const Candidate& c : candidates)
      if (c.weight > 0) samples.push_back({points[c.index], (*data_.scalar)[c.index], c.weight});
    result.scalar = params_.scalar == ScalarFieldType::Smooth ? smoothScalar(x, n, samples)
                                                              : shepardScalar(x, samples, support);
  }
  return result;
}

}  // namespace stampscan::fitting
