// The stereo path against the ground truth: rings (or square cells) found in both images, matched
// with a depth prior, and measured on the plane where both views agree (or from the deformation
// gradient of the cell's triangulated nodes).
#include "session_support.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/registration/stereo_rings.hpp"
#include "stampscan/registration/stereo_squares.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>

namespace {

using namespace stampscan;

registration::CameraModel modelOf(const sim::CameraIntrinsics& c) {
  registration::CameraModel m;
  m.size = cv::Size(c.width, c.height);
  m.matrix = cv::Matx33d(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  m.distortion = (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3);
  return m;
}

struct StereoMeasured {
  std::size_t found = 0, false_found = 0, truth_in_view = 0, truth_found = 0;
  std::size_t without_prior = 0;  // rings in the left image with no prior to match them on
  std::size_t rejected = 0;       // matched rings left out: the views disagree, a poor fit, a bend too tight
  double position_rms = 0, strain_rms = 0;
};

// An element is in full view of a pair when a circle a little wider than its ring lies inside both
// images (clear of the border), neither camera's rays to it meet the part first, and both cameras
// see it within 60 degrees of its normal. Beyond that a ring's minor axis is under half its size
// and its line under a pixel wide in the image: such a wall is left to another view, or the laser.
bool inFullView(const sim::PartScene& scene, const Eigen::Vector3d& position, const Eigen::Vector3d& normal,
                const sim::CameraIntrinsics* cams[2], const Eigen::Isometry3d poses[2], double reach) {
  const Eigen::Matrix3d frame = fitting::frameAround(normal);
  for (int c = 0; c < 2; ++c) {
    if (normal.dot((poses[c].translation() - position).normalized()) < 0.5) return false;
    const Eigen::Isometry3d camera_from_machine = poses[c].inverse();
    for (int k = 0; k < 8; ++k) {
      const double th = 2 * std::numbers::pi * k / 8;
      const Eigen::Vector3d q = position + reach * (std::cos(th) * frame.col(0) + std::sin(th) * frame.col(1));
      const Eigen::Vector3d in_camera = camera_from_machine * q;
      if (in_camera.z() <= 0) return false;
      const Eigen::Vector2d px = cams[c]->project(in_camera);
      if (px.x() < 20 || px.y() < 20 || px.x() > cams[c]->width - 21 || px.y() > cams[c]->height - 21) return false;
      const Eigen::Vector3d eye = poses[c].translation();
      const auto hit = scene.cast({eye, (q - eye).normalized()}, 0.0);
      if (!hit || std::abs(hit->t - (q - eye).norm()) > 0.1) return false;
    }
  }
  return true;
}

// Where the pair looks: the quick session's two views over the middle of the part, or one view of
// a full session's outer corner, which stands out and tilts 20 degrees inwards over the pan's
// corner, its walls and its doubly curved radii.
enum class Views { Middle, Corner };

// How the images are searched: for elements of the size the prior's depth gives (the whole view in
// one call), or of the size at the pair's working distance, before any prior is known (as a scan
// searches each view's images when they arrive), then matched on the prior.
enum class Search { AtPriorDepth, AtWorkingDistance };

// `hole_radius` > 0 leaves the prior out within that distance (xy) of the views' middle, as where
// the laser lost a polished spot of the sheet to glare. `image_scale`: the cameras' resolution.
StereoMeasured runStereo(sim::PartKind kind, std::uint64_t seed, sim::GridKind grid = sim::GridKind::Circle,
                         Views views = Views::Middle, double hole_radius = 0, double image_scale = 1.0,
                         Search search = Search::AtPriorDepth) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.part = kind;
  p.grid.kind = grid;
  p.laser = p.calibration = false;
  p.image_scale = image_scale;
  p.seed = seed;
  if (views == Views::Corner) {
    // A one-view plan over this region stands where the full session's 3 x 3 plan puts its corner
    // view, (-48, -36) on the pan, and tilts as far.
    p.scan_region = {sim::Vec2(-64, -48), sim::Vec2(-32, -24)};
    p.stereo_rows = p.stereo_columns = 1;
  }
  test_support::DecodedSession s;
  const sim::ScanSummary summary = sim::generateScan(p, s);
  const sim::CellTruth& truth = summary.truth;
  // The true calibration: this test is about the rings, the calibration has its own.
  registration::StereoRig rig;
  rig.left = modelOf(truth.left);
  rig.right = modelOf(truth.right);
  rig.head_from_left = truth.head_from_left;
  rig.right_from_left = truth.head_from_right.inverse() * truth.head_from_left;
  const std::unique_ptr<sim::FormedPart> part = sim::makePart(p);
  const sim::PartScene scene(*part, p.grid);
  const fitting::Cloud t = sim::groundTruth(*part, p.grid);
  std::vector<Eigen::Vector3d> prior;
  const Eigen::Vector2d middle = 0.5 * (p.scan_region.min + p.scan_region.max);
  for (const auto& q : t.positions)
    if ((q.head<2>() - middle).norm() >= hole_radius) prior.push_back(q);
  const std::int64_t offset = s.clockOffset("camera_left");
  std::vector<registration::GridElement> found;
  registration::StereoStats stats;
  std::vector<bool> in_view(t.size(), false);
  std::uint32_t view = 0;
  for (const auto& [trigger, pair] : s.pairs) {
    EXPECT_TRUE(pair.complete());
    if (!pair.complete()) continue;
    const Eigen::Isometry3d head = s.headAt(pair.left.device_time_ns - offset).pose();
    // The part's own surface as the depth prior (in the station, the laser's).
    const cv::Mat left = test_support::DecodedSession::image(pair.left), right = test_support::DecodedSession::image(pair.right);
    // Stage 1 at the prior's depth (as a pair without vergence is searched) or at the pair's working
    // distance (as a scan searches each view when its frames arrive); then stages 2 and 3.
    const registration::StereoViewPose pose{.rig = rig, .machine_from_head = head, .prior = prior, .index = view};
    const std::optional<double> depth =
        search == Search::AtPriorDepth ? std::optional<double>(registration::priorDepth(pose)) : registration::workingDistance(rig);
    EXPECT_TRUE(depth && *depth > 0);
    if (!depth || !(*depth > 0)) return {};
    std::vector<registration::GridElement> g;
    if (grid == sim::GridKind::Circle) {
      const registration::RingDetectionParams params;
      g = registration::measureStereoPair(
          registration::detectStereoRings(left, right, registration::pixelsAtDepth(rig, params.printed_radius, *depth), params), pose,
          params, &stats);
    } else {
      const registration::SquareDetectionParams params;
      g = registration::measureStereoSquares(
          registration::detectStereoCells(left, right, registration::pixelsAtDepth(rig, params.pitch, *depth), params), pose,
          params, &stats);
    }
    ++view;
    found.insert(found.end(), g.begin(), g.end());
    const sim::CameraIntrinsics* cams[2] = {&truth.left, &truth.right};
    const Eigen::Isometry3d poses[2] = {head * truth.head_from_left, head * truth.head_from_right};
    for (std::size_t i = 0; i < t.size(); ++i)
      if (!in_view[i])
        in_view[i] = inFullView(scene, t.positions[i], t.normals[i], cams, poses, grid == sim::GridKind::Circle ? 1.7 : 2.0);
  }
  StereoMeasured m;
  m.found = found.size();
  m.without_prior = stats.without_prior;
  m.rejected = stats.rejected_fit;
  const fitting::KdTree tree(t.positions);
  std::vector<fitting::Neighbor> nn;
  double sq_pos = 0, sq_strain = 0, bias_major = 0, bias_minor = 0;
  std::vector<double> abs_err;
  for (const auto& g : found) {
    tree.knn(g.position, 1, nn);
    if (nn[0].distance_sq > 0.5 * 0.5) {
      ++m.false_found;
      continue;
    }
    sq_pos += nn[0].distance_sq;
    sq_strain += std::pow(g.thickness_strain - t.strain[nn[0].index], 2);
    bias_major += g.major_strain - t.scalars.at("major_strain")[nn[0].index];
    bias_minor += g.minor_strain - t.scalars.at("minor_strain")[nn[0].index];
    abs_err.push_back(std::abs(g.thickness_strain - t.strain[nn[0].index]));
  }
  std::vector<Eigen::Vector3d> found_positions;
  for (const auto& g : found) found_positions.push_back(g.position);
  if (!found_positions.empty()) {
    const fitting::KdTree found_tree(found_positions);
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (!in_view[i]) continue;
      ++m.truth_in_view;
      found_tree.knn(t.positions[i], 1, nn);
      if (!nn.empty() && nn[0].distance_sq < 0.5 * 0.5) ++m.truth_found;
    }
  }
  std::sort(abs_err.begin(), abs_err.end());
  const double n = std::max<double>(1, static_cast<double>(found.size() - m.false_found));
  m.position_rms = std::sqrt(sq_pos / n);
  m.strain_rms = std::sqrt(sq_strain / n);
  if (!abs_err.empty())
    std::printf("  thickness strain error: median %.4f, 90%% %.4f, max %.4f; bias major %.4f, minor %.4f\n",
                abs_err[abs_err.size() / 2], abs_err[abs_err.size() * 9 / 10], abs_err.back(), bias_major / n, bias_minor / n);
  std::printf("stereo %s %ss: %u pairs, %zu left %zu right, %zu measured (%zu without prior, %zu unmatched, %zu "
              "rejected: the views disagree or a poor fit), %zu false; %zu of %zu elements in full view found; "
              "position RMS %.4f mm, strain RMS %.4f\n",
              part->name().c_str(), sim::toString(grid).c_str(), view, stats.left_rings, stats.right_rings, found.size(), stats.without_prior,
              stats.unmatched, stats.rejected_fit, m.false_found, m.truth_found, m.truth_in_view, m.position_rms,
              m.strain_rms);
  return m;
}

