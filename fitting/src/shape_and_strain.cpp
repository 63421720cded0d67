#include "stampscan/fitting/shape_and_strain.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include "robust_patch_fit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>

namespace stampscan::fitting {

namespace {
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Cube keys: three 21-bit coordinates (two million cubes along each axis).
constexpr int kBits = 21;
constexpr std::int64_t kBias = std::int64_t{1} << (kBits - 1);
std::uint64_t cubeKey(const Vec3& p, const Vec3& origin, double size) {
  const Vec3 g = (p - origin) / size;
  const auto c = [](double v) {
    return static_cast<std::uint64_t>(std::clamp(static_cast<std::int64_t>(std::floor(v)) + kBias, std::int64_t{0},
                                                 (std::int64_t{1} << kBits) - 1));
  };
  return (c(g.x()) << (2 * kBits)) | (c(g.y()) << kBits) | c(g.z());
}

// The mean of the shape points in each cube: a start for one output point there. The means lie on
// the surface to within its curvature over half a cube, which one projection removes.
std::vector<Vec3> cubeMeans(const std::vector<Vec3>& points, double size) {
  const Vec3 origin = boundsOf(points).min;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1 << 14), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i)
      keyed[i] = {cubeKey(points[i], origin, size), static_cast<std::uint32_t>(i)};
  });
  tbb::parallel_sort(keyed.begin(), keyed.end());
  std::vector<Vec3> means;
  for (std::size_t start = 0; start < keyed.size();) {
    std::size_t end = start;
    Vec3 sum = Vec3::Zero();
    for (; end < keyed.size() && keyed[end].first == keyed[start].first; ++end) sum += points[keyed[end].second];
    means.push_back(sum / static_cast<double>(end - start));
    start = end;
  }
  return means;
}

