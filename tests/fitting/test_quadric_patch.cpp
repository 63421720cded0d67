// The quadric height field's readings at its origin: height above the origin and curvature, on
// surfaces known in closed form.
#include "stampscan/fitting/quadric_patch.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace {

using stampscan::fitting::QuadricPatch;
using stampscan::fitting::Vec3;

// Points of a sphere of radius R (centre below the origin's pole) on a 5 x 5 grid of pitch 2.54,
// fitted in the frame of the pole's tangent plane but with the origin `lift` above the pole.
QuadricPatch sphereCap(double R, double lift) {
  QuadricPatch::Sums sums(Eigen::Matrix3d::Identity(), Vec3(0, 0, lift), 2.54);
  for (int i = -2; i <= 2; ++i)
    for (int j = -2; j <= 2; ++j) {
      const double x = 2.54 * i, y = 2.54 * j;
      sums.add(Vec3(x, y, std::sqrt(R * R - x * x - y * y) - R), 1.0);
    }
  const auto patch = QuadricPatch::fit(sums);
  EXPECT_TRUE(patch.has_value());
  return *patch;
}

TEST(QuadricPatchReadings, CurvatureOfASphereIsOneOverItsRadius) {
  for (const double R : {60.0, 20.0}) {
    const QuadricPatch p = sphereCap(R, 0.0);
    // A quadric fitted over +-5 mm of a sphere takes up some of its quartic term: 3.6 % at R = 20.
    EXPECT_NEAR(p.maxCurvatureAtOrigin(), 1 / R, 0.05 / R) << "R = " << R;
  }
}

TEST(QuadricPatchReadings, HeightAtTheOriginIsTheSurfaceBelowIt) {
  const QuadricPatch p = sphereCap(60.0, 0.05);  // origin 0.05 mm above the pole
  EXPECT_NEAR(p.heightAtOrigin(), -0.05, 1e-3);
}

TEST(QuadricPatchReadings, HessianOfACylinderBendsOnlyAcrossItsAxis) {
  // A cylinder of radius 10 mm whose axis runs at 30 degrees to the frame's first axis: the
  // Hessian is -(1/R) a a^T, with a the unit vector across the axis.
  const double R = 10, angle = std::numbers::pi / 6;
  const Eigen::Vector2d along(std::cos(angle), std::sin(angle)), across(-std::sin(angle), std::cos(angle));
  QuadricPatch::Sums sums(Eigen::Matrix3d::Identity(), Vec3::Zero(), 2.54);
  for (int i = -2; i <= 2; ++i)
    for (int j = -2; j <= 2; ++j) {
      const Eigen::Vector2d xy(1.27 * i, 1.27 * j);
      const double s = xy.dot(across);
      sums.add(Vec3(xy.x(), xy.y(), std::sqrt(R * R - s * s) - R), 1.0);
    }
  const auto p = QuadricPatch::fit(sums);
  ASSERT_TRUE(p.has_value());
  const Eigen::Matrix2d expected = -(1 / R) * across * across.transpose();
  EXPECT_LT((p->hessianAtOrigin() - expected).cwiseAbs().maxCoeff(), 0.002) << p->hessianAtOrigin();
  // The quartic term leaks a little into the quadric where the grid is not aligned with the axis.
  EXPECT_NEAR(along.dot(p->hessianAtOrigin() * along), 0.0, 0.01 / R);
}

TEST(QuadricPatchReadings, APlaneHasNoCurvature) {
  QuadricPatch::Sums sums(Eigen::Matrix3d::Identity(), Vec3::Zero(), 1.0);
  for (int i = -3; i <= 3; ++i)
    for (int j = -3; j <= 3; ++j) sums.add(Vec3(i, j, 0.2 * i - 0.1 * j + 0.3), 1.0);
  const auto p = QuadricPatch::fit(sums);
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->maxCurvatureAtOrigin(), 0.0, 1e-9);
  EXPECT_NEAR(p->heightAtOrigin(), 0.3, 1e-9);
}

}  // namespace
