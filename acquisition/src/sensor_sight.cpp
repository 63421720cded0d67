#include "stampscan/acquisition/sensor_sight.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <cmath>
#include <variant>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180;

Eigen::Isometry3d headOf(const HeadPose& p) {
  return trace::headPose(Vec3(p.position[0], p.position[1], p.position[2]), p.a, p.b);
}

// The fan's plane passes through q at some instant of the sweep, where q is within the fan, the
// measuring range and the full-return incidence, in sight of the mirror and not in glare.
bool laserSeesPoint(const SweepSight& s, const LaserSight& d, const Vec3& q, const Vec3& normal,
                    const SightLines* lines) {
  const Eigen::Matrix3d R = s.start.linear();
  const Vec3 fan_normal = R.col(1);  // the fan is the sensor's x-z plane
  const double rate = fan_normal.dot(s.travel);
  if (std::abs(rate) < 1e-9) return false;
  const double f = fan_normal.dot(q - s.start.translation()) / rate;
  if (f < s.from || f > s.to) return false;
  const Vec3 mirror = s.start.translation() + f * s.travel;
  const Vec3 local = R.transpose() * (q - mirror);
  const double range = local.norm();  // the digitizer measures along each ray of its fan
  if (std::abs(range - d.standoff_mm) > 0.5 * d.measuring_range_mm) return false;
  if (std::abs(std::atan2(local.x(), -local.z())) > d.half_fan_rad) return false;
  const double cos_incidence = normal.dot((mirror - q) / range);
  if (cos_incidence <= std::cos(d.measurable_incidence_rad)) return false;
  if (lines == nullptr) return true;
  const SightLines::Sight sight = lines->sight(mirror, q);
  return sight.clear && !(sight.polished && d.glare_incidence_rad > 0 && cos_incidence > std::cos(d.glare_incidence_rad));
}

}  // namespace

LaserSight laserSight(const DigitizerDrawing& digitizer) {
  LaserSight s;
  s.head_from_mirror = trace::toIsometry(toRigidPose(digitizer.mount));
  s.standoff_mm = digitizer.standoff_mm;
  s.measuring_range_mm = digitizer.measuring_range_mm;
  s.half_fan_rad = 0.5 * digitizer.fan_angle_deg * kDeg;
  s.measurable_incidence_rad = digitizer.incidence_limit_deg * kDeg;
  return s;
}

StereoSight stereoSight(const CameraDrawing& cameras, double line_width_mm) {
  StereoSight s;
  for (int c = 0; c < 2; ++c) {
    s.head_from_camera[static_cast<std::size_t>(c)] = trace::toIsometry(nominalCameraMount(cameras, c));
    s.intrinsics[static_cast<std::size_t>(c)] = nominalIntrinsics(cameras);
  }
  s.line_width_mm = line_width_mm;
  return s;
}

PlanSight planSight(const ScanPlan& plan, const LaserSight& laser, const StereoSight& stereo, double acceleration,
                    double report_interval_s) {
  PlanSight out;
  for (const PlanStep& step : plan.steps) {
    if (const auto* s = std::get_if<SweepStep>(&step); s && s->scene == Scene::Part) {
      const Eigen::Isometry3d a = headOf(s->start) * laser.head_from_mirror;
      const Eigen::Isometry3d b = headOf(s->end) * laser.head_from_mirror;
      const Vec3 travel = b.translation() - a.translation();
      const double run_up = sweepRunUp(s->speed, acceleration, report_interval_s);
      const double share = travel.norm() > 0 ? run_up / travel.norm() : 1.0;
      out.sweeps.push_back({a, travel, share, 1.0 - share});
    } else if (const auto* v = std::get_if<StereoStep>(&step); v && v->scene == Scene::Part) {
      const Eigen::Isometry3d head = headOf(v->pose);
      ViewSight view;
      for (std::size_t c = 0; c < 2; ++c) {
        const Eigen::Isometry3d frame_from_camera = head * stereo.head_from_camera[c];
        view.camera_from_frame[c] = frame_from_camera.inverse();
        view.eye[c] = frame_from_camera.translation();
      }
      out.views.push_back(view);
    }
  }
  return out;
}

bool laserSees(const SweepSight& sweep, const LaserSight& laser, std::span<const Vec3> outline,
               std::span<const Vec3> normals, const SightLines* lines) {
  if (outline.empty() || normals.size() != outline.size()) return false;
  for (std::size_t k = 0; k < outline.size(); ++k)
    if (!laserSeesPoint(sweep, laser, outline[k], normals[k], lines)) return false;
  return true;
}

bool stereoSees(const ViewSight& view, const StereoSight& stereo, const Vec3& centre, const Vec3& normal,
                std::span<const Vec3> outline, const SightLines* lines) {
  const std::span<const Vec3> points = outline.empty() ? std::span<const Vec3>(&centre, 1) : outline;
  const double cos_limit = std::cos(stereo.max_incidence_rad);
  for (std::size_t c = 0; c < 2; ++c) {
    const trace::CameraIntrinsicsRecord& k = stereo.intrinsics[c];
    const Vec3& eye = view.eye[c];
    const double cos_view = normal.dot((eye - centre).normalized());
    if (cos_view < cos_limit) return false;
    const double depth = (view.camera_from_frame[c] * centre).z();
    if (depth <= 0) return false;
    // The line across the direction the element tilts away in is foreshortened by the view's
    // obliquity: the ring's thinnest line in the image.
    if (stereo.line_width_mm > 0 && stereo.line_width_mm * cos_view * k.fx / depth < stereo.min_line_px) return false;
    const double border = stereo.image_border_px;
    for (const Vec3& q : points) {
      const Vec3 in_camera = view.camera_from_frame[c] * q;
      if (in_camera.z() <= 0) return false;
      const Eigen::Vector2d px = projectPixel(k, in_camera);
      if (px.x() < border || px.y() < border || px.x() > k.width - 1 - border || px.y() > k.height - 1 - border)
        return false;
      if (lines != nullptr && !lines->sight(eye, q).clear) return false;
    }
  }
  return true;
}

Eigen::Vector2d projectPixel(const trace::CameraIntrinsicsRecord& k, const Vec3& c) {
  const double x = c.x() / c.z(), y = c.y() / c.z();
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
  const double xd = x * radial + 2 * k.p1 * x * y + k.p2 * (r2 + 2 * x * x);
  const double yd = y * radial + k.p1 * (r2 + 2 * y * y) + 2 * k.p2 * x * y;
  return {k.fx * xd + k.cx, k.fy * yd + k.cy};
}

}  // namespace stampscan::acquisition
