// The whole fit on the sample stamped pan against its true surface and strain, and the contract:
// one output point per input point, same order, the same result for any thread count.
#include "shapes.hpp"
#include "stampscan/fitting/surface_fit.hpp"
#include "stampscan/sim/sample_cloud.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

using namespace stampscan;
using namespace stampscan::fitting;
using namespace stampscan::fitting::test;

namespace {
const sim::SampleCloud& sample() {
  static const sim::SampleCloud s = [] {
    sim::SampleCloudParams p;
    p.target_points = 60000;
    p.seed = 7;
    return sim::makeSampleCloud(sim::PanPart{}, p);
  }();
  return s;
}

double strainRms(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> d(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) d[i] = a[i] - b[i];
  return rmsOf(d);
}
}  // namespace

TEST(SurfaceFit, DefaultMethodOnTheSamplePan) {
  const sim::PanPart part;
  const auto& s = sample();
  const FitResult r = fitSurface(s.cloud);
  ASSERT_EQ(r.surface.size(), s.cloud.size());
  const double raw = sim::surfaceError(part, s.cloud.positions).rms;
  const double fitted = sim::surfaceError(part, r.surface.positions).rms;
  std::printf("sample pan, %zu points: RMS %.4f -> %.4f mm\n", s.cloud.size(), raw, fitted);
  EXPECT_LT(fitted, 0.25 * raw);
  EXPECT_LT(fitted, 0.016);
  const double strain_raw = strainRms(s.cloud.strain, s.true_strain);
  const double strain_fit = strainRms(r.surface.strain, s.true_strain);
  EXPECT_LT(strain_fit, 0.6 * strain_raw);
  // Normals are unit and face the sensor side (+z) on the flange and floor.
  for (std::size_t i = 0; i < r.surface.size(); ++i) {
    ASSERT_NEAR(r.surface.normals[i].norm(), 1.0, 1e-9);
    const Vec3& q = r.surface.positions[i];
    ASSERT_GT(r.surface.normals[i].dot(part.normal(q.x(), q.y())), 0.7) << "point " << i << " at " << q.transpose();
  }
}

TEST(SurfaceFit, OutputKeepsOrderAndAttributes) {
  Cloud c = sampleSphereCap(3000, 20.0, 0.5, 0.02, 51);
  for (std::size_t i = 0; i < c.size(); ++i) c.strain.push_back(-0.01 * static_cast<double>(i % 7));
  c.scalars["major_strain"] = std::vector<double>(c.size(), 0.2);
  const FitResult r = fitSurface(c);
  ASSERT_EQ(r.surface.size(), c.size());
  ASSERT_EQ(r.surface.strain.size(), c.size());
  ASSERT_EQ(r.surface.scalars.at("major_strain").size(), c.size());
  for (std::size_t i = 0; i < c.size(); ++i) ASSERT_LT((r.surface.positions[i] - c.positions[i]).norm(), 0.2);
}

TEST(SurfaceFit, SameResultForAnyThreadCount) {
  const auto& s = sample();
  for (FitMethod m : {FitMethod::Auto, FitMethod::Apss}) {
    FitParams p;
    p.method = m;
    Cloud one, two;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
      one = fitSurface(s.cloud, p).surface;
    }
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
      two = fitSurface(s.cloud, p).surface;
    }
    ASSERT_EQ(one.size(), two.size());
    for (std::size_t i = 0; i < one.size(); ++i) {
      ASSERT_EQ(one.positions[i], two.positions[i]) << toString(m) << " point " << i;
      ASSERT_EQ(one.normals[i], two.normals[i]) << toString(m) << " point " << i;
      ASSERT_EQ(one.strain[i], two.strain[i]) << toString(m) << " point " << i;
    }
  }
}

TEST(SurfaceFit, BadInputIsRejected) {
  EXPECT_THROW(fitSurface(Cloud{}), std::invalid_argument);
  Cloud c = samplePlane(100, 1.0, 0.0, 52);
  c.positions[10].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fitSurface(c), std::invalid_argument);
  Cloud ok = samplePlane(100, 1.0, 0.0, 52);
  FitParams p;
  p.bandwidth = -1.0;
  EXPECT_THROW(fitSurface(ok, p), std::invalid_argument);
  ok.strain.resize(5);
  EXPECT_THROW(fitSurface(ok), std::invalid_argument);
  EXPECT_THROW(parseFitMethod("pcl"), std::invalid_argument);
}

TEST(SurfaceFit, TinyCloudsDoNotCrash) {
  for (std::size_t n : {1u, 2u, 5u, 12u}) {
    const Cloud c = samplePlane(n, 1.0, 0.0, 53);
    for (FitMethod m : {FitMethod::Auto, FitMethod::Apss, FitMethod::Euclidean, FitMethod::Sig, FitMethod::Gaussian}) {
      FitParams p;
      p.method = m;
      const FitResult r = fitSurface(c, p);
      ASSERT_EQ(r.surface.size(), n);
      for (const Vec3& q : r.surface.positions) ASSERT_TRUE(q.allFinite());
    }
  }
}

TEST(SurfaceFit, WideningMakesAccuracyGrowWithDensityOnASmoothPart) {
  // The punch-stretched dome is smooth all over: with four times the points at the same noise, the
  // widened bandwidth grows and the error falls by at least a fifth, and (almost) every projection
  // converges.
  const sim::DomePart dome;
  const sim::SampleShape shape = sim::sampleShape(dome);
  std::vector<double> rms;
  for (const std::size_t n : {40000, 160000}) {
    sim::SampleCloudParams p;
    p.target_points = n;
    p.seed = 21;
    const sim::SampleCloud s = sim::makeSampleCloud(shape, p);
    FitParams params;
    params.anchored.widen = true;
    const FitResult r = fitSurface(s.cloud, params);
    rms.push_back(sim::surfaceError(shape, r.surface.positions).rms);
    std::printf("dome, %zu points: RMS %.4f -> %.4f mm, median h %.2f mm, %zu not converged\n", s.cloud.size(),
                sim::surfaceError(shape, s.cloud.positions).rms, rms.back(), r.stats.bandwidth.median,
                r.stats.not_converged);
    EXPECT_LE(r.stats.not_converged, s.cloud.size() / 1000);
  }
  EXPECT_LT(rms[1], 0.8 * rms[0]);
}
