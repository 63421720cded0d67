// WLS projection: Eqs. (1), (2), (6), (7) and Ahn's iteration, on analytic surfaces.
#include "shapes.hpp"
#include "stampscan/fitting/local_fit.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <gtest/gtest.h>

using namespace stampscan::fitting;
using namespace stampscan::fitting::test;

TEST(LocalFit, PlaneIsWeightedMeanAndSmallestEigenvector) {
  // Eq. (2): a is the weighted mean; Eqs. (6)-(7): n the least-variance direction.
  const Cloud c = samplePlane(200, 5.0, 0.0, 1);
  const Vec3 origin(0.3, -0.2, 1.0);
  WeightedSums sums(origin, 2.0);
  Vec3 expected_mean = Vec3::Zero();
  double w_total = 0;
  for (const Vec3& p : c.positions) {
    const double w = std::exp(-(p - origin).squaredNorm() / 4.0);
    sums.add(p, w);
    expected_mean += w * p;
    w_total += w;
  }
  expected_mean /= w_total;
  const auto plane = LocalSurface::fitPlane(sums);
  ASSERT_TRUE(plane);
  EXPECT_NEAR((plane->weightedMean() - expected_mean).norm(), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(plane->normal(origin).z()), 1.0, 1e-12);
  // Eq. (1): f(P*) = n.(a - P*); the projection of origin lands on z = 0.
  EXPECT_NEAR(plane->project(origin).z(), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(plane->signedDistance(origin)), 1.0, 1e-12);
}

TEST(LocalFit, CoincidentPointsDefineNoPlane) {
  WeightedSums sums(Vec3::Zero(), 1.0);
  for (int i = 0; i < 5; ++i) sums.add(Vec3(1, 2, 3), 1.0);
  EXPECT_FALSE(LocalSurface::fitPlane(sums));
}

TEST(LocalFit, SphereFitsRecoverRadius) {
  const Cloud c = sampleSphereCap(400, 10.0, 0.6, 0.0, 2);
  AlgebraicMoments moments(Vec3(0, 0, 10), 3.0);
  for (const Vec3& p : c.positions) moments.add(p, 1.0);
  const auto fit = LocalSurface::fitPrattSphere(moments);
  ASSERT_TRUE(fit);
  EXPECT_NEAR(std::abs(fit->curvature()), 0.1, 1e-9);
  EXPECT_NEAR(fit->project(Vec3(1, 2, 12)).norm(), 10.0, 1e-7);  // Pratt fit is regularised by 1e-10
}

namespace {
double maxSphereError(const Cloud& out, double R) {
  double e = 0;
  for (const Vec3& p : out.positions) e = std::max(e, std::abs(p.norm() - R));
  return e;
}
}  // namespace

TEST(Projection, PlaneFitShrinksAtCurvatureSphereDoesNot) {
  // Noise-free sphere of radius 10: the plane of Eq. (1) cuts inside the sphere (the shrinkage the
  // paper sees at peaks); the algebraic sphere lies on it.
  const Cloud c = sampleSphereCap(3000, 10.0, 0.8, 0.0, 3);
  FitParams plane;
  plane.method = FitMethod::Euclidean;
  plane.bandwidth = 2.0;
  FitParams sphere = plane;
  sphere.model = SurfaceModel::Sphere;
  const FitResult a = fitSurface(c, plane);
  const FitResult b = fitSurface(c, sphere);
  EXPECT_GT(maxSphereError(a.surface, 10.0), 0.01);
  EXPECT_LT(maxSphereError(b.surface, 10.0), 1e-4);
  // Normals are radial, except that a plane tilts where the cap's open edge makes it one-sided.
  for (const Cloud* out : {&a.surface, &b.surface}) {
    for (std::size_t i = 0; i < out->size(); ++i) {
      if (c.positions[i].normalized().z() > std::cos(0.6)) {
        EXPECT_GT(out->normals[i].dot(c.positions[i].normalized()), 0.995) << "normal " << i;
      }
    }
  }
}

