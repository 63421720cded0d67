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

TEST(ElementMerge, EachPathKeepsItsOwnShareOfTheSharedError) {
  // A fine laser and a coarse camera pair: each path's measurements of one element share an error
  // of half their own noise (a view's geometry and a print's flaw are the same for all of them).
  // The two paths' disagreement holds both shared errors; the laser's is a small part of it, and a
  // laser-led element stated with the cameras' would claim far too much doubt.
  constexpr double kLaserOwn = 0.0005, kStereoOwn = 0.0025, kSharedRatio = 0.5;
  const std::vector<Truth> truth = grid(40);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> z;
  std::vector<GridElement> m;
  for (const Truth& t : truth) {
    const Truth laser_seen{t.position, t.strain + kSharedRatio * kLaserOwn * z(rng)};
    const Truth stereo_seen{t.position, t.strain + kSharedRatio * kStereoOwn * z(rng)};
    for (std::uint32_t sweep = 0; sweep < 2; ++sweep) m.push_back(measured(laser_seen, Source::Laser, sweep, kLaserOwn, kLaserMm, rng));
    for (std::uint32_t v = 0; v < 3; ++v) m.push_back(measured(stereo_seen, Source::Stereo, 1000 + v, kStereoOwn, kStereoMm, rng));
  }
  const auto merged = registration::mergeMeasurements(m, 0.25 * 2.54);
  ASSERT_TRUE(merged.laser.strain_shared && merged.stereo.strain_shared);
  EXPECT_NEAR(*merged.laser.strain_shared, kSharedRatio * kLaserOwn, 0.3 * kSharedRatio * kLaserOwn);
  EXPECT_NEAR(*merged.stereo.strain_shared, kSharedRatio * kStereoOwn, 0.2 * kSharedRatio * kStereoOwn);
  const std::vector<Vec3> true_positions = positionsOf(truth);
  const fitting::KdTree tree(true_positions);
  std::vector<fitting::Neighbor> nn;
  std::size_t within = 0;
  for (const GridElement& g : merged.elements) {
    tree.knn(g.position, 1, nn);
    within += std::abs(g.thickness_strain - truth[nn[0].index].strain) <= 2 * g.strain_sigma;
  }
  const double share = static_cast<double>(within) / static_cast<double>(merged.elements.size());
  EXPECT_GT(share, 0.92);
  EXPECT_LT(share, 0.985) << "the stated uncertainty is inflated";
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

// One path's measurements of an element share part of their error: three stereo views that read
// one element alike but wrongly (a strongly thinned cell on a steep wall) are no majority against the
// laser's one reading of it. The laser's reading stays in the element.
TEST(ElementMerge, OnePathsAgreeingViewsDoNotOutvoteTheOtherPath) {
  const std::vector<Truth> truth = grid(20);
  std::vector<GridElement> m = session(truth, 5);
  const std::size_t k = 7 * 20 + 9;  // an element inside the grid
  const double true_strain = truth[k].strain;
  std::vector<GridElement> kept;
  bool laser_kept = false;
  for (GridElement g : m) {
    if ((g.position - truth[k].position).norm() < 0.5) {
      if (g.source == Source::Laser) {
        if (laser_kept) continue;  // one laser reading
        laser_kept = true;
      } else {
        g.thickness_strain = true_strain - 0.02;  // every view alike, all wrong
      }
    }
    kept.push_back(g);
  }
  // Three stereo views of it, as on the wall.
  std::mt19937_64 rng(9);
  std::size_t views = 0;
  for (const GridElement& g : kept) views += (g.position - truth[k].position).norm() < 0.5 && g.source == Source::Stereo;
  for (std::uint32_t v = static_cast<std::uint32_t>(views); v < 3; ++v) {
    GridElement g = measured(truth[k], Source::Stereo, 1000 + v, 0, kStereoMm, rng);
    g.thickness_strain = true_strain - 0.02;
    kept.push_back(g);
  }
  const auto merged = registration::mergeMeasurements(kept, 0.6);
  std::vector<Vec3> merged_positions;
  for (const GridElement& g : merged.elements) merged_positions.push_back(g.position);
  const fitting::KdTree tree(merged_positions);  // indexes the positions in place
  std::vector<fitting::Neighbor> nn;
  tree.knn(truth[k].position, 1, nn);
  ASSERT_FALSE(nn.empty());
  const GridElement& g = merged.elements[nn[0].index];
  EXPECT_EQ(g.measurements, 4u);  // the laser's reading and the three views
  EXPECT_GT(g.thickness_strain, true_strain - 0.02 + 0.001) << "the laser's reading was left out";
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

namespace {

// A flat sheet stretched by 12 % along x and compressed by 1 % along y, its printed grid at
// `pitch`, with major and minor strains that bend over it as quadratics of the printed coordinates
// (X, Y), measured as the means over outlines of `gauge` mm^2 (the centre's strain plus gauge times
// the material Laplacian).
struct BentStrain {
  static double major(double X, double Y) { return 0.12 + 0.002 * X - 0.0002 * X * X + 0.0001 * X * Y; }
  static double minor(double X, double Y) { return -0.01 + 0.0002 * Y * Y - 0.0001 * X * X; }
  static constexpr double kMajorLaplacian = 2 * -0.0002, kMinorLaplacian = 2 * 0.0002 + 2 * -0.0001;
};

std::vector<GridElement> outlineMeans(int n, double pitch, double gauge) {
  std::vector<GridElement> out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double X = pitch * (i - n / 2), Y = pitch * (j - n / 2);
      GridElement g;
      g.position = Vec3(std::exp(0.12) * X, std::exp(-0.01) * Y, 0);
      g.normal = Vec3::UnitZ();
      g.major_direction = Vec3::UnitX();
      g.major_strain = BentStrain::major(X, Y) + gauge * BentStrain::kMajorLaplacian;
      g.minor_strain = BentStrain::minor(X, Y) + gauge * BentStrain::kMinorLaplacian;
      g.thickness_strain = -(g.major_strain + g.minor_strain);
      g.gauge_mm2 = gauge;
      g.view = static_cast<std::uint32_t>(i * n + j);
      out.push_back(g);
    }
  return out;
}

}  // namespace

TEST(ElementMerge, StrainsAtCentresUndoTheOutlinesAveraging) {
  // A ring fitted at 1.2 mm averages as 1.2^2 / 8 = 0.18 mm^2: here 0.00007 of major strain.
  const double pitch = 2.54, gauge = 1.2 * 1.2 / 8;
  const std::vector<GridElement> means = outlineMeans(9, pitch, gauge);
  const registration::MergedElements merged = registration::mergeMeasurements(means, 0.25 * pitch);
  ASSERT_EQ(merged.elements.size(), means.size());
  const std::vector<GridElement> centred = registration::strainsAtCentres(means, merged, pitch);
  ASSERT_EQ(centred.size(), means.size());
  std::size_t moved = 0, kept = 0;
  for (std::size_t k = 0; k < centred.size(); ++k) {
    const int i = static_cast<int>(k) / 9, j = static_cast<int>(k) % 9;
    const double X = pitch * (i - 4), Y = pitch * (j - 4);
    const bool inside = i > 0 && i < 8 && j > 0 && j < 8;
    if (inside) {
      // The centre's strains. The printed distances to the neighbours come from each element's own
      // stretches, which here differ from the grid's uniform ones by up to 2 %: the Laplacian is
      // twice that off, and a tenth of the correction is what is asked.
      const double major_shift = gauge * BentStrain::kMajorLaplacian, minor_shift = gauge * BentStrain::kMinorLaplacian;
      EXPECT_NEAR(centred[k].major_strain, BentStrain::major(X, Y), 0.1 * std::abs(major_shift))
          << "element " << i << ", " << j;
      EXPECT_NEAR(centred[k].minor_strain, BentStrain::minor(X, Y), 0.1 * std::abs(minor_shift))
          << "element " << i << ", " << j;
      EXPECT_NEAR(centred[k].thickness_strain, -(centred[k].major_strain + centred[k].minor_strain), 1e-12);
      ++moved;
    } else {
      // At the grid's edge nothing surrounds the element: its mean stands.
      EXPECT_EQ(centred[k].major_strain, means[k].major_strain) << "element " << i << ", " << j;
      ++kept;
    }
  }
  EXPECT_EQ(moved, 49u);
  EXPECT_EQ(kept, 32u);
}

TEST(ElementMerge, StrainsAtCentresLeaveAFlatFieldAndAnUnknownGaugeAlone) {
  const double pitch = 2.54;
  std::vector<GridElement> means = outlineMeans(7, pitch, 0.0);  // no gauge: nothing to undo
  const registration::MergedElements merged = registration::mergeMeasurements(means, 0.25 * pitch);
  const std::vector<GridElement> centred = registration::strainsAtCentres(means, merged, pitch);
  for (std::size_t k = 0; k < centred.size(); ++k) EXPECT_EQ(centred[k].major_strain, means[k].major_strain);
  EXPECT_THROW(registration::strainsAtCentres(std::vector<GridElement>(3), merged, pitch), std::invalid_argument);
}

TEST(ElementMerge, AViewsQualityWeighsItsStrainAndStatesItsUncertainty) {
  // Stereo views of one element differ in how squarely they see it: a view's quality (its corners'
  // misfit, 0.001 to 0.02 mm) scales its own strain noise as sqrt(a + b q^2), from 0.0006 to 0.006.
  const std::vector<Truth> truth = grid(30);
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u;
  constexpr double kA = 0.0006 * 0.0006, kB = 0.3 * 0.3;  // strain^2, strain^2 / mm^2
  const auto sigma_at = [&](double q) { return std::sqrt(kA + kB * q * q); };
  std::vector<GridElement> m;
  std::vector<double> true_sigma;
  for (const Truth& t : truth) {
    for (std::uint32_t sweep = 0; sweep < 2; ++sweep) {
      m.push_back(measured(t, Source::Laser, sweep, kLaserStrain, kLaserMm, rng));
      true_sigma.push_back(kLaserStrain);
    }
    for (std::uint32_t v = 0; v < 3; ++v) {
      const double q = 0.001 + 0.019 * u(rng) * u(rng);
      GridElement g = measured(t, Source::Stereo, 1000 + v, sigma_at(q), kStereoMm, rng);
      g.fit_rms = q;
      m.push_back(g);
      true_sigma.push_back(sigma_at(q));
    }
  }
  const auto merged = registration::mergeMeasurements(m, 0.25 * 2.54);
  ASSERT_EQ(merged.strain_sigma_of.size(), m.size());
  // Each stereo view's stated uncertainty follows its quality (within a fifth).
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (m[i].source != Source::Stereo || m[i].fit_rms < 0.01) continue;
    EXPECT_NEAR(merged.strain_sigma_of[i], true_sigma[i], 0.2 * true_sigma[i]) << "q " << m[i].fit_rms;
  }
  // The merged elements as good as weights by the true noise would make them (within a tenth), and
  // their stated uncertainty honest.
  std::vector<double> ideal_sum(merged.elements.size(), 0.0), ideal_weight(merged.elements.size(), 0.0);
  for (std::size_t i = 0; i < m.size(); ++i) {
    const double w = 1 / (true_sigma[i] * true_sigma[i]);
    ideal_sum[merged.element_of[i]] += w * m[i].thickness_strain;
    ideal_weight[merged.element_of[i]] += w;
  }
  const std::vector<Vec3> true_positions = positionsOf(truth);
  const fitting::KdTree tree(true_positions);
  std::vector<fitting::Neighbor> nn;
  double sq = 0, ideal_sq = 0;
  std::size_t within = 0;
  for (std::size_t k = 0; k < merged.elements.size(); ++k) {
    const GridElement& g = merged.elements[k];
    tree.knn(g.position, 1, nn);
    const double e = g.thickness_strain - truth[nn[0].index].strain;
    sq += e * e;
    ideal_sq += std::pow(ideal_sum[k] / ideal_weight[k] - truth[nn[0].index].strain, 2);
    within += std::abs(e) <= 2 * g.strain_sigma;
  }
  const double n = static_cast<double>(merged.elements.size());
  EXPECT_LT(std::sqrt(sq / n), 1.1 * std::sqrt(ideal_sq / n));
  EXPECT_GT(static_cast<double>(within) / n, 0.92);
  EXPECT_LT(static_cast<double>(within) / n, 0.985);
}