// The goals of the registration issue: position RMS <= 0.05 mm, thickness strain RMS <= 0.005, no
// false elements, and 99 % of the elements in full view found.
void expectGoals(const StereoMeasured& m, std::size_t at_least = 2000) {
  EXPECT_GT(m.found, at_least);
  EXPECT_EQ(m.false_found, 0u);
  EXPECT_LE(m.position_rms, 0.05);
  EXPECT_LE(m.strain_rms, 0.005);
  EXPECT_GE(static_cast<double>(m.truth_found), 0.99 * static_cast<double>(m.truth_in_view));
}

TEST(StereoRings, DomeElementsMatchTheGroundTruth) { expectGoals(runStereo(sim::PartKind::Dome, 41)); }

// A hole in the prior as wide as the largest glare spot the laser loses (9 mm): the elements there
// are matched on the prior around it.
TEST(StereoRings, ElementsInAHoleOfThePriorAreFound) {
  const StereoMeasured m = runStereo(sim::PartKind::Dome, 47, sim::GridKind::Circle, Views::Middle, 4.5);
  expectGoals(m);
  EXPECT_EQ(m.without_prior, 0u);
}

// The pan's walls are seen at up to 60 degrees and its radii bend rings out of their plane. The
// rings over its 7 mm die radii (a sagitta of 0.07-0.11 mm on the sheet) are measured too: a die
// radius is where a part splits. With a bend limit of 0.06 mm a fifth of the matched rings here
// were left out, and some elements of the whole pan were seen by no measurement.
TEST(StereoRings, PanElementsMatchTheGroundTruth) {
  const StereoMeasured m = runStereo(sim::PartKind::Pan, 42);
  expectGoals(m);
  EXPECT_LE(static_cast<double>(m.rejected), 0.05 * static_cast<double>(m.found + m.rejected));
}

