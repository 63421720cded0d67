#include "stampscan/fitting/surface_fit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace stampscan::fitting {

namespace {
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

FitMethod parseFitMethod(const std::string& name) {
  if (name == "auto") return FitMethod::Auto;
  if (name == "apss") return FitMethod::Apss;
  if (name == "euclidean") return FitMethod::Euclidean;
  if (name == "sig") return FitMethod::Sig;
  if (name == "gaussian") return FitMethod::Gaussian;
  throw std::invalid_argument("unknown method '" + name + "' (expected auto, apss, euclidean, sig or gaussian)");
}

std::string toString(FitMethod method) {
  switch (method) {
    case FitMethod::Auto: return "auto";
    case FitMethod::Apss: return "apss";
    case FitMethod::Euclidean: return "euclidean";
    case FitMethod::Sig: return "sig";
    case FitMethod::Gaussian: return "gaussian";
  }
  return "?";
}

FittedSurface::FittedSurface(const Cloud& input, const FitParams& params) : input_(input), params_(params) {
  if (input.empty()) throw std::invalid_argument("cannot fit an empty cloud");
  input.validate();
  for (std::size_t i = 0; i < input.size(); ++i)
    if (!input.positions[i].allFinite())
      throw std::invalid_argument("point " + std::to_string(i) + " has a non-finite coordinate (readers skip these)");
  if (params.bandwidth && !(*params.bandwidth > 0 && std::isfinite(*params.bandwidth)))
    throw std::invalid_argument("bandwidth must be a positive number of millimetres");
  if (params.sig.r < 1) throw std::invalid_argument("sig r must be at least 1");
  if (params.max_iterations < 1) throw std::invalid_argument("max iterations must be at least 1");
  const auto& points = input.positions;
  prep_stats_.points = points.size();

  auto t0 = Clock::now();
  tree_ = std::make_unique<KdTree>(points);
  prep_stats_.stage_seconds["kd-tree"] = secondsSince(t0);

  if (params.method == FitMethod::Auto && !params.bandwidth) {
    t0 = Clock::now();
    AnchoredParams ap = params.anchored;
    ap.robust = params.robust.value_or(true);
    ap.orientation = params.orientation;
    ap.scalar = params.scalar;
    ap.max_iterations = std::min(params.max_iterations, ap.max_iterations);
    auto anchored = std::make_unique<AnchoredSurface>(points, *tree_, input.hasStrain() ? &input.strain : nullptr, ap,
                                                      params.progress);
    prep_stats_.bandwidth = anchored->stats().bandwidth;
    prep_stats_.widened = anchored->stats().widened;
    prep_stats_.data_bandwidth = prep_stats_.widened ? anchored->stats().narrow_bandwidth : anchored->stats().bandwidth;
    prep_stats_.anchors = anchored->stats().anchors;
    prep_stats_.probes = anchored->stats().probes;
    prep_stats_.orientation_components = anchored->stats().orientation_components;
    for (const auto& [stage, seconds] : anchored->stats().stage_seconds) prep_stats_.stage_seconds[stage] = seconds;
    surface_ = std::move(anchored);
    return;
  }

  // Bandwidths h_i at the data points, then Shepard-smoothed (Eqs. (9), (13)).
  t0 = Clock::now();
  std::vector<double> raw;
  if (params.bandwidth && params.method != FitMethod::Gaussian) {
    raw.assign(points.size(), *params.bandwidth);
  } else if (params.method == FitMethod::Sig) {
    raw = rthNeighborDistances(points, *tree_, params.sig.r);  // d_i of Eq. (9)
  } else if (params.method == FitMethod::Gaussian) {
    // Eq. (12) from an initial guess: the given bandwidth, else the density-robust scale's median.
    double h0 = params.bandwidth.value_or(0.0);
    if (!(h0 > 0)) h0 = summarize(robustScales(points, *tree_, params.scale)).median;
    raw = gaussianDataBandwidths(points, *tree_, h0);
  } else {
    raw = robustScales(points, *tree_, params.scale);
  }
  for (double& h : raw)
    if (!(h > 0)) h = 0;  // isolated duplicates: replaced by the interpolant below
  if (params.bandwidth && params.method != FitMethod::Gaussian) {
    bandwidths_ = std::make_unique<BandwidthField>(points, *tree_, std::move(raw));
  } else {
    // A zero h_i (all r neighbours coincide) carries no scale information: the interpolant leaves
    // it out, so it cannot pull h towards zero.
    std::vector<double> smoothed = BandwidthField(points, *tree_, std::move(raw)).smoothedAtPoints();
    const double floor = 1e-6 * boundsOf(points).diagonal();
    for (double& h : smoothed) h = std::max(h, floor);
    bandwidths_ = std::make_unique<BandwidthField>(points, *tree_, std::move(smoothed));
  }
  prep_stats_.bandwidth = summarize(bandwidths_->values());
  prep_stats_.data_bandwidth = prep_stats_.bandwidth;
  prep_stats_.stage_seconds["bandwidth"] = secondsSince(t0);
  if (params.progress) params.progress("bandwidth", 1.0);

  t0 = Clock::now();
  normals_ = estimateNormals(points, *tree_, bandwidths_->values());
  prep_stats_.stage_seconds["normals"] = secondsSince(t0);
  t0 = Clock::now();
  const OrientationReport orientation = orientNormals(points, normals_, params.orientation);
  prep_stats_.orientation_components = orientation.components;
  prep_stats_.stage_seconds["orientation"] = secondsSince(t0);
  if (params.progress) params.progress("normals", 1.0);

  if (params.method == FitMethod::Sig) {
    t0 = Clock::now();
    graph_ = std::make_unique<SigGraph>(SigGraph::build(points, *tree_, params.sig));
    prep_stats_.sig_edges = graph_->edgeCount();
    prep_stats_.sig_pruned = graph_->prunedEdgeCount();
    prep_stats_.stage_seconds["r-sig graph"] = secondsSince(t0);
  }

  ProjectionParams pp;
  // Auto with a fixed bandwidth has no bandwidth to choose: it runs as Apss with that h.
  const bool paper = params.method != FitMethod::Auto && params.method != FitMethod::Apss;
  pp.model = params.model.value_or(paper ? SurfaceModel::Plane : SurfaceModel::Sphere);
  pp.robust = params.robust.value_or(!paper);
  pp.kernel = params.method == FitMethod::Gaussian ? KernelType::Gaussian : params.kernel;
  pp.weights = params.method == FitMethod::Sig        ? WeightScheme::GraphDistance
               : params.method == FitMethod::Gaussian ? WeightScheme::DataToData
                                                      : WeightScheme::Euclidean;
  pp.max_iterations = params.max_iterations;
  pp.tolerance = params.tolerance;
  pp.scalar = params.scalar;
  SurfaceData data;
  data.points = &points;
  data.tree = tree_.get();
  data.bandwidths = bandwidths_.get();
  data.normals = &normals_.normals;
  data.graph = graph_.get();
  data.scalar = input.hasStrain() ? &input.strain : nullptr;
  surface_ = std::make_unique<WlsSurface>(data, pp);
}

FittedSurface::~FittedSurface() = default;

Cloud FittedSurface::projectAll(FitStats* stats_out) const {
  const auto t0 = Clock::now();
  const std::size_t n = input_.size();
  Cloud out;
  out.positions.resize(n);
  out.normals.resize(n);
  if (input_.hasStrain()) out.strain.resize(n);
  out.scalars = input_.scalars;  // further attributes (major/minor strain) travel with their point
  out.colors = input_.colors;

  // Visit points in the kd-tree's leaf order so neighbouring queries share cache lines; each result
  // lands at its own index, so the output does not depend on the order or the thread count.
  const std::vector<std::uint32_t> order = tree_->spatialOrder();
  std::vector<std::uint8_t> iterations(n, 0);
  std::vector<std::uint8_t> flags(n, 0);  // bit 0: converged, bit 1: valid
  std::atomic<std::size_t> done{0};
  std::atomic<int> reported{-1};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const std::size_t i = order[k];
      const Projection p = surface_->projectPoint(i);
      out.positions[i] = p.point;
      out.normals[i] = p.normal;
      if (input_.hasStrain()) out.strain[i] = std::isfinite(p.scalar) ? p.scalar : input_.strain[i];
      iterations[i] = static_cast<std::uint8_t>(std::min(p.iterations, 255));
      flags[i] = static_cast<std::uint8_t>((p.converged ? 1 : 0) | (p.valid ? 2 : 0));
    }
    const std::size_t total = done.fetch_add(range.size()) + range.size();
    if (params_.progress) {
      const int percent = static_cast<int>(100.0 * static_cast<double>(total) / static_cast<double>(n));
      int last = reported.load();
      if (percent > last && reported.compare_exchange_strong(last, percent)) params_.progress("projection", percent / 100.0);
    }
  });

  if (stats_out) {
    FitStats stats = prep_stats_;
    double sum_iterations = 0;
    for (std::size_t i = 0; i < n; ++i) {
      sum_iterations += iterations[i];
      stats.max_iterations = std::max(stats.max_iterations, static_cast<int>(iterations[i]));
      if (!(flags[i] & 1)) ++stats.not_converged;
      if (!(flags[i] & 2)) ++stats.invalid;
    }
    stats.mean_iterations = sum_iterations / static_cast<double>(n);
    stats.stage_seconds["projection"] = secondsSince(t0);
    double total = 0;
    for (const auto& [stage, seconds] : stats.stage_seconds) total += seconds;
    stats.seconds = total;
    *stats_out = stats;
  }
  return out;
}

FitResult fitSurface(const Cloud& input, const FitParams& params) {
  FittedSurface fitted(input, params);
  FitResult result;
  result.surface = fitted.projectAll(&result.stats);
  return result;
}

}  // namespace stampscan::fitting
