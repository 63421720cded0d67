#include "cell_pyramid.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"

#include "robust_patch_fit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>

namespace stampscan::fitting::detail {

namespace {
// Cell keys: three 21-bit cell coordinates (about two million cells along each axis).
using Key = std::uint64_t;
constexpr int kBits = 21;
constexpr std::int64_t kBias = std::int64_t{1} << (kBits - 1);
constexpr std::uint64_t kMask = (std::uint64_t{1} << kBits) - 1;

Key keyOf(std::int64_t i, std::int64_t j, std::int64_t k) {
  const auto c = [](std::int64_t v) { return static_cast<std::uint64_t>(std::clamp(v + kBias, std::int64_t{0}, std::int64_t{kMask})); };
  return (c(i) << (2 * kBits)) | (c(j) << kBits) | c(k);
}
// The key of the cell twice as large that holds cell `key`.
Key parentOf(Key key) {
  const auto half = [](std::uint64_t c) { return (c + static_cast<std::uint64_t>(kBias)) >> 1; };
  return (half((key >> (2 * kBits)) & kMask) << (2 * kBits)) | (half((key >> kBits) & kMask) << kBits) | half(key & kMask);
}

// Least number of cells a fit needs: the quadric has six parameters, and each cell adds one row.
constexpr std::size_t kMinCells = 10;
// Least variance of the difference of two nested fits, as a share of the narrower one's variance.
constexpr double kLeastDifferenceVariance = 0.1;
// Share of h by which the data's weighted centre may lie to one side before a fit counts as one-sided.
constexpr double kOneSidedShift = 0.5;
// Least in-plane spread (in h^2) of a fit's cells, as for the point fits (robust_patch_fit.cpp).
constexpr double kMinTangentSpread = 0.05;

// Running sums of one cell about a reference point (its first point), which keeps the covariance
// accurate in double precision whatever the coordinates' magnitude.
struct Accumulator {
  Vec3 reference = Vec3::Zero();
  double w = 0, w2 = 0, ws = 0, w_strain = 0;
  Vec3 wp = Vec3::Zero();
  Eigen::Matrix3d wpp = Eigen::Matrix3d::Zero();
  void add(const Vec3& p, double weight, double strain) {
    const Vec3 d = p - reference;
    w += weight;
    w2 += weight * weight;
    wp += weight * d;
    wpp.noalias() += weight * d * d.transpose();
    if (std::isfinite(strain)) {
      ws += weight * strain;
      w_strain += weight;
    }
  }
  void finish(Vec3& centroid, CellMoments& m) const {
    const Vec3 mean = wp / w;
    centroid = reference + mean;
    const Eigen::Matrix3d c = wpp / w - mean * mean.transpose();
    m.weight = static_cast<float>(w);
    m.weight_sq = static_cast<float>(w2);
    m.strain = w_strain > 0 ? static_cast<float>(ws / w_strain) : std::numeric_limits<float>::quiet_NaN();
    const double entries[6] = {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)};
    for (int k = 0; k < 6; ++k) m.cov[k] = static_cast<float>(entries[k]);
  }
};
}  // namespace

struct CellPyramid::Level {
  double size = 0;
  std::vector<Key> keys;  // sorted; only while the next level is built
  std::vector<Vec3> centroids;
  std::vector<CellMoments> moments;
  std::unique_ptr<KdTree> tree;
};

