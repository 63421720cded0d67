// Point-to-plane ICP: exact recovery of a known motion on a simulated part, robustness to partial
// overlap and outliers, and convergence to one pose from several starts on two real partial scans.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/registration/icp.hpp"
#include "stampscan/sim/formed_part.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

namespace {

using namespace stampscan;
using registration::Vec3;

Eigen::Isometry3d motion(double angle_deg, const Vec3& axis, const Vec3& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

double rotationAngle(const Eigen::Isometry3d& T) { return Eigen::AngleAxisd(T.linear()).angle(); }

// Points of the simulated stamped pan on a grid of machine xy, with noise. (Not the dome: a surface
// of revolution cannot pin down a rotation about its axis.)
std::vector<Vec3> panPoints(double x0, double x1, double step, double noise, std::uint64_t seed) {
  const sim::StampedPanPart pan;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Vec3> out;
  for (double x = x0; x <= x1; x += step)
    for (double y = -60; y <= 60; y += step)
      out.push_back(pan.surfacePoint(x, y) + noise * Vec3(g(rng), g(rng), g(rng)));
  return out;
}

TEST(PointToPlaneIcp, RecoversAKnownMotionOfAPartialOverlap) {
  // Target: the left 2/3 of the pan; source: the right 2/3, moved by a known motion (a view whose
  // known pose is off by a few degrees and millimetres).
  const std::vector<Vec3> target = panPoints(-70, 25, 1.0, 0.005, 1);
  const std::vector<Vec3> truth_points = panPoints(-25, 70, 1.1, 0.005, 2);
  const Eigen::Isometry3d truth = motion(4, Vec3(1, 2, 3), Vec3(2.0, -1.5, 1.0));
  std::vector<Vec3> source;
  for (const Vec3& p : truth_points) source.push_back(truth.inverse() * p);
  // Outliers: 2 % of the source displaced by up to 5 mm.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5, 5);
  for (std::size_t i = 0; i < source.size(); i += 50) source[i] += Vec3(u(rng), u(rng), u(rng));
  const registration::PointToPlaneIcp icp(target);
  registration::IcpParams params;
  params.max_correspondence_distance = 8;
  const registration::IcpResult r = icp.align(source, Eigen::Isometry3d::Identity(), params);
  EXPECT_TRUE(r.converged);
  const Eigen::Isometry3d error = r.transform * truth.inverse();
  EXPECT_LT(rotationAngle(error), 2e-4);           // rad
  EXPECT_LT(error.translation().norm(), 0.02);     // mm: the 1 mm sampling of curved walls limits it
  EXPECT_LT(r.rmse, 0.02);
  EXPECT_GT(r.fitness, 0.4);
}

// Grid elements measured twice (laser and stereo) on a flat floor: across the sheet both views agree
// whatever their offset along it, so point-to-plane cannot see a sideways shift; the elements pair
// one-to-one, and with their offset along the sheet counted too the shift is recovered.
TEST(PointToPlaneIcp, TangentialWeightRecoversASlideOfPairedElements) {
  std::vector<Vec3> target, source;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 0.01);
  const Vec3 slide(0.08, -0.05, 0.02);  // mm: a view's known pose, off by a little
  for (int i = -15; i <= 15; ++i)
    for (int j = -15; j <= 15; ++j) {
      const Vec3 p(2.54 * i, 2.54 * j, 0);
      target.push_back(p + Vec3(g(rng), g(rng), g(rng)));
      source.push_back(p - slide + Vec3(g(rng), g(rng), g(rng)));
    }
  const registration::PointToPlaneIcp icp(target, std::vector<Vec3>(target.size(), Vec3::UnitZ()));
  registration::IcpParams params;
  params.max_correspondence_distance = 1.0;
  const registration::IcpResult plane = icp.align(source, Eigen::Isometry3d::Identity(), params);
  params.tangential_weight = 1.0;
  const registration::IcpResult both = icp.align(source, Eigen::Isometry3d::Identity(), params);
  std::printf("slide left after point-to-plane %.4f mm, with the offset along the sheet %.4f mm\n",
              (plane.transform.translation() - slide).norm(), (both.transform.translation() - slide).norm());
  EXPECT_GT((plane.transform.translation() - slide).head<2>().norm(), 0.05);  // along the floor: unseen
  EXPECT_NEAR(plane.transform.translation().z(), slide.z(), 0.003);
  EXPECT_TRUE(both.converged);
  EXPECT_LT((both.transform.translation() - slide).norm(), 0.003);
  EXPECT_LT(rotationAngle(both.transform), 1e-4);
}

TEST(PointToPlaneIcp, RejectsTooSmallTargets) {
  const std::vector<Vec3> tiny(3, Vec3::Zero());
  EXPECT_THROW(registration::PointToPlaneIcp icp(tiny), std::invalid_argument);
}

// The two overlapping partial scans of a hippo from CGAL's data (real scanner data that nobody here
// made). There is no ground truth: the test checks that perturbed starts all converge to one pose.
TEST(PointToPlaneIcp, HippoScansConvergeToOnePoseFromSeveralStarts) {
  const std::filesystem::path dir = STAMPSCAN_HIPPO_DIR;
  if (!std::filesystem::exists(dir / "hippo1.ply") || !std::filesystem::exists(dir / "hippo2.ply"))
    GTEST_SKIP() << "hippo scans not found in " << dir << " (install Debian's libcgal-demo, which ships "
                 << STAMPSCAN_CGAL_ARCHIVE << ", and re-run cmake)";
  const fitting::Cloud target = fitting::readPly(dir / "hippo1.ply");
  const fitting::Cloud source = fitting::readPly(dir / "hippo2.ply");
  ASSERT_TRUE(target.hasNormals());
  const registration::PointToPlaneIcp icp(target.positions, target.normals);
  const double diag = icp.diagonal();
  registration::IcpParams params;
  params.max_correspondence_distance = 0.05 * diag;
  // The reference: from the scans' own placement.
  const registration::IcpResult reference = icp.align(source.positions, Eigen::Isometry3d::Identity(), params);
  ASSERT_TRUE(reference.converged);
  std::printf("hippo: %zu + %zu points, diagonal %.4f; residual RMS %.5f (%.3f %% of the diagonal), overlap %.0f %%, "
              "%d iterations\n",
              target.size(), source.size(), diag, reference.rmse, 100 * reference.rmse / diag, 100 * reference.fitness,
              reference.iterations);
  EXPECT_LT(reference.rmse, 0.005 * diag);
  EXPECT_GT(reference.fitness, 0.3);
  // Starts perturbed by up to 10 degrees and 3 % of the diagonal about the reference.
  const Vec3 centre = fitting::boundsOf(source.positions).min + 0.5 * fitting::boundsOf(source.positions).extent();
  int starts = 0;
  for (const auto& [angle, axis, shift] : {std::tuple{6.0, Vec3(1, 0, 0), Vec3(0.02, 0, 0)},
                                           std::tuple{-8.0, Vec3(0, 1, 0), Vec3(0, -0.03, 0.01)},
                                           std::tuple{10.0, Vec3(0, 0, 1), Vec3(-0.01, 0.02, 0)},
                                           std::tuple{-5.0, Vec3(1, 1, 0), Vec3(0.01, 0.01, -0.02)},
                                           std::tuple{7.0, Vec3(1, -1, 1), Vec3(-0.02, 0, 0.02)}}) {
    // Rotate about the source's centre so that the angle does not also swing it far away.
    const Eigen::Isometry3d about = Eigen::Translation3d(centre) * motion(angle, axis, Vec3::Zero()) *
                                    Eigen::Translation3d(-centre);
    Eigen::Isometry3d start = reference.transform * about;
    start.translation() += shift * diag;
    const registration::IcpResult r = icp.align(source.positions, start, params);
    const Eigen::Isometry3d diff = r.transform * reference.transform.inverse();
    EXPECT_LT(rotationAngle(diff), 1e-3) << "start " << starts;
    EXPECT_LT(diff.translation().norm(), 1e-3 * diag) << "start " << starts;
    ++starts;
  }
  EXPECT_EQ(starts, 5);
}

}  // namespace
