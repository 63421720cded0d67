#include "stampscan/fitting/shape_and_strain.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include "joined_surface.hpp"
#include "loop_progress.hpp"
#include "robust_patch_fit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <unordered_map>
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
// the surface to within its curvature over half a cube, which one projection removes. Summed by
// cube in one pass over the points, in their order (a table of the cubes, not a sorted key per
// point: a session's ten million returns would need 160 MB more for that at the end of the fit).
// Pieces are taken in their order, as one cloud would be.
std::vector<Vec3> cubeMeans(const std::vector<const std::vector<Vec3>*>& pieces, double size) {
  Vec3 origin = Vec3::Constant(std::numeric_limits<double>::infinity());
  for (const auto* points : pieces) origin = origin.cwiseMin(boundsOf(*points).min);
  std::unordered_map<std::uint64_t, std::pair<Vec3, std::uint32_t>> cubes;
  for (const auto* points : pieces)
    for (const Vec3& p : *points) {
      auto& [sum, count] = cubes.try_emplace(cubeKey(p, origin, size), Vec3::Zero(), 0u).first->second;
      sum += p;
      ++count;
    }
  std::vector<std::pair<std::uint64_t, Vec3>> keyed;
  keyed.reserve(cubes.size());
  for (const auto& [key, cube] : cubes) keyed.emplace_back(key, cube.first / static_cast<double>(cube.second));
  std::sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Vec3> means;
  means.reserve(keyed.size());
  for (const auto& [key, mean] : keyed) means.push_back(mean);
  return means;
}

// The carriers' strain as a smooth field over the shape (scalar_field.hpp: a polynomial in the
// tangent plane, Gaussian weights, Eq. (3)) with a bandwidth of its own. The carriers' shape fit
// would lend it the shape's bandwidth, which stops only at a count of carriers (some 16 mm on a
// 2.54 mm grid) and flattens the strain peaks, the very spots a forming analysis is about.
//
// The bandwidth, and whether the local field is a plane (Eq. (17)'s hyperplane) or a quadric, are
// chosen by cross-validation, leaving one element out: at each carrier, the field fitted to the
// others (its twins, within a quarter pitch, left out too: the same element found in two strips)
// predicts its strain, for bandwidths from half a pitch to seven and both degrees; each carrier
// takes the model whose predictions were best over its neighbourhood. A prediction error is what a
// point between elements sees: the noise, the bias of too wide a support or too low a degree, and
// the variance of too narrow a one, together. Across a die radius the strain bends within a pitch
// or two: a plane through the elements either side misses the band between them by a hundredth,
// a quadric follows it. (Lepski's rule, which serves the shape, starts at the eight nearest
// carriers, already wider than a strain peak between elements allows; cross-validation needs no
// start.) A point between carriers takes the harmonic mean of its neighbours' bandwidths and their
// share of quadrics, blending the two fits.
//
// At a carrier the smooth field still mixes its neighbours into its value; a correction there
// restores the carrier's best estimate of its own strain (its measurement and its neighbours'
// prediction, by their inverse variances); between elements the corrections are interpolated.
class CarrierStrain {
  // Candidate bandwidths: half a pitch times 1.4^k, up to seven pitches; each with both degrees.
  static constexpr int kBandwidths = 9;
  static constexpr double kBandwidthStep = 1.4;
  static constexpr int kModels = 2 * kBandwidths;  // model m: bandwidth m / 2, degree 1 + m % 2
  using PerModel = std::array<double, kModels>;
  static constexpr std::size_t kPitchRank = 4;
  // The most a field value may amplify the carriers' noise (1: an average of them), per degree: an
  // interpolation within a grid cell stays near it, an extrapolation beyond the last carriers
  // exceeds it. A quadric's coefficients are larger within the cell too.
  static constexpr double kMostAmplification[2] = {1.5, 2.5};
  static constexpr int kWidenings = 3;  // the chosen bandwidth and two steps wider
  // A carrier's neighbourhood for the choice (and for its tangent plane): a few pitches across.
  static constexpr std::size_t kPoolSize = 16;
  // The width of the corrections' interpolation, in pitches, and the least sum of weights their mean
  // is divided by: one carrier's weight at half a pitch.
  static constexpr double kBumpWidth = 0.4;
  static constexpr double kCorrectionWeightFloor = 0.2096;  // exp(-(0.5 / 0.4)^2)
  // The least variance granted the neighbours' prediction, as a share of the carriers' own.
  static constexpr double kLeastPredictionVariance = 0.1;

