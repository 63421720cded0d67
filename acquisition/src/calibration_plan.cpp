#include "stampscan/acquisition/calibration_plan.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numbers>
#include <random>
#include <stdexcept>
#include <variant>
#include <vector>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;

Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

// The articulating head's rotation at tilt a and turn b (the trace's convention).
Eigen::Matrix3d headRotation(double a, double b) { return trace::headPose(Vec3::Zero(), a, b).linear(); }

class ScenePlanner {
 public:
  ScenePlanner(const CellGeometry& cell, const MachineLimits& limits, ScanPlan& plan)
      : cell_(cell), limits_(limits), plan_(plan), mount_(trace::toIsometry(toRigidPose(cell.digitizer.mount))) {}

  void plateViews(int count, std::uint64_t seed) {
    std::mt19937_64 rng(seed * 0x2545F4914F6CDD1Dull + 0x9Aull);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const PlateArtefact& plate = cell_.plate;
    const Vec3 centre_on_plate(0.5 * (plate.columns - 1) * plate.pitch_mm, 0.5 * (plate.rows - 1) * plate.pitch_mm, 0);
    const Eigen::Isometry3d plate_pose = trace::toIsometry(machineFromPlate(plate));
    const double drop = cell_.cameras.drop_mm, distance = cell_.cameras.convergence_mm;
    // The head turns with the plate's own turn on the table, so that the plate looks upright to the
    // cameras whatever its placement.
    const double plate_turn = std::atan2(plate_pose.linear()(1, 0), plate_pose.linear()(0, 0));
    for (int k = 0; k < count; ++k) {
      // Turns within +-30 degrees of it: the plate then stays within +-45 degrees of upright in the
      // image, where its dots are numbered unambiguously. An indexing head takes its nearest stops.
      const double a = stop(0.4 * u(rng)), b = stop(plate_turn + 0.5 * u(rng));
      const Vec3 target = plate_pose * (centre_on_plate + Vec3(8 * u(rng), 8 * u(rng), 0));
      const Vec3 head = target + headRotation(a, b) * Vec3(0, 0, drop + distance * (1 + 0.1 * u(rng)));
      StereoStep v;
      v.scene = Scene::CalibrationPlate;
      v.index = static_cast<std::uint32_t>(k);
      v.pose = {{head.x(), head.y(), head.z()}, a, b};
      v.settle_s = 0.4;
      plan_.steps.emplace_back(v);
    }
  }

  void sphereSweeps(const Vec3& centre_of_ball, double radius, Scene scene, int count) {
    struct Sweep {
      double b, a, speed, direction, lateral, depth;
    };
    const double quarter = std::numbers::pi / 2;
    const Sweep sweeps[] = {{0, 0, 10, 1, -12, 0},    {quarter, 0.3, 40, -1, 12, 8}, {0, -0.3, 40, 1, 0, 15},
                            {quarter, 0, 10, -1, 0, -15}, {0, 0.3, 10, -1, 8, -8},   {quarter, -0.3, 40, 1, -8, 0},
                            {0, 0, 40, -1, 4, 12},      {quarter, 0.3, 10, 1, -4, -12}};
    // The fan positions and depths above are for the drawn fan and range; a narrower sensor gets
    // them scaled to its own.
    const double half_fan = 0.5 * stripeWidth(cell_.digitizer);
    const double lateral_scale = std::min(1.0, 0.8 * half_fan / 12.0);
    const double depth_scale = std::min(1.0, 0.4 * cell_.digitizer.measuring_range_mm / 15.0);
    for (int k = 0; k < count; ++k) {
      // Beyond the eight patterns, each further round turns the head on by an eighth of a turn and
      // crosses the fan on the other side: new sweeps, not repeats of the first ones.
      const Sweep& s = sweeps[k % 8];
      const int round = k / 8;
      const double a = stop(s.a), b = stop(std::remainder(s.b + round * std::numbers::pi / 4, 2 * std::numbers::pi));
      const double lateral = (round % 2 == 0 ? 1 : -1) * s.lateral;
      const Eigen::Matrix3d R = headRotation(a, b) * mount_.linear();  // the sensor's axes, machine frame
      // The mirror above the ball, offset across the fan and along the view.
      const Vec3 centre = centre_of_ball + (cell_.digitizer.standoff_mm + depth_scale * s.depth) * R.col(2) -
                          lateral_scale * lateral * R.col(0);
      const Vec3 along = s.direction * (radius + 8) * R.col(1);
      SweepStep w;
      w.scene = scene;
      w.index = static_cast<std::uint32_t>(k);
      w.start = headAt(centre - along, a, b);
      w.end = headAt(centre + along, a, b);
      w.speed = s.speed;
      plan_.steps.emplace_back(w);
    }
  }

