// What a plan is predicted to see of a model's grid area (part_planner.hpp): each sample asked of the
// sensors' sight (sensor_sight.hpp), its lines of sight cast with Embree against the model and the
// fixture's solids; and the bounds a plan's motion is set against.
#include "stampscan/acquisition/part_planner.hpp"

#include "grid_samples.hpp"
#include "stampscan/acquisition/sensor_sight.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <Eigen/Geometry>
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180;

Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

// A fixture's solid as triangles in the datum frame, for lines of sight: a box's six faces, a
// cylinder's mantle and caps, a sphere's bands (fine enough to shade a sample a millimetre apart).
NominalModel solidTriangles(const BodySolid& solid) {
  NominalModel m;
  const Eigen::Isometry3d pose = trace::toIsometry(toRigidPose(solid.placement));
  const auto add = [&](const Vec3& p) {
    const Vec3 q = pose * p;
    m.vertices.push_back({q.x(), q.y(), q.z()});
    return static_cast<std::uint32_t>(m.vertices.size() - 1);
  };
  constexpr int kSegments = 48;
  switch (solid.shape) {
    case BodySolid::Shape::Box: {
      const Vec3 h = 0.5 * vec(solid.size_mm);
      std::uint32_t c[8];
      for (int i = 0; i < 8; ++i) c[i] = add(Vec3(i & 1 ? h.x() : -h.x(), i & 2 ? h.y() : -h.y(), i & 4 ? h.z() : -h.z()));
      const int faces[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
      for (const auto& f : faces) {
        m.triangles.push_back({c[f[0]], c[f[1]], c[f[2]]});
        m.triangles.push_back({c[f[0]], c[f[2]], c[f[3]]});
      }
      break;
    }
    case BodySolid::Shape::Cylinder: {
      const double r = solid.radius_mm, h = 0.5 * solid.length_mm;
      const std::uint32_t bottom = add(Vec3(0, 0, -h)), top = add(Vec3(0, 0, h));
      std::vector<std::uint32_t> lo, hi;
      for (int k = 0; k < kSegments; ++k) {
        const double t = 2 * std::numbers::pi * k / kSegments;
        lo.push_back(add(Vec3(r * std::cos(t), r * std::sin(t), -h)));
        hi.push_back(add(Vec3(r * std::cos(t), r * std::sin(t), h)));
      }
      for (int k = 0; k < kSegments; ++k) {
        const int n = (k + 1) % kSegments;
        m.triangles.push_back({lo[k], lo[n], hi[n]});
        m.triangles.push_back({lo[k], hi[n], hi[k]});
        m.triangles.push_back({bottom, lo[n], lo[k]});
        m.triangles.push_back({top, hi[k], hi[n]});
      }
      break;
    }
    case BodySolid::Shape::Sphere: {
      const double r = solid.radius_mm;
      const int rings = kSegments / 2;
      std::vector<std::vector<std::uint32_t>> at(rings + 1);
      for (int i = 0; i <= rings; ++i)
        for (int k = 0; k < kSegments; ++k) {
          const double polar = std::numbers::pi * i / rings, t = 2 * std::numbers::pi * k / kSegments;
          at[i].push_back(add(r * Vec3(std::sin(polar) * std::cos(t), std::sin(polar) * std::sin(t), std::cos(polar))));
        }
      for (int i = 0; i < rings; ++i)
        for (int k = 0; k < kSegments; ++k) {
          const int n = (k + 1) % kSegments;
          m.triangles.push_back({at[i][k], at[i + 1][k], at[i + 1][n]});
          m.triangles.push_back({at[i][k], at[i + 1][n], at[i][n]});
        }
      break;
    }
  }
  return m;
}

// The model and the fixture's solids as Embree's scene, for lines of sight: is anything of the part
// or the fixture between a sample and a sensor? Single precision, as Embree works; the tolerance
// covers it at a cell's scale. The nominal model knows no polished spots.
class Occluder : public SightLines {
 public:
  Occluder(const NominalModel& model, const std::vector<BodySolid>& fixture, double tolerance)
      : tolerance_(static_cast<float>(tolerance)) {
    device_ = rtcNewDevice("threads=1");
    if (device_ == nullptr) throw std::runtime_error("Embree: cannot create a device for the model's lines of sight");
    scene_ = rtcNewScene(device_);
    attach(model);
    for (const BodySolid& solid : fixture) attach(solidTriangles(solid));
    rtcCommitScene(scene_);
  }
  ~Occluder() override {
    if (scene_ != nullptr) rtcReleaseScene(scene_);
    if (device_ != nullptr) rtcReleaseDevice(device_);
  }
  Occluder(const Occluder&) = delete;
  Occluder& operator=(const Occluder&) = delete;

  Sight sight(const Vec3& eye, const Vec3& point) const override { return {!blocked(point, eye), false}; }

  // True when the segment from `from` (a sample on the surface) to `to` (a sensor) meets the model
  // beyond the tolerance at either end.
  bool blocked(const Vec3& from, const Vec3& to) const {
    const Vec3 d = to - from;
    const double length = d.norm();
    if (length <= 2 * tolerance_) return false;
    const Vec3 u = d / length;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray{};
    ray.org_x = static_cast<float>(from.x());
    ray.org_y = static_cast<float>(from.y());
    ray.org_z = static_cast<float>(from.z());
    ray.dir_x = static_cast<float>(u.x());
    ray.dir_y = static_cast<float>(u.y());
    ray.dir_z = static_cast<float>(u.z());
    ray.tnear = tolerance_;
    ray.tfar = static_cast<float>(length) - tolerance_;
    ray.mask = 0xFFFFFFFFu;
    rtcOccluded1(scene_, &context, &ray);
    return ray.tfar < 0;  // Embree sets it to -inf when the ray is blocked
  }

 private:
  void attach(const NominalModel& model) {
    if (model.triangles.empty()) return;
    RTCGeometry geometry = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), model.vertices.size()));
    auto* t = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), model.triangles.size()));
    for (std::size_t i = 0; i < model.vertices.size(); ++i)
      for (std::size_t k = 0; k < 3; ++k) v[3 * i + k] = static_cast<float>(model.vertices[i][k]);
    for (std::size_t i = 0; i < model.triangles.size(); ++i)
      for (std::size_t k = 0; k < 3; ++k) t[3 * i + k] = model.triangles[i][k];
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);
  }

  float tolerance_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace

Coverage predictCoverage(const NominalModel& model, const ScanPlan& plan, const CellGeometry& cell,
                         const MachineLimits& limits, const CoverageOptions& options) {
  const GridSamples samples = sampleGridArea(model, options.sample_spacing_mm, options.grid_normal_z);
  const LaserSight laser = laserSight(cell.digitizer);
  StereoSight stereo = stereoSight(cell.cameras, plan.part.line_width);
  stereo.image_border_px = options.image_border_px;
  stereo.max_incidence_rad = options.camera_max_incidence_deg * kDeg;
  const PlanSight steps = planSight(plan, laser, stereo, limits.acceleration);
  std::optional<Occluder> occluder;
  if (options.occlusion) occluder.emplace(model, cell.fixture.body, options.occlusion_tolerance_mm);
  const SightLines* lines = occluder ? &*occluder : nullptr;
  Coverage c;
  const std::size_t n = samples.points.size();
  c.points.resize(n);
  c.sample_area = samples.area;
  c.laser_passes.assign(n, 0);
  c.stereo.assign(n, 0);
  c.sweep_area.assign(steps.sweeps.size(), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::span<const Vec3> point(&samples.points[i], 1), normal(&samples.normals[i], 1);
    c.points[i] = {point[0].x(), point[0].y(), point[0].z()};
    for (std::size_t s = 0; s < steps.sweeps.size(); ++s)
      if (laserSees(steps.sweeps[s], laser, point, normal, lines)) {
        c.laser_passes[i] = static_cast<std::uint16_t>(std::min<int>(c.laser_passes[i] + 1, 65535));
        c.sweep_area[s] += samples.area[i];
      }
    for (const ViewSight& view : steps.views)
      if (stereoSees(view, stereo, point[0], normal[0], {}, lines)) {
        c.stereo[i] = 1;
        break;
      }
    const double a = samples.area[i];
    c.grid_area += a;
    if (c.laser_passes[i] > 0) c.laser_area += a;
    if (c.laser_passes[i] > 1) c.overlap_area += a;
    if (c.stereo[i]) c.stereo_area += a;
    if (c.laser_passes[i] > 0 || c.stereo[i]) c.either_area += a;
  }
  return c;
}

double scanTimeLowerBound(double grid_area, const CellGeometry& cell, double sweep_speed) {
  const double stripe = stripeWidth(cell.digitizer);
  return stripe > 0 && sweep_speed > 0 ? grid_area / (stripe * sweep_speed) : 0;
}

double scanTimeFloor(double grid_area, const CellGeometry& cell, double sweep_speed) {
  const DigitizerDrawing& d = cell.digitizer;
  const double far = d.standoff_mm + 0.5 * d.measuring_range_mm;
  return scanTimeLowerBound(grid_area, cell, sweep_speed) * d.standoff_mm / far;
}

double sweepingSeconds(const ScanPlan& plan, const MachineLimits& limits) {
  double t = 0;
  for (const PlanStep& step : plan.steps)
    if (const auto* s = std::get_if<SweepStep>(&step); s && s->scene == Scene::Part)
      t += moveSeconds(s->start, s->end, s->speed, limits);
  return t;
}

}  // namespace stampscan::acquisition