 public:
  struct Scratch {
    std::vector<Neighbor> near;
    std::vector<ScalarSample> samples;
  };
  CarrierStrain(const Cloud& carriers, const ShapeAndStrainParams& params)
      : positions_(carriers.positions), strain_(carriers.strain), tree_(positions_) {
    const std::vector<double> variance = statedVariances(carriers);
    const std::vector<Vec3> normals = measureGrid();
    reach_ = params.strain_reach * spacing_;
    // Carriers all at one place (or a single one): no grid, no field.
    if (!(spacing_ > 0)) return;
    for (int k = 0; k < kBandwidths; ++k)
      candidates_[static_cast<std::size_t>(k)] = 0.5 * spacing_ * std::pow(kBandwidthStep, k);
    std::vector<PerModel> error(n()), prediction(n());
    crossValidate(normals, error, prediction);
    const Choice choice = chooseModels(error, prediction, variance);
    // An element its neighbours contradict weighs less in the smooth field too, so that an outlier
    // does not reach its neighbours through their fits.
    for (std::size_t i = 0; i < n(); ++i) certainty_[i] *= choice.trust[i];
    correctTowardsEstimates(normals, choice.estimate);
  }

  // NaN beyond reach of every carrier.
  double at(const Vec3& x, const Vec3& normal, Scratch& scratch) const {
    if (!field_) return std::numeric_limits<double>::quiet_NaN();
    const double smooth = smoothAt(x, normal, scratch);
    if (!std::isfinite(smooth)) return smooth;
    // The carriers' corrections, interpolated by Gaussian weights (Eq. (3)'s) of 0.4 pitch: at an
    // element its own (the next element's weight is 0.2 % of it), between elements their mean, and
    // twins (the same element measured twice) share theirs rather than count twice. Beyond half a
    // pitch from every carrier (a gap, the grid's edge) the weights' sum falls below the floor and
    // the correction fades to nothing by the support's edge.
    tree_.radius(x, detail::kSupport * bump_, scratch.near);
    double sum = 0, weights = 0;
    for (const Neighbor& nb : scratch.near) {
      const double w = gaussianWeightSq(nb.distance_sq, bump_ * bump_);
      sum += w * correction_[nb.index];
      weights += w;
    }
    return smooth + sum / std::max(weights, kCorrectionWeightFloor);
  }
  const BandwidthSummary& bandwidth() const { return bandwidth_; }
  double spacing() const { return spacing_; }

 private:
  std::size_t n() const { return positions_.size(); }

  // Each carrier's weight relative to a typical one: the inverse variance of its strain's noise when
  // the carriers state it (a merged element measured by several sweeps and views counts for more than
  // one seen once, a laser element more than a noisier stereo one; what its neighbours leave
  // unexplained is for the field to find, not a reason to trust it less), scaled so that the median carrier
  // weighs one (the Gaussian's scale stays that of the bandwidth). Returns the stated variances
  // (NaN where none is stated).
  std::vector<double> statedVariances(const Cloud& carriers) {
    certainty_.assign(n(), 1.0);
    std::vector<double> variance(n(), std::numeric_limits<double>::quiet_NaN());
    auto u = carriers.scalars.find(kStrainNoise);
    if (u == carriers.scalars.end() || u->second.size() != n()) u = carriers.scalars.find(kStrainUncertainty);
    if (u == carriers.scalars.end() || u->second.size() != n()) return variance;
    std::vector<double> finite;
    for (double s : u->second)
      if (std::isfinite(s) && s > 0) finite.push_back(s);
    if (finite.empty()) return variance;
    const double typical = summarize(finite).median;
    for (std::size_t i = 0; i < n(); ++i) {
      const double s = u->second[i];
      if (!(std::isfinite(s) && s > 0)) continue;
      certainty_[i] = std::pow(typical / s, 2);
      variance[i] = s * s;
    }
    return variance;
  }