TEST(ElementMerge, TheFieldAroundAnElementWidensItsUncertaintyWhereItIsNotSmooth) {
  const double pitch = 2.54;
  // A smooth quadratic field measured with a stated noise: the uncertainty grows only by the shift
  // to the centre (gauge times the Laplacian).
  std::vector<GridElement> means = outlineMeans(9, pitch, 0.18);
  for (GridElement& g : means) g.strain_sigma = g.strain_noise = 0.0005;
  registration::MergedElements smooth;
  smooth.elements = means;
  registration::addFieldUncertainty(smooth, pitch);
  const double shift = 0.18 * (BentStrain::kMajorLaplacian + BentStrain::kMinorLaplacian);
  const std::size_t centre = 4 * 9 + 4, corner = 0;
  EXPECT_NEAR(smooth.elements[centre].strain_sigma, std::hypot(0.0005, shift), 0.05 * std::abs(shift));
  EXPECT_EQ(smooth.elements[corner].strain_sigma, 0.0005) << "at the grid's edge the element keeps its own";
  // The same with every other element's strain off by 0.004 (a chequerboard no quadratic follows):
  // the uncertainty grows to about that.
  registration::MergedElements rough;
  rough.elements = means;
  for (std::size_t k = 0; k < rough.elements.size(); ++k) {
    GridElement& g = rough.elements[k];
    const double off = ((k / 9 + k % 9) % 2 ? 0.002 : -0.002);
    g.major_strain += off / 2, g.minor_strain += off / 2, g.thickness_strain -= off;
  }
  registration::addFieldUncertainty(rough, pitch);
  EXPECT_GT(rough.elements[centre].strain_sigma, 0.0015);
  EXPECT_LT(rough.elements[centre].strain_sigma, 0.004);
  EXPECT_THROW(registration::addFieldUncertainty(rough, 0.0), std::invalid_argument);
}

