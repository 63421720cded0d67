// The shape from dense points, the strain from sparse carriers (shape_and_strain.hpp), against a
// sphere cap whose strain field is known.
#include "stampscan/fitting/shape_and_strain.hpp"

#include "stampscan/fitting/kdtree.hpp"

#include "shapes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace stampscan::fitting {
namespace {

constexpr double kRadius = 80.0;  // mm
double trueStrain(const Vec3& p) { return 0.05 + 0.002 * p.x() + 1e-4 * p.y() * p.y(); }

// Grid elements at a 2.54 mm pitch on the cap where x < x_max, with noisy positions and strain;
// those with y > 0 measured twice (as where two laser strips overlap).
Cloud carriersOnCap(double x_max, double position_noise, double strain_noise, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Cloud c;
  for (double x = -30; x < x_max; x += 2.54)
    for (double y = -30; y <= 30; y += 2.54) {
      if (x * x + y * y > 26.0 * 26.0) continue;
      if (std::hypot(x + 12.7, y + 7.6) < 3.0) continue;  // a few elements not found: a gap in the grid
      const Vec3 on(x, y, std::sqrt(kRadius * kRadius - x * x - y * y));
      for (int twice = 0; twice < (y > 0 ? 2 : 1); ++twice) {
        c.positions.push_back(on + position_noise * Vec3(g(rng), g(rng), g(rng)));
        c.strain.push_back(trueStrain(on) + strain_noise * g(rng));
      }
    }
  return c;
}

// A fit can be stopped within a stage: its loops tell their progress as they go, and a callback
// that throws stops the fit there (a scan stopped after its motion does so).
TEST(ShapeAndStrain, AFitStopsWithinAStageWhenItsProgressThrows) {
  const Cloud shape = test::sampleSphereCap(150000, kRadius, 0.35, 0.03, 9);
  struct Stop {};
  std::vector<std::pair<std::string, double>> told;
  std::mutex told_mutex;
  ShapeAndStrainParams params;
  params.shape.progress = [&](const std::string& stage, double fraction) {
    std::lock_guard lock(told_mutex);
    told.emplace_back(stage, fraction);
    if (fraction > 0 && fraction < 1) throw Stop{};
  };
  EXPECT_THROW(ShapeSurface(shape.positions, params), Stop);
  ASSERT_FALSE(told.empty());
  EXPECT_LT(told.back().second, 1.0) << "stopped at " << told.back().first << " " << told.back().second;
  // Without the stop the same fit runs to its end, telling each stage.
  told.clear();
  params.shape.progress = [&](const std::string& stage, double fraction) {
    std::lock_guard lock(told_mutex);
    told.emplace_back(stage, fraction);
  };
  const ShapeSurface whole(shape.positions, params);
  EXPECT_GT(whole.surface().size(), 1000u);
  EXPECT_GT(told.size(), 10u);
}

TEST(ShapeAndStrain, DenseShapeCarriesTheElementsStrainAndStopsBeyondThem) {
  const double noise = 0.03;
  const Cloud shape = test::sampleSphereCap(150000, kRadius, 0.35, noise, 7);
  const Cloud carriers = carriersOnCap(5.0, 0.01, 0.002, 8);
  ShapeAndStrainParams params;
  const ShapeAndStrain fit = fitShapeAndStrain(shape, carriers, params);

  ASSERT_GT(fit.surface.size(), 5000u);  // ~2,400 mm^2 at 0.5 mm
  ASSERT_EQ(fit.surface.strain.size(), fit.surface.size());
  ASSERT_EQ(fit.surface.normals.size(), fit.surface.size());
  std::vector<double> shape_error, strain_error;
  std::size_t near_without = 0, near_total = 0, far_with = 0, far_total = 0;
  for (std::size_t i = 0; i < fit.surface.size(); ++i) {
    const Vec3& p = fit.surface.positions[i];
    shape_error.push_back(p.norm() - kRadius);
    EXPECT_GT(std::abs(fit.surface.normals[i].dot(p.normalized())), 0.99);
    const double s = fit.surface.strain[i];
    if (p.x() < -2.0 && p.head<2>().norm() < 22.0) {  // among the carriers, away from their edge
      ++near_total;
      if (std::isfinite(s)) strain_error.push_back(s - trueStrain(p));
      else ++near_without;
    }
    if (p.x() > 20.0) {  // more than 15 mm from the last carrier
      ++far_total;
      far_with += std::isfinite(s);
    }
  }
  // The shape is fitted to far below the points' noise; the strain to below the carriers' noise.
  EXPECT_LT(test::rmsOf(shape_error), noise / 4);
  EXPECT_EQ(near_without, 0u);
  ASSERT_GT(strain_error.size(), 1000u);
  EXPECT_LT(test::rmsOf(strain_error), 0.0015);
  // Nowhere an extrapolated slope, not even in the gap.
  double worst = 0;
  for (double e : strain_error) worst = std::max(worst, std::abs(e));
  std::printf("worst strain error %.5f\n", worst);
  EXPECT_LT(worst, 0.006);
  ASSERT_GT(far_total, 100u);
  EXPECT_EQ(far_with, 0u) << "strain beyond the carriers must be left out, not extrapolated";
  EXPECT_EQ(fit.without_strain, static_cast<std::size_t>(std::count_if(fit.surface.strain.begin(), fit.surface.strain.end(),
                                                                      [](double s) { return !std::isfinite(s); })));
  EXPECT_NEAR(fit.carrier_spacing, 2.54, 0.1);
  EXPECT_LT(fit.not_converged, fit.surface.size() / 1000 + 1);

  // The mesh lies on the shape and carries the strain where the carriers are.
  ASSERT_GT(fit.mesh.triangles.size(), 5000u);
  ASSERT_EQ(fit.mesh.vertices.strain.size(), fit.mesh.vertices.size());
  std::vector<double> mesh_shape, mesh_strain;
  for (std::size_t i = 0; i < fit.mesh.vertices.size(); ++i) {
    const Vec3& p = fit.mesh.vertices.positions[i];
    mesh_shape.push_back(p.norm() - kRadius);
    if (p.x() < -2.0 && p.head<2>().norm() < 22.0 && std::isfinite(fit.mesh.vertices.strain[i]))
      mesh_strain.push_back(fit.mesh.vertices.strain[i] - trueStrain(p));
  }
  std::printf("shape RMS %.4f mm (points), %.4f mm (mesh); strain RMS %.5f (points), %.5f (mesh); strain h median %.2f mm\n",
              test::rmsOf(shape_error), test::rmsOf(mesh_shape), test::rmsOf(strain_error), test::rmsOf(mesh_strain),
              fit.strain_bandwidth.median);
  EXPECT_LT(test::rmsOf(mesh_shape), noise / 4);
  EXPECT_LT(test::rmsOf(mesh_strain), 0.0015);
}

// A scan fits each sweep's returns as it is measured and joins the pieces (joined_surface.hpp).
// Three strips that overlap, each with its own points of the overlaps (two sweeps see the same
// sheet, each with its own returns): the joined surface is as true as one fit of all the points,
// along the strips' edges too (no seam), with the same output points, normals and mesh.
TEST(ShapeAndStrain, StripsFittedApartAndJoinedAreAsTrueAsOneFitOfAllThePoints) {
  const double noise = 0.03;
  const Cloud shape = test::sampleSphereCap(150000, kRadius, 0.35, noise, 11);
  std::mt19937_64 rng(12);
  std::bernoulli_distribution coin(0.5);
  std::vector<std::vector<Vec3>> strips(3);
  for (const Vec3& p : shape.positions) {
    const double x = p.x();
    if (x < -4) strips[0].push_back(p);
    else if (x < 4) strips[coin(rng) ? 0 : 1].push_back(p);  // overlap of strips 0 and 1
    else if (x < 8) strips[1].push_back(p);
    else if (x < 14) strips[coin(rng) ? 1 : 2].push_back(p);  // overlap of strips 1 and 2
    else strips[2].push_back(p);
  }
  const ShapeAndStrainParams params;
  const ShapeSurface whole(shape.positions, params);
  std::vector<std::unique_ptr<ShapePiece>> pieces;
  for (auto& strip : strips) pieces.push_back(std::make_unique<ShapePiece>(std::move(strip), params.shape));
  const ShapeSurface joined(std::move(pieces), params);
  EXPECT_EQ(joined.pieces(), 3u);
  EXPECT_EQ(joined.points(), shape.size());

  const auto errors = [](const Cloud& c, double x_lo, double x_hi) {
    std::vector<double> e;
    for (const Vec3& p : c.positions)
      if (p.x() >= x_lo && p.x() < x_hi) e.push_back(p.norm() - kRadius);
    return e;
  };
  const double whole_rms = test::rmsOf(errors(whole.surface(), -1e9, 1e9));
  const double joined_rms = test::rmsOf(errors(joined.surface(), -1e9, 1e9));
  std::printf("shape RMS: whole %.5f mm, joined %.5f mm\n", whole_rms, joined_rms);
  EXPECT_LT(joined_rms, noise / 4);
  EXPECT_LT(joined_rms, 1.15 * whole_rms + 0.0002);
  // Along each strip's edge, where one piece's data end inside another's: no seam.
  for (const double edge : {-4.0, 4.0, 8.0, 14.0}) {
    const std::vector<double> near_edge = errors(joined.surface(), edge - 1.5, edge + 1.5);
    ASSERT_GT(near_edge.size(), 100u);
    double worst = 0;
    for (double e : near_edge) worst = std::max(worst, std::abs(e));
    std::printf("edge at x = %.0f: RMS %.5f, worst %.5f mm\n", edge, test::rmsOf(near_edge), worst);
    EXPECT_LT(test::rmsOf(near_edge), 1.5 * whole_rms + 0.0002);
    EXPECT_LT(worst, noise / 2);
  }
  // The same output points (one per cube of the union), every normal outward.
  EXPECT_NEAR(static_cast<double>(joined.surface().size()), static_cast<double>(whole.surface().size()),
              0.002 * static_cast<double>(whole.surface().size()));
  for (std::size_t i = 0; i < joined.surface().size(); ++i)
    ASSERT_GT(joined.surface().normals[i].dot(joined.surface().positions[i].normalized()), 0.99) << "point " << i;
  // The mesh is whole across the strips and on the sphere.
  EXPECT_NEAR(static_cast<double>(joined.mesh().triangles.size()), static_cast<double>(whole.mesh().triangles.size()),
              0.01 * static_cast<double>(whole.mesh().triangles.size()));
  std::vector<double> mesh_error;
  for (const Vec3& p : joined.mesh().vertices.positions) mesh_error.push_back(p.norm() - kRadius);
  EXPECT_LT(test::rmsOf(mesh_error), noise / 4);
  // The joined surface projects by position only.
  EXPECT_THROW(joined.implicitSurface().projectPoint(0), std::logic_error);
}

// A strain band narrower than the pitch allows a plane to follow (a die radius: a Gaussian ridge of
// 0.2 across 5 mm), carriers that state their uncertainty, and one outlier element: at the elements
// the map is as true as the elements, halfway between them within 1.5 times of it, the ridge's peak
// is kept, and the outlier reaches no neighbour.
TEST(ShapeAndStrain, TheMapHonoursTheElementsFollowsABandAndDoesNotSpreadAnOutlier) {
  const auto truth = [](const Vec3& p) { return 0.02 + 0.2 * std::exp(-std::pow(p.x() / 5.0, 2)); };
  const double noise = 0.002;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  Cloud shape, carriers;
  for (double x = -25; x <= 25; x += 0.25)
    for (double y = -25; y <= 25; y += 0.25) shape.positions.push_back(Vec3(x, y, 0.002 * g(rng)));
  std::size_t outlier = 0;
  for (int i = -9; i <= 9; ++i)
    for (int j = -9; j <= 9; ++j) {
      const Vec3 p(2.54 * i + 0.3, 2.54 * j, 0);  // the ridge's crest between two columns of elements
      carriers.positions.push_back(p);
      carriers.strain.push_back(truth(p) + noise * g(rng));
      if (i == -6 && j == 2) {
        outlier = carriers.size() - 1;
        carriers.strain.back() += 0.1;
      }
    }
  carriers.scalars[kStrainUncertainty].assign(carriers.size(), noise);
  ShapeAndStrainParams params;
  params.with_mesh = false;
  params.output_spacing_mm = 0.25;
  const ShapeAndStrain fit = fitShapeAndStrain(shape, carriers, params);

  std::vector<double> own, at_elements, between;
  for (std::size_t k = 0; k < carriers.size(); ++k) {
    const Vec3& p = carriers.positions[k];
    if (k == outlier || std::abs(p.x()) > 20 || std::abs(p.y()) > 20) continue;
    own.push_back(carriers.strain[k] - truth(p));
    at_elements.push_back(fit.strain_at_carriers[k] - truth(p));
  }
  const KdTree element_tree(carriers.positions);
  std::vector<Neighbor> nn;
  double worst_near_outlier = 0;
  for (std::size_t i = 0; i < fit.surface.size(); ++i) {
    const Vec3& p = fit.surface.positions[i];
    const double s = fit.surface.strain[i];
    ASSERT_TRUE(std::isfinite(s) || std::abs(p.x()) > 20 || std::abs(p.y()) > 20) << p.transpose();
    element_tree.knn(p, 1, nn);
    const double d = std::sqrt(nn[0].distance_sq);
    if (std::abs(p.x()) > 20 || std::abs(p.y()) > 20) continue;  // within the grid
    // Around the outlier's neighbours (a pitch away from it), within their own half pitch.
    const double from_outlier = (p - carriers.positions[outlier]).norm();
    if (from_outlier > 1.5 * 2.54 && from_outlier < 3.5 * 2.54)
      worst_near_outlier = std::max(worst_near_outlier, std::abs(s - truth(p)));
    if (nn[0].index == outlier) continue;
    if (d > 0.4 * 2.54 && d < 0.6 * 2.54 && from_outlier > 2.54) between.push_back(s - truth(p));
  }
  const double own_rms = test::rmsOf(own), at_rms = test::rmsOf(at_elements), between_rms = test::rmsOf(between);
  std::printf("strain RMS: elements %.5f, the map at them %.5f, halfway between them %.5f; worst beside the outlier %.5f\n",
              own_rms, at_rms, between_rms, worst_near_outlier);
  EXPECT_LE(at_rms, own_rms);
  EXPECT_LE(between_rms, 1.5 * own_rms);
  EXPECT_LT(worst_near_outlier, 5 * noise);
  // The crest (0.22 between the columns at x = -2.24 and 0.3) is kept, not flattened.
  double crest = 0;
  for (std::size_t i = 0; i < fit.surface.size(); ++i)
    if (std::abs(fit.surface.positions[i].y()) < 10) crest = std::max(crest, fit.surface.strain[i]);
  EXPECT_NEAR(crest, 0.22, 0.006);
}

TEST(ShapeAndStrain, RefusesWhatItCannotFit) {
  const Cloud shape = test::sampleSphereCap(2000, kRadius, 0.35, 0.03, 1);
  const Cloud carriers = carriersOnCap(30.0, 0.01, 0.002, 2);
  EXPECT_THROW(fitShapeAndStrain(Cloud{}, carriers), std::invalid_argument);
  EXPECT_THROW(fitShapeAndStrain(shape, Cloud{}), std::invalid_argument);
  Cloud no_strain = carriers;
  no_strain.strain.clear();
  EXPECT_THROW(fitShapeAndStrain(shape, no_strain), std::invalid_argument);
  EXPECT_THROW(fitShapeAndStrain(carriers, carriers), std::invalid_argument);  // shape with strain
  ShapeAndStrainParams bad;
  bad.output_spacing_mm = 0;
  EXPECT_THROW(fitShapeAndStrain(shape, carriers, bad), std::invalid_argument);
}

}  // namespace
}  // namespace stampscan::fitting
