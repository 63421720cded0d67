#include "stampscan/fitting/anchored_surface.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/quadric_patch.hpp"

#include "cell_pyramid.hpp"
#include "loop_progress.hpp"
#include "robust_patch_fit.hpp"
#include "spanning_orientation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <unordered_map>

namespace stampscan::fitting {

using detail::FitScratch;
using detail::fitLocal;
using detail::kSupport;
using detail::LocalFit;

namespace {
// A point takes fine anchor cells where at least this share of the nearby probes were limited by
// misfit rather than by their point count.
constexpr double kFineShare = 0.25;
// A blended projection that moves a data point by more than this many noise deviations is checked
// against a fit centred at the point.
constexpr double kTrustedMoveSigmas = 5.0;
// The narrowest fit the cell pyramid serves, in typical narrow bandwidths. Each Lepski sequence
// starts near the narrow h, so fits there are the most frequent: read from points they cost about
// three quarters of the widening's time, read from cells a fraction of it. Cells cost accuracy
// where they are coarse against the surface's detail and memory where they are fine. Measured on
// the benchmark's dome and pan: serving from 2 h gave the lowest RMS and 121-125 B per point; from
// 1.4 h 1-2 % more RMS, 130-137 B per point and 20 % less time; from 1 h no lower RMS than 1.4 h
// and 144-149 B per point (the budget is 150).
constexpr double kFinestCellFit = 1.4;
// A blended step shorter than this share of h counts as near the surface, where the next round's
// result can be predicted from this round's feet (blend's predictedStep).
constexpr double kPredictableStep = 0.25;

// The blend's gate exp(-e^2) (see blend). Patches mostly agree to a small fraction of the gate's
// width, where the series is within 2e-13 of it and much cheaper than exp.
double gate(double excess) {
  const double e2 = excess * excess;
  return e2 < 1e-4 ? 1.0 - e2 + 0.5 * e2 * e2 : std::exp(-e2);
}

// ---------------------------------------------------------------------------------------------
// Sparse multi-level grid keys: level in the top bits, then three 19-bit cell coordinates.
using Key = std::uint64_t;
constexpr int kCellBits = 19;
constexpr std::int64_t kCellBias = std::int64_t{1} << (kCellBits - 1);
constexpr std::uint64_t kCellMask = (std::uint64_t{1} << kCellBits) - 1;

Key makeKey(int level, std::int64_t i, std::int64_t j, std::int64_t k) {
  const auto c = [](std::int64_t v) { return static_cast<std::uint64_t>(std::clamp(v + kCellBias, std::int64_t{0}, std::int64_t{kCellMask})); };
  return (static_cast<std::uint64_t>(level) << (3 * kCellBits)) | (c(i) << (2 * kCellBits)) | (c(j) << kCellBits) | c(k);
}
}  // namespace

// ---------------------------------------------------------------------------------------------
struct AnchoredSurface::Impl {
  const std::vector<Vec3>& points;
  const KdTree& tree;
  const std::vector<double>* strain;
  AnchoredParams params;

  // Bandwidth field: probe positions, their chosen h, and a tree over them.
  std::vector<Vec3> probe_points;
  std::unique_ptr<KdTree> probe_tree;
  // The wide field's own probes (widening): a subset of the narrow ones.
  std::vector<Vec3> wide_probe_points;
  std::unique_ptr<KdTree> wide_probe_tree;
  std::unique_ptr<BandwidthField> h_field;
  // After widening: the narrow field the point fits use (h_field then holds the wide one).
  std::unique_ptr<BandwidthField> narrow_field;
  std::unique_ptr<detail::CellPyramid> pyramid;
  bool widened = false;  // the anchors were fitted on the pyramid (which a shape alone drops after)
  double step_tolerance = 0;  // mm: a projection has converged when a step is below this
  std::vector<double> noise_floor;        // residual variance floor seen by each probe
  std::vector<std::optional<QuadricPatch>> probe_patches;  // each probe's fit at its chosen h
  std::vector<double> curvature_limited;  // 1 where misfit, not the point count, limited h
  double h0 = 1;  // bandwidth of level 0
  Vec3 grid_origin = Vec3::Zero();
  int levels = 1;

  struct Anchor {
    Key key = 0;
    Vec3 centre = Vec3::Zero();
    double h = 0;
    double cell = 0;  // cell size of its level
    bool valid = false;
    QuadricPatch surface;
    double strain = std::numeric_limits<double>::quiet_NaN();
    Vec3 strain_gradient = Vec3::Zero();
    double noise_floor = 0;  // residual variance the probes saw here
    double strain_h = 0;     // the strain field's own bandwidth here (widened surfaces)
  };
  std::vector<Anchor> anchors;              // sorted by key
  std::vector<std::size_t> adjacency_offset;  // CSR: anchors near each anchor, itself first
  std::vector<std::uint32_t> adjacency;
  std::vector<std::uint32_t> anchor_of_point;

  Impl(const std::vector<Vec3>& p, const KdTree& t, const std::vector<double>* s, const AnchoredParams& a,
       const Progress& pr)
      : points(p), tree(t), strain(s), params(a), caller_progress(pr) {}
  // The caller's progress, told by the construction's loops (loop_progress.hpp); not used after it.
  const Progress& caller_progress;