CellPyramid::CellPyramid(const std::vector<Vec3>& points, const KdTree& tree, std::vector<float> point_weights,
                         const std::vector<double>* strain, double base_cell, double largest_bandwidth)
    : points_(points), point_tree_(tree), weights_(std::move(point_weights)), strain_(strain), base_cell_(base_cell) {
  const std::vector<float>& weights = weights_;
  if (!(base_cell > 0)) throw std::invalid_argument("cell pyramid: the base cell size must be positive");
  const std::size_t n = points.size();
  // Level 0 from the points: sort them by cell, then sum each run.
  std::vector<std::pair<Key, std::uint32_t>> keyed;
  keyed.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!(weights[i] > 0)) continue;
    const Vec3 g = points[i] / base_cell;
    keyed.emplace_back(keyOf(static_cast<std::int64_t>(std::floor(g.x())), static_cast<std::int64_t>(std::floor(g.y())),
                             static_cast<std::int64_t>(std::floor(g.z()))),
                       static_cast<std::uint32_t>(i));
  }
  tbb::parallel_sort(keyed.begin(), keyed.end());
  auto level = std::make_unique<Level>();
  level->size = base_cell;
  for (std::size_t start = 0; start < keyed.size();) {
    std::size_t end = start;
    Accumulator acc;
    acc.reference = points[keyed[start].second];
    for (; end < keyed.size() && keyed[end].first == keyed[start].first; ++end) {
      const std::uint32_t i = keyed[end].second;
      acc.add(points[i], weights[i], strain ? (*strain)[i] : std::numeric_limits<double>::quiet_NaN());
    }
    level->keys.push_back(keyed[start].first);
    level->centroids.emplace_back();
    level->moments.emplace_back();
    acc.finish(level->centroids.back(), level->moments.back());
    start = end;
  }
  std::vector<std::pair<Key, std::uint32_t>>().swap(keyed);
  levels_.push_back(std::move(level));

  // Each further level merges the cells below in eights (parallel-axis rule for the covariance).
  while (levels_.back()->size * kCellsPerBandwidth < largest_bandwidth && levels_.back()->centroids.size() > 1 &&
         levels_.size() < 24) {
    const Level& below = *levels_.back();
    std::vector<std::pair<Key, std::uint32_t>> parents(below.keys.size());
    for (std::size_t c = 0; c < below.keys.size(); ++c) parents[c] = {parentOf(below.keys[c]), static_cast<std::uint32_t>(c)};
    std::sort(parents.begin(), parents.end());
    auto next = std::make_unique<Level>();
    next->size = 2.0 * below.size;
    for (std::size_t start = 0; start < parents.size();) {
      std::size_t end = start;
      Accumulator acc;
      acc.reference = below.centroids[parents[start].second];
      for (; end < parents.size() && parents[end].first == parents[start].first; ++end) {
        const std::uint32_t c = parents[end].second;
        const CellMoments& m = below.moments[c];
        const Vec3 d = below.centroids[c] - acc.reference;
        acc.w += m.weight;
        acc.w2 += m.weight_sq;
        acc.wp += m.weight * d;
        acc.wpp.noalias() += m.weight * (d * d.transpose() + m.covariance());
        if (std::isfinite(m.strain)) {
          acc.ws += static_cast<double>(m.weight) * m.strain;
          acc.w_strain += m.weight;
        }
      }
      next->keys.push_back(parents[start].first);
      next->centroids.emplace_back();
      next->moments.emplace_back();
      acc.finish(next->centroids.back(), next->moments.back());
      start = end;
    }
    levels_.push_back(std::move(next));
  }
  for (auto& l : levels_) {
    std::vector<Key>().swap(l->keys);
    l->centroids.shrink_to_fit();
    l->moments.shrink_to_fit();
    l->tree = std::make_unique<KdTree>(l->centroids);
  }
}

CellPyramid::~CellPyramid() = default;

double CellPyramid::cellSize(int level) const { return levels_[static_cast<std::size_t>(level)]->size; }

int CellPyramid::levelFor(double h, double cells_per_bandwidth) const {
  const double ratio = h / (cells_per_bandwidth * base_cell_);
  if (ratio < 1) return -1;
  return std::min(static_cast<int>(std::floor(std::log2(ratio) + 1e-9)), levels() - 1);
}

void CellPyramid::near(int level, const Vec3& x, double radius, std::vector<Neighbor>& out) const {
  if (level < 0) {
    point_tree_.radius(x, radius, out);
    // Points without weight (outliers) are no elements.
    out.erase(std::remove_if(out.begin(), out.end(), [&](const Neighbor& nb) { return !(weights_[nb.index] > 0); }),
              out.end());
    return;
  }
  levels_[static_cast<std::size_t>(level)]->tree->radius(x, radius, out);
}

CellElement CellPyramid::element(int level, std::uint32_t index) const {
  if (level < 0) {
    const double w = weights_[index];
    return {points_[index], nullptr, w, w * w, strain_ ? (*strain_)[index] : std::numeric_limits<double>::quiet_NaN()};
  }
  const Level& l = *levels_[static_cast<std::size_t>(level)];
  const CellMoments& m = l.moments[index];
  return {l.centroids[index], &m, m.weight, m.weight_sq, m.strain};
}

const Vec3& CellPyramid::centroid(int level, std::uint32_t cell) const {
  return levels_[static_cast<std::size_t>(level)]->centroids[cell];
}

