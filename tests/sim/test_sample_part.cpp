// PanPart, the analytic stamped pan every accuracy test measures against: its height, normal,
// closest point and thickness strain, checked against first principles (finite differences,
// construction of points at a known distance, the shape's stated dimensions).
#include "stampscan/sim/sample_cloud.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace stampscan::sim {
namespace {

// A regular grid over the whole blank (edges included), `n` x `n` samples.
std::vector<Eigen::Vector2d> blankGrid(const PanPart& part, int n) {
  const PanParams& p = part.params();
  std::vector<Eigen::Vector2d> xy;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = -p.half_length + 2.0 * p.half_length * i / (n - 1);
      const double y = -p.half_width + 2.0 * p.half_width * j / (n - 1);
      xy.emplace_back(x, y);
    }
  }
  return xy;
}

// Horizontal scan lines through the interesting features: the axes (across both walls and the dome),
// a diagonal through the rounded pocket corners, and an off-centre line grazing the dome edge.
struct ScanLine {
  Eigen::Vector2d from, to;
};
std::vector<ScanLine> scanLines(const PanPart& part) {
  const PanParams& p = part.params();
  return {{{-p.half_length, 0}, {p.half_length, 0}},
          {{0, -p.half_width}, {0, p.half_width}},
          {{-p.half_length, -p.half_width}, {p.half_length, p.half_width}},
          {{-p.half_length, 0.9 * p.dome_radius}, {p.half_length, 0.9 * p.dome_radius}},
          {{0.3 * p.pocket_a, -p.half_width}, {0.3 * p.pocket_a, p.half_width}}};
}

TEST(PanPart, NormalIsUnitAndPerpendicularToFiniteDifferenceTangents) {
  const PanPart part;
  const double e = 1e-4;
  for (const Eigen::Vector2d& q : blankGrid(part, 61)) {
    const double x = q.x(), y = q.y();
    const Vec3 n = part.normal(x, y);
    ASSERT_NEAR(n.norm(), 1.0, 1e-12) << "at (" << x << ", " << y << ")";
    EXPECT_GT(n.z(), 0.0) << "normal must face +z at (" << x << ", " << y << ")";
    const Vec3 tx = (part.surfacePoint(x + e, y) - part.surfacePoint(x - e, y)).normalized();
    const Vec3 ty = (part.surfacePoint(x, y + e) - part.surfacePoint(x, y - e)).normalized();
    EXPECT_NEAR(n.dot(tx), 0.0, 1e-6) << "at (" << x << ", " << y << ")";
    EXPECT_NEAR(n.dot(ty), 0.0, 1e-6) << "at (" << x << ", " << y << ")";
  }
}

TEST(PanPart, NormalIsUpOnFlatsAndTiltsOutwardOnWalls) {
  const PanPart part;
  const PanParams& p = part.params();
  EXPECT_NEAR((part.normal(0.95 * p.half_length, 0) - Vec3::UnitZ()).norm(), 0.0, 1e-9);  // flange
  EXPECT_NEAR((part.normal(0.55 * p.pocket_a, 0) - Vec3::UnitZ()).norm(), 0.0, 1e-9);    // floor
  EXPECT_NEAR((part.normal(0, 0) - Vec3::UnitZ()).norm(), 0.0, 1e-9);                    // dome pole
  // Mid-wall on +y: the surface rises towards +y, so the upward normal leans towards -y (into the pocket).
  const Vec3 wall = part.normal(0, p.pocket_b);
  EXPECT_LT(wall.y(), -0.5);
  EXPECT_NEAR(wall.x(), 0.0, 1e-9);
}