  // The grid's pitch (spacing_): the fourth neighbour's distance, which twins do not shorten (a
  // square grid's four nearest are a pitch away). Returns each carrier's tangent plane's normal,
  // from the carriers' own plane there.
  std::vector<Vec3> measureGrid() {
    std::vector<double> fourth(n(), 0.0);
    std::vector<Vec3> normals(n(), Vec3::UnitZ());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n(), 256), [&](const auto& range) {
      std::vector<Neighbor> near;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        tree_.knn(positions_[i], kPitchRank + 1, near);
        fourth[i] = std::sqrt(near.back().distance_sq);
        tree_.knn(positions_[i], kPoolSize, near);
        WeightedSums sums(positions_[i], fourth[i] > 0 ? fourth[i] : 1.0);
        for (const Neighbor& nb : near) sums.add(positions_[nb.index], 1.0);
        if (const auto plane = LocalSurface::fitPlane(sums)) normals[i] = plane->normal(positions_[i]);
      }
    });
    spacing_ = summarize(fourth).median;
    return normals;
  }

  // Leave-one-element-out predictions and their squared errors, per carrier and model (NaN: the
  // others do not determine it).
  void crossValidate(const std::vector<Vec3>& normals, std::vector<PerModel>& error, std::vector<PerModel>& prediction) const {
    const double twin_sq = 0.0625 * spacing_ * spacing_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n(), 64), [&](const auto& range) {
      std::vector<Neighbor> near;
      std::vector<ScalarSample> samples;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        error[i].fill(std::numeric_limits<double>::quiet_NaN());
        prediction[i].fill(std::numeric_limits<double>::quiet_NaN());
        if (!std::isfinite(strain_[i])) continue;
        for (int k = 0; k < kBandwidths; ++k) {
          const double h = candidates_[static_cast<std::size_t>(k)];
          tree_.radius(positions_[i], detail::kSupport * h, near);
          samples.clear();
          for (const Neighbor& nb : near)
            if (nb.distance_sq > twin_sq && std::isfinite(strain_[nb.index]))
              samples.push_back({positions_[nb.index], strain_[nb.index], weight(nb, h)});
          for (int degree = 1; degree <= 2; ++degree) {
            const auto field = fitTangentPolynomial(positions_[i], normals[i], samples, degree, h);
            if (!field) continue;
            const auto m = static_cast<std::size_t>(2 * k + degree - 1);
            prediction[i][m] = field->value;
            error[i][m] = std::pow(field->value - strain_[i], 2);
          }
        }
      }
    });
  }

  // Each carrier's best estimate of its own strain (NaN: keep the smooth field's), and how far its
  // neighbours trust it (below 1: an element they contradict).
  struct Choice {
    std::vector<double> estimate, trust;
  };

  // Each carrier takes the model whose predictions were best over its neighbourhood: its bandwidth
  // (the field between carriers, field_) and degree (quadric_).
  Choice chooseModels(const std::vector<PerModel>& error, const std::vector<PerModel>& prediction,
                      const std::vector<double>& variance) {
    std::vector<double> h(n(), candidates_.back());
    quadric_.assign(n(), 0.0);
    Choice choice{std::vector<double>(n(), std::numeric_limits<double>::quiet_NaN()), std::vector<double>(n(), 1.0)};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n(), 64), [&](const auto& range) {
      std::vector<Neighbor> near;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        tree_.knn(positions_[i], kPoolSize, near);
        double best = std::numeric_limits<double>::infinity();
        int chosen = -1;
        for (int m = 0; m < kModels; ++m) {
          double sum = 0;
          std::size_t count = 0;
          for (const Neighbor& nb : near) {
            const double e = error[nb.index][static_cast<std::size_t>(m)];
            if (std::isfinite(e)) {
              sum += e;
              ++count;
            }
          }
          // A model that predicts fewer than half the neighbourhood is too narrow here.
          if (2 * count < near.size() || !(sum / static_cast<double>(count) < best)) continue;
          best = sum / static_cast<double>(count);
          chosen = m;
        }
        if (chosen < 0) continue;
        const auto m = static_cast<std::size_t>(chosen);
        h[i] = candidates_[m / 2];
        quadric_[i] = m % 2 == 1 ? 1.0 : 0.0;
        const OwnEstimate own = ownEstimate(i, m, near, error, prediction, variance);
        choice.estimate[i] = own.value;
        choice.trust[i] = own.trust;
      }
    });
    bandwidth_ = summarize(h);
    field_ = std::make_unique<BandwidthField>(positions_, tree_, std::move(h), BandwidthField::Mean::Harmonic);
    return choice;
  }

  // The corrections at the carriers that restore each one's best estimate over the smooth field.
  void correctTowardsEstimates(const std::vector<Vec3>& normals, const std::vector<double>& estimate) {
    correction_.assign(n(), 0.0);
    bump_ = kBumpWidth * spacing_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n(), 64), [&](const auto& range) {
      Scratch scratch;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        if (!std::isfinite(estimate[i])) continue;
        const double smooth = smoothAt(positions_[i], normals[i], scratch);
        if (std::isfinite(smooth)) correction_[i] = estimate[i] - smooth;
      }
    });
  }
  // The best linear estimate of carrier i's strain from its own measurement s (variance stated) and
  // its neighbours' leave-one-out prediction p with model m. p's variance is what the
  // neighbourhood's prediction errors hold beyond the carriers' own noise: E[(p - s)^2] = var p +
  // var s. NaN (keep the smooth field) when the carriers state no uncertainty.
  struct OwnEstimate {
    double value = std::numeric_limits<double>::quiet_NaN();
    // The measurement's weight in the smooth field, relative to its stated one: one over the excess
    // ratio beyond three standard deviations (a gross outlier all but drops out of its neighbours' fits).
    double trust = 1.0;
  };
  OwnEstimate ownEstimate(std::size_t i, std::size_t m, const std::vector<Neighbor>& near, const std::vector<PerModel>& error,
                     const std::vector<PerModel>& prediction, const std::vector<double>& variance) const {
    const double s = strain_[i], p = prediction[i][m], var_s = variance[i];
    if (!std::isfinite(s) || !std::isfinite(p) || !std::isfinite(var_s)) return {};
    double excess = 0, noise = 0;
    std::size_t count = 0;
    for (const Neighbor& nb : near) {
      const double e = error[nb.index][m], v = variance[nb.index];
      if (nb.index == i || !std::isfinite(e) || !std::isfinite(v)) continue;  // its neighbours' errors alone
      excess += e - v;
      noise += v;
      ++count;
    }
    if (count < 3) return {};
    // A floor: a neighbourhood's few errors never prove the prediction exact.
    const double var_p = std::max(excess, kLeastPredictionVariance * noise) / static_cast<double>(count);
    // Beyond three standard deviations of their difference the measurement's variance grows with
    // the excess (a Huber weight): an outlier gives way to its neighbours, smoothly, while a real
    // peak whose element understates its noise is not thrown away.
    const double excess_ratio = std::pow(s - p, 2) / (9.0 * (var_s + var_p));
    const double var_measured = excess_ratio > 1 ? var_s * std::sqrt(excess_ratio) : var_s;
    return {(s / var_measured + p / var_p) / (1.0 / var_measured + 1.0 / var_p), excess_ratio > 1 ? 1.0 / excess_ratio : 1.0};
  }

  // The smooth field: the plane's and the quadric's values blended by the neighbours' share of
  // quadrics. NaN beyond reach of every carrier.
  double smoothAt(const Vec3& x, const Vec3& normal, Scratch& scratch) const {
    tree_.knn(x, 1, scratch.near);
    if (scratch.near.empty() || scratch.near.front().distance_sq > reach_ * reach_)
      return std::numeric_limits<double>::quiet_NaN();
    const auto [h, quadric] = field_->atAndOther(x, quadric_, 4);
    if (quadric <= 0.0) return fieldOfDegree(x, normal, h, 1, scratch);
    if (quadric >= 1.0) return fieldOfDegree(x, normal, h, 2, scratch);
    return (1.0 - quadric) * fieldOfDegree(x, normal, h, 1, scratch) + quadric * fieldOfDegree(x, normal, h, 2, scratch);
  }

  // The polynomial field of `degree` at x. The carriers' choice of bandwidth holds wherever the
  // field there is interpolated, not extrapolated: then it is what the cross-validation chose it
  // to be. Where x lies off the carriers that carry weight (a gap in the grid, the grid's edge), the
  // fit's coefficients grow and alternate in sign, and one carrier's noise is amplified: the support
  // widens a little until their absolute sum is small. Widening further would reach over the part
  // and bring its far strain back as a slope or a curvature (at a dome's flange, the pole's): where
  // a little does not do, the quadric gives way to the plane, and the plane to the carriers'
  // weighted mean, whose gain is one (beyond the grid's last row, the strain of the rows before).
  double fieldOfDegree(const Vec3& x, const Vec3& normal, double h, int degree, Scratch& scratch) const {
    const double chosen = h;
    for (int widen = 0; widen < kWidenings; ++widen, h *= kBandwidthStep) {
      gather(x, h, scratch);
      const auto fit = fitTangentPolynomial(x, normal, scratch.samples, degree, h);
      if (fit && fit->amplification <= kMostAmplification[degree - 1]) return fit->value;
    }
    if (degree == 2) return fieldOfDegree(x, normal, chosen, 1, scratch);
    // The weighted mean at the chosen bandwidth, or the first wider one that holds a carrier.
    h = chosen;
    for (int widen = 0; widen < kWidenings; ++widen, h *= kBandwidthStep) {
      gather(x, h, scratch);
      double sum = 0, weights = 0;
      for (const ScalarSample& sample : scratch.samples) {
        sum += sample.weight * sample.value;
        weights += sample.weight;
      }
      if (weights > 0) return sum / weights;
    }
    return std::numeric_limits<double>::quiet_NaN();
  }
  // The carriers with strain within the support of bandwidth h around x, weighted.
  void gather(const Vec3& x, double h, Scratch& scratch) const {
    tree_.radius(x, detail::kSupport * h, scratch.near);
    scratch.samples.clear();
    for (const Neighbor& nb : scratch.near)
      if (std::isfinite(strain_[nb.index]))
        scratch.samples.push_back({positions_[nb.index], strain_[nb.index], weight(nb, h)});
  }

  // A carrier's weight at bandwidth h: the Gaussian of Eq. (3) times its certainty.
  double weight(const Neighbor& nb, double h) const {
    return gaussianWeightSq(nb.distance_sq, h * h) * certainty_[nb.index];
  }

  const std::vector<Vec3>& positions_;
  const std::vector<double>& strain_;
  KdTree tree_;
  std::vector<double> certainty_;
  std::array<double, kBandwidths> candidates_{};
  std::vector<double> quadric_;     // per carrier: 1 where its neighbourhood chose a quadric
  std::vector<double> correction_;  // per carrier: its best estimate minus the smooth field there
  std::unique_ptr<BandwidthField> field_;
  double spacing_ = 0, reach_ = 0, bump_ = 0;
  BandwidthSummary bandwidth_;
};
}  // namespace