const CellMoments& CellPyramid::moments(int level, std::uint32_t cell) const {
  return levels_[static_cast<std::size_t>(level)]->moments[cell];
}

std::size_t CellPyramid::cells(int level) const { return levels_[static_cast<std::size_t>(level)]->centroids.size(); }

std::size_t CellPyramid::bytes() const {
  std::size_t total = 0;
  for (const auto& l : levels_) total += l->centroids.capacity() * (sizeof(Vec3) + sizeof(CellMoments) + 2 * sizeof(std::uint32_t));
  total += weights_.capacity() * sizeof(float);
  return total;
}

std::optional<CellFit> fitOnCells(const CellPyramid& pyramid, const Vec3& centre, double h, const Vec3* frame_normal,
                                  CellFitScratch& s) {
  const int level = pyramid.levelFor(h);
  pyramid.near(level, centre, kSupport * h, s.near);
  if (s.near.size() < kMinCells) return std::nullopt;
  const double h_sq = h * h;
  s.weight.resize(s.near.size());
  WeightedSums plane_sums(centre, h);
  double plane_w = 0;
  Vec3 plane_wp = Vec3::Zero();
  for (std::size_t k = 0; k < s.near.size(); ++k) {
    const CellElement e = pyramid.element(level, s.near[k].index);
    s.weight[k] = gaussianWeightSq(s.near[k].distance_sq, h_sq);  // Eq. (3), at the cell's centroid
    plane_sums.addCell(e.centroid, e.covariance(), s.weight[k] * e.weight);
    plane_w += s.weight[k] * e.weight;
    plane_wp += s.weight[k] * e.weight * (e.centroid - centre);
  }
  // Eqs. (2), (6), (7): the weighted plane gives the frame; its spread says whether the cells cover
  // two directions at all.
  const std::optional<LocalSurface> plane = LocalSurface::fitPlane(plane_sums);
  if (!plane || plane->tangentSpread() < kMinTangentSpread) return std::nullopt;
  const Vec3 normal = frame_normal ? *frame_normal : plane->normal(centre);
  // At the edge of the data the support is one-sided and the cubic terms are poorly determined: a
  // patch read there extrapolates them. Where the data's weighted centre lies more than half a
  // bandwidth to one side, the quadric is fitted instead.
  const Vec3 shift = plane_w > 0 ? Vec3(plane_wp / plane_w) : Vec3::Zero();
  const bool one_sided = (shift - normal * normal.dot(shift)).norm() > kOneSidedShift * h;
  QuadricPatch::Sums sums(frameAround(normal), centre, h, one_sided ? 2 : 3, &s.variance_rows);
  double sum_w = 0, sum_w2 = 0;
  for (std::size_t k = 0; k < s.near.size(); ++k) {
    const CellElement e = pyramid.element(level, s.near[k].index);
    const double g = s.weight[k];
    const double variance_weight = g * g * e.weight_sq;
    sums.addCell(e.centroid, e.covariance(), g * e.weight, variance_weight);
    sum_w += g * e.weight;
    sum_w2 += variance_weight;
  }
  const std::optional<QuadricPatch::FitWithVariance> fitted = QuadricPatch::fitWithOffsetVariance(sums);
  if (!fitted || !(sum_w2 > 0)) return std::nullopt;
  CellFit fit{fitted->patch};
  const QuadricPatch* surface = &fit.surface;
  fit.frame_normal = normal;
  fit.offset = surface->signedDistance(centre);
  fit.offset_factor = std::sqrt(fitted->offset_variance_factor);
  fit.effective_count = sum_w * sum_w / sum_w2;
  if (!std::isfinite(fit.offset_factor)) return std::nullopt;
  return fit;
}

double strainNear(const CellPyramid& pyramid, const Vec3& x, const Vec3& n, double h, CellFitScratch& s) {
  const int level = pyramid.levelFor(h, kStrainCellsPerBandwidth);
  pyramid.near(level, x, kSupport * h, s.near);
  const double h_sq = h * h;
  s.samples.clear();
  for (const Neighbor& nb : s.near) {
    const CellElement e = pyramid.element(level, nb.index);
    if (std::isfinite(e.strain)) s.samples.push_back({e.centroid, e.strain, gaussianWeightSq(nb.distance_sq, h_sq) * e.weight});
  }
  return smoothScalar(x, n, s.samples);
}