  // A tier is a level and a spacing: coarse cells (anchor_spacing * h) where the probes found the
  // surface smooth enough that h was limited by the point count, fine cells (one h) where misfit
  // limited h: there the quadrics hold over a shorter distance and need closer neighbours.
  static int tierOf(int level, bool fine) { return 2 * level + (fine ? 1 : 0); }
  double cellSize(int tier) const {
    // Wide patches are read closer to their centres: the shape's cubic terms, which cancel at the
    // centre of a symmetric support, grow with the distance from it.
    const double spacing = widened ? params.wide_anchor_spacing
                                   : tier % 2 ? params.fine_anchor_spacing : params.anchor_spacing;
    return spacing * h0 * std::pow(params.scale_step, tier / 2);
  }
  int levelFor(double h) const {
    const int level = static_cast<int>(std::floor(std::log(std::max(h, h0) / h0) / std::log(params.scale_step) + 1e-9));
    return std::clamp(level, 0, levels - 1);
  }
  Key keyFor(const Vec3& x, int tier) const {
    const Vec3 g = (x - grid_origin) / cellSize(tier);
    return makeKey(tier, static_cast<std::int64_t>(std::floor(g.x())), static_cast<std::int64_t>(std::floor(g.y())),
                   static_cast<std::int64_t>(std::floor(g.z())));
  }
  const Anchor* findAnchor(Key key, std::uint32_t* index = nullptr) const {
    const auto it = std::lower_bound(anchors.begin(), anchors.end(), key, [](const Anchor& a, Key k) { return a.key < k; });
    if (it == anchors.end() || it->key != key) return nullptr;
    if (index) *index = static_cast<std::uint32_t>(it - anchors.begin());
    return &*it;
  }

  void chooseBandwidths(AnchoredStats& stats);
  void buildAnchors();
  void fitAnchors(const Progress& progress);
  std::vector<float> pointWeights() const;
  void widenBandwidths(AnchoredStats& stats, const Progress& progress);
  std::vector<std::size_t> thinnedProbes(double cube) const;
  void fitAnchorsOnCells(const Progress& progress);
  const BandwidthField& pointField() const { return narrow_field ? *narrow_field : *h_field; }
  void linkAnchors();
  std::size_t orientAnchors();
  // One anchor's part in a blend at a point: its weight, the point's foot on its patch and how far
  // the point moved to get there.
  struct Contribution {
    const Anchor* anchor;
    double phi;
    Vec3 projected;
    double moved;
  };
  Projection blend(const Vec3& start, const std::uint32_t* candidates, std::size_t count) const;
  bool contributions(const Vec3& x, const std::uint32_t* candidates, std::size_t count, std::vector<Contribution>& near) const;
  double predictedStep(const std::vector<Contribution>& near, const Vec3& next) const;
  void normalAndStrain(const std::vector<Contribution>& near, const Vec3& x, double h_mean, Projection& result) const;
  Projection checkedAgainstLocalFit(const Vec3& x, const Projection& blended) const;
};

void AnchoredSurface::Impl::chooseBandwidths(AnchoredStats& stats) {
  // Probes: every probe_stride-th point in the kd-tree's spatial order, so they cover the part evenly
  // in index space (denser where the data are denser).
  const std::vector<std::uint32_t> order = tree.spatialOrder();
  const std::size_t stride = std::max<std::size_t>(1, std::min(params.probe_stride, points.size() / 64 + 1));
  std::vector<std::uint32_t> probes;
  for (std::size_t k = stride / 2; k < order.size(); k += stride) probes.push_back(order[k]);
  if (probes.empty()) probes.push_back(order.front());
  std::vector<double> chosen(probes.size(), 0.0);
  std::vector<double> floors(probes.size(), 0.0);
  std::vector<double> smallest(probes.size(), 0.0);  // smallest scale that could be fitted
  std::vector<double> limited(probes.size(), 0.0);
  std::vector<std::uint8_t> capped(probes.size(), 0);  // h stopped at the effective-count cap
  std::vector<std::optional<QuadricPatch>> patches(probes.size());  // the fit at the chosen h
  std::vector<std::optional<QuadricPatch>> first_patches(probes.size());  // at the smallest h

  detail::LoopProgress ticks(caller_progress, "bandwidth", probes.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, probes.size(), 8), [&](const auto& range) {
    ticks.add(range.size());
    FitScratch scratch;
    std::vector<Neighbor> knn;
    for (std::size_t p = range.begin(); p != range.end(); ++p) {
      const Vec3& x = points[probes[p]];
      tree.knn(x, static_cast<std::size_t>(params.start_rank) + 1, knn);
      const double h_start = std::max(std::sqrt(knn.back().distance_sq), 1e-9);
      // Grow h while the quadric still explains the neighbourhood down to the noise: the residual
      // variance stays at the floor set by the best smaller scale (misfit would add to it), and
      // stop once enough points carry weight that more would not lower the error noticeably.
      double floor_variance = std::numeric_limits<double>::infinity();
      double best = 0;
      double h = h_start;
      for (int j = 0; j < params.max_scales; ++j, h *= params.scale_step) {
        const auto fit = fitLocal(points, tree, nullptr, x, h, params.robust, params.min_points, scratch);
        if (!fit) continue;  // too few points at this scale: try a wider one
        if (best > 0 && fit->residual_variance > (1.0 + params.misfit_tolerance) * floor_variance) {
          limited[p] = 1.0;
          break;
        }
        if (best == 0) {
          smallest[p] = h;
          first_patches[p] = fit->surface;
        }
        floor_variance = std::min(floor_variance, fit->residual_variance);
        best = h;
        patches[p] = fit->surface;
        if (fit->effective_count >= params.max_effective_count) {
          capped[p] = 1;
          break;
        }
      }
      floors[p] = std::isfinite(floor_variance) ? floor_variance : 0.0;
      chosen[p] = best > 0 ? best : h_start * std::pow(params.scale_step, params.max_scales - 1);
    }
  });