// How far a carrier may lie from its foot on the shape, in carrier spacings, to be on the surface.
constexpr double kMostCarrierOffset = 0.1;

ShapePiece::ShapePiece(std::vector<Vec3> points, const FitParams& params) {
  if (points.empty()) throw std::invalid_argument("shape and strain: no shape points");
  if (points.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("shape and strain: more than 4 billion shape points");
  const auto t0 = Clock::now();
  points_.positions = std::move(points);
  points_.positions.shrink_to_fit();  // held to the end of the scan's fit: no slack from growing
  fit_ = std::make_unique<FittedSurface>(points_, params);
  seconds_ = secondsSince(t0);
}

ShapePiece::~ShapePiece() = default;

namespace {
// The pieces' preparation figures as one fit's: counts and times add up, the bandwidths span all
// pieces (the median: the points-weighted mean of the pieces' medians).
FitStats combinedStats(const std::vector<std::unique_ptr<ShapePiece>>& pieces) {
  if (pieces.size() == 1) return pieces.front()->stats();
  FitStats out;
  double weighted_median = 0, weighted_data_median = 0;
  out.bandwidth.min = out.data_bandwidth.min = std::numeric_limits<double>::infinity();
  for (const auto& piece : pieces) {
    const FitStats& s = piece->stats();
    const double w = static_cast<double>(s.points);
    out.points += s.points;
    out.bandwidth.min = std::min(out.bandwidth.min, s.bandwidth.min);
    out.bandwidth.max = std::max(out.bandwidth.max, s.bandwidth.max);
    out.data_bandwidth.min = std::min(out.data_bandwidth.min, s.data_bandwidth.min);
    out.data_bandwidth.max = std::max(out.data_bandwidth.max, s.data_bandwidth.max);
    weighted_median += w * s.bandwidth.median;
    weighted_data_median += w * s.data_bandwidth.median;
    out.widened = out.widened || s.widened;
    out.not_converged += s.not_converged;
    out.invalid += s.invalid;
    out.orientation_components += s.orientation_components;
    out.anchors += s.anchors;
    out.probes += s.probes;
    for (const auto& [stage, seconds] : s.stage_seconds) out.stage_seconds[stage] += seconds;
    out.seconds += s.seconds;
  }
  out.bandwidth.median = weighted_median / static_cast<double>(out.points);
  out.data_bandwidth.median = weighted_data_median / static_cast<double>(out.points);
  return out;
}
}  // namespace

ShapeSurface::ShapeSurface(std::vector<Vec3> points, const ShapeAndStrainParams& params) {
  if (!(params.output_spacing_mm > 0)) throw std::invalid_argument("shape and strain: the output spacing must be positive");
  pieces_.push_back(std::make_unique<ShapePiece>(std::move(points), params.shape));
  join(params);
}

ShapeSurface::ShapeSurface(std::vector<std::unique_ptr<ShapePiece>> pieces, const ShapeAndStrainParams& params)
    : pieces_(std::move(pieces)) {
  if (pieces_.empty()) throw std::invalid_argument("shape and strain: no shape pieces");
  for (const auto& piece : pieces_)
    if (!piece) throw std::invalid_argument("shape and strain: a shape piece is missing");
  if (!(params.output_spacing_mm > 0)) throw std::invalid_argument("shape and strain: the output spacing must be positive");
  join(params);
}

void ShapeSurface::join(const ShapeAndStrainParams& params) {
  const auto t0 = Clock::now();
  const auto& progress = params.shape.progress;
  stats_ = combinedStats(pieces_);
  std::vector<const std::vector<Vec3>*> piece_points;
  std::vector<const FittedSurface*> fits;
  for (const auto& piece : pieces_) {
    points_ += piece->points();
    piece_points.push_back(&piece->points_.positions);
    fits.push_back(piece->fit_.get());
    seconds_ += piece->seconds();
  }
  if (fits.size() == 1) {
    surface_ = &fits.front()->surface();
    data_ = std::make_unique<TreeLocator>(fits.front()->tree(), fits.front()->input().positions);
  } else {
    auto joined = std::make_unique<detail::JoinedSurface>(fits);
    surface_ = joined.get();
    data_ = std::move(joined);
  }

  auto t = Clock::now();
  const std::vector<Vec3> starts = cubeMeans(piece_points, params.output_spacing_mm);
  std::vector<Projection> feet(starts.size());
  detail::LoopProgress ticks(progress, "surface points", starts.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starts.size(), 256), [&](const auto& range) {
    ticks.add(range.size());
    for (std::size_t k = range.begin(); k != range.end(); ++k) feet[k] = surface_->project(starts[k]);
  });
  for (const Projection& foot : feet) {
    if (!foot.valid) continue;
    surface_points_.positions.push_back(foot.point);
    surface_points_.normals.push_back(foot.normal);
    not_converged_ += !foot.converged;
  }
  stats_.stage_seconds["surface points"] = secondsSince(t);
  if (progress) progress("surface points", 1.0);

  if (params.with_mesh) {
    t = Clock::now();
    MeshParams mesh_params;
    mesh_params.progress = progress;
    mesh_ = meshSurface(*surface_, *data_, surface_points_, params.output_spacing_mm, mesh_params, &mesh_stats_);
    mesh_.vertices.strain.clear();
    stats_.stage_seconds["mesh"] = secondsSince(t);
  }
  join_seconds_ = secondsSince(t0);
  seconds_ += join_seconds_;
}