// Rings there are bent and strained unevenly, so no longer ellipses in the images: the line model's
// third harmonic follows them, and each is cast onto the curved sheet.
TEST(StereoRings, PanCornerViewElementsMatchTheGroundTruth) {
  expectGoals(runStereo(sim::PartKind::Pan, 45, sim::GridKind::Circle, Views::Corner), 700);
}

// A coarser camera (0.11 mm pixels, as the second cell's: the printed lines 1.3 px wide). Where two
// rings touch their lines run side by side, and the sheet level must bridge both, or the lines
// pass as interior and whole areas of rings join into one region: 58 % of the elements in view of
// both cameras were found so, 82 % now (each element is seen by several pairs of a scan). Each ring
// is seen by fewer pixels, so its strain is read worse than at the default resolution (0.0012).
TEST(StereoRings, ACoarseCameraFindsItsRings) {
  const StereoMeasured m = runStereo(sim::PartKind::Dome, 48, sim::GridKind::Circle, Views::Middle, 0, 0.6);
  EXPECT_EQ(m.false_found, 0u);
  EXPECT_LE(m.position_rms, 0.05);
  EXPECT_LE(m.strain_rms, 0.005);
  EXPECT_GE(static_cast<double>(m.truth_found), 0.8 * static_cast<double>(m.truth_in_view));
}

