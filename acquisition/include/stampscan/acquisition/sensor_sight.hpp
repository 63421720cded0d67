// What the cell's sensors see of a surface point during one step of a plan: the one model of a
// sensor's sight that the planner's coverage prediction (part_planner.hpp), `station scan --dry-run`
// and the virtual cell's yardstick (sim/visibility.hpp) share. Each caller brings its own scene for
// the lines of sight (the nominal model; the simulator's formed part) and its own sensors (as drawn
// in the cell file; as the simulator drew them), and asks the same questions:
//
// - the laser digitizer, in one part sweep: the fan's plane passes through the point at some instant
//   of the sweep, away from the run-ups at either end (sweepRunUp: there the head's track is not to
//   be trusted); there the point lies within the fan's angle and the measuring range (along the
//   ray, centred on the standoff), is lit at an incidence at which the sensor returns every point,
//   and is in sight of the mirror; on a polished spot, not so near normal incidence that glare
//   saturates the sensor's camera;
// - the stereo pair, in one part view: both cameras have every point of the element's outline inside
//   their images (clear of a border) and in sight, see the element within their incidence limit,
//   and resolve its printed line (at least `min_line_px` wide where the view's obliquity makes it
//   thinnest).
//
// An element is seen whole by a sensor when every point of its outline is seen in one step; the
// planner asks about single points of the model's grid area (an outline of one point).
#pragma once

#include "stampscan/acquisition/cell_geometry.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"

#include <Eigen/Geometry>

#include <array>
#include <numbers>
#include <span>
#include <vector>

namespace stampscan::acquisition {

// The lines of sight through the scene.
class SightLines {
 public:
  virtual ~SightLines() = default;
  struct Sight {
    bool clear = false;     // nothing of the scene between the eye and the point
    bool polished = false;  // the point lies on a polished spot (glare near normal incidence)
  };
  virtual Sight sight(const Eigen::Vector3d& eye, const Eigen::Vector3d& point) const = 0;
};

// The laser digitizer as its sight needs it.
struct LaserSight {
  Eigen::Isometry3d head_from_mirror = Eigen::Isometry3d::Identity();  // looking down its -z, fan in x-z
  double standoff_mm = 100, measuring_range_mm = 60;
  double half_fan_rad = 0.21;
  // Up to this incidence the sensor returns enough of a surface to measure an outline on it (beyond
  // it, it loses too many points).
  double measurable_incidence_rad = 1.31;
  double glare_incidence_rad = 0;  // on a polished spot, nearer normal than this saturates (0: none)
};
// The digitizer as drawn in the cell file: it returns points up to its incidence limit.
LaserSight laserSight(const DigitizerDrawing& digitizer);

// The stereo pair as its sight needs it.
struct StereoSight {
  std::array<Eigen::Isometry3d, 2> head_from_camera{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  std::array<trace::CameraIntrinsicsRecord, 2> intrinsics;  // OpenCV's model, distortion applied
  double image_border_px = 20;  // an outline must be this far inside each image
  // Beyond 60 degrees a ring's minor axis is under half its size and its printed line well under a
  // pixel wide in the images: the cameras cannot resolve it.
  double max_incidence_rad = std::numbers::pi / 3;
  double line_width_mm = 0;  // the printed line; 0: its width in the images is not checked
  double min_line_px = 1.0;  // a line narrower in an image cannot be located in it
};
// The pair as drawn in the cell file (nominal mounts and intrinsics), for a grid of this line width.
StereoSight stereoSight(const CameraDrawing& cameras, double line_width_mm);

// One part sweep: the mirror's straight track and the share of it that measures.
struct SweepSight {
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();  // frame_from_mirror at the start
  Eigen::Vector3d travel = Eigen::Vector3d::Zero();
  double from = 0, to = 1;
};
// One part view: each camera's pose.
struct ViewSight {
  std::array<Eigen::Isometry3d, 2> camera_from_frame{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  std::array<Eigen::Vector3d, 2> eye{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
};
// The part steps of a plan, in the plan's frame and order. The run-ups follow from the machine's
// acceleration and the interval of its position reports.
struct PlanSight {
  std::vector<SweepSight> sweeps;
  std::vector<ViewSight> views;
};
PlanSight planSight(const ScanPlan& plan, const LaserSight& laser, const StereoSight& stereo, double acceleration,
                    double report_interval_s = kCmmReportInterval);

// The sweep sees every point of the outline (with its normals) whole; `lines` may be null (nothing
// is in the way).
bool laserSees(const SweepSight& sweep, const LaserSight& laser, std::span<const Eigen::Vector3d> outline,
               std::span<const Eigen::Vector3d> normals, const SightLines* lines);
// Both cameras of the view see the element at `centre` (its normal) whole: every point of its
// outline (the centre alone when the outline is empty).
bool stereoSees(const ViewSight& view, const StereoSight& stereo, const Eigen::Vector3d& centre,
                const Eigen::Vector3d& normal, std::span<const Eigen::Vector3d> outline, const SightLines* lines);

// Pixel coordinates of a point in the camera's frame (z > 0), OpenCV's distortion applied.
Eigen::Vector2d projectPixel(const trace::CameraIntrinsicsRecord& k, const Eigen::Vector3d& camera_point);

}  // namespace stampscan::acquisition