  // The noise of a scanner is much the same all over a part, so the typical floor tells noise from
  // misfit: where even the smallest scale left more than twice the typical floor (sparse data over a
  // tight radius), that floor was misfit already and the smallest scale is kept.
  std::vector<double> measured;
  for (double f : floors)
    if (f > 0) measured.push_back(f);
  const double typical = measured.empty() ? 0.0 : summarize(measured).median;
  for (std::size_t p = 0; p < probes.size(); ++p) {
    if (typical > 0 && floors[p] > 2.0 * typical && smallest[p] > 0) {
      chosen[p] = smallest[p];
      limited[p] = 1.0;
      patches[p] = first_patches[p];
    }
    if (typical > 0) floors[p] = std::min(floors[p] > 0 ? floors[p] : typical, 2.0 * typical);
  }

  stats.count_capped_share =
      static_cast<double>(std::count(capped.begin(), capped.end(), std::uint8_t{1})) / static_cast<double>(probes.size());
  probe_points.reserve(probes.size());
  for (std::uint32_t i : probes) probe_points.push_back(points[i]);
  probe_tree = std::make_unique<KdTree>(probe_points);
  stats.probes = probes.size();
  stats.bandwidth = summarize(chosen);
  h0 = stats.bandwidth.min;
  levels = 1 + static_cast<int>(std::ceil(std::log(stats.bandwidth.max / h0) / std::log(params.scale_step) - 1e-9));
  levels = std::clamp(levels, 1, 60);
  h_field = std::make_unique<BandwidthField>(probe_points, *probe_tree, std::move(chosen), BandwidthField::Mean::Harmonic);
  noise_floor = std::move(floors);
  curvature_limited = std::move(limited);
  probe_patches = std::move(patches);
  grid_origin = boundsOf(points).min;
}

void AnchoredSurface::Impl::buildAnchors() {
  // Each point joins the cell of its level (its bandwidth rounded down to h0 * 1.5^level); a cell's
  // points make one anchor at their centroid (summed in the points' order), the anchors sorted by
  // key. The keys are found in parallel a block of points at a time and gathered in a table of the
  // cells: a sorted key per point would take 160 MB more on a session's ten million returns.
  const std::size_t n = points.size();
  constexpr std::size_t kBlock = std::size_t{1} << 20;
  anchor_of_point.assign(n, 0);
  std::unordered_map<Key, std::uint32_t> cell_index;
  std::vector<Key> cell_keys;
  std::vector<Vec3> cell_sums;
  std::vector<std::uint32_t> cell_counts;
  std::vector<Key> block(std::min(n, kBlock));
  for (std::size_t begin = 0; begin < n; begin += kBlock) {
    const std::size_t end = std::min(n, begin + kBlock);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end, 1024), [&](const auto& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        const auto [h, limited] = h_field->atAndOther(points[i], curvature_limited, 4);
        block[i - begin] = keyFor(points[i], tierOf(levelFor(h), limited > kFineShare));
      }
    });
    for (std::size_t i = begin; i < end; ++i) {
      const auto [at, added] = cell_index.try_emplace(block[i - begin], static_cast<std::uint32_t>(cell_keys.size()));
      if (added) {
        cell_keys.push_back(block[i - begin]);
        cell_sums.push_back(Vec3::Zero());
        cell_counts.push_back(0);
      }
      cell_sums[at->second] += points[i];
      ++cell_counts[at->second];
      anchor_of_point[i] = at->second;
    }
  }
  std::vector<std::uint32_t> by_key(cell_keys.size());
  std::iota(by_key.begin(), by_key.end(), 0u);
  std::sort(by_key.begin(), by_key.end(), [&](std::uint32_t a, std::uint32_t b) { return cell_keys[a] < cell_keys[b]; });
  std::vector<std::uint32_t> rank(by_key.size());
  anchors.reserve(by_key.size());
  for (std::uint32_t r = 0; r < by_key.size(); ++r) {
    const std::uint32_t c = by_key[r];
    rank[c] = r;
    Anchor a;
    a.key = cell_keys[c];
    a.centre = cell_sums[c] / static_cast<double>(cell_counts[c]);
    a.cell = cellSize(static_cast<int>(a.key >> (3 * kCellBits)));
    anchors.push_back(a);
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) anchor_of_point[i] = rank[anchor_of_point[i]];
  });
}

void AnchoredSurface::Impl::fitAnchors(const Progress& progress) {
  detail::LoopProgress ticks(caller_progress, "anchors", anchors.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, anchors.size(), 16), [&](const auto& range) {
    ticks.add(range.size());
    FitScratch scratch;
    for (std::size_t a = range.begin(); a != range.end(); ++a) {
      Anchor& anchor = anchors[a];
      anchor.h = h_field->at(anchor.centre, 4);
      // The noise floor the probes saw here.
      const double floor = h_field->interpolateOther(anchor.centre, noise_floor, 4);
      anchor.noise_floor = floor;
      // A fit that fails (too few points, or too few kept) is retried wider, a few times, as long as
      // the wider fit still explains its neighbourhood (a wide fit over a tight radius would not, and
      // is worse than leaving the cell to its neighbours).
      std::optional<LocalFit> fit;
      const double first_h = anchor.h;
      for (int attempt = 0; attempt < 4 && !fit; ++attempt) {
        fit = fitLocal(points, tree, strain, anchor.centre, anchor.h, params.robust, params.min_points, scratch);
        if (fit && attempt > 0 && fit->residual_variance > 4.0 * floor) fit.reset();
        if (!fit) anchor.h *= params.scale_step;
      }
      if (!fit) anchor.h = first_h;
      // The interpolated h may come from flatter surroundings: where the fit leaves more than the
      // noise floor (the probes' misfit rule, applied here), narrow h while that helps, until the fit
      // is down to the floor.
      const bool misfit = fit && fit->residual_variance > (1.0 + params.misfit_tolerance) * floor;
      for (int step = 0; fit && misfit && step < 3; ++step) {
        const double h = anchor.h / params.scale_step;
        auto narrower = fitLocal(points, tree, strain, anchor.centre, h, params.robust, params.min_points, scratch);
        if (!narrower || narrower->residual_variance >= fit->residual_variance) break;
        const bool settled = narrower->residual_variance <= (1.0 + params.misfit_tolerance) * floor;
        fit = std::move(narrower);
        anchor.h = h;
        if (settled) break;
      }
      if (!fit) continue;
      anchor.valid = true;
      anchor.surface = fit->surface;
      anchor.strain = fit->strain;
      anchor.strain_gradient = fit->strain_gradient;
    }
  });
  if (progress) progress("anchors", 1.0);
}

