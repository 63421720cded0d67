// Measurements of one printed element by several sweeps and views merged into one element, with
// each path's noise estimated from the scan's own twins; against a known grid and known noise.
#include "stampscan/registration/element_merge.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace {

using namespace stampscan;
using registration::GridElement;
using registration::Source;
using registration::Vec3;

struct Truth {
  Vec3 position;
  double strain;
};

// A 2.54 mm grid over a gently curved sheet, with a strain that varies over it.
std::vector<Truth> grid(int n) {
  std::vector<Truth> out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = 2.54 * i, y = 2.54 * j;
      out.push_back({Vec3(x, y, 0.002 * (x * x + y * y)), -0.05 - 0.1 * std::sin(0.05 * x) * std::cos(0.07 * y)});
    }
  return out;
}

std::vector<Vec3> positionsOf(const std::vector<Truth>& truth) {
  std::vector<Vec3> p;
  for (const Truth& t : truth) p.push_back(t.position);
  return p;
}

GridElement measured(const Truth& t, Source source, std::uint32_t view, double sigma_strain, double sigma_mm,
                     std::mt19937_64& rng) {
  std::normal_distribution<double> z;
  GridElement g;
  g.position = t.position + sigma_mm * Vec3(z(rng), z(rng), z(rng));
  g.thickness_strain = t.strain + sigma_strain * z(rng);
  g.major_strain = -0.5 * g.thickness_strain + 0.01;
  g.minor_strain = -0.5 * g.thickness_strain - 0.01;
  g.major_direction = (view % 2 ? -1.0 : 1.0) * Vec3::UnitX();  // an axis: either sign
  g.source = source;
  g.view = view;
  return g;
}

// Two laser sweeps overlap on every element, and three stereo views see most of them.
constexpr double kLaserStrain = 0.0006, kLaserMm = 0.004, kStereoStrain = 0.0015, kStereoMm = 0.015;

std::vector<GridElement> session(const std::vector<Truth>& truth, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<GridElement> m;
  for (const Truth& t : truth)
    for (std::uint32_t sweep = 0; sweep < 2; ++sweep) m.push_back(measured(t, Source::Laser, sweep, kLaserStrain, kLaserMm, rng));
  std::uniform_real_distribution<double> u;
  for (const Truth& t : truth)
    for (std::uint32_t v = 0; v < 3; ++v)
      if (u(rng) < 0.8) m.push_back(measured(t, Source::Stereo, 1000 + v, kStereoStrain, kStereoMm, rng));
  return m;
}

TEST(ElementMerge, OneElementPerPrintedElementWithItsPathsNoise) {
  const std::vector<Truth> truth = grid(30);
  const std::vector<GridElement> m = session(truth, 1);
  const auto merged = registration::mergeMeasurements(m, 0.25 * 2.54);
  ASSERT_EQ(merged.elements.size(), truth.size());
  ASSERT_EQ(merged.element_of.size(), m.size());
  EXPECT_EQ(merged.measurements, m.size());
  // Each path's noise as the twins show it, within a tenth of the truth.
  ASSERT_TRUE(merged.laser.strain && merged.stereo.strain);
  EXPECT_NEAR(*merged.laser.strain, kLaserStrain, 0.1 * kLaserStrain);
  EXPECT_NEAR(*merged.stereo.strain, kStereoStrain, 0.1 * kStereoStrain);
  EXPECT_NEAR(*merged.laser.position_mm, kLaserMm, 0.1 * kLaserMm);
  EXPECT_NEAR(*merged.stereo.position_mm, kStereoMm, 0.1 * kStereoMm);

  // The merged strain is better than one laser measurement, and its stated uncertainty honest: about
  // 95 % of the elements within two standard uncertainties of the truth.
  const std::vector<Vec3> true_positions = positionsOf(truth);
  const fitting::KdTree tree(true_positions);  // indexes the positions in place
  double sq = 0;
  std::size_t within = 0;
  std::vector<fitting::Neighbor> nn;
  for (const GridElement& g : merged.elements) {
    tree.knn(g.position, 1, nn);
    const double e = g.thickness_strain - truth[nn[0].index].strain;
    sq += e * e;
    ASSERT_TRUE(std::isfinite(g.strain_sigma));
    EXPECT_LT(g.strain_sigma, kLaserStrain);
    within += std::abs(e) <= 2 * g.strain_sigma;
    EXPECT_GE(g.measurements, 2u);
    EXPECT_NEAR(std::abs(g.major_direction.x()), 1.0, 1e-9) << "the major axis is averaged as an axis";
  }
  const double n = static_cast<double>(merged.elements.size());
  EXPECT_LT(std::sqrt(sq / n), 0.8 * kLaserStrain);
  const double share = static_cast<double>(within) / n;
  EXPECT_GT(share, 0.92);
  EXPECT_LT(share, 0.985);
}

