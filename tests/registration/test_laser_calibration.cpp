// The laser path: head track and profile geometry, and the digitizer's mount and latency recovered
// from the simulator's reference-sphere sweeps, against the simulator's truth.
#include "session_support.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/laser_geometry.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace {

using namespace stampscan;
using test_support::profileOf;
using test_support::trackOf;



TEST(LaserGeometry, HeadPoseMatchesTheSimulatorsKinematics) {
  for (const auto& [a, b] : {std::pair{0.0, 0.0}, std::pair{0.3, -0.2}, std::pair{-0.35, 1.2}}) {
    const sim::HeadState h{Eigen::Vector3d(10, -20, 300), a, b, 0};
    EXPECT_TRUE(trace::headPose(h.position, a, b).isApprox(h.pose(), 1e-15));
  }
}

TEST(LaserGeometry, TrackRejectsUnorderedReportsAndTimesOutside) {
  EXPECT_THROW(registration::HeadTrack({{0, Eigen::Vector3d::Zero(), 0, 0}}), std::invalid_argument);
  EXPECT_THROW(registration::HeadTrack({{5, Eigen::Vector3d::Zero(), 0, 0}, {5, Eigen::Vector3d::Zero(), 0, 0}}),
               std::invalid_argument);
  const registration::HeadTrack track({{0, Eigen::Vector3d::Zero(), 0, 0}, {10, Eigen::Vector3d(10, 0, 0), 0, 0}});
  EXPECT_NEAR(track.at(4).position.x(), 4.0, 1e-12);
  EXPECT_THROW(track.at(11), std::out_of_range);
}

TEST(DigitizerCalibration, RecoversMountAndLatencyFromSphereSweeps) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.laser = p.stereo = false;
  p.plate_poses = 0;
  p.sphere_sweeps = 8;
  p.seed = 21;
  test_support::DecodedSession s;
  const sim::ScanSummary summary = sim::generateScan(p, s);
  const sim::CellTruth& truth = summary.truth;
  const registration::HeadTrack track = trackOf(s);
  std::vector<registration::Profile> profiles;
  for (const auto& m : s.profiles) profiles.push_back(profileOf(m));
  ASSERT_GT(profiles.size(), 1000u);

  registration::SphereCalibrationParams params;
  params.sphere_radius = p.sphere.radius;
  params.nominal.head_from_digitizer = truth.head_from_digitizer_nominal;
  params.nominal.clock_offset_ns = s.clockOffset("digitizer");
  const registration::SphereCalibrationResult r = registration::calibrateDigitizer(profiles, track, params);

  const Eigen::Isometry3d error = r.calibration.head_from_digitizer * truth.head_from_digitizer.inverse();
  const double latency_error_ms = static_cast<double>(r.calibration.latency_ns - truth.digitizer_latency_ns) * 1e-6;
  std::printf("sphere calibration: %zu points (%zu inliers), rms %.4f mm, %d iterations\n", r.points, r.inliers, r.rms_mm,
              r.iterations);
  std::printf("  mount error %.4f mm, %.4f deg; latency %.3f ms (true %.3f); clock offset error %.3f ms; centre error %.4f mm\n",
              (r.calibration.head_from_digitizer.translation() - truth.head_from_digitizer.translation()).norm(),
              Eigen::AngleAxisd(error.linear()).angle() * 180 / M_PI, static_cast<double>(r.calibration.latency_ns) * 1e-6,
              static_cast<double>(truth.digitizer_latency_ns) * 1e-6,
              static_cast<double>(params.nominal.clock_offset_ns - truth.digitizer_clock_offset_ns) * 1e-6,
              (r.sphere_centre - truth.sphere.centre).norm());
  EXPECT_LT((r.calibration.head_from_digitizer.translation() - truth.head_from_digitizer.translation()).norm(), 0.02);
  EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 1e-4);  // 0.006 degrees
  EXPECT_LT(std::abs(latency_error_ms), 0.05);
  EXPECT_LT((r.sphere_centre - truth.sphere.centre).norm(), 0.05);
  EXPECT_LT(r.rms_mm, 0.015);
}

}  // namespace