// The carriers' strain as a smooth field over the shape (scalar_field.hpp: linear in the tangent
// plane, Gaussian weights, Eq. (3)) with a bandwidth of its own. The carriers' shape fit would lend
// it the shape's bandwidth, which stops only at a count of carriers (some 16 mm on a 2.54 mm grid)
// and flattens the strain peaks, the very spots a forming analysis is about.
//
// The bandwidth is chosen by cross-validation, leaving one element out: at each carrier, the field
// fitted to the others (its twins, within a quarter pitch, left out too: the same element found in
// two strips) predicts its strain, at bandwidths from half a pitch to seven; each carrier takes the
// bandwidth whose predictions were best over its neighbourhood. A prediction error is what a point
// between elements sees: the noise, the bias of too wide a support and the variance of too narrow
// a one, together. (Lepski's rule, which serves the shape, starts at the eight nearest carriers,
// already wider than a strain peak between elements allows; cross-validation needs no start.) A
// point between carriers takes the harmonic mean of its neighbours' bandwidths.
class CarrierStrain {
 public:
  struct Scratch {
    std::vector<Neighbor> near;
    std::vector<ScalarSample> samples;
  };
  CarrierStrain(const Cloud& carriers, const ShapeAndStrainParams& params)
      : positions_(carriers.positions), strain_(carriers.strain), tree_(positions_) {
    const std::size_t n = positions_.size();
    const std::vector<double>& strain = strain_;
    // Each carrier's weight relative to a typical one: the inverse variance of its strain when the
    // carriers state it (a merged element measured by several sweeps and views counts for more than
    // one seen once, a laser element more than a noisier stereo one), scaled so that the median
    // carrier weighs one (the Gaussian's scale stays that of the bandwidth).
    certainty_.assign(n, 1.0);
    if (const auto u = carriers.scalars.find(kStrainUncertainty); u != carriers.scalars.end() && u->second.size() == n) {
      std::vector<double> finite;
      for (double s : u->second)
        if (std::isfinite(s) && s > 0) finite.push_back(s);
      if (!finite.empty()) {
        const double typical = summarize(finite).median;
        for (std::size_t i = 0; i < n; ++i) {
          const double s = u->second[i];
          certainty_[i] = std::isfinite(s) && s > 0 ? std::pow(typical / s, 2) : 1.0;
        }
      }
    }
    // The grid's pitch: the fourth neighbour's distance, which twins do not shorten (a square
    // grid's four nearest are a pitch away).
    std::vector<double> fourth(n, 0.0);
    std::vector<Vec3> normals(n, Vec3::UnitZ());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
      std::vector<Neighbor> near;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        tree_.knn(positions_[i], kPitchRank + 1, near);
        fourth[i] = std::sqrt(near.back().distance_sq);
        // The carriers' own plane gives the tangent plane of the strain fits there.
        tree_.knn(positions_[i], kPoolSize, near);
        WeightedSums sums(positions_[i], fourth[i] > 0 ? fourth[i] : 1.0);
        for (const Neighbor& nb : near) sums.add(positions_[nb.index], 1.0);
        if (const auto plane = LocalSurface::fitPlane(sums)) normals[i] = plane->normal(positions_[i]);
      }
    });
    spacing_ = summarize(fourth).median;
    reach_ = params.strain_reach * spacing_;
    std::array<double, kCandidates> candidates{};
    for (int k = 0; k < kCandidates; ++k) candidates[static_cast<std::size_t>(k)] = 0.5 * spacing_ * std::pow(kCandidateStep, k);

    // Leave-one-element-out squared errors, per carrier and candidate (NaN: too few others).
    std::vector<std::array<double, kCandidates>> error(n);
    const double twin_sq = 0.0625 * spacing_ * spacing_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const auto& range) {
      std::vector<Neighbor> near;
      std::vector<ScalarSample> samples;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        for (int k = 0; k < kCandidates; ++k) {
          const double h = candidates[static_cast<std::size_t>(k)];
          double& e = error[i][static_cast<std::size_t>(k)];
          e = std::numeric_limits<double>::quiet_NaN();
          if (!std::isfinite(strain[i])) continue;
          tree_.radius(positions_[i], detail::kSupport * h, near);
          samples.clear();
          for (const Neighbor& nb : near)
            if (nb.distance_sq > twin_sq && std::isfinite(strain[nb.index]))
              samples.push_back({positions_[nb.index], strain[nb.index], weight(nb, h)});
          if (samples.size() < 3) continue;
          if (const auto field = fitTangentLinear(positions_[i], normals[i], samples)) {
            const double r = field->value - strain[i];
            e = r * r;
          }
        }
      }
    });
    std::vector<double> h(n, candidates.back());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const auto& range) {
      std::vector<Neighbor> near;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        tree_.knn(positions_[i], kPoolSize, near);
        double best = std::numeric_limits<double>::infinity();
        for (int k = 0; k < kCandidates; ++k) {
          double sum = 0;
          std::size_t count = 0;
          for (const Neighbor& nb : near) {
            const double e = error[nb.index][static_cast<std::size_t>(k)];
            if (std::isfinite(e)) {
              sum += e;
              ++count;
            }
          }
          // A bandwidth that predicts fewer than half the neighbourhood is too narrow here.
          if (2 * count < near.size() || !(sum / static_cast<double>(count) < best)) continue;
          best = sum / static_cast<double>(count);
          h[i] = candidates[static_cast<std::size_t>(k)];
        }
      }
    });
    bandwidth_ = summarize(h);
    field_ = std::make_unique<BandwidthField>(positions_, tree_, std::move(h), BandwidthField::Mean::Harmonic);
  }

  // NaN beyond reach of every carrier.
  double at(const Vec3& x, const Vec3& normal, Scratch& scratch) const {
    std::uint32_t nearest = 0;
    double h = field_->at(x, 4, &nearest);
    if ((positions_[nearest] - x).squaredNorm() > reach_ * reach_) return std::numeric_limits<double>::quiet_NaN();
    // The carriers' choice holds wherever the field there is interpolated, not extrapolated: then it
    // is what the cross-validation chose it to be, the best prediction between elements, and at an
    // element it keeps that element's own value (its weight dominates, its neighbours give the
    // slope), so a peak the elements measured stays in the map. The linear fit's value at x is a
    // weighted sum of the carriers' values; where x lies off the carriers that carry weight (a gap
    // in the grid, the grid's edge), the sum's coefficients grow and alternate in sign, and one
    // carrier's noise is amplified. The support widens until their absolute sum (the fit's
    // amplification of noise, 1 for an average) is small.
    for (int widen = 0; widen < kCandidates; ++widen, h *= kCandidateStep) {
      tree_.radius(x, detail::kSupport * h, scratch.near);
      if (amplification(x, normal, h, scratch.near) <= kMostAmplification) break;
    }
    // The smooth field over the carriers of that support (scalar_field.hpp), Gaussian weights (Eq. (3)).
    scratch.samples.clear();
    for (const Neighbor& nb : scratch.near)
      if (std::isfinite(strain_[nb.index]))
        scratch.samples.push_back({positions_[nb.index], strain_[nb.index], weight(nb, h)});
    return smoothScalar(x, normal, scratch.samples);
  }
  const BandwidthSummary& bandwidth() const { return bandwidth_; }
  double spacing() const { return spacing_; }

 private:
  // The sum of the absolute coefficients of the tangent-linear fit's value at x over `near`
  // (infinite when the fit is not determined): for weights w_i and design rows a_i = (1, u_i, v_i),
  // the value is sum_i w_i (a_i . z) s_i with z = (sum_i w_i a_i a_i^T)^-1 (1, 0, 0).
  double amplification(const Vec3& x, const Vec3& normal, double h, const std::vector<Neighbor>& near) const {
    const Eigen::Matrix3d frame = frameAround(normal);
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    const auto row = [&](const Neighbor& nb) {
      const Vec3 d = (positions_[nb.index] - x) / h;  // scaled, for conditioning
      return Eigen::Vector3d(1.0, d.dot(frame.col(0)), d.dot(frame.col(1)));
    };
    std::size_t used = 0;
    for (const Neighbor& nb : near) {
      if (!std::isfinite(strain_[nb.index])) continue;
      const Eigen::Vector3d a = row(nb);
      M += weight(nb, h) * a * a.transpose();
      ++used;
    }
    if (used < 3) return std::numeric_limits<double>::infinity();
    const Eigen::LDLT<Eigen::Matrix3d> solver(M);
    if (solver.info() != Eigen::Success || !(std::abs(M.determinant()) > 1e-12 * std::pow(M.trace(), 3)))
      return std::numeric_limits<double>::infinity();
    const Eigen::Vector3d z = solver.solve(Eigen::Vector3d::UnitX());
    double sum = 0;
    for (const Neighbor& nb : near)
      if (std::isfinite(strain_[nb.index])) sum += std::abs(weight(nb, h) * row(nb).dot(z));
    return std::isfinite(sum) ? sum : std::numeric_limits<double>::infinity();
  }
  // A carrier's weight at bandwidth h: the Gaussian of Eq. (3) times its certainty.
  double weight(const Neighbor& nb, double h) const {
    return gaussianWeightSq(nb.distance_sq, h * h) * certainty_[nb.index];
  }
  // Candidate bandwidths: half a pitch times 1.4^k, up to seven pitches.
  static constexpr int kCandidates = 9;
  static constexpr double kCandidateStep = 1.4;
  static constexpr std::size_t kPitchRank = 4;
  // The most a field value may amplify the carriers' noise (1: an average of them; an interpolation
  // within a grid cell stays near it, an extrapolation beyond the last carriers exceeds it).
  static constexpr double kMostAmplification = 1.5;
  // A carrier's neighbourhood for the choice (and for its tangent plane): a few pitches across.
  static constexpr std::size_t kPoolSize = 16;
  const std::vector<Vec3>& positions_;
  const std::vector<double>& strain_;
  KdTree tree_;
  std::vector<double> certainty_;
  std::unique_ptr<BandwidthField> field_;
  double spacing_ = 0, reach_ = 0;
  BandwidthSummary bandwidth_;
};
}  // namespace