TEST(ElementMerge, AnElementOverlappingABetterSupportedOneIsFound) {
  // A grid measured twice each, and one stereo match across two cells: a cell twice the size,
  // measured once, halfway between two true ones.
  const double pitch = 2.54;
  std::vector<GridElement> m;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (std::uint32_t sweep = 0; sweep < 2; ++sweep) {
        GridElement g;
        g.position = Vec3(pitch * i, pitch * j, 0) + 0.003 * Vec3(sweep, 0, 0);
        g.semi_major = g.semi_minor = 0.5 * pitch;
        g.normal = Vec3::UnitZ();
        g.major_direction = Vec3::UnitX();
        g.view = sweep;
        m.push_back(g);
      }
  GridElement wrong;
  wrong.position = Vec3(pitch * 2.5, pitch * 3, 0);
  wrong.semi_major = 1.6 * pitch;  // twice the area, stretched along x
  wrong.semi_minor = 0.6 * pitch;
  wrong.source = Source::Stereo;
  wrong.view = 1000;
  m.push_back(wrong);
  const auto merged = registration::mergeMeasurements(m, 0.25 * pitch);
  ASSERT_EQ(merged.elements.size(), 37u);
  const std::vector<std::uint32_t> overlapping = registration::overlappingElements(merged);
  ASSERT_EQ(overlapping.size(), 1u);
  EXPECT_EQ(overlapping[0], merged.element_of.back());
  // True neighbours a pitch apart do not overlap, nor does a lone element.
  m.pop_back();
  EXPECT_TRUE(registration::overlappingElements(registration::mergeMeasurements(m, 0.25 * pitch)).empty());
}
