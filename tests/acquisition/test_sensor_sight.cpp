// What a sensor sees of a surface point during a plan's step (acquisition/sensor_sight.hpp): the one
// model the planner's prediction and the virtual cell's yardstick share. A flat sheet at z = 0 under
// the head, the sensors as drawn in the default cell file.
#include "stampscan/acquisition/sensor_sight.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace stampscan::acquisition {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180;

// Lines of sight that a test sets: everything clear, or blocked, or on a polished spot.
class ScriptedLines : public SightLines {
 public:
  explicit ScriptedLines(Sight answer) : answer_(answer) {}
  Sight sight(const Vec3&, const Vec3&) const override { return answer_; }

 private:
  Sight answer_;
};

const CellGeometry kCell{};
const LaserSight kLaser = laserSight(kCell.digitizer);
const StereoSight kStereo = stereoSight(kCell.cameras, 0.15);

// A sweep along +y with the mirror at the standoff above z = 0 (the head placed so), 100 mm long.
ScanPlan sweepPlan(double mirror_height) {
  const double head_z = mirror_height - kLaser.head_from_mirror.translation().z();
  ScanPlan plan;
  SweepStep sweep;
  sweep.start = {{0, -50, head_z}, 0, 0};
  sweep.end = {{0, 50, head_z}, 0, 0};
  sweep.speed = 25;
  plan.steps.push_back(sweep);
  return plan;
}

bool seesPoint(const SweepSight& s, const Vec3& q, const Vec3& normal, const SightLines* lines = nullptr,
               const LaserSight& laser = kLaser) {
  return laserSees(s, laser, std::span<const Vec3>(&q, 1), std::span<const Vec3>(&normal, 1), lines);
}

TEST(SensorSight, TheLaserSeesWhatItsFanCrossesWithinItsRangeAndNotInTheRunUps) {
  const PlanSight steps = planSight(sweepPlan(kLaser.standoff_mm), kLaser, kStereo, 1000);
  ASSERT_EQ(steps.sweeps.size(), 1u);
  const SweepSight& s = steps.sweeps[0];
  const Vec3 up = Vec3::UnitZ();
  EXPECT_TRUE(seesPoint(s, {0, 0, 0}, up));
  // Within the fan's half width at the standoff, not beyond it.
  const double half = kLaser.standoff_mm * std::tan(kLaser.half_fan_rad);
  EXPECT_TRUE(seesPoint(s, {0.9 * half, 0, 0}, up));
  EXPECT_FALSE(seesPoint(s, {1.1 * half, 0, 0}, up));
  // Within the measuring range along the ray, not beyond it.
  EXPECT_TRUE(seesPoint(s, {0, 0, 0.45 * kLaser.measuring_range_mm}, up));
  EXPECT_FALSE(seesPoint(s, {0, 0, -0.55 * kLaser.measuring_range_mm}, up));
  // The run-ups at either end measure nothing; past the sweep's end nothing either.
  const double run_up = sweepRunUp(25, 1000);
  EXPECT_FALSE(seesPoint(s, {0, -50 + 0.5 * run_up, 0}, up));
  EXPECT_TRUE(seesPoint(s, {0, -50 + 1.5 * run_up, 0}, up));
  EXPECT_FALSE(seesPoint(s, {0, 60, 0}, up));
}

TEST(SensorSight, TheLaserLosesSteepSurfacesAndWhatIsHiddenOrInGlare) {
  const SweepSight s = planSight(sweepPlan(kLaser.standoff_mm), kLaser, kStereo, 1000).sweeps.at(0);
  const double limit = kLaser.measurable_incidence_rad;
  const Vec3 within(std::sin(limit - 2 * kDeg), 0, std::cos(limit - 2 * kDeg));
  const Vec3 beyond(std::sin(limit + 2 * kDeg), 0, std::cos(limit + 2 * kDeg));
  EXPECT_TRUE(seesPoint(s, {0, 0, 0}, within));
  EXPECT_FALSE(seesPoint(s, {0, 0, 0}, beyond));

  const ScriptedLines blocked({false, false}), polished({true, true}), clear({true, false});
  EXPECT_TRUE(seesPoint(s, {0, 0, 0}, Vec3::UnitZ(), &clear));
  EXPECT_FALSE(seesPoint(s, {0, 0, 0}, Vec3::UnitZ(), &blocked));
  // A polished spot glares only where the sensor says it does, and only near normal incidence.
  EXPECT_TRUE(seesPoint(s, {0, 0, 0}, Vec3::UnitZ(), &polished));
  LaserSight glaring = kLaser;
  glaring.glare_incidence_rad = 20 * kDeg;
  EXPECT_FALSE(seesPoint(s, {0, 0, 0}, Vec3::UnitZ(), &polished, glaring));
  EXPECT_TRUE(seesPoint(s, {0, 0, 0}, Vec3(std::sin(30 * kDeg), 0, std::cos(30 * kDeg)), &polished, glaring));

  // An outline is seen whole only when every point of it is.
  const std::vector<Vec3> ring{{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}};
  std::vector<Vec3> normals(ring.size(), Vec3::UnitZ());
  EXPECT_TRUE(laserSees(s, kLaser, ring, normals, nullptr));
  normals[2] = beyond;
  EXPECT_FALSE(laserSees(s, kLaser, ring, normals, nullptr));
}