// Points offset from a known foot along the normal, |d| <= max_offset, at random places over the part
// and every 0.25 mm along the feature lines (steepest and most curved places, both signs of d).
// Returns the worst foot error and distance error, with where they happened.
struct ClosestPointError {
  double foot = 0, distance = 0;
  Vec3 at = Vec3::Zero();  // x, y of the foot and d of the worst foot error
  std::size_t checked = 0, over_tolerance = 0;
};
ClosestPointError closestPointError(const PanPart& part, double max_offset, double tolerance) {
  const PanParams& p = part.params();
  ClosestPointError worst;
  const auto check = [&](double x, double y, double d) {
    const Vec3 foot = part.surfacePoint(x, y);
    const Vec3 q = foot + d * part.normal(x, y);
    const double foot_error = (part.closestPoint(q) - foot).norm();
    const double distance_error = std::abs(part.distance(q) - std::abs(d));
    if (foot_error > worst.foot) {
      worst.foot = foot_error;
      worst.at = Vec3(x, y, d);
    }
    worst.distance = std::max(worst.distance, distance_error);
    worst.over_tolerance += foot_error > tolerance || distance_error > tolerance;
    ++worst.checked;
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-0.95 * p.half_length, 0.95 * p.half_length);
  std::uniform_real_distribution<double> uy(-0.95 * p.half_width, 0.95 * p.half_width);
  std::uniform_real_distribution<double> ud(-max_offset, max_offset);
  for (int k = 0; k < 4000; ++k) {
    const double x = ux(rng), y = uy(rng);
    check(x, y, ud(rng));
  }
  for (const ScanLine& line : scanLines(part)) {
    const int n = static_cast<int>((line.to - line.from).norm() / 0.25);
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d q = line.from + (line.to - line.from) * (static_cast<double>(i) / n);
      for (const double d : {-max_offset, -0.5 * max_offset, 0.5 * max_offset, max_offset}) check(q.x(), q.y(), d);
    }
  }
  return worst;
}

TEST(PanPart, ClosestPointRecoversFootWithinNoiseAndOutlierRange) {
  // Offsets up to 0.5 mm: ten times the default scan noise, a third of the largest outlier offset.
  const PanPart part;
  const ClosestPointError e = closestPointError(part, 0.5, 1e-6);
  EXPECT_EQ(e.over_tolerance, 0u) << "of " << e.checked << "; worst foot error " << e.foot << " mm at foot ("
                                  << e.at.x() << ", " << e.at.y() << "), d = " << e.at.z()
                                  << "; worst distance error " << e.distance << " mm";
  EXPECT_GT(e.checked, 5000u);
}

TEST(PanPart, ClosestPointRecoversFootAtTwoMillimetres) {
  // The minimum radius of curvature of the pan is about 2.33 mm (wall toe and shoulder along the y
  // axis), so a point 2 mm off the surface along the normal still has that foot as its closest point.
  const PanPart part;
  const ClosestPointError e = closestPointError(part, 2.0, 1e-6);
  EXPECT_EQ(e.over_tolerance, 0u) << "of " << e.checked << "; worst foot error " << e.foot << " mm at foot ("
                                  << e.at.x() << ", " << e.at.y() << "), d = " << e.at.z()
                                  << "; worst distance error " << e.distance << " mm";
  // Whatever closestPoint returns must never be farther than the known foot: if it is, it is not the
  // closest point.
  const Vec3 foot = part.surfacePoint(e.at.x(), e.at.y());
  const Vec3 q = foot + e.at.z() * part.normal(e.at.x(), e.at.y());
  EXPECT_LE(part.distance(q) - std::abs(e.at.z()), 1e-9)
      << "closestPoint returned a point farther from q than the known foot, so not the closest point";
}

TEST(PanPart, ClosestPointOfSurfacePointIsItself) {
  const PanPart part;
  for (const Eigen::Vector2d& q : blankGrid(part, 41)) {
    const Vec3 s = part.surfacePoint(q.x(), q.y());
    EXPECT_LT((part.closestPoint(s) - s).norm(), 1e-9);
    EXPECT_LT(part.distance(s), 1e-9);
  }
}

TEST(PanPart, HeightIsContinuousAlongFineScanLines) {
  // A jump (or a kink large enough to matter) would show as a step far above slope * step.
  const PanPart part;
  const double step = 0.005;
  for (const ScanLine& line : scanLines(part)) {
    const Eigen::Vector2d dir = (line.to - line.from).normalized();
    const int n = static_cast<int>((line.to - line.from).norm() / step);
    double z_prev = part.height(line.from.x(), line.from.y());
    double slope_prev = part.gradient(line.from.x(), line.from.y()).dot(dir);
    double max_dz = 0, max_dslope = 0;
    for (int i = 1; i <= n; ++i) {
      const Eigen::Vector2d q = line.from + dir * (i * step);
      const double z = part.height(q.x(), q.y());
      const double slope = part.gradient(q.x(), q.y()).dot(dir);
      ASSERT_TRUE(std::isfinite(z));
      max_dz = std::max(max_dz, std::abs(z - z_prev) - 0.5 * (std::abs(slope) + std::abs(slope_prev)) * step);
      max_dslope = std::max(max_dslope, std::abs(slope - slope_prev));
      z_prev = z;
      slope_prev = slope;
    }
    // Excess of the step over the local slope bound: only curvature * step^2 terms remain.
    EXPECT_LT(max_dz, 1e-4) << "line from " << line.from.transpose() << " to " << line.to.transpose();
    // The shape is C2, so the slope changes by at most (max curvature ~1/mm) * step.
    EXPECT_LT(max_dslope, 0.01) << "line from " << line.from.transpose() << " to " << line.to.transpose();
  }
}