 private:
  double stop(double angle) const { return nearestHeadStop(angle, limits_); }
  // The head pose that puts the digitizer's mirror at `sensor` (its drawn mount).
  HeadPose headAt(const Vec3& sensor, double a, double b) const {
    const Vec3 head = sensor - headRotation(a, b) * mount_.translation();
    return {{head.x(), head.y(), head.z()}, a, b};
  }

  const CellGeometry& cell_;
  const MachineLimits& limits_;
  ScanPlan& plan_;
  Eigen::Isometry3d mount_;
};

}  // namespace

void appendCalibrationScenes(const CellGeometry& cell, const MachineLimits& limits, const CalibrationScenes& scenes,
                             ScanPlan& plan) {
  ScenePlanner planner(cell, limits, plan);
  if (scenes.plate_views > 0) planner.plateViews(scenes.plate_views, scenes.seed);
  if (scenes.sphere_sweeps > 0)
    planner.sphereSweeps(vec(cell.sphere.centre_mm), 0.5 * cell.sphere.diameter_mm, Scene::ReferenceSphere, scenes.sphere_sweeps);
  if (scenes.second_sphere_sweeps > 0 && cell.ball_bar)
    planner.sphereSweeps(vec(cell.ball_bar->centre_mm), 0.5 * cell.ball_bar->diameter_mm, Scene::SecondSphere,
                         scenes.second_sphere_sweeps);
}

CalibrationScenes calibrationScenes(const CalibrationPolicy& policy, double share, std::uint64_t seed) {
  if (!(share > 0 && share <= 1)) throw std::invalid_argument("calibration scenes: the share must be in (0, 1]");
  const auto part = [share](int count) { return std::max(std::min(count, 4), static_cast<int>(std::lround(share * count))); };
  CalibrationScenes scenes;
  scenes.plate_views = part(policy.plate_views);
  scenes.sphere_sweeps = part(policy.sphere_sweeps);
  scenes.seed = seed;
  return scenes;
}

ScanPlan calibrationPlan(const CellConfig& cell, const CalibrationScenes& scenes) {
  ScanPlan plan;
  plan.name = "calibration scenes";
  plan.part.kind = "none";
  plan.travel_speed = 200;
  plan.park = parkingPose(cell.limits);
  appendCalibrationScenes(cell.geometry, cell.limits, scenes, plan);
  return plan;
}

ScanPlan withCalibrationScenes(ScanPlan part_plan, const CellGeometry& cell, const MachineLimits& limits,
                               const CalibrationScenes& scenes) {
  ScanPlan calibration;
  appendCalibrationScenes(cell, limits, scenes, calibration);
  const auto isPlateView = [](const PlanStep& step) {
    const auto* view = std::get_if<StereoStep>(&step);
    return view != nullptr && view->scene == Scene::CalibrationPlate;
  };
  const auto isView = [](const PlanStep& step) { return std::holds_alternative<StereoStep>(step); };
  // The part's sweeps and views each keep their own order; a plan that mixes them has its sweeps first.
  std::vector<PlanStep> steps;
  const auto append = [&](const std::vector<PlanStep>& from, const auto& keep) {
    std::copy_if(from.begin(), from.end(), std::back_inserter(steps), keep);
  };
  append(calibration.steps, [&](const PlanStep& step) { return !isPlateView(step); });
  append(part_plan.steps, [&](const PlanStep& step) { return !isView(step); });
  append(calibration.steps, isPlateView);
  append(part_plan.steps, isView);
  part_plan.steps = std::move(steps);
  return part_plan;
}

}  // namespace stampscan::acquisition