std::vector<float> AnchoredSurface::Impl::pointWeights() const {
  // Tukey's biweight of each point's residual from the nearest probe's robust fit at its chosen h,
  // against the noise there: outliers get no weight in the wide fits, whose cells could not single
  // them out. The probes lie one per probe_stride points, within about a narrow bandwidth of every
  // point where the data are dense (the only place the widening runs), where a probe's quadric
  // still holds to well under the noise: no narrow anchors need be fitted for this.
  std::vector<float> weights(points.size(), 0.0f);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 4096), [&](const auto& range) {
    std::vector<Neighbor> near;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      probe_tree->knn(points[i], 4, near);
      for (const Neighbor& nb : near) {
        const std::optional<QuadricPatch>& patch = probe_patches[nb.index];
        if (!patch) continue;  // no fit at this probe: the next nearest judges
        const double sigma = std::sqrt(std::max(noise_floor[nb.index], 1e-12));
        const double r = patch->signedDistance(points[i]) / (4.685 * sigma);
        weights[i] = r * r < 1.0 ? static_cast<float>((1.0 - r * r) * (1.0 - r * r)) : 0.0f;
        break;
      }
    }
  });
  return weights;
}

std::vector<std::size_t> AnchoredSurface::Impl::thinnedProbes(double cube) const {
  // The probes are in the kd-tree's spatial order; a probe is kept when its cube holds no kept one.
  std::vector<std::pair<Key, std::size_t>> keyed(probe_points.size());
  for (std::size_t p = 0; p < probe_points.size(); ++p) {
    const Vec3 g = (probe_points[p] - grid_origin) / cube;
    keyed[p] = {makeKey(0, static_cast<std::int64_t>(std::floor(g.x())), static_cast<std::int64_t>(std::floor(g.y())),
                        static_cast<std::int64_t>(std::floor(g.z()))),
                p};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::size_t> kept;
  for (std::size_t k = 0; k < keyed.size(); ++k)
    if (k == 0 || keyed[k].first != keyed[k - 1].first) kept.push_back(keyed[k].second);
  std::sort(kept.begin(), kept.end());
  return kept;
}

void AnchoredSurface::Impl::widenBandwidths(AnchoredStats& stats, const Progress& progress) {
  const std::vector<double>& narrow = h_field->values();
  stats.narrow_bandwidth = summarize(narrow);
  const double largest = stats.narrow_bandwidth.max * std::pow(params.scale_step, params.wide_scales - 1);
  // The finest cells serve fits from kFinestCellFit times the typical narrow h; narrower fits read
  // the points.
  widened = true;
  pyramid = std::make_unique<detail::CellPyramid>(
      points, tree, pointWeights(), strain, kFinestCellFit * stats.narrow_bandwidth.median / detail::kCellsPerBandwidth, largest);
  for (int l = 0; l < pyramid->levels(); ++l) stats.pyramid_cells += pyramid->cells(l);
  stats.pyramid_bytes = pyramid->bytes();
  // The probes' patches have given the point weights.
  std::vector<std::optional<QuadricPatch>>().swap(probe_patches);

  // The wide field is only where each anchor's own choice starts (fitAnchorsOnCells re-chooses from
  // two steps below it), so it needs probes about as far apart as the narrowest wide supports, not
  // the narrow field's: where the data are dense, one probe per cube of wide_probe_spacing narrow
  // bandwidths (the first in the kd-tree's spatial order) decides it.
  const std::vector<std::size_t> kept = thinnedProbes(params.wide_probe_spacing * stats.narrow_bandwidth.median);
  stats.wide_probes = kept.size();
  std::vector<double> wide(kept.size(), 0.0);
  std::vector<double> limited(kept.size(), 0.0);
  detail::LoopProgress ticks(caller_progress, "widening", kept.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, kept.size(), 8), [&](const auto& range) {
    ticks.add(range.size());
    detail::CellFitScratch scratch;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const std::size_t p = kept[k];
      const double sigma = std::sqrt(std::max(noise_floor[p], 1e-12));
      const detail::BandwidthChoice choice = detail::chooseBandwidth(*pyramid, probe_points[p], narrow[p], params.scale_step,
                                                           params.wide_scales, sigma, params.agreement_sigmas, scratch);
      // Where no cell fit could be made the narrow choice stands.
      wide[k] = choice.fit ? std::max(choice.h, narrow[p]) : narrow[p];
      limited[k] = choice.limited ? 1.0 : 0.0;
    }
  });
  stats.shape_limited_share = kept.empty() ? 0.0 : static_cast<double>(std::count(limited.begin(), limited.end(), 1.0)) / static_cast<double>(kept.size());
  stats.bandwidth = summarize(wide);
  narrow_field = std::move(h_field);
  h0 = stats.bandwidth.min;
  levels = 1 + static_cast<int>(std::ceil(std::log(stats.bandwidth.max / h0) / std::log(params.scale_step) - 1e-9));
  levels = std::clamp(levels, 1, 60);
  wide_probe_points.reserve(kept.size());
  for (std::size_t p : kept) wide_probe_points.push_back(probe_points[p]);
  wide_probe_tree = std::make_unique<KdTree>(wide_probe_points);
  h_field = std::make_unique<BandwidthField>(wide_probe_points, *wide_probe_tree, std::move(wide), BandwidthField::Mean::Harmonic);
  curvature_limited = std::move(limited);
  if (progress) progress("widening", 1.0);
}