TEST(PanPart, FlatFlangeFloorAndDomeHeights) {
  const PanPart part;
  const PanParams& p = part.params();
  // Flange: far outside the pocket outline plus half the wall run.
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {0.95 * p.half_length, 0}, {-0.95 * p.half_length, 0}, {0, 0.95 * p.half_width},
           {0, -0.95 * p.half_width}, {p.half_length, p.half_width}, {-p.half_length, -p.half_width},
           {0.9 * p.half_length, -0.8 * p.half_width}}) {
    EXPECT_EQ(part.height(x, y), 0.0) << "flange at (" << x << ", " << y << ")";
    EXPECT_EQ(part.thicknessStrain(x, y), 0.0) << "flange at (" << x << ", " << y << ")";
  }
  // Pocket floor: well inside the outline minus half the wall run, outside the dome.
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {25, 0}, {-25, 0}, {0, 18}, {0, -18}, {20, -15}, {-25, 10}, {-15, -16}}) {
    ASSERT_GE(std::hypot(x, y), p.dome_radius);
    EXPECT_NEAR(part.height(x, y), -p.depth, 1e-12) << "floor at (" << x << ", " << y << ")";
    EXPECT_NEAR(part.thicknessStrain(x, y), 0.0, 1e-12) << "floor at (" << x << ", " << y << ")";
  }
  // Dome: its pole stands dome_height above the floor, and it rises monotonically towards the pole.
  EXPECT_NEAR(part.height(0, 0), -p.depth + p.dome_height, 1e-12);
  double previous = -p.depth;
  for (double r = p.dome_radius; r >= 0; r -= 0.5) {
    const double z = part.height(r, 0);
    EXPECT_GE(z, previous - 1e-12) << "r = " << r;
    previous = z;
  }
  // Walls: monotonic from the floor up to the flange along both axes, passing mid-depth near the outline.
  for (const Eigen::Vector2d& dir : {Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1), Eigen::Vector2d(-1, 0)}) {
    const double outline = dir.x() != 0 ? p.pocket_a : p.pocket_b;
    double z_prev = part.height(dir.x() * (outline - p.wall_width), dir.y() * (outline - p.wall_width));
    for (double s = outline - p.wall_width; s <= outline + p.wall_width; s += 0.1) {
      const double z = part.height(dir.x() * s, dir.y() * s);
      EXPECT_GE(z, z_prev - 1e-12) << "s = " << s;
      z_prev = z;
    }
    EXPECT_NEAR(part.height(dir.x() * outline, dir.y() * outline), -0.5 * p.depth, 1e-9);
  }
}

TEST(PanPart, HeightStaysWithinFloorAndFlange) {
  const PanPart part;
  const PanParams& p = part.params();
  for (const Eigen::Vector2d& q : blankGrid(part, 161)) {
    const double z = part.height(q.x(), q.y());
    EXPECT_LE(z, 1e-12);
    EXPECT_GE(z, -p.depth - 1e-12);
  }
}

TEST(PanPart, ThicknessStrainIsThinningOnlyAndPeaksOnWallsAndDome) {
  const PanPart part;
  const PanParams& p = part.params();
  double min_strain = 0;
  Eigen::Vector2d argmin(0, 0);
  for (const Eigen::Vector2d& q : blankGrid(part, 201)) {
    const double e = part.thicknessStrain(q.x(), q.y());
    ASSERT_TRUE(std::isfinite(e));
    EXPECT_LE(e, 0.0) << "at " << q.transpose();
    if (e < min_strain) {
      min_strain = e;
      argmin = q;
    }
  }
  // The most thinning is on a wall: steep there, and off the flats.
  EXPECT_GT(part.gradient(argmin.x(), argmin.y()).norm(), 1.0) << "minimum at " << argmin.transpose();
  // ... and about the stated maximum thinning (the header: |eps3| at the steepest wall).
  EXPECT_NEAR(-min_strain, p.max_thinning_strain, 0.1 * p.max_thinning_strain) << "minimum at " << argmin.transpose();
  // Walls thin more than flats; the dome thins, most at its pole.
  const double mid_wall = part.thicknessStrain(0, p.pocket_b);
  EXPECT_LT(mid_wall, -0.5 * p.max_thinning_strain);
  // On the dome every point thins, the flat pole too (biaxial stretch), more than the floor around it.
  EXPECT_LT(part.thicknessStrain(0, 0), -0.05);
  for (double r = 0; r <= 0.7 * p.dome_radius; r += 0.5) {
    EXPECT_LT(part.thicknessStrain(r, 0), -0.01) << "dome at r = " << r;
    EXPECT_LT(part.thicknessStrain(0, -r), -0.01) << "dome at r = " << r;
  }
  // Strain grows in magnitude with slope: the x walls (longer run) thin less than the y walls.
  EXPECT_LT(part.thicknessStrain(0, p.pocket_b), part.thicknessStrain(p.pocket_a, 0));
}

