#include "robust_patch_fit.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/median.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::fitting::detail {

namespace {
constexpr double kTukeyC = 4.685;
// Least in-plane spread (in h^2) of a fit's neighbours; an evenly covered disk has 0.5, a half disk
// at the edge of the data about 0.2.
constexpr double kMinTangentSpread = 0.05;
// Least share of its Gaussian weight a robust fit must keep (Tukey keeps ~90 % on clean data).
constexpr double kMinKeptWeight = 0.4;
}  // namespace



std::optional<LocalFit> fitLocal(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>* strain,
                                 const Vec3& centre, double h, bool robust, std::size_t min_points, FitScratch& s) {
  tree.radius(centre, kSupport * h, s.near);
  if (s.near.size() < min_points) return std::nullopt;
  const double h_sq = h * h;
  s.weight.resize(s.near.size());
  for (std::size_t k = 0; k < s.near.size(); ++k) s.weight[k] = gaussianWeightSq(s.near[k].distance_sq, h_sq);

  // Tukey's biweight on the residuals from `reference`, applied to the Gaussian weights.
  const auto reweight = [&](const auto& reference) {
    s.residual.resize(s.near.size());
    s.abs_residual.clear();
    // The robust scale needs a median, not every residual: a stride keeps it to ~256 samples.
    const std::size_t stride = 1 + s.near.size() / 256;
    for (std::size_t k = 0; k < s.near.size(); ++k) {
      s.residual[k] = reference.signedDistance(points[s.near[k].index]);
      // Every neighbour counts for the scale, whatever its weight: around an outlier the nearest
      // (heaviest) points are the outliers themselves, the majority by count is the surface.
      if (k % stride == 0) s.abs_residual.push_back(std::abs(s.residual[k]));
    }
    if (s.abs_residual.size() < min_points) return;
    const double sigma = std::max(1.4826 * medianInPlace(s.abs_residual), 1e-6 * h);
    const double cutoff = kTukeyC * sigma;
    for (std::size_t k = 0; k < s.near.size(); ++k) {
      const double r = s.residual[k] / cutoff;
      s.weight[k] = s.base_weight[k] * (r * r < 1.0 ? (1.0 - r * r) * (1.0 - r * r) : 0.0);
    }
  };
  const auto fitPlane = [&](bool uniform) {
    WeightedSums sums(centre, h);
    for (std::size_t k = 0; k < s.near.size(); ++k)
      if (s.weight[k] > 0) sums.add(points[s.near[k].index], uniform ? 1.0 : s.weight[k]);
    return LocalSurface::fitPlane(sums);
  };
  s.base_weight = s.weight;
  // Eqs. (2), (6), (7): the weighted plane gives the frame, and with robust weighting the first
  // residuals: a curved fit centred on an outlier can bend round it and make it look like an
  // inlier; a plane cannot. The quadric is then fitted over the plane's frame and refitted with
  // Tukey weights from its own residuals, which do not mistake curvature for outliers. The
  // residuals of that first quadric also give the variance below: the refit moves them by far less
  // than the noise.
  std::optional<LocalSurface> plane = fitPlane(false);
  // A surface needs neighbours spread in two directions: one cluster of repeated observations, or
  // a single row, only looks like a good fit.
  if (!plane || plane->tangentSpread() < kMinTangentSpread) return std::nullopt;
  if (robust) {
    // Outliers are first judged against a plane through the whole support with equal weights: a
    // Gaussian centred on an outlier would give it the largest weight and pull the plane onto it.
    if (const auto even = fitPlane(true)) reweight(*even);
    plane = fitPlane(false);
    if (!plane) return std::nullopt;
  }
  const auto fitQuadric = [&]() {
    QuadricPatch::Sums sums(*plane, centre, h);
    for (std::size_t k = 0; k < s.near.size(); ++k)
      if (s.weight[k] > 0) sums.add(points[s.near[k].index], s.weight[k]);
    return QuadricPatch::fit(sums);
  };
  std::optional<QuadricPatch> surface = fitQuadric();
  if (!surface) return std::nullopt;
  if (robust) {
    reweight(*surface);
    // A fit that keeps little of its Gaussian weight has followed a few points (a cluster of outliers
    // under the centre) and thrown away the surface around them: not a fit of the surface.
    double kept = 0, offered = 0;
    for (std::size_t k = 0; k < s.near.size(); ++k) {
      kept += s.weight[k];
      offered += s.base_weight[k];
    }
    if (kept < kMinKeptWeight * offered) return std::nullopt;
    surface = fitQuadric();
    if (!surface) return std::nullopt;
  } else {
    s.residual.resize(s.near.size());
    for (std::size_t k = 0; k < s.near.size(); ++k) s.residual[k] = surface->signedDistance(points[s.near[k].index]);
  }

  LocalFit fit{*surface};
  fit.offset = surface->signedDistance(centre);
  // Standard deviation of the fitted offset: residual variance over the effective sample size
  // (sum w)^2 / sum w^2, inflated by the six parameters of the quadric.
  double sw = 0, sw2 = 0, swr2 = 0;
  for (std::size_t k = 0; k < s.near.size(); ++k) {
    const double w = s.weight[k];
    sw += w;
    sw2 += w * w;
    swr2 += w * s.residual[k] * s.residual[k];
  }
  if (!(sw > 0)) return std::nullopt;
  const double n_eff = sw * sw / sw2;
  constexpr double kParameters = 6.0;  // of the quadric
  if (n_eff < kParameters + 1.0) return std::nullopt;
  const double var = swr2 / sw * n_eff / (n_eff - kParameters);
  fit.offset_sigma = std::sqrt(var * kParameters / n_eff);
  fit.residual_variance = var;
  fit.effective_count = n_eff;

  if (strain) {
    // Linear strain field c0 + g.t in the tangent plane at the centre's foot point, with the
    // fit's weights (the smooth scalar field of scalar_field.hpp).
    const Vec3 foot = surface->project(centre);
    s.samples.clear();
    for (std::size_t k = 0; k < s.near.size(); ++k)
      if (s.weight[k] > 0) s.samples.push_back({points[s.near[k].index], (*strain)[s.near[k].index], s.weight[k]});
    const auto field = fitTangentLinear(foot, surface->normal(foot), s.samples);
    if (!field) return std::nullopt;
    fit.strain = field->value;
    fit.strain_gradient = field->gradient;
    // Express the linear field about the centre so that evaluation needs no foot point.
    fit.strain -= fit.strain_gradient.dot(foot - centre);
  }
  return fit;
}

}  // namespace stampscan::fitting::detail