void AnchoredSurface::Impl::fitAnchorsOnCells(const Progress& progress) {
  // Each anchor chooses its own bandwidth by the same rule, from the narrow h there up to one step
  // beyond the wide field's: the field is interpolated between probes and may be too wide where a
  // radius starts between them.
  detail::LoopProgress ticks(caller_progress, "wide anchors", anchors.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, anchors.size(), 16), [&](const auto& range) {
    ticks.add(range.size());
    detail::CellFitScratch scratch;
    for (std::size_t a = range.begin(); a != range.end(); ++a) {
      Anchor& anchor = anchors[a];
      const auto [h_narrow, floor] = narrow_field->atAndOther(anchor.centre, noise_floor, 4);
      const double h_wide = h_field->at(anchor.centre, 4);
      anchor.noise_floor = floor;
      // Start two steps below the field's h (or at the narrow h, if that is wider): the field may be
      // too wide where a radius begins between probes, and the narrower fits let the rule see it.
      const double h_start = std::max(h_narrow, h_wide / (params.scale_step * params.scale_step));
      const int scales =
          2 + static_cast<int>(std::ceil(std::log(std::max(h_wide / h_start, 1.0)) / std::log(params.scale_step) - 1e-9));
      const detail::BandwidthChoice choice =
          detail::chooseBandwidth(*pyramid, anchor.centre, h_start, params.scale_step, scales,
                                  std::sqrt(std::max(floor, 1e-12)), params.agreement_sigmas, scratch);
      anchor.h = choice.fit ? choice.h : h_wide;
      if (!choice.fit) continue;
      anchor.valid = true;
      anchor.surface = choice.fit->surface;
      if (strain) {
        // From a third of the narrow h up to the shape's own.
        const double h_low = h_narrow / (params.scale_step * params.scale_step * params.scale_step);
        const Vec3 foot = anchor.surface.project(anchor.centre);
        const int strain_scales =
            1 + static_cast<int>(std::ceil(std::log(std::max(anchor.h / h_low, 1.0)) / std::log(params.scale_step) - 1e-9));
        const detail::StrainChoice field =
            detail::chooseStrainBandwidth(*pyramid, foot, anchor.surface.normal(foot), h_low, params.scale_step,
                                          std::min(strain_scales, 8), params.agreement_sigmas, scratch);
        anchor.strain_h = field.h;
        if (field.h > 0 && std::isfinite(field.value)) {
          // The anchor's own strain field (linear about the foot; blend fits the strain again at
          // each projected point, and falls back on these where that finds no strain).
          anchor.strain = field.value - field.gradient.dot(foot - anchor.centre);
          anchor.strain_gradient = field.gradient;
        }
      }
    }
  });
  if (progress) progress("wide anchors", 1.0);
}

void AnchoredSurface::Impl::linkAnchors() {
  // Candidates for blending at a point of anchor a's cell: every anchor whose support could reach
  // that cell, found once per anchor (an anchor one level coarser has a support 1.5x wider). The
  // lists end up in one array (no per-anchor vectors, whose slack would double the memory).
  std::vector<Vec3> centres(anchors.size());
  for (std::size_t a = 0; a < anchors.size(); ++a) centres[a] = anchors[a].centre;
  const KdTree anchor_tree(centres);
  const auto candidates = [&](std::size_t a, std::vector<Neighbor>& near, auto&& emit) {
    const double reach = (params.blend_radius * params.scale_step + std::sqrt(3.0)) * anchors[a].cell;
    anchor_tree.radius(anchors[a].centre, reach, near, /*sorted=*/true);
    emit(static_cast<std::uint32_t>(a));
    // Keep b only if its support (see blend) can reach a point of a's cell.
    for (const Neighbor& nb : near) {
      if (nb.index == a) continue;
      const Anchor& b = anchors[nb.index];
      const double support = params.blend_radius * std::min(b.cell, b.h) + std::sqrt(3.0) * anchors[a].cell;
      if (nb.distance_sq <= support * support) emit(nb.index);
    }
  };
  // Blocks of anchors are listed in parallel, each into its own buffer, then stitched in order.
  constexpr std::size_t kBlock = 256;
  const std::size_t blocks = (anchors.size() + kBlock - 1) / kBlock;
  std::vector<std::vector<std::uint32_t>> block_lists(blocks);
  adjacency_offset.assign(anchors.size() + 1, 0);
  detail::LoopProgress ticks(caller_progress, "anchor links", blocks);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t block) {
    ticks.add(1);
    std::vector<Neighbor> near;
    auto& list = block_lists[block];
    for (std::size_t a = block * kBlock; a < std::min(anchors.size(), (block + 1) * kBlock); ++a) {
      const std::size_t before = list.size();
      candidates(a, near, [&](std::uint32_t b) { list.push_back(b); });
      adjacency_offset[a + 1] = list.size() - before;
    }
  });
  for (std::size_t a = 0; a < anchors.size(); ++a) adjacency_offset[a + 1] += adjacency_offset[a];
  adjacency.reserve(adjacency_offset.back());
  for (auto& list : block_lists) {
    adjacency.insert(adjacency.end(), list.begin(), list.end());
    std::vector<std::uint32_t>().swap(list);
  }
}

