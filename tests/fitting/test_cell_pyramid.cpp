// The cell pyramid of the wide fits (fitting/src/cell_pyramid.hpp): its moments against sums over
// the points, fits on cells against the true surface, and the bandwidth the confidence intervals
// choose on flat and on tightly curved data.
#include "../../fitting/src/cell_pyramid.hpp"
#include "shapes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace stampscan::fitting {
namespace {

using detail::CellFitScratch;
using detail::CellPyramid;

TEST(CellPyramid, EveryLevelHoldsTheWeightedMomentsOfItsPoints) {
  const Cloud c = test::sampleSphereCap(20000, 30.0, 0.6, 0.05, 3);
  std::vector<float> weights(c.size());
  std::vector<double> strain(c.size());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t i = 0; i < c.size(); ++i) {
    weights[i] = i % 97 == 0 ? 0.0f : static_cast<float>(0.2 + 0.8 * u(rng));  // some points left out
    strain[i] = -0.1 + 0.01 * c.positions[i].x();
  }
  const KdTree tree(c.positions);
  const CellPyramid pyramid(c.positions, tree, weights, &strain, 0.3, 20.0);
  ASSERT_GE(pyramid.levels(), 5);  // 0.3 mm cells doubling until 20 / 4 mm
  double w_points = 0, ws_points = 0;
  Vec3 wp_points = Vec3::Zero();
  Eigen::Matrix3d wpp_points = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < c.size(); ++i) {
    w_points += weights[i];
    ws_points += weights[i] * strain[i];
    wp_points += weights[i] * c.positions[i];
    wpp_points += weights[i] * c.positions[i] * c.positions[i].transpose();
  }
  for (int level = 0; level < pyramid.levels(); ++level) {
    double w = 0, ws = 0;
    Vec3 wp = Vec3::Zero();
    Eigen::Matrix3d wpp = Eigen::Matrix3d::Zero();
    for (std::uint32_t k = 0; k < pyramid.cells(level); ++k) {
      const auto& m = pyramid.moments(level, k);
      const Vec3& p = pyramid.centroid(level, k);
      EXPECT_GT(m.weight, 0.0f);
      w += m.weight;
      ws += m.weight * m.strain;
      wp += m.weight * p;
      wpp += m.weight * (p * p.transpose() + m.covariance());
    }
    EXPECT_NEAR(w, w_points, 1e-4 * w_points) << "level " << level;
    EXPECT_NEAR(ws / w, ws_points / w_points, 1e-5) << "level " << level;
    EXPECT_LT((wp / w - wp_points / w_points).norm(), 1e-6) << "level " << level;
    EXPECT_LT((wpp / w - wpp_points / w_points).norm(), 1e-3) << "level " << level;
    if (level > 0) {
      EXPECT_LT(pyramid.cells(level), pyramid.cells(level - 1));
    }
  }
}

TEST(CellPyramid, FitsOnCellsCarryNoCurvatureBiasAtAnyBandwidth) {
  // Noise-free sphere of radius 20: a centroid of a curved cell lies inside the surface; the
  // covariance correction must remove that at every level, including cells much coarser than h/4.
  const double R = 20;
  const Cloud c = test::sampleSphereCap(200000, R, 0.9, 0.0, 7);
  const std::vector<float> weights(c.size(), 1.0f);
  for (const double base : {0.2, 0.8}) {
    const KdTree tree(c.positions);
    const CellPyramid pyramid(c.positions, tree, weights, nullptr, base, 8.0);
    CellFitScratch scratch;
    for (const double h : {1.0, 2.0, 4.0}) {
      const Vec3 centre = Vec3(0.3, -0.2, 1.0).normalized() * R;
      const auto fit = detail::fitOnCells(pyramid, centre, h, nullptr, scratch);
      ASSERT_TRUE(fit) << "h " << h;
      // A quadric osculates the sphere: what is left is the quartic term, ~h^4 / (8 R^3).
      EXPECT_LT(std::abs(fit->offset), 2e-4 + std::pow(h, 4) / (4 * R * R * R)) << "base " << base << " h " << h;
      EXPECT_GT(fit->effective_count, 10.0);
      EXPECT_GT(fit->offset_factor, 0.0);
    }
  }
}

TEST(CellPyramid, OffsetSpreadMatchesItsPredictedStandardDeviation) {
  // Over many noisy planes, the fitted offsets scatter as offset_factor * sigma says.
  const double sigma = 0.05;
  std::vector<double> offsets;
  double predicted = 0;
  for (unsigned seed = 1; seed <= 40; ++seed) {
    const Cloud c = test::samplePlane(20000, 10.0, sigma, seed);
    const std::vector<float> weights(c.size(), 1.0f);
    const KdTree tree(c.positions);
    const CellPyramid pyramid(c.positions, tree, weights, nullptr, 0.25, 4.0);
    CellFitScratch scratch;
    const auto fit = detail::fitOnCells(pyramid, Vec3::Zero(), 1.5, nullptr, scratch);
    ASSERT_TRUE(fit);
    offsets.push_back(fit->offset);
    predicted += fit->offset_factor * sigma / 40.0;
  }
  const double observed = test::rmsOf(offsets);
  EXPECT_GT(observed, 0.7 * predicted);
  EXPECT_LT(observed, 1.3 * predicted);
}

TEST(CellPyramid, IntervalsWidenOnAFlatPlaneAndStopAtATightBend) {
  const double sigma = 0.02;
  CellFitScratch scratch;
  {
    const Cloud c = test::samplePlane(100000, 20.0, sigma, 11);
    const std::vector<float> weights(c.size(), 1.0f);
    const KdTree tree(c.positions);
    const CellPyramid pyramid(c.positions, tree, weights, nullptr, 0.2, 12.0);
    const auto choice = detail::chooseBandwidth(pyramid, Vec3::Zero(), 0.8, 1.5, 6, sigma, 2.0, scratch);
    ASSERT_TRUE(choice.fit);
    EXPECT_FALSE(choice.limited);
    EXPECT_NEAR(choice.h, 0.8 * std::pow(1.5, 5), 1e-9);  // every scale kept
  }
  {
    // A cylinder of radius 3: a quadric holds across it only over a narrow support (the quartic term
    // of the circle, h^4 / (8 R^3), passes the noise near h = 1.2).
    const Cloud c = test::sampleCylinder(200000, 3.0, 20.0, sigma, 13);
    const std::vector<float> weights(c.size(), 1.0f);
    const KdTree tree(c.positions);
    const CellPyramid pyramid(c.positions, tree, weights, nullptr, 0.1, 12.0);
    const Vec3 centre(0.0, 0.0, 3.0);
    const auto choice = detail::chooseBandwidth(pyramid, centre, 0.4, 1.5, 8, sigma, 2.0, scratch);
    ASSERT_TRUE(choice.fit);
    EXPECT_TRUE(choice.limited);
    EXPECT_LT(choice.h, 3.0);
    EXPECT_LT(std::abs(choice.fit->offset), sigma);
  }
}

}  // namespace
}  // namespace stampscan::fitting