TEST(ElementMerge, TheOrderOfTheMeasurementsDoesNotMatter) {
  const std::vector<Truth> truth = grid(12);
  std::vector<GridElement> m = session(truth, 2);
  const auto a = registration::mergeMeasurements(m, 0.6);
  std::shuffle(m.begin(), m.end(), std::mt19937_64(3));
  const auto b = registration::mergeMeasurements(m, 0.6);
  ASSERT_EQ(a.elements.size(), b.elements.size());
  const auto key = [](const GridElement& g) { return std::make_pair(std::round(g.position.x()), std::round(g.position.y())); };
  auto sa = a.elements, sb = b.elements;
  const auto by = [&](const GridElement& p, const GridElement& q) { return key(p) < key(q); };
  std::sort(sa.begin(), sa.end(), by);
  std::sort(sb.begin(), sb.end(), by);
  for (std::size_t i = 0; i < sa.size(); ++i) {
    EXPECT_NEAR(sa[i].thickness_strain, sb[i].thickness_strain, 1e-6);
    EXPECT_NEAR((sa[i].position - sb[i].position).norm(), 0.0, 1e-6);
  }
}

TEST(ElementMerge, AWrongMeasurementAmongSeveralIsLeftOut) {
  const std::vector<Truth> truth = grid(20);
  std::vector<GridElement> m = session(truth, 4);
  // One stereo view misreads an element by 0.05 (a ring across a fold).
  std::size_t victim = 0;
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m[i].source == Source::Stereo) {
      victim = i;
      break;
    }
  m[victim].thickness_strain += 0.05;
  const auto merged = registration::mergeMeasurements(m, 0.6);
  const GridElement& g = merged.elements[merged.element_of[victim]];
  const std::vector<Vec3> true_positions = positionsOf(truth);
  const fitting::KdTree tree(true_positions);  // indexes the positions in place
  std::vector<fitting::Neighbor> nn;
  tree.knn(g.position, 1, nn);
  EXPECT_LT(std::abs(g.thickness_strain - truth[nn[0].index].strain), 5 * kLaserStrain);
}

TEST(ElementMerge, WithoutTwinsTheNoiseIsNotKnownAndNothingIsClaimed) {
  const std::vector<Truth> truth = grid(10);
  std::mt19937_64 rng(5);
  std::vector<GridElement> once;
  for (const Truth& t : truth) once.push_back(measured(t, Source::Laser, 0, kLaserStrain, kLaserMm, rng));
  const auto merged = registration::mergeMeasurements(once, 0.6);
  EXPECT_EQ(merged.elements.size(), truth.size());
  EXPECT_FALSE(merged.laser.strain);
  for (const GridElement& g : merged.elements) EXPECT_FALSE(std::isfinite(g.strain_sigma));
  EXPECT_TRUE(registration::mergeMeasurements({}, 0.6).elements.empty());
  EXPECT_THROW(registration::mergeMeasurements(once, 0.0), std::invalid_argument);
}

}  // namespace
