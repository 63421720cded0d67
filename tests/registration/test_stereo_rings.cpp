// The stereo path against the ground truth: rings found in both images, matched with a depth prior,
// triangulated and measured on the surface's tangent plane.
#include "session_support.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/registration/stereo_rings.hpp"
#include "stampscan/sim/grid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace {

using namespace stampscan;

registration::CameraModel modelOf(const sim::CameraIntrinsics& c) {
  registration::CameraModel m;
  m.size = cv::Size(c.width, c.height);
  m.matrix = cv::Matx33d(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  m.distortion = (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3);
  return m;
}

void runStereo(sim::PartKind kind, std::uint64_t seed) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.part = kind;
  p.laser = p.calibration = false;
  p.image_scale = 1.0;
  p.seed = seed;
  test_support::DecodedSession s;
  const sim::ScanSummary summary = sim::generateScan(p, s);
  const sim::CellTruth& truth = summary.truth;
  registration::StereoRig rig;
  rig.left = modelOf(truth.left);
  rig.right = modelOf(truth.right);
  rig.head_from_left = truth.head_from_left;
  rig.right_from_left = truth.head_from_right.inverse() * truth.head_from_left;
  const std::unique_ptr<sim::FormedPart> part = sim::makePart(p);
  const fitting::Cloud t = sim::groundTruth(*part, p.grid);
  const std::int64_t offset = s.clockOffset("camera_left");
  std::vector<registration::GridElement> found;
  registration::StereoStats stats;
  std::uint32_t view = 0;
  for (const auto& [trigger, pair] : s.pairs) {
    ASSERT_TRUE(pair.complete());
    const Eigen::Isometry3d head = s.headAt(pair.left.device_time_ns - offset).pose();
    const auto g = registration::measureStereoPair(test_support::DecodedSession::image(pair.left),
                                                   test_support::DecodedSession::image(pair.right), rig, head,
                                                   t.positions, {}, view++, &stats);
    found.insert(found.end(), g.begin(), g.end());
  }
  const fitting::KdTree tree(t.positions);
  std::vector<fitting::Neighbor> nn;
  double sq_pos = 0, sq_strain = 0, bias_major = 0, bias_minor = 0;
  std::vector<double> abs_err;
  std::size_t false_found = 0;
  for (const auto& g : found) {
    tree.knn(g.position, 1, nn);
    if (nn[0].distance_sq > 0.5 * 0.5) {
      ++false_found;
      continue;
    }
    sq_pos += nn[0].distance_sq;
    sq_strain += std::pow(g.thickness_strain - t.strain[nn[0].index], 2);
    bias_major += g.major_strain - t.scalars.at("major_strain")[nn[0].index];
    bias_minor += g.minor_strain - t.scalars.at("minor_strain")[nn[0].index];
    abs_err.push_back(std::abs(g.thickness_strain - t.strain[nn[0].index]));
  }
  std::sort(abs_err.begin(), abs_err.end());
  if (!abs_err.empty())
    std::printf("  strain error median %.4f, 90%% %.4f, max %.4f; bias major %.4f minor %.4f\n", abs_err[abs_err.size() / 2],
                abs_err[abs_err.size() * 9 / 10], abs_err.back(), bias_major / static_cast<double>(abs_err.size()),
                bias_minor / static_cast<double>(abs_err.size()));
  const double n = std::max<double>(1, static_cast<double>(found.size() - false_found));
  std::printf("stereo %s: %u views, rings %zu left %zu right, %zu measured (%zu without prior, %zu unmatched, %zu poor "
              "fits), %zu false; position RMS %.4f mm, strain RMS %.4f\n",
              part->name().c_str(), view, stats.left_rings, stats.right_rings, found.size(), stats.without_prior,
              stats.unmatched, stats.rejected_fit, false_found, std::sqrt(sq_pos / n), std::sqrt(sq_strain / n));
  EXPECT_GT(found.size(), 2000u);
  EXPECT_EQ(false_found, 0u);
  // Where the stereo path stands today, not the goal (0.05 mm, 0.005): the printed lines are only
  // 2-3 pixels wide in these images, and the line's position is found to about 0.1 px, which is
  // about 1 % of a ring's radius. The laser path meets the goal; see the issue notes.
  EXPECT_LE(std::sqrt(sq_pos / n), 0.08);
  EXPECT_LE(std::sqrt(sq_strain / n), 0.035);
}

TEST(StereoRings, DomeElementsMatchTheGroundTruth) { runStereo(sim::PartKind::Dome, 41); }
TEST(StereoRings, PanElementsMatchTheGroundTruth) { runStereo(sim::PartKind::Pan, 42); }

}  // namespace
