#include "stampscan/acquisition/cell_geometry.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <variant>

namespace stampscan::acquisition {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

Eigen::Isometry3d isometry(const Placement& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(p.rotation_deg[2] * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(p.rotation_deg[1] * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(p.rotation_deg[0] * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.position_mm[0], p.position_mm[1], p.position_mm[2]);
  return T;
}

// `pose` of the datum frame carried onto the machine frame by machine_from_datum (see placeOnFixture);
// `pivot` (head frame) is the point kept where the datum puts it when the angles are not exact.
HeadPose placePose(const HeadPose& pose, const Eigen::Isometry3d& machine_from_datum, const Eigen::Vector3d& pivot,
                   double index_step) {
  const Eigen::Isometry3d target =
      machine_from_datum * trace::headPose({pose.position[0], pose.position[1], pose.position[2]}, pose.a, pose.b);
  // trace::headPose is Rz(b) Rx(a): its x axis (cos b, sin b, 0) is level and gives the turn; the
  // tilt is then the z axis's about that x axis. Exact for a turn of the datum about z, with no
  // degenerate case at a = 0; for a tilted datum the nearest two-axis pose (no roll of the fan).
  const Eigen::Vector3d x = target.linear().col(0);
  double b = std::atan2(x.y(), x.x());
  const Eigen::Vector3d z = Eigen::AngleAxisd(-b, Eigen::Vector3d::UnitZ()) * target.linear().col(2);
  double a = std::atan2(-z.y(), z.z());
  if (index_step > 0) {
    a = std::round(a / index_step) * index_step;
    b = std::round(b / index_step) * index_step;
  }
  const Eigen::Matrix3d R = trace::headPose(Eigen::Vector3d::Zero(), a, b).linear();
  const Eigen::Vector3d position = target.translation() + (target.linear() - R) * pivot;
  return HeadPose{{position.x(), position.y(), position.z()}, a, b};
}

}  // namespace

ScanPlan placeOnFixture(const ScanPlan& plan, const CellGeometry& cell, double index_step) {
  ScanPlan placed = plan;
  if (cell.fixture.datum == Placement{}) return placed;
  const Eigen::Isometry3d machine_from_datum = isometry(cell.fixture.datum);
  // A sweep keeps the digitizer's mirror in place, a view the point the cameras' axes cross at.
  const auto& m = cell.digitizer.mount.position_mm;
  const Eigen::Vector3d mirror(m[0], m[1], m[2]);
  const Eigen::Vector3d aim(0, 0, -(cell.cameras.drop_mm + cell.cameras.convergence_mm));
  for (PlanStep& step : placed.steps) {
    if (auto* sweep = std::get_if<SweepStep>(&step); sweep && sweep->scene == Scene::Part) {
      sweep->start = placePose(sweep->start, machine_from_datum, mirror, index_step);
      sweep->end = placePose(sweep->end, machine_from_datum, mirror, index_step);
    } else if (auto* view = std::get_if<StereoStep>(&step); view && view->scene == Scene::Part) {
      view->pose = placePose(view->pose, machine_from_datum, aim, index_step);
    }
  }
  return placed;
}

NominalModel placeOnFixture(const NominalModel& model, const CellGeometry& cell) {
  NominalModel placed = model;
  const Eigen::Isometry3d machine_from_datum = isometry(cell.fixture.datum);
  for (std::array<double, 3>& v : placed.vertices) {
    const Eigen::Vector3d p = machine_from_datum * Eigen::Vector3d(v[0], v[1], v[2]);
    v = {p.x(), p.y(), p.z()};
  }
  return placed;
}

trace::RigidPose toRigidPose(const Placement& placement) { return trace::toRigidPose(isometry(placement)); }

const char* toString(BodySolid::Shape shape) {
  switch (shape) {
    case BodySolid::Shape::Box: return "box";
    case BodySolid::Shape::Cylinder: return "cylinder";
    case BodySolid::Shape::Sphere: return "sphere";
  }
  return "?";
}

const char* toString(HeadDescription::Kind kind) {
  return kind == HeadDescription::Kind::Indexing ? "indexing" : "continuous";
}

double stripeWidth(const DigitizerDrawing& d) {
  return 2 * d.standoff_mm * std::tan(0.5 * d.fan_angle_deg * std::numbers::pi / 180);
}

trace::CameraIntrinsicsRecord nominalIntrinsics(const CameraDrawing& c) {
  trace::CameraIntrinsicsRecord r;
  r.width = c.width;
  r.height = c.height;
  r.fx = r.fy = c.focal_length_mm / (c.pixel_size_um * 1e-3);
  r.cx = 0.5 * (c.width - 1);
  r.cy = 0.5 * (c.height - 1);
  r.k1 = c.k1;
  r.k2 = c.k2;
  return r;
}

CameraDrawing atResolution(const CameraDrawing& cameras, double factor) {
  CameraDrawing c = cameras;
  c.width = static_cast<int>(std::lround(cameras.width * factor));
  c.height = static_cast<int>(std::lround(cameras.height * factor));
  c.pixel_size_um = cameras.pixel_size_um * cameras.width / c.width;
  return c;
}

trace::RigidPose nominalCameraMount(const CameraDrawing& c, int which) {
  // The camera's axes: z towards the point where the two optical axes cross, x as near the head's
  // x as that allows, y = z x x (OpenCV's camera frame).
  const Eigen::Vector3d position((which == 0 ? -0.5 : 0.5) * c.baseline_mm, 0, -c.drop_mm);
  const Eigen::Vector3d target(0, 0, -c.drop_mm - c.convergence_mm);
  const Eigen::Vector3d z = (target - position).normalized();
  const Eigen::Vector3d x = (Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX().dot(z) * z).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = position;
  return trace::toRigidPose(T);
}

trace::RigidPose machineFromPlate(const PlateArtefact& plate) {
  // The placement puts the pattern's centre; dot (0, 0) is half the pattern away from it.
  const Eigen::Vector3d centre_on_plate(0.5 * (plate.columns - 1) * plate.pitch_mm, 0.5 * (plate.rows - 1) * plate.pitch_mm, 0);
  Eigen::Isometry3d T = isometry(plate.placement);
  T.translate(-centre_on_plate);
  return trace::toRigidPose(T);
}

trace::SessionDescription describeCell(const CellGeometry& cell) {
  trace::SessionDescription s;
  const DigitizerDrawing& d = cell.digitizer;
  s.digitizer_points_per_profile = d.points_per_profile;
  s.digitizer_profile_rate_hz = d.profile_rate_hz;
  s.digitizer_standoff_mm = d.standoff_mm;
  s.digitizer_measuring_range_mm = d.measuring_range_mm;
  s.head_from_digitizer_nominal = toRigidPose(d.mount);
  s.camera_nominal = nominalIntrinsics(cell.cameras);
  s.camera_bits = cell.cameras.bits;
  s.stereo_half_baseline_mm = 0.5 * cell.cameras.baseline_mm;
  s.plate = trace::PlateRecord{cell.plate.columns, cell.plate.rows, cell.plate.pitch_mm, cell.plate.dot_diameter_mm};
  s.reference_sphere_radius_mm = 0.5 * cell.sphere.diameter_mm;
  s.fixture = cell.fixture.name;
  return s;
}

trace::SessionDescription describeSession(const CellGeometry& cell, const ScanPlan& plan) {
  trace::SessionDescription s = describeCell(cell);
  s.part = plan.part.kind;
  s.plan = plan.name;
  s.grid = plan.part.grid;
  s.grid_pitch_mm = plan.part.pitch;
  s.grid_circle_diameter_mm = plan.part.circle_diameter;
  s.grid_line_width_mm = plan.part.line_width;
  return s;
}

}  // namespace stampscan::acquisition