// How far a carrier may lie from its foot on the shape, in carrier spacings, to be on the surface.
constexpr double kMostCarrierOffset = 0.1;

ShapeAndStrain fitShapeAndStrain(const Cloud& shape, const Cloud& carriers, const ShapeAndStrainParams& params) {
  if (shape.empty()) throw std::invalid_argument("shape and strain: no shape points");
  if (shape.hasStrain()) throw std::invalid_argument("shape and strain: the shape points must not carry strain");
  if (carriers.empty() || !carriers.hasStrain())
    throw std::invalid_argument("shape and strain: no carriers with strain");
  if (!(params.output_spacing_mm > 0)) throw std::invalid_argument("shape and strain: the output spacing must be positive");
  if (shape.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("shape and strain: more than 4 billion shape points");
  const auto t0 = Clock::now();
  const auto& progress = params.shape.progress;
  ShapeAndStrain out;
  out.shape_points = shape.size();
  out.carriers = carriers.size();

  const FittedSurface shape_fit(shape, params.shape);
  out.shape_stats = shape_fit.preparationStats();
  auto t = Clock::now();
  const CarrierStrain strain_field(carriers, params);
  out.strain_bandwidth = strain_field.bandwidth();
  out.carrier_spacing = strain_field.spacing();
  out.shape_stats.stage_seconds["strain field"] = secondsSince(t);

  t = Clock::now();
  const std::vector<Vec3> starts = cubeMeans(shape.positions, params.output_spacing_mm);
  std::vector<Projection> feet(starts.size());
  std::vector<double> strain(starts.size(), std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starts.size(), 256), [&](const auto& range) {
    CarrierStrain::Scratch scratch;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      feet[k] = shape_fit.surface().project(starts[k]);
      if (feet[k].valid) strain[k] = strain_field.at(feet[k].point, feet[k].normal, scratch);
    }
  });
  out.strain_at_carriers.assign(carriers.size(), std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, carriers.size(), 256), [&](const auto& range) {
    CarrierStrain::Scratch scratch;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      // A carrier beyond the shape's points (an element only the stereo views saw) has no surface
      // under it: its projection lands elsewhere, or nowhere.
      const Projection foot = shape_fit.surface().project(carriers.positions[k]);
      if (foot.valid && (foot.point - carriers.positions[k]).norm() <= kMostCarrierOffset * strain_field.spacing())
        out.strain_at_carriers[k] = strain_field.at(foot.point, foot.normal, scratch);
    }
  });
  for (std::size_t k = 0; k < starts.size(); ++k) {
    if (!feet[k].valid) continue;
    out.surface.positions.push_back(feet[k].point);
    out.surface.normals.push_back(feet[k].normal);
    out.surface.strain.push_back(strain[k]);
    out.without_strain += !std::isfinite(strain[k]);
    out.not_converged += !feet[k].converged;
  }
  out.shape_stats.stage_seconds["surface points"] = secondsSince(t);
  if (progress) progress("surface points", 1.0);

  if (params.with_mesh) {
    t = Clock::now();
    MeshParams mesh_params;
    mesh_params.cell_size = params.output_spacing_mm;
    mesh_params.progress = progress;
    out.mesh = meshSurface(shape_fit, out.surface, mesh_params, &out.mesh_stats);
    Cloud& v = out.mesh.vertices;
    v.strain.assign(v.size(), std::numeric_limits<double>::quiet_NaN());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, v.size(), 256), [&](const auto& range) {
      CarrierStrain::Scratch scratch;
      for (std::size_t k = range.begin(); k != range.end(); ++k)
        v.strain[k] = strain_field.at(v.positions[k], v.normals[k], scratch);
    });
    out.shape_stats.stage_seconds["mesh"] = secondsSince(t);
  }
  out.seconds = secondsSince(t0);
  return out;
}

}  // namespace stampscan::fitting