StrainChoice chooseStrainBandwidth(const CellPyramid& pyramid, const Vec3& x, const Vec3& n, double h_start,
                                   double step, int scales, double gamma, CellFitScratch& s) {
  constexpr double kLeastEffectiveCount = 8;  // a linear field has three parameters
  StrainChoice chosen;
  double noise_sd = -1;
  struct Accepted {
    double value, factor;  // the fit's value at x and its SD per unit of strain noise
  };
  std::vector<Accepted> accepted;
  double h = h_start;
  for (int j = 0; j < scales; ++j, h *= step) {
    const int level = pyramid.levelFor(h, kStrainCellsPerBandwidth);
    pyramid.near(level, x, kSupport * h, s.near);
    const double h_sq = h * h;
    s.samples.clear();
    double sw = 0, sw2 = 0;
    for (const Neighbor& nb : s.near) {
      const CellElement e = pyramid.element(level, nb.index);
      if (!std::isfinite(e.strain)) continue;
      const double g = gaussianWeightSq(nb.distance_sq, h_sq);
      s.samples.push_back({e.centroid, e.strain, g * e.weight});
      sw += g * e.weight;
      sw2 += g * g * e.weight_sq;
    }
    if (!(sw > 0) || sw * sw / sw2 < kLeastEffectiveCount) continue;  // too little data yet: wider
    const auto field = fitTangentLinear(x, n, s.samples);
    if (!field) continue;
    const double n_eff = sw * sw / sw2;
    const double factor = std::sqrt(sw2) / sw;
    if (noise_sd < 0) {
      // The strain noise from this fit's residuals (a cell's mean strain is an average: its
      // residual is scaled back to one point's by its weight).
      double swr2 = 0;
      for (const ScalarSample& q : s.samples) {
        const double r = q.value - field->value - field->gradient.dot(q.position - x);
        swr2 += q.weight * r * r;
      }
      noise_sd = std::sqrt(swr2 / sw * n_eff / (n_eff - 3.0));
    }
    const double sd = noise_sd * factor;
    const bool agrees = std::all_of(accepted.begin(), accepted.end(), [&](const Accepted& a) {
      const double a_sd = noise_sd * a.factor;
      return std::abs(field->value - a.value) <= gamma * std::sqrt(std::max(a_sd * a_sd - sd * sd, kLeastDifferenceVariance * a_sd * a_sd));
    });
    if (!agrees) break;
    accepted.push_back({field->value, factor});
    chosen = {h, field->value, field->gradient};
  }
  return chosen;
}

BandwidthChoice chooseBandwidth(const CellPyramid& pyramid, const Vec3& centre, double h_start, double step,
                                int scales, double noise_sigma, double gamma, CellFitScratch& scratch) {
  BandwidthChoice choice;
  struct Accepted {
    double offset, sd;
  };
  std::vector<Accepted> accepted;
  accepted.reserve(static_cast<std::size_t>(std::max(scales, 0)));
  Vec3 normal = Vec3::Zero();
  double h = h_start;
  for (int j = 0; j < scales; ++j, h *= step) {
    // One height axis for every scale, the first fit's: the offsets are then comparable.
    auto fit = fitOnCells(pyramid, centre, h, choice.fit ? &normal : nullptr, scratch);
    if (!fit) {
      if (choice.fit) break;  // the data end: a wider support would not hold more of this surface
      continue;               // too few cells yet: try wider
    }
    if (!choice.fit) normal = fit->frame_normal;
    const double sd = noise_sigma * fit->offset_factor;
    // The wider fit must agree with every narrower one to within the noise of their difference.
    // Nested kernel estimates share most of their data: the difference of a narrow one and a wider
    // one has about the variance sd_i^2 - sd_j^2, far less than the sum (the floor covers a wider
    // fit that gained little, at the edge of the data).
    const bool agrees = std::all_of(accepted.begin(), accepted.end(), [&](const Accepted& a) {
      const double difference_sd = std::sqrt(std::max(a.sd * a.sd - sd * sd, kLeastDifferenceVariance * a.sd * a.sd));
      return std::abs(fit->offset - a.offset) <= gamma * difference_sd;
    });
    if (!agrees) {
      choice.limited = true;
      break;
    }
    accepted.push_back({fit->offset, sd});
    choice.fit = std::move(fit);
    choice.h = h;
  }
  return choice;
}

}  // namespace stampscan::fitting::detail
