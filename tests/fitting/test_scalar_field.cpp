// The scalar attribute: Shepard's interpolant (Eqs. (15)-(16)) and the smooth WLS linear field.
#include "shapes.hpp"
#include "stampscan/fitting/scalar_field.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <gtest/gtest.h>

using namespace stampscan::fitting;
using namespace stampscan::fitting::test;

TEST(ScalarField, ShepardInterpolatesSmoothReproducesLinear) {
  std::vector<ScalarSample> samples;
  for (int i = -5; i <= 5; ++i)
    for (int j = -5; j <= 5; ++j) {
      const Vec3 p(i * 0.5, j * 0.5, 0.0);
      samples.push_back({p, 0.1 + 0.02 * p.x() - 0.03 * p.y(), std::exp(-p.squaredNorm() / 4.0)});
    }
  // At a data point Shepard returns the datum.
  EXPECT_DOUBLE_EQ(shepardScalar(samples[60].position, samples, 3.0), samples[60].value);
  // Between data points the smooth field reproduces a linear field exactly; Shepard does not.
  const Vec3 x(0.23, -0.41, 0.0);
  const double truth = 0.1 + 0.02 * x.x() - 0.03 * x.y();
  EXPECT_NEAR(smoothScalar(x, Vec3::UnitZ(), samples), truth, 1e-12);
  EXPECT_GT(std::abs(shepardScalar(x, samples, 3.0) - truth), 1e-5);
  EXPECT_TRUE(std::isnan(shepardScalar(Vec3(100, 0, 0), samples, 3.0)));
}

TEST(ScalarField, FitCarriesStrainOntoSurface) {
  // A linear strain field over a noisy plane; both fields recover it, the smooth one better.
  Cloud c = samplePlane(6000, 10.0, 0.02, 21);
  std::mt19937_64 rng(21);
  std::normal_distribution<double> noise(0.0, 0.01);
  for (const Vec3& p : c.positions) c.strain.push_back(-0.1 - 0.01 * p.x() + noise(rng));
  FitParams smooth;
  FitParams shepard;
  shepard.scalar = ScalarFieldType::Shepard;
  shepard.method = FitMethod::Apss;
  std::vector<double> e_smooth, e_shepard;
  const FitResult a = fitSurface(c, smooth);
  const FitResult b = fitSurface(c, shepard);
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (std::abs(c.positions[i].x()) > 8 || std::abs(c.positions[i].y()) > 8) continue;
    e_smooth.push_back(a.surface.strain[i] - (-0.1 - 0.01 * a.surface.positions[i].x()));
    e_shepard.push_back(b.surface.strain[i] - (-0.1 - 0.01 * b.surface.positions[i].x()));
  }
  EXPECT_LT(rmsOf(e_smooth), 0.002);
  EXPECT_LT(rmsOf(e_smooth), 0.5 * rmsOf(e_shepard));
}
