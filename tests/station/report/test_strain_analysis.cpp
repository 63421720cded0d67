// Zones of hand-made strain states, and a verdict that one noisy element cannot decide.
#include "stampscan/report/strain_analysis.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace stampscan::report {
namespace {

using fitting::Vec3;

Material steel() {
  Material m;
  m.name = "test steel";
  m.thickness_mm = 1.0;
  m.n = 0.21;
  m.safety_margin_percent = 10;
  m.flc = FormingLimitCurve::keelerBrazier(keelerBrazierFlc0(1.0, 0.21));  // FLC0 37.43%
  return m;
}

// An element from engineering strains in %, volume constant.
ElementStrain element(double major_percent, double minor_percent) {
  const double e1 = trueStrain(major_percent), e2 = trueStrain(minor_percent);
  return analyseElement(Vec3::Zero(), e1, e2, -(e1 + e2), steel());
}

TEST(StrainAnalysis, ZonesOfHandMadeStrainStates) {
  EXPECT_EQ(element(40, 0).zone, Zone::Failure);     // above FLC0
  EXPECT_EQ(element(37.43, 0).zone, Zone::Failure);  // on it
  EXPECT_EQ(element(30, 0).zone, Zone::Marginal);    // 7.4% below
  EXPECT_EQ(element(38, 10).zone, Zone::Marginal);   // below the right branch (43.4% there) by 6.7% along the path
  EXPECT_EQ(element(45, 10).zone, Zone::Failure);    // above the right branch
  EXPECT_EQ(element(20, 5).zone, Zone::Safe);
  EXPECT_EQ(element(40, -15).zone, Zone::Safe);  // the left branch is high
  EXPECT_EQ(element(1, 0.5).zone, Zone::InsufficientStretch);
  EXPECT_EQ(element(1.5, -0.5).zone, Zone::InsufficientStretch);
  // Thickened (eps1 + eps2 < 0) and compressed beyond 2%: tendency between pure shear and uniaxial
  // compression, wrinkling beyond uniaxial compression.
  const auto byTrue = [](double eps1, double eps2) {
    return analyseElement(Vec3::Zero(), eps1, eps2, -(eps1 + eps2), steel());
  };
  EXPECT_EQ(byTrue(0.03, -0.04).zone, Zone::WrinklingTendency);
  EXPECT_EQ(byTrue(0.01, -0.05).zone, Zone::Wrinkling);
  EXPECT_EQ(byTrue(-0.01, -0.04).zone, Zone::Wrinkling);
  EXPECT_EQ(byTrue(0.005, -0.01).zone, Zone::InsufficientStretch);  // within the noise floor
  EXPECT_EQ(byTrue(0.05, -0.04).zone, Zone::Safe);                  // thinned: drawn, not wrinkling
}

TEST(StrainAnalysis, AnElementWhoseMarginIsWithinItsUncertaintyIsMarginal) {
  // A material with no safety band: only the measurement's own uncertainty keeps an element near the
  // curve from being called safe.
  Material m = steel();
  m.safety_margin_percent = 0;
  const double e1 = trueStrain(36.5), e2 = 0;  // 0.9 % below FLC0 (37.43 %)
  EXPECT_EQ(analyseElement(Vec3::Zero(), e1, e2, -(e1 + e2), m).zone, Zone::Safe);
  // Expanded uncertainty 2 x 0.004 x 136.5 = 1.1 % of major strain: it could be on the curve.
  const ElementStrain unsure = analyseElement(Vec3::Zero(), e1, e2, -(e1 + e2), m, {}, 0.004);
  EXPECT_EQ(unsure.zone, Zone::Marginal);
  EXPECT_EQ(unsure.thickness_uncertainty, 0.004);
  // 0.0015 (0.4 %) does not reach the curve; above the curve it fails whatever the uncertainty.
  EXPECT_EQ(analyseElement(Vec3::Zero(), e1, e2, -(e1 + e2), m, {}, 0.0015).zone, Zone::Safe);
  const double over = trueStrain(38);
  EXPECT_EQ(analyseElement(Vec3::Zero(), over, e2, -over, m, {}, 0.004).zone, Zone::Failure);
}

TEST(StrainAnalysis, ElementMeasures) {
  const ElementStrain e = analyseElement(Vec3(1, 2, 3), std::log(1.3), std::log(1.1), std::log(0.7), steel());
  EXPECT_NEAR(e.major_percent, 30, 1e-9);
  EXPECT_NEAR(e.minor_percent, 10, 1e-9);
  EXPECT_NEAR(e.thinning_percent, 30, 1e-9);  // eps3 taken as measured, not from eps1 + eps2
  EXPECT_NEAR(e.flc_major_percent, 37.43 + 6, 1e-9);
  EXPECT_GT(e.margin_percent, 10);
  // Major and minor given the wrong way round are put right.
  const ElementStrain swapped = analyseElement(Vec3::Zero(), std::log(1.1), std::log(1.3), std::log(0.7), steel());
  EXPECT_NEAR(swapped.major_percent, 30, 1e-9);
}

// A 20 x 20 grid at the standard pitch, every element safely stretched (15% plane strain).
fitting::Cloud safePlate() {
  fitting::Cloud c;
  auto& major = c.scalars["major_strain"];
  auto& minor = c.scalars["minor_strain"];
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      c.positions.emplace_back(2.54 * i, 2.54 * j, 0);
      major.push_back(trueStrain(15));
      minor.push_back(0);
      c.strain.push_back(-trueStrain(15));
    }
  return c;
}

