// Ground truth of the formed parts against their own geometry: the strains derived from the
// deformation gradient must match what happens to a printed circle when the forming map is applied
// to it point by point.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/grid.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <filesystem>
#include <numbers>

namespace {

using namespace stampscan::sim;

// Maps a printed circle of radius r0 around material point m onto the formed part, projects it into
// the tangent plane and returns its semi-axes from the second moments of the curve (for an ellipse
// sampled uniformly in angle, the covariance of the points is diag(a^2, b^2) / 2).
std::pair<double, double> mappedCircleAxes(const FormedPart& part, const Vec2& m, double r0) {
  const Deformation d = part.deformationOfMaterial(m);
  const Eigen::Matrix3d frame = stampscan::fitting::frameAround(d.normal);
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  Vec2 mean = Vec2::Zero();
  const int n = 720;
  std::vector<Vec2> pts;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * std::numbers::pi * k / n;
    const Vec3 p = part.position(m + r0 * Vec2(std::cos(a), std::sin(a))) - d.point;
    pts.emplace_back(frame.col(0).dot(p), frame.col(1).dot(p));
    mean += pts.back();
  }
  mean /= n;
  for (const Vec2& p : pts) cov += (p - mean) * (p - mean).transpose();
  cov /= n;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  return {std::sqrt(2 * eig.eigenvalues()(1)), std::sqrt(2 * eig.eigenvalues()(0))};
}

TEST(DomePart, PoleIsEquibiaxialAndDieIsUnstrained) {
  DomeParams params;
  const DomePart dome(params);
  const Deformation pole = dome.deformationAt(0, 0);
  EXPECT_NEAR(pole.point.z(), params.depth, 1e-12);
  EXPECT_NEAR(pole.major_strain, params.pole_strain, 1e-6);
  EXPECT_NEAR(pole.minor_strain, params.pole_strain, 1e-6);
  EXPECT_NEAR(pole.thickness_strain, -2 * params.pole_strain, 2e-6);
  const Deformation flange = dome.deformationAt(params.die_radius + 5, 3);
  EXPECT_NEAR(flange.major_strain, 0, 1e-6);
  EXPECT_NEAR(flange.minor_strain, 0, 1e-6);
  EXPECT_NEAR(flange.point.z(), 0, 1e-12);
}

TEST(DomePart, WallIsStretchedAlongTheMeridian) {
  const DomePart dome;
  const Deformation wall = dome.deformationAt(0, 30);  // steep part of the wall, on the y axis
  EXPECT_GT(wall.major_strain, wall.minor_strain + 0.05);
  // The major direction runs down the wall: in the y-z plane.
  EXPECT_LT(std::abs(wall.major_direction.x()), 1e-6);
  EXPECT_NEAR(wall.major_direction.dot(wall.normal), 0, 1e-9);
  EXPECT_NEAR(wall.thickness_strain, -(wall.major_strain + wall.minor_strain), 1e-12);
}

TEST(FormedPart, PositionInvertsMaterialAt) {
  const DomePart dome;
  const StampedPanPart pan;
  for (const FormedPart* part : {static_cast<const FormedPart*>(&dome), static_cast<const FormedPart*>(&pan)}) {
    for (const Vec2& m : {Vec2(0, 0), Vec2(10, -7), Vec2(33, 21), Vec2(-41, 12), Vec2(60, 40)}) {
      const Vec3 p = part->position(m);
      EXPECT_LT((part->materialAt(p.x(), p.y()) - m).norm(), 1e-9) << part->name();
      EXPECT_NEAR(p.z(), part->height(p.x(), p.y()), 1e-12);
    }
  }
}

TEST(FormedPart, GradientMatchesDifferencesOfPositions) {
  const StampedPanPart pan;
  for (const Vec2& m : {Vec2(5, 3), Vec2(40, 2), Vec2(-20, 30), Vec2(48, -28)}) {
    const Deformation d = pan.deformationOfMaterial(m);
    const double h = 1e-4;
    const Vec3 du = (pan.position(m + Vec2(h, 0)) - pan.position(m - Vec2(h, 0))) / (2 * h);
    const Vec3 dv = (pan.position(m + Vec2(0, h)) - pan.position(m - Vec2(0, h))) / (2 * h);
    EXPECT_LT((du - d.gradient.col(0)).norm(), 1e-5) << m.transpose();
    EXPECT_LT((dv - d.gradient.col(1)).norm(), 1e-5) << m.transpose();
  }
}

