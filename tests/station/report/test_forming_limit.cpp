// The forming-limit curve: the Keeler-Brazier formula at known points, the branch shapes, measured
// curves, and the safety margin along a strain path.
#include "stampscan/report/forming_limit.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace stampscan::report {
namespace {

TEST(FormingLimit, KeelerBrazierFlc0MatchesTheFormula) {
  // FLC0 = (23.3 + 14.13 t) n / 0.21, t in mm.
  EXPECT_NEAR(keelerBrazierFlc0(1.0, 0.21), 37.43, 1e-9);
  EXPECT_NEAR(keelerBrazierFlc0(0.8, 0.23), (23.3 + 14.13 * 0.8) * 0.23 / 0.21, 1e-9);
  EXPECT_NEAR(keelerBrazierFlc0(2.0, 0.15), (23.3 + 28.26) * 0.15 / 0.21, 1e-9);
  // The thickness term stops growing at 3 mm.
  EXPECT_NEAR(keelerBrazierFlc0(3.0, 0.2), (23.3 + 14.13 * 3) * 0.2 / 0.21, 1e-9);
  EXPECT_DOUBLE_EQ(keelerBrazierFlc0(5.0, 0.2), keelerBrazierFlc0(3.0, 0.2));
  EXPECT_THROW(keelerBrazierFlc0(0.0, 0.2), std::invalid_argument);
  EXPECT_THROW(keelerBrazierFlc0(1.0, -0.1), std::invalid_argument);
}

TEST(FormingLimit, KeelerBrazierBranches) {
  const double flc0 = keelerBrazierFlc0(1.0, 0.21);
  const FormingLimitCurve flc = FormingLimitCurve::keelerBrazier(flc0);
  EXPECT_DOUBLE_EQ(flc.flc0(), flc0);
  // Right branch: a straight line of slope 0.6 in engineering strain.
  EXPECT_NEAR(flc.majorAt(10), flc0 + 6, 1e-9);
  EXPECT_NEAR(flc.majorAt(30), flc0 + 18, 1e-9);
  // Left branch: constant thickness, (1 + e1)(1 + e2) = 1 + FLC0, i.e. eps1 + eps2 = const in true strain.
  for (const double minor : {-5.0, -10.0, -20.0, -35.0}) {
    const double major = flc.majorAt(minor);
    EXPECT_NEAR((1 + major / 100) * (1 + minor / 100), 1 + flc0 / 100, 1e-12) << minor;
    EXPECT_NEAR(trueStrain(major) + trueStrain(minor), trueStrain(flc0), 1e-12) << minor;
  }
  EXPECT_GT(flc.majorAt(-20), flc.majorAt(-10));
}

TEST(FormingLimit, StrainConversions) {
  EXPECT_NEAR(engineeringPercent(std::log(1.25)), 25.0, 1e-12);
  EXPECT_NEAR(trueStrain(25.0), std::log(1.25), 1e-12);
  // eps3 = ln(0.8): the sheet is 80% of its thickness, 20% thinner.
  EXPECT_NEAR(thinningPercent(std::log(0.8)), 20.0, 1e-12);
  EXPECT_NEAR(thinningPercent(std::log(1.05)), -5.0, 1e-12);  // thickened
}

TEST(FormingLimit, MarginAlongTheStrainPath) {
  const double flc0 = 37.43;
  const FormingLimitCurve flc = FormingLimitCurve::keelerBrazier(flc0);
  // Plane strain: the path is the major axis.
  EXPECT_NEAR(flc.marginAlongPath(0, 30), flc0 - 30, 1e-6);
  EXPECT_NEAR(flc.marginAlongPath(0, 45), flc0 - 45, 1e-6);  // above the curve: negative
  // Equibiaxial, e1 = e2: meets the right branch where e = FLC0 + 0.6 e, e = FLC0 / 0.4.
  const double at = flc0 / 0.4;
  EXPECT_NEAR(flc.marginAlongPath(10, 10), std::sqrt(2.0) * (at - 10), 1e-6);
  // Uniaxial tension, eps2 = -eps1 / 2 in true strain: meets the constant-thickness branch
  // eps1 + eps2 = ln(1 + FLC0) at eps1 = 2 ln(1 + FLC0). The margin is the distance in the
  // engineering diagram from the element to that point.
  const double eps1 = 2 * std::log1p(flc0 / 100);
  const FldPoint limit{engineeringPercent(-eps1 / 2), engineeringPercent(eps1)};
  EXPECT_NEAR(flc.majorAt(limit.minor), limit.major, 1e-9);
  const FldPoint element{engineeringPercent(-0.05), engineeringPercent(0.1)};
  EXPECT_NEAR(flc.marginAlongPath(element.minor, element.major),
              std::hypot(limit.minor - element.minor, limit.major - element.major), 1e-6);
  // Beyond the limit, the same distance counts against the element.
  const FldPoint beyond{engineeringPercent(-0.4), engineeringPercent(0.8)};
  EXPECT_NEAR(flc.marginAlongPath(beyond.minor, beyond.major),
              -std::hypot(limit.minor - beyond.minor, limit.major - beyond.major), 1e-6);
  // Pure shear (eps2 = -eps1) runs parallel to the constant-thickness branch: the path never meets it.
  EXPECT_TRUE(std::isinf(flc.marginAlongPath(engineeringPercent(-0.1), engineeringPercent(0.1))));
  // The undeformed sheet is measured along plane strain.
  EXPECT_NEAR(flc.marginAlongPath(0, 0), flc0, 1e-6);
}

TEST(FormingLimit, MarginCurveLiesTheMarginBelowAlongEachPath) {
  const FormingLimitCurve flc = FormingLimitCurve::keelerBrazier(35);
  for (const FldPoint& p : flc.marginCurve(10, -30, 30, 31))
    EXPECT_NEAR(flc.marginAlongPath(p.minor, p.major), 10, 1e-6);
}

TEST(FormingLimit, MeasuredCurveInterpolatesAndExtends) {
  const FormingLimitCurve flc = FormingLimitCurve::measured({{-20, 36}, {0, 23}, {20, 30}});
  EXPECT_TRUE(flc.isMeasured());
  EXPECT_DOUBLE_EQ(flc.flc0(), 23);
  EXPECT_NEAR(flc.majorAt(-10), 29.5, 1e-12);
  EXPECT_NEAR(flc.majorAt(10), 26.5, 1e-12);
  EXPECT_NEAR(flc.majorAt(30), 33.5, 1e-12);   // beyond the last point along the last segment
  EXPECT_NEAR(flc.majorAt(-30), 42.5, 1e-12);  // and before the first
  EXPECT_NEAR(flc.marginAlongPath(0, 20), 3, 1e-6);
  EXPECT_THROW(FormingLimitCurve::measured({{0, 23}}), std::invalid_argument);
  EXPECT_THROW(FormingLimitCurve::measured({{0, 23}, {0, 30}}), std::invalid_argument);
  EXPECT_THROW(FormingLimitCurve::measured({{-10, -3}, {10, -1}}), std::invalid_argument);
}

}  // namespace
}  // namespace stampscan::report
