#include "stampscan/sim/sample_cloud.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace stampscan::sim {

namespace {
constexpr double kStrainNoise = 0.005;  // measurement noise on strain, true-strain units
}

SampleShape sampleShape(const PanPart& part) {
  SampleShape shape;
  shape.height = [&part](double x, double y) { return part.height(x, y); };
  shape.slope = [&part](double x, double y) { return part.gradient(x, y).norm(); };
  shape.thickness_strain = [&part](double x, double y) { return part.thicknessStrain(x, y); };
  shape.distance = [&part](const Vec3& p) { return part.distance(p); };
  shape.half_length = part.params().half_length;
  shape.half_width = part.params().half_width;
  return shape;
}

SampleShape sampleShape(const FormedPart& part) {
  SampleShape shape;
  shape.height = [&part](double x, double y) { return part.height(x, y); };
  shape.slope = [&part](double x, double y) {
    const Vec3 n = part.normal(x, y);
    return std::sqrt(n.x() * n.x() + n.y() * n.y()) / std::max(std::abs(n.z()), 1e-9);
  };
  shape.thickness_strain = [&part](double x, double y) { return part.deformationAt(x, y).thickness_strain; };
  shape.distance = [&part](const Vec3& p) { return part.distance(p); };
  const BlankRect box = part.footprint();
  shape.half_length = std::min(-box.min.x(), box.max.x());
  shape.half_width = std::min(-box.min.y(), box.max.y());
  return shape;
}

SampleCloud makeSampleCloud(const SampleShape& part, const SampleCloudParams& params) {
  std::mt19937_64 rng(params.seed);
  // normal_distribution needs a positive spread: noise-free samples get exactly zero.
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto noise = [&](std::mt19937_64& g) { return params.noise_sigma > 0 ? params.noise_sigma * gauss(g) : 0.0; };
  std::normal_distribution<double> strain_noise(0.0, kStrainNoise);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  struct {
    double half_length, half_width;
  } const pp{part.half_length, part.half_width};
  const double x_split = pp.half_length * (1.0 - 2.0 * params.stereo_fraction);  // stereo beyond this x
  const Vec3 hole_centre(-0.5 * pp.half_length, 0.35 * pp.half_width, 0);

  SampleCloud out;
  auto& cloud = out.cloud;
  const auto emit = [&](double x, double y) {
    if (params.hole_radius > 0 && std::hypot(x - hole_centre.x(), y - hole_centre.y()) < params.hole_radius) return false;
    Vec3 p = Vec3(x, y, part.height(x, y)) + Vec3(noise(rng), noise(rng), noise(rng));
    const double truth = part.thickness_strain(x, y);
    cloud.positions.push_back(p);
    cloud.strain.push_back(truth + strain_noise(rng));
    out.true_strain.push_back(truth);
    return true;
  };

  // Laser sweeps along y, each a strip of profiles across x, overlapping their neighbours by 30 % and
  // turned by a small angle so that overlaps cross at small angles (paper Sec. 3.1).
  // Stereo sites sit on the grid whatever the target; for small targets only a share of them is
  // kept (as if fewer views were taken), so that the total stays near the target.
  const double stereo_sites = std::max(0.0, (pp.half_length - x_split) / params.grid_pitch + 1.0) *
                              (2.0 * pp.half_width / params.grid_pitch + 1.0);
  const double stereo_expected = stereo_sites * 0.5 * (1.0 + std::max(1, params.max_repeats));
  const double target = static_cast<double>(params.target_points);
  const double stereo_keep = stereo_expected > 0 ? std::min(1.0, 0.25 * target / stereo_expected) : 0.0;
  const double laser_target = std::max(target - stereo_keep * stereo_expected, 0.5 * target);
  const double laser_x0 = -pp.half_length, laser_x1 = std::min(x_split + 5.0, pp.half_length);
  const double area = (laser_x1 - laser_x0) * 2.0 * pp.half_width * 1.35;
  const double per_point_area = area / laser_target;
  const double along_profile = std::sqrt(per_point_area * 0.5);  // points within a profile
  const double between_profiles = per_point_area / along_profile;
  const double strip_width = 30.0;
  const double strip_step = strip_width * 0.7;
  int strip_index = 0;
  for (double sx = laser_x0 - 5.0; sx < laser_x1 + 5.0; sx += strip_step, ++strip_index) {
    const double angle = (strip_index % 2 ? 1.0 : -1.0) * 2.0 * std::numbers::pi / 180.0;
    const double c = std::cos(angle), s = std::sin(angle);
    for (double v = -pp.half_width - 5.0; v <= pp.half_width + 5.0; v += between_profiles) {
      for (double u = 0; u <= strip_width; u += along_profile) {
        const double x = sx + c * u - s * v, y = s * u + c * v;
        if (x < laser_x0 || x > laser_x1 || std::abs(y) > pp.half_width || x > pp.half_length) continue;
        // Steep walls scatter the beam: drop points with a chance that grows with the slope.
        const double slope = part.slope(x, y);
        if (unit(rng) < params.steep_dropout * slope * slope / (1.0 + slope * slope)) continue;
        if (emit(x, y)) ++out.laser_points;
      }
    }
  }

  // Stereo: each grid element seen in 1..max_repeats views, each observation with its own noise.
  std::uniform_int_distribution<int> repeats(1, std::max(1, params.max_repeats));
  for (double x = x_split; x <= pp.half_length; x += params.grid_pitch) {
    for (double y = -pp.half_width; y <= pp.half_width; y += params.grid_pitch) {
      const int m = repeats(rng);
      if (unit(rng) >= stereo_keep) continue;
      for (int k = 0; k < m; ++k)
        if (emit(x, y)) ++out.stereo_points;
    }
  }

  // Outliers: a few points displaced off the surface (specular glints, mismatched stereo pairs).
  std::uniform_int_distribution<std::size_t> pick(0, cloud.size() - 1);
  const auto count = static_cast<std::size_t>(params.outlier_fraction * static_cast<double>(cloud.size()));
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = pick(rng);
    const double offset = (unit(rng) < 0.5 ? -1.0 : 1.0) * (0.3 + 1.2 * unit(rng));
    cloud.positions[i].z() += offset;
    ++out.outliers;
  }
  return out;
}

SurfaceError surfaceError(const SampleShape& part, const std::vector<Vec3>& points) {
  struct Acc {
    double sum_sq = 0, max = 0;
  };
  const Acc total = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, points.size(), 4096), Acc{},
      [&](const tbb::blocked_range<std::size_t>& r, Acc acc) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          const double d = part.distance(points[i]);
          acc.sum_sq += d * d;
          acc.max = std::max(acc.max, d);
        }
        return acc;
      },
      [](Acc a, const Acc& b) {
        a.sum_sq += b.sum_sq;
        a.max = std::max(a.max, b.max);
        return a;
      });
  SurfaceError e;
  if (!points.empty()) e.rms = std::sqrt(total.sum_sq / static_cast<double>(points.size()));
  e.max = total.max;
  return e;
}

}  // namespace stampscan::sim