TEST(FormedPart, PrintedCircleBecomesTheEllipseOfTheStrain) {
  const DomePart dome;
  const StampedPanPart pan;
  int checked = 0;
  for (const FormedPart* part : {static_cast<const FormedPart*>(&dome), static_cast<const FormedPart*>(&pan)}) {
    for (const Vec2& m : {Vec2(0, 0), Vec2(20, 5), Vec2(2.54 * 8, 2.54 * 9), Vec2(-35, 0), Vec2(0, -24),
                          Vec2(50, 30), Vec2(0, 30), Vec2(-45, -3)}) {
      const Deformation d = part->deformationOfMaterial(m);
      // The strain is the image of a small circle. Over a 0.2 mm circle the map is linear to well
      // under 0.1 %, and the surface's curvature (radii of 4 mm and more) shortens the projection
      // into the tangent plane by less than that.
      const double r0 = 0.2;
      const auto [a, b] = mappedCircleAxes(*part, m, r0);
      EXPECT_NEAR(std::log(a / r0), d.major_strain, 0.002) << part->name() << " at " << m.transpose();
      EXPECT_NEAR(std::log(b / r0), d.minor_strain, 0.002) << part->name() << " at " << m.transpose();
      ++checked;
    }
  }
  EXPECT_EQ(checked, 16);
  // A whole printed circle (1.27 mm radius) on the gentle dome still shows the centre's strain.
  for (const Vec2& m : {Vec2(0, 0), Vec2(2.54 * 4, 2.54 * 3), Vec2(0, 2.54 * 10)}) {
    const Deformation d = dome.deformationOfMaterial(m);
    const auto [a, b] = mappedCircleAxes(dome, m, 1.27);
    EXPECT_NEAR(std::log(a / 1.27), d.major_strain, 0.003) << m.transpose();
    EXPECT_NEAR(std::log(b / 1.27), d.minor_strain, 0.003) << m.transpose();
  }
}

TEST(StampedPanPart, DrawsTheFlangeAndPeaksAboveThePunchRadius) {
  StampedPanParams params;
  const StampedPanPart pan(params);
  // The flange is drawn in: shrinks along the outline (negative minor strain), so it thickens.
  const Deformation flange = pan.deformationAt(0, 45);
  EXPECT_LT(flange.minor_strain, -0.05);
  EXPECT_GT(flange.thickness_strain, 0.0);
  // Across the short side's wall (y from 18 to 46), the largest major strain sits in the lower third
  // of the wall, close to the punch radius, and reaches about the requested peak.
  double best = -1, best_y = 0;
  for (double y = 18; y <= 46; y += 0.05) {
    const double e = pan.deformationAt(0, y).major_strain;
    if (e > best) best = e, best_y = y;
  }
  EXPECT_GT(best, 0.8 * params.peak_strain);
  EXPECT_LT(best, 1.5 * params.peak_strain);
  const double wall_bottom = params.pocket_b - 0.5 * params.wall_width;
  EXPECT_GT(best_y, wall_bottom);
  EXPECT_LT(best_y, wall_bottom + 0.45 * params.wall_width);
  // The formed part lies inside its footprint and the blank is larger than it.
  EXPECT_GT(pan.blank().max.x(), params.half_length);
}

TEST(Grid, CoverageOfLinesAndRings) {
  GridSpec grid;
  const BlankRect printed{Vec2(-50, -50), Vec2(50, 50)};
  // On a ring's centre line, sharp: covered; midway between line and centre: bare.
  EXPECT_DOUBLE_EQ(inkCoverage(grid, printed, Vec2(1.27, 0), 0), 1.0);
  EXPECT_DOUBLE_EQ(inkCoverage(grid, printed, Vec2(0.6, 0), 0), 0.0);
  // A footprint twice the line width sees half of it.
  EXPECT_NEAR(inkCoverage(grid, printed, Vec2(1.27, 0), 0.3), 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(inkCoverage(grid, printed, Vec2(60, 0), 0), 0.0);  // unprinted
  grid.kind = GridKind::Square;
  EXPECT_DOUBLE_EQ(inkCoverage(grid, printed, Vec2(2.54, 1.0), 0), 1.0);
  EXPECT_DOUBLE_EQ(inkCoverage(grid, printed, Vec2(1.27, 1.27), 0), 0.0);
  EXPECT_THROW(gridKindFromString("hexagon"), std::invalid_argument);
}

TEST(Grid, GroundTruthFileHasTheContractProperties) {
  const DomePart dome;
  GridSpec grid;
  const auto truth = groundTruth(dome, grid);
  // A 150 mm blank less 2 mm margins: whole circles at 2.54 mm pitch, 57 per row.
  EXPECT_EQ(truth.size(), 57u * 57u);
  const auto file = std::filesystem::temp_directory_path() / "stampscan_truth_test.ply";
  writeGroundTruth(file, truth);
  const auto back = stampscan::fitting::readPly(file);
  std::filesystem::remove(file);
  ASSERT_EQ(back.size(), truth.size());
  ASSERT_TRUE(back.hasNormals());
  ASSERT_TRUE(back.hasStrain());
  ASSERT_TRUE(back.scalars.count("major_strain"));
  ASSERT_TRUE(back.scalars.count("minor_strain"));
  for (std::size_t i = 0; i < truth.size(); i += 97) {
    EXPECT_NEAR(back.strain[i], -(back.scalars.at("major_strain")[i] + back.scalars.at("minor_strain")[i]), 1e-9);
    EXPECT_LT(dome.distance(back.positions[i]), 1e-6);
  }
  grid.kind = GridKind::Square;
  EXPECT_EQ(groundTruth(dome, grid).size(), 56u * 56u);  // whole cells between the lines
}

}  // namespace