std::size_t AnchoredSurface::Impl::orientAnchors() {
  // Same rule as for point normals (spanning_orientation.hpp), over the anchor graph; the nearest
  // dozen candidates of each anchor (its list is sorted by distance) suffice to carry the sign.
  const std::size_t m = anchors.size();
  std::vector<Vec3> normal(m, Vec3::UnitZ());
  std::vector<std::uint8_t> usable(m, 0);
  for (std::size_t a = 0; a < m; ++a) {
    if (!anchors[a].valid) continue;
    usable[a] = 1;
    normal[a] = anchors[a].surface.normal(anchors[a].surface.project(anchors[a].centre));
  }
  const OrientationParams& o = params.orientation;
  return detail::orientOverGraph(
      normal, adjacency_offset, adjacency, 13, &usable,
      [&](std::uint32_t v) {
        return o.mode == OrientationMode::TowardsViewpoint ? Vec3((o.viewpoint - anchors[v].centre).normalized())
                                                           : Vec3(o.direction.normalized());
      },
      [&](std::uint32_t v) { anchors[v].surface.flip(); });
}

// The anchors whose support reaches x, each with its weight gated by how far its projection moves x
// beyond the closest one's (see blend); outside every support, the nearest anchor alone. False when
// no valid anchor is around.
bool AnchoredSurface::Impl::contributions(const Vec3& x, const std::uint32_t* candidates, std::size_t count,
                                          std::vector<Contribution>& near) const {
  near.clear();
  const Anchor* nearest = nullptr;
  double nearest_d2 = std::numeric_limits<double>::infinity();
  double least_moved = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < count; ++k) {
    const Anchor& a = anchors[candidates[k]];
    if (!a.valid) continue;
    const double d2 = (x - a.centre).squaredNorm();
    if (d2 < nearest_d2) {
      nearest_d2 = d2;
      nearest = &a;
    }
    // Support in cells, but never wider than the fit's own bandwidth warrants.
    const double R = params.blend_radius * std::min(a.cell, a.h);
    const double t = 1.0 - d2 / (R * R);
    if (t <= 0) continue;
    const Vec3 p = a.surface.project(x);
    const double moved = (p - x).norm();
    least_moved = std::min(least_moved, moved);
    near.push_back({&a, t * t * t, p, moved});
  }
  if (near.empty()) {
    if (!nearest) return false;
    near.push_back({nearest, 1.0, nearest->surface.project(x), 0.0});
    least_moved = 0;
  }
  for (Contribution& c : near) c.phi *= gate((c.moved - least_moved) / (0.25 * c.anchor->h));
  return true;
}

// Another round from `next` would project it onto the same patches. Near the surface (the step small
// against h) its feet stay where they are: `next` moved from x along the blended normal, which the
// patches' normals agree with to a small angle, so each foot moves by the step times that angle.
// What changes are the weights, which depend on where the point is: the mean of the same feet under
// the weights at `next` is where that round would put it, to second order.
double AnchoredSurface::Impl::predictedStep(const std::vector<Contribution>& near, const Vec3& next) const {
  double least = std::numeric_limits<double>::infinity();
  for (const Contribution& c : near) least = std::min(least, (c.projected - next).norm());
  Vec3 sum = Vec3::Zero();
  double weight = 0;
  for (const Contribution& c : near) {
    const double R = params.blend_radius * std::min(c.anchor->cell, c.anchor->h);
    const double t = std::max(0.0, 1.0 - (next - c.anchor->centre).squaredNorm() / (R * R));
    const double excess = ((c.projected - next).norm() - least) / (0.25 * c.anchor->h);
    const double phi = t * t * t * gate(excess);
    sum += phi * c.projected;
    weight += phi;
  }
  return weight > 0 ? (sum / weight - next).norm() : std::numeric_limits<double>::infinity();
}