// A view from above at the cameras' convergence distance.
ViewSight viewFromAbove() {
  ScanPlan plan;
  const double head_z = kCell.cameras.drop_mm + kCell.cameras.convergence_mm;
  StereoStep view;
  view.pose = {{0, 0, head_z}, 0, 0};
  plan.steps.push_back(view);
  const PlanSight steps = planSight(plan, kLaser, kStereo, 1000);
  EXPECT_EQ(steps.views.size(), 1u);
  return steps.views.at(0);
}

TEST(SensorSight, TheStereoPairSeesWhatBothImagesHoldAtAnAngleTheyResolve) {
  const ViewSight view = viewFromAbove();
  EXPECT_TRUE(stereoSees(view, kStereo, {0, 0, 0}, Vec3::UnitZ(), {}, nullptr));
  // Far outside both images.
  EXPECT_FALSE(stereoSees(view, kStereo, {400, 0, 0}, Vec3::UnitZ(), {}, nullptr));
  // Tilted beyond the cameras' incidence limit.
  const double tilt = kStereo.max_incidence_rad + 5 * kDeg;
  EXPECT_FALSE(stereoSees(view, kStereo, {0, 0, 0}, {std::sin(tilt), 0, std::cos(tilt)}, {}, nullptr));
  // Hidden from one camera.
  const ScriptedLines blocked({false, false});
  EXPECT_FALSE(stereoSees(view, kStereo, {0, 0, 0}, Vec3::UnitZ(), {}, &blocked));
  // A printed line too thin for the images.
  StereoSight fine = kStereo;
  fine.line_width_mm = 0.01;
  EXPECT_FALSE(stereoSees(view, fine, {0, 0, 0}, Vec3::UnitZ(), {}, nullptr));
  // An outline straddling an image's edge is not seen whole, though its centre is inside.
  const StereoSight& s = kStereo;
  const auto inside = [&](std::size_t c, const Vec3& q) {
    const Eigen::Vector2d px = projectPixel(s.intrinsics[c], view.camera_from_frame[c] * q);
    return px.x() >= s.image_border_px && px.x() <= s.intrinsics[c].width - 1 - s.image_border_px;
  };
  double x_edge = 0;  // walk out along x until one camera loses the point
  for (double x = 0; x < 400 && x_edge == 0; x += 0.5)
    if (!inside(0, Vec3(x, 0, 0)) || !inside(1, Vec3(x, 0, 0))) x_edge = x;
  ASSERT_GT(x_edge, 0);
  const Vec3 centre(x_edge - 1.0, 0, 0);
  const std::vector<Vec3> ring{centre + Vec3(-2, 0, 0), centre + Vec3(2, 0, 0)};
  EXPECT_TRUE(stereoSees(view, kStereo, centre, Vec3::UnitZ(), {}, nullptr));
  EXPECT_FALSE(stereoSees(view, kStereo, centre, Vec3::UnitZ(), ring, nullptr));
}

TEST(SensorSight, ProjectionFollowsOpenCvsDistortionModel) {
  trace::CameraIntrinsicsRecord k{2048, 1536, 4600, 4600, 1023.5, 767.5, -0.08, 0.12, 0, 0, 0};
  // On the axis, the principal point; off it, radial distortion pulls a point in (k1 < 0 dominates).
  const Eigen::Vector2d centre = projectPixel(k, {0, 0, 300});
  EXPECT_NEAR(centre.x(), 1023.5, 1e-9);
  EXPECT_NEAR(centre.y(), 767.5, 1e-9);
  const double x = 0.1, r2 = x * x, radial = 1 + r2 * (-0.08 + r2 * 0.12);
  EXPECT_NEAR(projectPixel(k, {30, 0, 300}).x(), 4600 * x * radial + 1023.5, 1e-9);
}

}  // namespace
}  // namespace stampscan::acquisition
