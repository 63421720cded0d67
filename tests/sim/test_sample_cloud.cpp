// makeSampleCloud: the synthetic scan of the pan. Checked against the part it samples: determinism,
// size, attribute alignment, noise level, the hole, the stereo clusters, outliers and the strain truth.
#include "stampscan/sim/sample_cloud.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <vector>

namespace stampscan::sim {
namespace {

constexpr std::size_t kTarget = 20000;

SampleCloudParams smallParams() {
  SampleCloudParams p;
  p.target_points = kTarget;
  return p;
}

// Same as the sampler's hole placement (documented by its position in the part: x = -L/2, y = 0.35 W).
Eigen::Vector2d holeCentre(const PanPart& part) {
  return {-0.5 * part.params().half_length, 0.35 * part.params().half_width};
}

bool bytesEqual(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(a[i].data(), b[i].data(), 3 * sizeof(double)) != 0) return false;
  return true;
}
bool bytesEqual(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

double rmsDistance(const PanPart& part, const std::vector<Vec3>& points) {
  double sum = 0;
  for (const Vec3& p : points) {
    const double d = part.distance(p);
    sum += d * d;
  }
  return std::sqrt(sum / static_cast<double>(points.size()));
}

TEST(SampleCloud, SameSeedGivesIdenticalCloud) {
  const PanPart part;
  const SampleCloud a = makeSampleCloud(part, smallParams());
  const SampleCloud b = makeSampleCloud(part, smallParams());
  ASSERT_GT(a.cloud.size(), 0u);
  EXPECT_TRUE(bytesEqual(a.cloud.positions, b.cloud.positions));
  EXPECT_TRUE(bytesEqual(a.cloud.strain, b.cloud.strain));
  EXPECT_TRUE(bytesEqual(a.true_strain, b.true_strain));
  EXPECT_EQ(a.laser_points, b.laser_points);
  EXPECT_EQ(a.stereo_points, b.stereo_points);
  EXPECT_EQ(a.outliers, b.outliers);
}

TEST(SampleCloud, DifferentSeedsGiveDifferentClouds) {
  const PanPart part;
  SampleCloudParams p1 = smallParams(), p2 = smallParams();
  p1.seed = 1;
  p2.seed = 2;
  const SampleCloud a = makeSampleCloud(part, p1);
  const SampleCloud b = makeSampleCloud(part, p2);
  EXPECT_FALSE(bytesEqual(a.cloud.positions, b.cloud.positions));
  EXPECT_FALSE(bytesEqual(a.cloud.strain, b.cloud.strain));
  // Not merely a reordering or one changed point: most of the common prefix differs.
  const std::size_t n = std::min(a.cloud.size(), b.cloud.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < n; ++i) differing += a.cloud.positions[i] != b.cloud.positions[i];
  EXPECT_GT(differing, n / 2);
}

void expectCountNearTarget(std::size_t target) {
  SampleCloudParams p = smallParams();
  p.target_points = target;
  const SampleCloud s = makeSampleCloud(PanPart{}, p);
  const double ratio = static_cast<double>(s.cloud.size()) / static_cast<double>(target);
  EXPECT_GT(ratio, 0.75) << "target " << target << ", got " << s.cloud.size() << " (" << s.laser_points
                         << " laser, " << s.stereo_points << " stereo)";
  EXPECT_LT(ratio, 1.25) << "target " << target << ", got " << s.cloud.size() << " (" << s.laser_points
                         << " laser, " << s.stereo_points << " stereo)";
}

TEST(SampleCloud, PointCountIsNearTarget) {
  expectCountNearTarget(kTarget);
  expectCountNearTarget(50000);
}

TEST(SampleCloud, PointCountIsNearSmallTargets) {
  // `station sample --points` accepts 1000 and up; the count should follow the target there too.
  expectCountNearTarget(5000);
  expectCountNearTarget(1000);
}

TEST(SampleCloud, CountsAddUpAndAttributesAreAligned) {
  const PanPart part;
  const SampleCloud s = makeSampleCloud(part, smallParams());
  EXPECT_EQ(s.laser_points + s.stereo_points, s.cloud.size());
  EXPECT_GT(s.laser_points, 0u);
  EXPECT_GT(s.stereo_points, 0u);
  EXPECT_NO_THROW(s.cloud.validate());
  EXPECT_TRUE(s.cloud.hasStrain());
  EXPECT_EQ(s.cloud.strain.size(), s.cloud.size());
  EXPECT_EQ(s.true_strain.size(), s.cloud.size());
  // Outliers displace existing points; they are a share of the cloud, not extra points.
  EXPECT_EQ(s.outliers, static_cast<std::size_t>(smallParams().outlier_fraction * static_cast<double>(s.cloud.size())));
  for (const Vec3& p : s.cloud.positions) ASSERT_TRUE(p.allFinite());
  for (const double e : s.cloud.strain) ASSERT_TRUE(std::isfinite(e));
}

TEST(SampleCloud, PointsStayOnTheBlank) {
  const PanPart part;
  const PanParams& pp = part.params();
  SampleCloudParams p = smallParams();
  p.noise_sigma = 0;
  p.outlier_fraction = 0;
  const SampleCloud s = makeSampleCloud(part, p);
  for (const Vec3& q : s.cloud.positions) {
    ASSERT_LE(std::abs(q.x()), pp.half_length + 1e-9);
    ASSERT_LE(std::abs(q.y()), pp.half_width + 1e-9);
  }
  // The whole blank is covered: no 10 mm x 10 mm cell without points, except the hole's.
  const Eigen::Vector2d hole = holeCentre(part);
  for (double x = -pp.half_length; x < pp.half_length; x += 10) {
    for (double y = -pp.half_width; y < pp.half_width; y += 10) {
      if (std::hypot(x + 5 - hole.x(), y + 5 - hole.y()) < p.hole_radius + 8) continue;
      const bool any = std::any_of(s.cloud.positions.begin(), s.cloud.positions.end(), [&](const Vec3& q) {
        return q.x() >= x && q.x() < x + 10 && q.y() >= y && q.y() < y + 10;
      });
      EXPECT_TRUE(any) << "empty cell at (" << x << ", " << y << ")";
    }
  }
}

TEST(SampleCloud, NormalDistanceMatchesNoiseSigma) {
  const PanPart part;
  for (const double sigma : {0.02, 0.05, 0.2}) {
    SampleCloudParams p = smallParams();
    p.noise_sigma = sigma;
    p.outlier_fraction = 0;
    const SampleCloud s = makeSampleCloud(part, p);
    EXPECT_EQ(s.outliers, 0u);
    // Isotropic noise of sigma per coordinate has a normal component of sigma.
    const double rms = rmsDistance(part, s.cloud.positions);
    EXPECT_NEAR(rms, sigma, 0.2 * sigma) << "noise_sigma " << sigma;
    EXPECT_NEAR(surfaceError(part, s.cloud.positions).rms, rms, 1e-9 * (1 + rms));
  }
}

TEST(SampleCloud, NoiselessCloudLiesOnTheSurface) {
  const PanPart part;
  SampleCloudParams p = smallParams();
  p.noise_sigma = 0;
  p.outlier_fraction = 0;
  const SampleCloud s = makeSampleCloud(part, p);
  ASSERT_GT(s.cloud.size(), 0u);
  double max_distance = 0;
  for (const Vec3& q : s.cloud.positions) {
    max_distance = std::max(max_distance, part.distance(q));
    ASSERT_LT(std::abs(q.z() - part.height(q.x(), q.y())), 1e-9) << "at " << q.transpose();
  }
  EXPECT_LT(max_distance, 1e-6);
  const SurfaceError e = surfaceError(part, s.cloud.positions);
  EXPECT_LT(e.rms, 1e-6);
  EXPECT_LT(e.max, 1e-6);
}

TEST(SampleCloud, NoPointInsideTheHole) {
  const PanPart part;
  const Eigen::Vector2d c = holeCentre(part);
  {
    SampleCloudParams p = smallParams();
    p.noise_sigma = 0;
    const SampleCloud s = makeSampleCloud(part, p);
    std::size_t near_rim = 0;
    for (const Vec3& q : s.cloud.positions) {
      const double r = std::hypot(q.x() - c.x(), q.y() - c.y());
      ASSERT_GE(r, p.hole_radius) << "point " << q.transpose() << " inside the hole";
      near_rim += r < p.hole_radius + 2;
    }
    EXPECT_GT(near_rim, 10u) << "the hole's surroundings should be scanned";
  }
  {
    // With noise, a sample may wander across the rim by a few sigma, not further.
    const SampleCloudParams p = smallParams();
    const SampleCloud s = makeSampleCloud(part, p);
    for (const Vec3& q : s.cloud.positions)
      ASSERT_GE(std::hypot(q.x() - c.x(), q.y() - c.y()), p.hole_radius - 6 * p.noise_sigma) << q.transpose();
  }
  {
    // hole_radius = 0: the same disk is scanned like the rest.
    SampleCloudParams p = smallParams();
    p.hole_radius = 0;
    const SampleCloud s = makeSampleCloud(part, p);
    const auto inside = std::count_if(s.cloud.positions.begin(), s.cloud.positions.end(), [&](const Vec3& q) {
      return std::hypot(q.x() - c.x(), q.y() - c.y()) < 6.0;
    });
    EXPECT_GT(inside, 20);
  }
}

// Runs of identical (x, y) among the stereo points of a noiseless cloud: one run per grid element.
struct StereoCluster {
  Eigen::Vector2d xy;
  int size;
};
std::vector<StereoCluster> stereoClusters(const SampleCloud& s) {
  std::vector<StereoCluster> clusters;
  for (std::size_t i = s.laser_points; i < s.cloud.size(); ++i) {
    const Eigen::Vector2d xy = s.cloud.positions[i].head<2>();
    if (!clusters.empty() && clusters.back().xy == xy) ++clusters.back().size;
    else clusters.push_back({xy, 1});
  }
  return clusters;
}

TEST(SampleCloud, StereoPointsComeInClustersOnTheGrid) {
  const PanPart part;
  SampleCloudParams p = smallParams();
  p.noise_sigma = 0;
  p.outlier_fraction = 0;
  const SampleCloud s = makeSampleCloud(part, p);
  const std::vector<StereoCluster> clusters = stereoClusters(s);
  ASSERT_GT(clusters.size(), 50u);
  int min_size = p.max_repeats + 1, max_size = 0;
  double total = 0;
  for (const StereoCluster& c : clusters) {
    min_size = std::min(min_size, c.size);
    max_size = std::max(max_size, c.size);
    total += c.size;
  }
  EXPECT_EQ(min_size, 1);
  EXPECT_EQ(max_size, p.max_repeats);
  EXPECT_NEAR(total / static_cast<double>(clusters.size()), 0.5 * (1 + p.max_repeats), 0.6);
  EXPECT_EQ(static_cast<std::size_t>(total), s.stereo_points);
  // Every cluster sits on the grid: offsets from the first one are whole multiples of the pitch.
  const Eigen::Vector2d origin = clusters.front().xy;
  for (const StereoCluster& c : clusters) {
    for (int k = 0; k < 2; ++k) {
      const double steps = (c.xy[k] - origin[k]) / p.grid_pitch;
      ASSERT_NEAR(steps, std::round(steps), 1e-6) << "cluster at " << c.xy.transpose();
    }
  }
  // Consecutive clusters in a grid column are a whole number of pitches apart (small targets keep
  // only a share of the grid elements, as if fewer views were taken), most of them one pitch.
  std::size_t neighbours = 0, adjacent = 0;
  for (std::size_t i = 1; i < clusters.size(); ++i) {
    if (clusters[i].xy.x() != clusters[i - 1].xy.x()) continue;
    const double steps = (clusters[i].xy.y() - clusters[i - 1].xy.y()) / p.grid_pitch;
    EXPECT_NEAR(steps, std::round(steps), 1e-9);
    EXPECT_GE(std::round(steps), 1.0);
    adjacent += std::round(steps) == 1.0;
    ++neighbours;
  }
  EXPECT_GT(neighbours, clusters.size() / 2);
  EXPECT_GT(adjacent, neighbours / 4);
  // The stereo region is the +x end of the part.
  for (const StereoCluster& c : clusters) EXPECT_GT(c.xy.x(), 0.0);
}

TEST(SampleCloud, StereoRepeatsFollowMaxRepeats) {
  const PanPart part;
  SampleCloudParams p = smallParams();
  p.noise_sigma = 0;
  p.outlier_fraction = 0;
  p.max_repeats = 3;
  const std::vector<StereoCluster> clusters = stereoClusters(makeSampleCloud(part, p));
  ASSERT_FALSE(clusters.empty());
  for (const StereoCluster& c : clusters) {
    EXPECT_GE(c.size, 1);
    EXPECT_LE(c.size, 3);
  }
  p.max_repeats = 1;
  for (const StereoCluster& c : stereoClusters(makeSampleCloud(part, p))) EXPECT_EQ(c.size, 1);
}

TEST(SampleCloud, NoisyStereoObservationsScatterAroundTheirGridElement) {
  const PanPart part;
  const SampleCloudParams p = smallParams();
  const SampleCloud s = makeSampleCloud(part, p);
  // Each stereo observation lies within a few sigma of a grid node (in x and y).
  SampleCloudParams clean = p;
  clean.noise_sigma = 0;
  clean.outlier_fraction = 0;
  const std::vector<StereoCluster> clusters = stereoClusters(makeSampleCloud(part, clean));
  ASSERT_FALSE(clusters.empty());
  const Eigen::Vector2d origin = clusters.front().xy;
  for (std::size_t i = s.laser_points; i < s.cloud.size(); ++i) {
    const Eigen::Vector2d xy = s.cloud.positions[i].head<2>();
    for (int k = 0; k < 2; ++k) {
      const double steps = (xy[k] - origin[k]) / p.grid_pitch;
      ASSERT_LT(std::abs(steps - std::round(steps)) * p.grid_pitch, 6 * p.noise_sigma) << xy.transpose();
    }
  }
}

TEST(SampleCloud, TrueStrainMatchesThePartAtEachSample) {
  const PanPart part;
  {
    SampleCloudParams p = smallParams();
    p.noise_sigma = 0;
    const SampleCloud s = makeSampleCloud(part, p);
    for (std::size_t i = 0; i < s.cloud.size(); ++i) {
      const Vec3& q = s.cloud.positions[i];
      ASSERT_NEAR(s.true_strain[i], part.thicknessStrain(q.x(), q.y()), 1e-12) << "point " << i;
    }
  }
  {
    // With position noise the truth is at the closest surface point; the sample's own (x, y) is
    // within noise of it, so the strain there agrees to |grad eps| * noise.
    const SampleCloudParams p = smallParams();
    const SampleCloud s = makeSampleCloud(part, p);
    double sum_sq = 0, max_diff = 0;
    for (std::size_t i = 0; i < s.cloud.size(); ++i) {
      const Vec3 foot = part.closestPoint(s.cloud.positions[i]);
      const double diff = s.true_strain[i] - part.thicknessStrain(foot.x(), foot.y());
      sum_sq += diff * diff;
      max_diff = std::max(max_diff, std::abs(diff));
    }
    EXPECT_LT(std::sqrt(sum_sq / static_cast<double>(s.cloud.size())), 0.01);
    EXPECT_LT(max_diff, 0.15);  // outliers move up to 1.5 mm, on a wall that is a few strain hundredths
  }
}

TEST(SampleCloud, MeasuredStrainIsTruthPlusSmallNoise) {
  const PanPart part;
  const SampleCloud s = makeSampleCloud(part, smallParams());
  double sum = 0, sum_sq = 0;
  for (std::size_t i = 0; i < s.cloud.size(); ++i) {
    const double diff = s.cloud.strain[i] - s.true_strain[i];
    sum += diff;
    sum_sq += diff * diff;
  }
  const double n = static_cast<double>(s.cloud.size());
  const double rms = std::sqrt(sum_sq / n);
  EXPECT_GT(rms, 0.0);    // it is a measurement, not the truth
  EXPECT_LT(rms, 0.02);   // small against the 0.35 strain range
  EXPECT_LT(std::abs(sum / n), 4 * rms / std::sqrt(n));  // unbiased
  // The strain range itself spans the part's thinning: flats near 0, walls strongly negative.
  const auto [lo, hi] = std::minmax_element(s.true_strain.begin(), s.true_strain.end());
  EXPECT_LT(*lo, -0.25);
  EXPECT_NEAR(*hi, 0.0, 1e-12);
}

TEST(SampleCloud, OutliersAreVerticalDisplacementsOfExistingPoints) {
  const PanPart part;
  SampleCloudParams clean = smallParams();
  clean.noise_sigma = 0;
  clean.outlier_fraction = 0;
  SampleCloudParams dirty = clean;
  dirty.outlier_fraction = 0.01;
  const SampleCloud a = makeSampleCloud(part, clean);
  const SampleCloud b = makeSampleCloud(part, dirty);
  ASSERT_EQ(a.cloud.size(), b.cloud.size());
  EXPECT_EQ(b.outliers, static_cast<std::size_t>(0.01 * static_cast<double>(b.cloud.size())));
  std::size_t moved = 0;
  for (std::size_t i = 0; i < a.cloud.size(); ++i) {
    const Vec3& p = a.cloud.positions[i];
    const Vec3& q = b.cloud.positions[i];
    EXPECT_EQ(p.x(), q.x());
    EXPECT_EQ(p.y(), q.y());
    EXPECT_EQ(a.cloud.strain[i], b.cloud.strain[i]);
    if (p.z() == q.z()) continue;
    ++moved;
    const double dz = std::abs(q.z() - p.z());
    EXPECT_GE(dz, 0.3 - 1e-9) << "point " << i;
    EXPECT_LE(dz, 2 * 1.5 + 1e-9) << "point " << i;  // a point may be picked twice
    EXPECT_GT(part.distance(q), 0.05) << "point " << i;
  }
  EXPECT_LE(moved, b.outliers);
  EXPECT_GE(moved + 3, b.outliers);  // repeats of the same point are rare
}

TEST(SampleCloud, SteepWallsLoseLaserPoints) {
  const PanPart part;
  SampleCloudParams keep = smallParams();
  keep.steep_dropout = 0;
  SampleCloudParams drop = smallParams();
  drop.steep_dropout = 1;
  const SampleCloud a = makeSampleCloud(part, keep);
  const SampleCloud b = makeSampleCloud(part, drop);
  const auto on_wall = [&](const SampleCloud& s) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < s.laser_points; ++i) {
      const Vec3& q = s.cloud.positions[i];
      n += part.gradient(q.x(), q.y()).norm() > 1.5;
    }
    return n;
  };
  EXPECT_LT(b.laser_points, a.laser_points);
  EXPECT_LT(static_cast<double>(on_wall(b)), 0.8 * static_cast<double>(on_wall(a)));
  EXPECT_GT(on_wall(b), 0u);
}

}  // namespace
}  // namespace stampscan::sim