void setStrain(fitting::Cloud& c, std::size_t i, double major_percent) {
  c.scalars["major_strain"][i] = trueStrain(major_percent);
  c.strain[i] = -trueStrain(major_percent);
}

std::size_t at(int i, int j) { return static_cast<std::size_t>(i * 20 + j); }

TEST(StrainAnalysis, VerdictIgnoresASingleOutlier) {
  fitting::Cloud c = safePlate();
  setStrain(c, at(10, 10), 60);  // one element far above the FLC
  const StrainAnalysis a = analyseStrains(c, steel());
  EXPECT_EQ(a.count(Zone::Failure), 1u);
  EXPECT_EQ(a.verdict, Verdict::Good) << a.verdict_reason;
  EXPECT_EQ(a.isolated_failures, 1u);
  EXPECT_NE(a.verdict_reason.find("noise"), std::string::npos) << a.verdict_reason;
  EXPECT_NEAR(a.grid_pitch_mm, 2.54, 1e-9);
  // It still heads the worst spots, marked as not counted.
  ASSERT_FALSE(a.worst_spots.empty());
  EXPECT_EQ(a.worst_spots[0].element, at(10, 10));
  EXPECT_FALSE(a.worst_spots[0].counted);
  EXPECT_EQ(a.worst_spots[0].patch_size, 1u);
}

TEST(StrainAnalysis, VerdictFailsAPatch) {
  fitting::Cloud c = safePlate();
  for (const auto& [i, j] : {std::pair{10, 10}, {10, 11}, {11, 10}, {11, 11}}) setStrain(c, at(i, j), 45);
  const StrainAnalysis a = analyseStrains(c, steel());
  EXPECT_EQ(a.verdict, Verdict::Failed) << a.verdict_reason;
  EXPECT_EQ(a.count(Zone::Failure), 4u);
  ASSERT_FALSE(a.worst_spots.empty());
  EXPECT_TRUE(a.worst_spots[0].counted);
  EXPECT_EQ(a.worst_spots[0].patch_size, 4u);
  // One worst spot per place: the patch's other elements are not listed again.
  for (std::size_t s = 1; s < a.worst_spots.size(); ++s)
    EXPECT_GT((a.elements[a.worst_spots[s].element].position - a.elements[a.worst_spots[0].element].position).norm(),
              10.0);
}

