#include "stampscan/fitting/shape_and_strain.hpp"

#include "cell_pyramid.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
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
// and flattens the strain peaks, the very spots a forming analysis is about. Here each carrier
// chooses the strain field's bandwidth by Lepski's rule (cell_pyramid.hpp, chooseStrainBandwidth)
// and a point between them takes the harmonic mean of its neighbours' choices, so the field
// narrows where strain changes fast and smooths the noise where it does not.
class CarrierStrain {
 public:
  CarrierStrain(const Cloud& carriers, const ImplicitSurface& shape, const ShapeAndStrainParams& params)
      : positions_(carriers.positions),
        tree_(positions_),
        // Cells wider than the part: every strain fit reads the carriers themselves (level -1).
        pyramid_(positions_, tree_, std::vector<float>(positions_.size(), 1.0f), &carriers.strain,
                 2.0 * boundsOf(positions_).diagonal() + 1.0, 0.0) {
    const std::size_t n = positions_.size();
    std::vector<double> spacing(n, 0.0), h(n, 0.0);
    const double step = params.strain.anchored.scale_step;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const auto& range) {
      detail::CellFitScratch scratch;
      std::vector<Neighbor> near;
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        tree_.knn(positions_[i], kStartRank + 1, near);
        // The grid's pitch: the fourth neighbour's distance, which twins (an element found in two
        // overlapping strips) do not shorten: a square grid's four nearest are a pitch away.
        spacing[i] = std::sqrt(near[std::min<std::size_t>(kPitchRank, near.size() - 1)].distance_sq);
        const double h_start = std::max(std::sqrt(near.back().distance_sq), 1e-6);
        const Projection foot = shape.project(positions_[i]);
        const detail::StrainChoice choice =
            detail::chooseStrainBandwidth(pyramid_, positions_[i], foot.valid ? foot.normal : Vec3::UnitZ(), h_start, step,
                                          kScales, params.strain.anchored.agreement_sigmas, scratch);
        h[i] = choice.h > 0 ? choice.h : h_start * std::pow(step, kScales - 1);
      }
    });
    spacing_ = n > 1 ? summarize(spacing).median : 0.0;
    reach_ = params.strain_reach * spacing_;
    bandwidth_ = summarize(h);
    field_ = std::make_unique<BandwidthField>(positions_, tree_, std::move(h), BandwidthField::Mean::Harmonic);
  }

  // NaN beyond reach of every carrier.
  double at(const Vec3& x, const Vec3& normal, detail::CellFitScratch& scratch) const {
    std::uint32_t nearest = 0;
    const double h = field_->at(x, 4, &nearest);
    if ((positions_[nearest] - x).norm() > reach_) return std::numeric_limits<double>::quiet_NaN();
    return detail::strainNear(pyramid_, x, normal, h, scratch);
  }
  const BandwidthSummary& bandwidth() const { return bandwidth_; }
  double spacing() const { return spacing_; }

 private:
  // A linear field has three parameters: the narrowest fit starts with eight carriers or so, and
  // the widest is 1.5^7 = 17 times as wide.
  static constexpr int kStartRank = 8;
  static constexpr int kScales = 8;
  static constexpr std::size_t kPitchRank = 4;
  const std::vector<Vec3>& positions_;
  KdTree tree_;
  detail::CellPyramid pyramid_;
  std::unique_ptr<BandwidthField> field_;
  double spacing_ = 0, reach_ = 0;
  BandwidthSummary bandwidth_;
};
}  // namespace

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
  const CarrierStrain strain_field(carriers, shape_fit.surface(), params);
  out.strain_bandwidth = strain_field.bandwidth();
  out.carrier_spacing = strain_field.spacing();
  out.shape_stats.stage_seconds["strain field"] = secondsSince(t);

  t = Clock::now();
  const std::vector<Vec3> starts = cubeMeans(shape.positions, params.output_spacing_mm);
  std::vector<Projection> feet(starts.size());
  std::vector<double> strain(starts.size(), std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starts.size(), 256), [&](const auto& range) {
    detail::CellFitScratch scratch;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      feet[k] = shape_fit.surface().project(starts[k]);
      if (feet[k].valid) strain[k] = strain_field.at(feet[k].point, feet[k].normal, scratch);
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
      detail::CellFitScratch scratch;
      for (std::size_t k = range.begin(); k != range.end(); ++k)
        v.strain[k] = strain_field.at(v.positions[k], v.normals[k], scratch);
    });
    out.shape_stats.stage_seconds["mesh"] = secondsSince(t);
  }
  out.seconds = secondsSince(t0);
  return out;
}

}  // namespace stampscan::fitting