// A scan searches each view's images as they arrive, before the laser has measured the part: for
// elements of the size they have at the pair's working distance. The pan's floor and rim lie
// 20 mm nearer or further than that; its walls are seen at up to 60 degrees.
TEST(StereoRings, ImagesSearchedBeforeThePriorIsKnownMeetTheGoals) {
  expectGoals(runStereo(sim::PartKind::Pan, 42, sim::GridKind::Circle, Views::Middle, 0, 1.0, Search::AtWorkingDistance));
}
TEST(StereoSquares, ImagesSearchedBeforeThePriorIsKnownMeetTheGoals) {
  expectGoals(runStereo(sim::PartKind::Pan, 44, sim::GridKind::Square, Views::Middle, 0, 1.0, Search::AtWorkingDistance));
}

// The working distance is where the two optical axes cross, along the left one: 60 mm either side
// of the middle, crossing 300 mm below, sqrt(60^2 + 300^2) from each camera. A pair without
// vergence has none.
TEST(StereoRig, TheWorkingDistanceIsWhereTheOpticalAxesCross) {
  const auto looking_at = [](const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
    const Eigen::Vector3d z = (target - eye).normalized(), x = Eigen::Vector3d::UnitY().cross(z).normalized();
    Eigen::Isometry3d head_from_camera = Eigen::Isometry3d::Identity();
    head_from_camera.linear() << x, z.cross(x), z;
    head_from_camera.translation() = eye;
    return head_from_camera;
  };
  registration::StereoRig rig;
  const Eigen::Vector3d target(0, 0, 300);
  rig.head_from_left = looking_at({-60, 0, 0}, target);
  const Eigen::Isometry3d head_from_right = looking_at({60, 0, 0}, target);
  rig.right_from_left = head_from_right.inverse() * rig.head_from_left;
  const std::optional<double> depth = registration::workingDistance(rig);
  ASSERT_TRUE(depth.has_value());
  EXPECT_NEAR(*depth, std::hypot(60.0, 300.0), 1e-9);
  rig.right_from_left = Eigen::Isometry3d(Eigen::Translation3d(-120, 0, 0));
  EXPECT_FALSE(registration::workingDistance(rig).has_value());
}

TEST(StereoSquares, DomeCellsMatchTheGroundTruth) {
  expectGoals(runStereo(sim::PartKind::Dome, 43, sim::GridKind::Square));
}
TEST(StereoSquares, PanCellsMatchTheGroundTruth) {
  expectGoals(runStereo(sim::PartKind::Pan, 44, sim::GridKind::Square));
}
// A cell's sides over the radii are arcs, longer than the chords between its nodes.
TEST(StereoSquares, PanCornerViewCellsMatchTheGroundTruth) {
  expectGoals(runStereo(sim::PartKind::Pan, 46, sim::GridKind::Square, Views::Corner), 700);
}

}  // namespace
