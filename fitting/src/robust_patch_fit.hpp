// One robust local fit of the anchored surface (a private part of fitting/): a quadric patch with
// Gaussian weights (Eq. (3)) around a centre, outliers removed with Tukey's biweight, and the linear
// strain field in its tangent plane.
#pragma once

#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/median.hpp"
#include "stampscan/fitting/quadric_patch.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include <limits>
#include <optional>
#include <vector>

namespace stampscan::fitting::detail {

// Neighbours beyond this multiple of h are left out of a local fit: their Gaussian weight is below
// exp(-4.84) = 0.8 %, and leaving them out saves a fifth of the work of the paper's 2.5 h.
inline constexpr double kSupport = 2.2;

struct LocalFit {
  QuadricPatch surface;
  double offset = 0;             // signed distance from the centre to the fitted surface, mm
  double offset_sigma = 0;       // its standard deviation from the residuals and the effective count
  double residual_variance = 0;  // weighted, corrected for the six fitted parameters
  double effective_count = 0;    // (sum w)^2 / sum w^2
  double strain = std::numeric_limits<double>::quiet_NaN();
  Vec3 strain_gradient = Vec3::Zero();  // strain = strain + gradient . (x - centre)
};

// Buffers reused from one fit to the next by the same thread.
struct FitScratch {
  std::vector<Neighbor> near;
  std::vector<double> weight;
  std::vector<double> base_weight;
  std::vector<double> residual;
  std::vector<double> abs_residual;
  std::vector<ScalarSample> samples;
};

// The fit at `centre` with bandwidth h over `points` (indexed by `tree`); `strain` may be null.
// Nothing when fewer than min_points neighbours, when they do not spread in two directions, or when
// the robust fit keeps too little of its weight (it followed a cluster of outliers).
std::optional<LocalFit> fitLocal(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>* strain,
                                 const Vec3& centre, double h, bool robust, std::size_t min_points, FitScratch& scratch);

}  // namespace stampscan::fitting::detail