TEST(Projection, AhnIterationConvergesInAFewSteps) {
  const Cloud c = samplePlane(4000, 10.0, 0.05, 4);
  FitParams p;
  p.method = FitMethod::Euclidean;
  p.bandwidth = 1.0;
  const FitResult r = fitSurface(c, p);
  EXPECT_EQ(r.stats.not_converged, 0u);
  EXPECT_GE(r.stats.mean_iterations, 1.0);
  EXPECT_LE(r.stats.mean_iterations, 5.0);  // the paper sees 3-4
  // Every projected point is a zero of f (Eq. (1)): projecting it again does not move it.
  FittedSurface fitted(c, p);
  for (std::size_t i = 0; i < c.size(); i += 199) {
    const Projection again = fitted.surface().project(r.surface.positions[i]);
    EXPECT_LT((again.point - r.surface.positions[i]).norm(), 1e-4);
  }
  // Noise is averaged away: residual height well below the 0.05 mm of the data.
  std::vector<double> z;
  for (const Vec3& q : r.surface.positions) z.push_back(q.z());
  EXPECT_LT(rmsOf(z), 0.015);
}

TEST(Projection, CylinderWithSphereModel) {
  // A sphere cannot take the two different curvatures of a cylinder, but on a symmetric
  // neighbourhood its error at the centre cancels to first order; what remains comes from the
  // random sampling. The plane of Eq. (1) shrinks by about h^2 / (2R) instead.
  const Cloud c = sampleCylinder(6000, 8.0, 10.0, 0.0, 5);
  const auto worstError = [&](std::optional<SurfaceModel> model) {
    FitParams p;
    p.method = FitMethod::Euclidean;
    p.bandwidth = 1.5;
    p.model = model;
    const FitResult r = fitSurface(c, p);
    double worst = 0;
    for (std::size_t i = 0; i < c.size(); ++i) {
      const Vec3& q = r.surface.positions[i];
      // Away from the open ends and edges, where the neighbourhood is one-sided.
      if (std::abs(q.y()) > 7.0 || std::abs(q.x()) > 8.0 * std::cos(0.3 * std::numbers::pi)) continue;
      worst = std::max(worst, std::abs(std::hypot(q.x(), q.z()) - 8.0));
    }
    return worst;
  };
  const double sphere = worstError(SurfaceModel::Sphere);
  const double plane = worstError(SurfaceModel::Plane);
  EXPECT_LT(sphere, 0.01);
  EXPECT_LT(sphere, 0.2 * plane);
}

TEST(Projection, RobustReweightingIgnoresOutliers) {
  Cloud c = samplePlane(5000, 10.0, 0.02, 6);
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(0.5, 2.0);
  std::vector<bool> outlier(c.size(), false);
  for (std::size_t i = 0; i < c.size(); i += 20) {
    c.positions[i].z() += u(rng);
    outlier[i] = true;
  }
  FitParams robust;
  robust.method = FitMethod::Apss;
  robust.bandwidth = 1.5;
  FitParams plain = robust;
  plain.robust = false;
  const auto rms = [&](const FitResult& r, bool outliers) {
    std::vector<double> z;
    for (std::size_t i = 0; i < c.size(); ++i)
      if (outlier[i] == outliers) z.push_back(r.surface.positions[i].z());
    return rmsOf(z);
  };
  const FitResult with = fitSurface(c, robust);
  const FitResult without = fitSurface(c, plain);
  EXPECT_LT(rms(with, false), 0.005);
  EXPECT_LT(rms(with, false), 0.3 * rms(without, false));
  // The default method also carries the outliers themselves onto the surface.
  const FitResult by_default = fitSurface(c);
  EXPECT_LT(rms(by_default, false), 0.005);
  EXPECT_LT(rms(by_default, true), 0.01);
}