Projection AnchoredSurface::Impl::blend(const Vec3& start, const std::uint32_t* candidates, std::size_t count) const {
  // Partition of unity: phi_a(x) = (1 - d^2 / R_a^2)^3 with R_a = blend_radius * cell. The point moves
  // to the weighted mean of its projections onto each anchor's patch, until the step is small.
  // A local fit is only trusted near its own surface: across a tight radius the anchor on the flange
  // would pull a wall point onto the flange's plane. So each weight is also gated by how far the
  // anchor's projection moves x beyond the closest anchor's: g = exp(-(excess / (h_a/4))^2).
  thread_local std::vector<Contribution> near;
  Projection result;
  result.point = start;
  result.scalar = std::numeric_limits<double>::quiet_NaN();
  Vec3 x = start;
  double h_mean = 0;
  for (int it = 1; it <= params.max_iterations; ++it) {
    if (!contributions(x, candidates, count, near)) return result;  // no valid anchor around: left alone
    Vec3 sum_p = Vec3::Zero();
    double sum_w = 0, sum_h = 0;
    for (const Contribution& c : near) {
      sum_w += c.phi;
      sum_p += c.phi * c.projected;
      sum_h += c.phi * c.anchor->h;
    }
    Vec3 next = sum_p / sum_w;
    h_mean = sum_h / sum_w;
    // After the first step the point moves along the surface normal only. Where patches disagree a
    // little (sparse data), the mean of their feet shifts as x moves along the surface and would
    // drag the point sideways by a small, steady step each round: never converging, and carrying
    // the point away from the foot of the measurement it came from.
    if (it > 1) {
      const Contribution& strongest =
          *std::max_element(near.begin(), near.end(), [](const Contribution& a, const Contribution& b) { return a.phi < b.phi; });
      const Vec3 n = strongest.anchor->surface.normal(strongest.projected);
      next = x + n * n.dot(next - x);
    }
    const double step = (next - x).norm();
    // The blended point lies among its feet on the patches; when they agree to within the
    // tolerance, projecting it again cannot move it farther than that: converged without another
    // round of projections.
    double spread_sq = 0;
    for (const Contribution& c : near) spread_sq += c.phi * (c.projected - next).squaredNorm();
    const double tolerance = std::min(params.tolerance * h_mean, step_tolerance);
    const bool settled = step < tolerance || spread_sq < tolerance * tolerance * sum_w ||
                         (step < kPredictableStep * h_mean && predictedStep(near, next) < tolerance);
    x = next;
    result.iterations = it;
    result.valid = true;
    if (settled) {
      result.converged = true;
      break;
    }
  }
  normalAndStrain(near, x, h_mean, result);
  result.point = x;
  result.bandwidth = h_mean;
  result.neighbors = count;
  return result;
}

// Normal and strain from the last blend, evaluated once at the end. Each patch normal is turned to
// agree with the strongest one, so that a neighbour whose orientation came out the other way (sparse
// data, the far side of a thin wall) cannot tilt the sum.
void AnchoredSurface::Impl::normalAndStrain(const std::vector<Contribution>& near, const Vec3& x, double h_mean,
                                            Projection& result) const {
  const Contribution* strongest = nullptr;
  for (const Contribution& c : near)
    if (!strongest || c.phi > strongest->phi) strongest = &c;
  const Vec3 reference = strongest ? strongest->anchor->surface.normal(strongest->projected) : Vec3::UnitZ();
  Vec3 sum_n = Vec3::Zero();
  double sum_w = 0, sum_c = 0;
  for (const Contribution& c : near) {
    sum_w += c.phi;
    const Vec3 n = c.anchor->surface.normal(c.projected);
    sum_n += (n.dot(reference) < 0 ? -c.phi : c.phi) * n;
    if (strain) sum_c += c.phi * (c.anchor->strain + c.anchor->strain_gradient.dot(c.projected - c.anchor->centre));
  }
  if (sum_w > 0) {
    result.normal = sum_n.normalized();
    if (strain) result.scalar = sum_c / sum_w;
  }
  // Strain has a scale of its own: the widened bandwidth suits the shape, whose noise is averaged
  // down over many points, not the strain field, which changes faster than the shape's curvature
  // (it follows the stretch). Where the fits were widened, strain is fitted at the narrow scale the
  // data's spacing called for, exactly at the projected point.
  double strain_h = h_mean;
  if (pyramid) {
    double sum_sh = 0, sum_shw = 0;
    for (const Contribution& c : near)
      if (c.anchor->strain_h > 0) {
        sum_sh += c.phi * c.anchor->strain_h;
        sum_shw += c.phi;
      }
    strain_h = sum_shw > 0 ? sum_sh / sum_shw : pointField().at(x, 4);
  }
  if (strain && pyramid && params.scalar == ScalarFieldType::Smooth && sum_w > 0) {
    thread_local detail::CellFitScratch scratch;
    const double smooth = detail::strainNear(*pyramid, x, result.normal, strain_h, scratch);
    if (std::isfinite(smooth)) result.scalar = smooth;
  }
  if (strain && params.scalar == ScalarFieldType::Shepard) {
    thread_local std::vector<Neighbor> data;
    thread_local std::vector<ScalarSample> samples;
    const double R = kSupport * strain_h;
    tree.radius(x, R, data);
    samples.clear();
    for (const Neighbor& nb : data) samples.push_back({points[nb.index], (*strain)[nb.index], 1.0});
    const double shepard = shepardScalar(x, samples, R);  // Eqs. (15)-(16)
    if (std::isfinite(shepard)) result.scalar = shepard;
  }
}

AnchoredSurface::AnchoredSurface(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>* strain,
                                 const AnchoredParams& params, const Progress& progress)
    : impl_(std::make_unique<Impl>(points, tree, strain, params, progress)) {
  if (points.empty()) throw std::invalid_argument("cannot fit an empty cloud");
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  const auto lap = [&](const char* stage) {
    const auto t1 = Clock::now();
    stats_.stage_seconds[stage] = std::chrono::duration<double>(t1 - t0).count();
    t0 = t1;
  };
  impl_->chooseBandwidths(stats_);
  lap("bandwidth");
  if (progress) progress("bandwidth", 1.0);
  impl_->step_tolerance = params.tolerance * stats_.bandwidth.median;
  const bool widen = params.widen && stats_.count_capped_share >= params.widen_min_capped_share;
  if (!widen) {
    std::vector<std::optional<QuadricPatch>>().swap(impl_->probe_patches);  // only the widening reads them
    impl_->buildAnchors();
    lap("anchor cells");
    impl_->fitAnchors(progress);
    lap("anchor fits");
  }
  if (widen) {
    stats_.widened = true;
    impl_->widenBandwidths(stats_, progress);
    lap("widening");
    impl_->buildAnchors();
    lap("wide anchor cells");
    impl_->fitAnchorsOnCells(progress);
    lap("wide anchor fits");
  }
  impl_->linkAnchors();
  lap("anchor links");
  stats_.orientation_components = impl_->orientAnchors();
  lap("orientation");
  // Projections read the pyramid only for the strain: a shape alone (a scan's laser returns) frees
  // it, some hundreds of megabytes on a session's returns, while the other sweeps are fitted.
  if (!impl_->strain) impl_->pyramid.reset();
  stats_.anchors = impl_->anchors.size();
  stats_.invalid_anchors = static_cast<std::size_t>(
      std::count_if(impl_->anchors.begin(), impl_->anchors.end(), [](const Impl::Anchor& a) { return !a.valid; }));
}