TEST(StrainAnalysis, VerdictMarginalFromAPatchOfMarginalAndFailureElements) {
  fitting::Cloud c = safePlate();
  setStrain(c, at(5, 5), 45);  // failure
  setStrain(c, at(5, 6), 30);  // marginal
  setStrain(c, at(6, 6), 31);  // marginal, diagonal neighbour
  const StrainAnalysis a = analyseStrains(c, steel());
  EXPECT_EQ(a.verdict, Verdict::Marginal) << a.verdict_reason;
  EXPECT_EQ(a.count(Zone::Marginal), 2u);
}

TEST(StrainAnalysis, AnElementMeasuredTwiceCountsOnce) {
  fitting::Cloud c = safePlate();
  setStrain(c, at(3, 3), 50);
  setStrain(c, at(3, 4), 50);
  // The same grid element seen again by an overlapping sweep.
  const fitting::Cloud before = c;
  c.appendPoint(before, at(3, 3));
  c.positions.back() += Vec3(0.01, 0, 0);
  StrainAnalysis a = analyseStrains(c, steel());
  EXPECT_EQ(a.count(Zone::Failure), 3u);
  EXPECT_EQ(a.verdict, Verdict::Good) << "two grid elements are under the patch size of 3: " << a.verdict_reason;
  EXPECT_NEAR(a.grid_pitch_mm, 2.54, 1e-9);  // the repeat does not shrink the pitch
  setStrain(c, at(4, 4), 50);
  a = analyseStrains(c, steel());
  EXPECT_EQ(a.verdict, Verdict::Failed) << a.verdict_reason;
}

TEST(StrainAnalysis, MissingStrainsAreNamed) {
  fitting::Cloud c = safePlate();
  c.scalars.erase("minor_strain");
  try {
    analyseStrains(c, steel());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("minor_strain"), std::string::npos) << e.what();
  }
}

// A verdict is never better than the data allow: an element with a strain that is not a number,
// or beyond any sheet's, refuses the analysis (naming it), or is left out when asked, and then the
// part is not called good and the verdict says what it rests on.
TEST(StrainAnalysis, InvalidElementsAreRefusedOrLeftOutNeverGood) {
  for (const double bad : {std::nan(""), 1e30, -2.0}) {
    fitting::Cloud c = safePlate();
    c.scalars["major_strain"][at(3, 4)] = bad;
    c.strain[at(7, 7)] = std::nan("");
    try {
      analyseStrains(c, steel());
      FAIL() << "no error for " << bad;
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("2 of " + std::to_string(c.size()) + " elements have invalid strains"), std::string::npos) << what;
      EXPECT_NE(what.find("element " + std::to_string(at(3, 4)) + ": major_strain"), std::string::npos) << what;
    }
    AnalysisParams leave_out;
    leave_out.leave_out_invalid = true;
    const StrainAnalysis a = analyseStrains(c, steel(), leave_out);
    EXPECT_EQ(a.left_out, 2u);
    EXPECT_EQ(a.elements.size(), c.size() - 2);
    EXPECT_EQ(a.elements_in_cloud, c.size());
    EXPECT_EQ(a.verdict, Verdict::Marginal) << a.verdict_reason;
    EXPECT_NE(a.verdict_reason.find("left out"), std::string::npos) << a.verdict_reason;
    EXPECT_NE(a.verdict_reason.find("judged on " + std::to_string(c.size() - 2) + " of " + std::to_string(c.size())),
              std::string::npos)
        << a.verdict_reason;
  }
  // The same plate whole is good, on all of its elements.
  const StrainAnalysis whole = analyseStrains(safePlate(), steel());
  EXPECT_EQ(whole.verdict, Verdict::Good) << whole.verdict_reason;
  EXPECT_EQ(whole.left_out, 0u);
}

}  // namespace
}  // namespace stampscan::report
