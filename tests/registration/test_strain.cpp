// Strain maths against the formed parts' ground truth.
#include "stampscan/registration/strain.hpp"
#include "stampscan/sim/formed_part.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace {

using namespace stampscan;
using registration::Vec3;

TEST(Strain, FromEllipseAxes) {
  const auto s = registration::strainsFromEllipse(1.27 * std::exp(0.1), 1.27 * std::exp(-0.03), 1.27);
  EXPECT_NEAR(s.major, 0.1, 1e-12);
  EXPECT_NEAR(s.minor, -0.03, 1e-12);
  EXPECT_NEAR(s.thickness, -0.07, 1e-12);
  // Axes in either order.
  EXPECT_NEAR(registration::strainsFromEllipse(1.0, 2.0, 1.0).major, std::log(2.0), 1e-12);
  EXPECT_NEAR(registration::thinningPercent(-0.07), (1 - std::exp(-0.07)) * 100, 1e-12);
  EXPECT_NEAR(registration::engineeringStrain(0.1), std::exp(0.1) - 1, 1e-15);
  EXPECT_THROW(registration::strainsFromEllipse(0, 1, 1), std::invalid_argument);
  EXPECT_THROW(registration::strainsFromEllipse(1, 1, -1), std::invalid_argument);
}

TEST(Strain, SquareCellCornersGiveTheTrueStrainOfTheFormedPan) {
  const sim::StampedPanPart pan;
  const double pitch = 2.54;
  double worst = 0;
  for (double u = -50; u <= 50; u += 7.62)
    for (double v = -40; v <= 40; v += 7.62) {
      const sim::Vec2 m(u, v);
      const std::array<Vec3, 4> corners = {pan.position(m), pan.position(m + sim::Vec2(pitch, 0)),
                                           pan.position(m + sim::Vec2(pitch, pitch)), pan.position(m + sim::Vec2(0, pitch))};
      const auto s = registration::strainsFromSquareCell(corners, pitch);
      const sim::Deformation d = pan.deformationOfMaterial(m + sim::Vec2(0.5 * pitch, 0.5 * pitch));
      worst = std::max({worst, std::abs(s.major - d.major_strain), std::abs(s.minor - d.minor_strain)});
    }
  // Over a 2.54 mm cell the map is not linear where the strain changes fast (near the radii): the
  // cell's chord-based strain differs from the centre's by a little.
  EXPECT_LT(worst, 0.02);
}

TEST(Strain, SquareCellOfAPureStretch) {
  const double p = 2.0;
  const std::array<Vec3, 4> corners = {Vec3(0, 0, 0), Vec3(p * 1.2, 0, 0), Vec3(p * 1.2, p * 0.9, 0), Vec3(0, p * 0.9, 0)};
  const auto s = registration::strainsFromSquareCell(corners, p);
  EXPECT_NEAR(s.major, std::log(1.2), 1e-12);
  EXPECT_NEAR(s.minor, std::log(0.9), 1e-12);
  EXPECT_NEAR(std::abs(s.major_direction.x()), 1.0, 1e-12);
}

}  // namespace