ShapeSurface::~ShapeSurface() = default;

ShapeAndStrain strainOnShape(const ShapeSurface& shape, const Cloud& carriers, const ShapeAndStrainParams& params) {
  if (carriers.empty() || !carriers.hasStrain())
    throw std::invalid_argument("shape and strain: no carriers with strain");
  const auto t0 = Clock::now();
  ShapeAndStrain out;
  out.shape_points = shape.points();
  out.carriers = carriers.size();
  out.shape_stats = shape.stats();
  out.mesh_stats = shape.meshStats();
  out.not_converged = shape.notConverged();

  const CarrierStrain strain_field(carriers, params);
  out.strain_bandwidth = strain_field.bandwidth();
  out.carrier_spacing = strain_field.spacing();
  out.shape_stats.stage_seconds["strain field"] = secondsSince(t0);

  const auto t = Clock::now();
  const ImplicitSurface& surface = shape.implicitSurface();
  // Every point of the shape and of its mesh reads the field where it lies, with its normal.
  const auto readField = [&](Cloud& cloud) {
    cloud.strain.assign(cloud.size(), std::numeric_limits<double>::quiet_NaN());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), 256), [&](const auto& range) {
      CarrierStrain::Scratch scratch;
      for (std::size_t k = range.begin(); k != range.end(); ++k)
        cloud.strain[k] = strain_field.at(cloud.positions[k], cloud.normals[k], scratch);
    });
  };
  out.surface = shape.surface();
  readField(out.surface);
  out.without_strain = static_cast<std::size_t>(
      std::count_if(out.surface.strain.begin(), out.surface.strain.end(), [](double v) { return !std::isfinite(v); }));
  out.mesh = shape.mesh();
  if (!out.mesh.vertices.empty()) readField(out.mesh.vertices);
  out.strain_at_carriers.assign(carriers.size(), std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, carriers.size(), 256), [&](const auto& range) {
    CarrierStrain::Scratch scratch;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      // A carrier beyond the shape's points (an element only the stereo views saw) has no surface
      // under it: its projection lands elsewhere, or nowhere.
      const Projection foot = surface.project(carriers.positions[k]);
      if (foot.valid && (foot.point - carriers.positions[k]).norm() <= kMostCarrierOffset * strain_field.spacing())
        out.strain_at_carriers[k] = strain_field.at(foot.point, foot.normal, scratch);
    }
  });
  out.shape_stats.stage_seconds["strain on the surface"] = secondsSince(t);
  if (params.shape.progress) params.shape.progress("strain on the surface", 1.0);
  out.seconds = shape.seconds() + secondsSince(t0);
  return out;
}

ShapeAndStrain fitShapeAndStrain(const Cloud& shape, const Cloud& carriers, const ShapeAndStrainParams& params) {
  if (shape.hasStrain()) throw std::invalid_argument("shape and strain: the shape points must not carry strain");
  if (carriers.empty() || !carriers.hasStrain())
    throw std::invalid_argument("shape and strain: no carriers with strain");
  const ShapeSurface fitted(shape.positions, params);
  return strainOnShape(fitted, carriers, params);
}

}  // namespace stampscan::fitting