TEST(PanPart, ThicknessStrainIsSmooth) {
  const PanPart part;
  const double step = 0.005;
  for (const ScanLine& line : scanLines(part)) {
    const Eigen::Vector2d dir = (line.to - line.from).normalized();
    const int n = static_cast<int>((line.to - line.from).norm() / step);
    double prev = part.thicknessStrain(line.from.x(), line.from.y());
    double prev_diff = 0, max_diff = 0, max_second = 0;
    for (int i = 1; i <= n; ++i) {
      const Eigen::Vector2d q = line.from + dir * (i * step);
      const double e = part.thicknessStrain(q.x(), q.y());
      const double diff = e - prev;
      max_diff = std::max(max_diff, std::abs(diff));
      if (i > 1) max_second = std::max(max_second, std::abs(diff - prev_diff));
      prev = e;
      prev_diff = diff;
    }
    // |d eps / ds| stays below ~0.5 per mm, so a 5 um step changes it by well under 0.005.
    EXPECT_LT(max_diff, 0.005) << "line from " << line.from.transpose() << " to " << line.to.transpose();
    // No kinks: the first difference itself changes only by O(step^2).
    EXPECT_LT(max_second, 2e-4) << "line from " << line.from.transpose() << " to " << line.to.transpose();
  }
}

TEST(PanPart, CustomParametersAreHonoured) {
  PanParams params;
  params.depth = 10;
  params.dome_height = 0;
  params.max_thinning_strain = 0.2;
  const PanPart part(params);
  EXPECT_EQ(part.params().depth, 10);
  EXPECT_NEAR(part.height(0, 0), -10, 1e-12);
  EXPECT_NEAR(part.height(25, 0), -10, 1e-12);
  EXPECT_EQ(part.height(0.95 * params.half_length, 0), 0.0);
  EXPECT_NEAR(part.height(params.pocket_a, 0), -5, 1e-9);
}

TEST(PanPartSurfaceError, ExactSurfacePointsHaveZeroError) {
  const PanPart part;
  std::vector<Vec3> points;
  for (const Eigen::Vector2d& q : blankGrid(part, 101)) points.push_back(part.surfacePoint(q.x(), q.y()));
  const SurfaceError e = surfaceError(part, points);
  EXPECT_LT(e.rms, 1e-9);
  EXPECT_LT(e.max, 1e-9);
}

TEST(PanPartSurfaceError, PointsAtKnownDistanceGiveThatDistance) {
  const PanPart part;
  std::vector<Vec3> points;
  const double d = 0.7;
  int k = 0;
  for (const Eigen::Vector2d& q : blankGrid(part, 101)) {
    const double sign = (k++ % 2) ? 1.0 : -1.0;
    points.push_back(part.surfacePoint(q.x(), q.y()) + sign * d * part.normal(q.x(), q.y()));
  }
  // One point further away sets the maximum.
  points.push_back(part.surfacePoint(60, 50) + 1.5 * part.normal(60, 50));
  const SurfaceError e = surfaceError(part, points);
  const double n = static_cast<double>(points.size());
  EXPECT_NEAR(e.rms, std::sqrt(((n - 1) * d * d + 1.5 * 1.5) / n), 1e-6);
  EXPECT_NEAR(e.max, 1.5, 1e-6);
}

TEST(PanPartSurfaceError, EmptyInputGivesZero) {
  const SurfaceError e = surfaceError(PanPart{}, {});
  EXPECT_EQ(e.rms, 0.0);
  EXPECT_EQ(e.max, 0.0);
}

}  // namespace
}  // namespace stampscan::sim