AnchoredSurface::~AnchoredSurface() = default;

Projection AnchoredSurface::projectPoint(std::size_t i) const {
  const std::uint32_t a = impl_->anchor_of_point[i];
  const std::size_t begin = impl_->adjacency_offset[a], end = impl_->adjacency_offset[a + 1];
  const Vec3& x = impl_->points[i];
  Projection blended = impl_->blend(x, impl_->adjacency.data() + begin, end - begin);
  if (!blended.valid) {
    // No fit reaches this point's cell (an outlier alone in a cell off the surface, whose own fit
    // was rejected): borrow the anchors of the nearest point whose cell has a fit.
    thread_local std::vector<Neighbor> near;
    impl_->tree.knn(x, 16, near);
    for (const Neighbor& nb : near) {
      const std::uint32_t b = impl_->anchor_of_point[nb.index];
      if (b == a || !impl_->anchors[b].valid) continue;
      blended = impl_->blend(x, impl_->adjacency.data() + impl_->adjacency_offset[b],
                             impl_->adjacency_offset[b + 1] - impl_->adjacency_offset[b]);
      break;
    }
  }
  return impl_->checkedAgainstLocalFit(x, blended);
}

Projection AnchoredSurface::Impl::checkedAgainstLocalFit(const Vec3& x, const Projection& blended) const {
  // Where the data are too sparse for the tightest radius of the part, the patches can all be wider
  // than the feature and agree on a surface that cuts the corner. A move of many noise deviations is
  // checked against a fit centred at the point itself, as narrow as the data allow: an outlier is
  // carried onto the surface by that fit too, a point on a tight radius is not.
  const double floor = pointField().interpolateOther(x, noise_floor, 4);
  const double moved = (blended.point - x).norm();
  const double sigma = std::sqrt(floor);
  if (!blended.valid || !(floor > 0) || moved <= kTrustedMoveSigmas * sigma) return blended;
  // An outlier is far from a surface that passes close to the data around its foot point; where the
  // surface cuts a corner, the data nearest the foot are far from it too.
  thread_local std::vector<Neighbor> near;
  thread_local std::vector<double> neighbour_moves;
  tree.knn(blended.point, 9, near);
  neighbour_moves.clear();
  for (const Neighbor& nb : near) {
    if (points[nb.index] == x) continue;
    const std::uint32_t b = anchor_of_point[nb.index];
    const Projection p = blend(points[nb.index], adjacency.data() + adjacency_offset[b],
                               adjacency_offset[b + 1] - adjacency_offset[b]);
    if (p.valid) neighbour_moves.push_back((p.point - points[nb.index]).norm());
  }
  if (neighbour_moves.empty() || median(neighbour_moves) <= 0.5 * kTrustedMoveSigmas * sigma) return blended;
  thread_local FitScratch scratch;
  double h = pointField().at(x, 4) / (params.scale_step * params.scale_step);
  for (int attempt = 0; attempt < 5; ++attempt, h *= params.scale_step) {
    const auto fit = fitLocal(points, tree, strain, x, h, params.robust, params.min_points, scratch);
    if (!fit) continue;
    const Vec3 foot = fit->surface.project(x);
    // Only a local fit that keeps the point within a plausible noise excursion is taken.
    if ((foot - x).norm() > 2.0 * kTrustedMoveSigmas * sigma) break;
    Projection local = blended;
    local.point = foot;
    const Vec3 n = fit->surface.normal(foot);
    local.normal = n.dot(blended.normal) < 0 ? Vec3(-n) : n;
    if (strain && params.scalar == ScalarFieldType::Smooth) local.scalar = fit->strain + fit->strain_gradient.dot(foot - x);
    local.bandwidth = h;
    return local;
  }
  // Nothing here fits the data well enough to move the point by that much: the data are too sparse
  // for the part's radii at this spot. The measured point is kept as it is, which is never worse
  // than its own noise.
  Projection kept = blended;
  kept.point = x;
  kept.converged = false;
  return kept;
}

double AnchoredSurface::bandwidthAt(const Vec3& x) const { return impl_->pointField().at(x, 4); }

bool AnchoredSurface::hasScalar() const { return impl_->strain != nullptr; }

Projection AnchoredSurface::project(const Vec3& x) const {
  // The anchor of x's own cell if there is one, else the anchor of its nearest data point.
  std::uint32_t a = 0;
  const auto [h, limited] = impl_->h_field->atAndOther(x, impl_->curvature_limited, 4);
  if (!impl_->findAnchor(impl_->keyFor(x, Impl::tierOf(impl_->levelFor(h), limited > kFineShare)), &a)) {
    thread_local std::vector<Neighbor> near;
    impl_->tree.knn(x, 1, near);
    a = impl_->anchor_of_point[near.front().index];
  }
  const std::size_t begin = impl_->adjacency_offset[a], end = impl_->adjacency_offset[a + 1];
  return impl_->blend(x, impl_->adjacency.data() + begin, end - begin);
}

}  // namespace stampscan::fitting
