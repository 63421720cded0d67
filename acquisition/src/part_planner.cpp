#include "stampscan/acquisition/part_planner.hpp"

#include "stampscan/acquisition/sensor_sight.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <Eigen/Geometry>
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180;

Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }
Eigen::Matrix3d headRotation(double a, double b) { return trace::headPose(Vec3::Zero(), a, b).linear(); }

// The grid area as samples: each facet facing the sensors' side split into k x k sub-triangles no
// wider than the spacing, one sample at each one's centroid standing for its area.
struct GridSamples {
  std::vector<Vec3> points, normals;
  std::vector<double> area;
};

GridSamples sampleGridArea(const NominalModel& model, double spacing, double min_normal_z) {
  GridSamples s;
  for (const auto& t : model.triangles) {
    const Vec3 p0 = vec(model.vertices[t[0]]), p1 = vec(model.vertices[t[1]]), p2 = vec(model.vertices[t[2]]);
    const Vec3 cross = (p1 - p0).cross(p2 - p0);
    const double twice_area = cross.norm();
    if (!(twice_area > 0)) continue;
    const Vec3 n = cross / twice_area;
    if (n.z() < min_normal_z) continue;
    const double longest = std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
    const int k = std::max(1, static_cast<int>(std::ceil(longest / spacing)));
    const double sub_area = 0.5 * twice_area / (k * k);
    const Vec3 e1 = (p1 - p0) / k, e2 = (p2 - p0) / k;
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        const Vec3 corner = p0 + i * e1 + j * e2;
        s.points.push_back(corner + (e1 + e2) / 3.0);  // the upright sub-triangle
        s.normals.push_back(n);
        s.area.push_back(sub_area);
        if (i + j + 1 < k) {  // and the inverted one beside it
          s.points.push_back(corner + (2.0 * e1 + 2.0 * e2) / 3.0);
          s.normals.push_back(n);
          s.area.push_back(sub_area);
        }
      }
  }
  return s;
}

class PartPlanner {
 public:
  PartPlanner(const GridSamples& samples, const PartSpec& part, const CellGeometry& cell, const MachineLimits& limits,
              const PlannerOptions& o)
      : samples_(samples), cell_(cell), limits_(limits), o_(o),
        mount_(trace::toIsometry(toRigidPose(cell.digitizer.mount))) {
    plan_.name = "generated for " + (cell.fixture.name.empty() ? std::string("the cell") : cell.fixture.name);
    plan_.part = part;
    plan_.travel_speed = o.travel_speed;
    plan_.park = parkingPose(limits);
    lo_ = Vec3::Constant(std::numeric_limits<double>::infinity());
    hi_ = -lo_;
    for (const Vec3& p : samples.points) {
      lo_ = lo_.cwiseMin(p);
      hi_ = hi_.cwiseMax(p);
    }
  }

  ScanPlan plan() {
    if (o_.laser) laserPasses();
    if (o_.stereo) stereoViews();
    return std::move(plan_);
  }

 private:
  double stop(double angle) const { return nearestHeadStop(angle, limits_); }
  HeadPose headAt(const Vec3& sensor, double a, double b) const {
    const Vec3 head = sensor - headRotation(a, b) * mount_.translation();
    return {{head.x(), head.y(), head.z()}, a, b};
  }

  // One height a pass is flown at: the depth band it measures and the part of the grid area under it.
  struct Band {
    double z_mid = 0;           // the band's middle: which samples it measures
    double z_top = 0;           // the highest sample in it: where the stripe is narrowest
    double z_fly = 0;           // where the sensor's standoff is put: as high as the band's lowest sample allows
    double y_lo = 0, y_hi = 0;  // the samples' extent along the pass
  };

  // The depth bands of a pass at x whose stripe is `width` wide: where the surface under it spans
  // more than a band, several, the top one first (the head comes down from the park). Empty over
  // nothing.
  std::vector<Band> bandsUnder(double x, double width) const {
    const double band = o_.depth_use * cell_.digitizer.measuring_range_mm;
    double z_lo = std::numeric_limits<double>::infinity(), z_hi = -z_lo;
    for (const Vec3& p : samples_.points)
      if (std::abs(p.x() - x) <= 0.5 * width) z_lo = std::min(z_lo, p.z()), z_hi = std::max(z_hi, p.z());
    std::vector<Band> out;
    if (!(z_hi >= z_lo)) return out;
    const int bands = std::max(1, static_cast<int>(std::ceil((z_hi - z_lo) / band - 1e-9)));
    for (int layer = 0; layer < bands; ++layer) {
      Band b;
      b.z_mid = bands == 1 ? 0.5 * (z_lo + z_hi) : z_hi - (layer + 0.5) * (z_hi - z_lo) / bands;
      const double half_band = 0.5 * std::max(band, (z_hi - z_lo) / bands);
      b.y_lo = b.z_top = std::numeric_limits<double>::infinity();
      b.y_hi = -b.y_lo;
      b.z_top = -b.z_top;
      double z_bottom = b.z_mid;
      for (const Vec3& p : samples_.points)
        if (std::abs(p.x() - x) <= 0.5 * width && std::abs(p.z() - b.z_mid) <= half_band) {
          b.y_lo = std::min(b.y_lo, p.y());
          b.y_hi = std::max(b.y_hi, p.y());
          b.z_top = std::max(b.z_top, p.z());
          z_bottom = std::min(z_bottom, p.z());
        }
      // The stripe is wider the further the surface lies: the sensor flies as high as keeps the
      // band's lowest sample within the share of the measuring range a band may take.
      b.z_fly = std::max(b.z_top - 0.5 * band, z_bottom + 0.5 * band);
      if (b.y_hi >= b.y_lo) out.push_back(b);
    }
    return out;
  }

  // The stripe a pass lays on the surface it flies over: narrowest where the surface comes nearest
  // the sensor (the fan widens with the distance). Over nothing, the stripe at the standoff.
  double stripeOver(const std::vector<Band>& bands) const {
    const DigitizerDrawing& d = cell_.digitizer;
    const double half_fan = 0.5 * d.fan_angle_deg * kDeg;
    if (bands.empty()) return stripeWidth(d);
    double width = std::numeric_limits<double>::infinity();
    for (const Band& b : bands)
      width = std::min(width, 2 * std::max(0.0, d.standoff_mm - (b.z_top - b.z_fly)) * std::tan(half_fan));
    return width;
  }

  // Passes along y, side by side in x, laid from one side of the grid area to the other: each
  // pass's stripe (at the nearest surface under it) overlaps the ground its neighbour covered by the
  // stated share, so that passes over flat ground lie wider apart than over a slope.
  void laserPasses() {
    const double nominal = stripeWidth(cell_.digitizer);
    if (!(nominal > 0)) return;
    // Beyond the grid each pass runs on by an element's outline and the sweep's run-up, so that the
    // elements at its ends are crossed where the head's track can be trusted.
    const double lead = plan_.part.pitch + sweepRunUp(o_.sweep_speed, limits_.acceleration);
    std::uint32_t index = 0;
    bool forward = true;
    double covered_to = lo_.x();  // the grid area left of this is covered
    for (int guard = 0; covered_to < hi_.x() && guard < 10000; ++guard) {
      // The pass's place depends on its stripe, its stripe on what lies under it: a few rounds settle it.
      double width = nominal, x = 0;
      std::vector<Band> bands;
      for (int round = 0; round < 4; ++round) {
        x = covered_to - o_.strip_overlap * width + 0.5 * width;
        bands = bandsUnder(x, width);
        width = std::max(0.2 * nominal, stripeOver(bands));
      }
      covered_to = x + 0.5 * width;
      for (const Band& band : bands) {
        const double b = stop((index % 2 ? 2.0 : -2.0) * kDeg);
        const Eigen::Matrix3d R = headRotation(0, b) * mount_.linear();
        const Vec3 along = Vec3(R(0, 1), R(1, 1), 0).normalized();
        const Vec3 centre = Vec3(x, 0.5 * (band.y_lo + band.y_hi), band.z_fly) + cell_.digitizer.standoff_mm * R.col(2);
        const double half = 0.5 * (band.y_hi - band.y_lo) + lead;
        const double direction = forward ? 1.0 : -1.0;
        SweepStep s;
        s.scene = Scene::Part;
        s.index = index++;
        s.start = headAt(centre - direction * half * along, 0, b);
        s.end = headAt(centre + direction * half * along, 0, b);
        s.speed = o_.sweep_speed;
        plan_.steps.emplace_back(s);
        forward = !forward;
      }
    }
  }

  // A rows x columns lattice over the grid area at the cameras' working distance; the outer views
  // stand further out and look inwards.
  void stereoViews() {
    const int rows = std::max(0, o_.stereo_rows), cols = std::max(0, o_.stereo_columns);
    if (rows == 0 || cols == 0) return;
    const Eigen::Vector2d mid(0.5 * (lo_.x() + hi_.x()), 0.5 * (lo_.y() + hi_.y()));
    const Eigen::Vector2d half(0.5 * (hi_.x() - lo_.x()), 0.5 * (hi_.y() - lo_.y()));
    const double z_mid = 0.5 * (lo_.z() + hi_.z());
    const double max_reach = half.norm() + 1e-9;
    std::uint32_t index = 0;
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < cols; ++i) {
        const double fx = cols == 1 ? 0.0 : 2.0 * i / (cols - 1) - 1.0;
        const double fy = rows == 1 ? 0.0 : 2.0 * j / (rows - 1) - 1.0;
        const Eigen::Vector2d offset(fx * 0.6 * half.x(), fy * 0.6 * half.y());
        const double reach = std::min(1.0, offset.norm() / max_reach);
        const double a = stop(0.35 * reach);
        const double phi = std::atan2(offset.y(), offset.x());
        const double b = stop(reach > 1e-6 ? std::atan2(std::cos(phi), -std::sin(phi)) : 0.0);
        const Vec3 target(mid.x() + offset.x(), mid.y() + offset.y(), z_mid);
        const Vec3 head =
            target + headRotation(a, b) * Vec3(0, 0, cell_.cameras.drop_mm + cell_.cameras.convergence_mm);
        StereoStep v;
        v.scene = Scene::Part;
        v.index = index++;
        v.pose = {{head.x(), head.y(), head.z()}, a, b};
        v.settle_s = 0.4;
        plan_.steps.emplace_back(v);
      }
  }

  const GridSamples& samples_;
  const CellGeometry& cell_;
  const MachineLimits& limits_;
  const PlannerOptions& o_;
  Eigen::Isometry3d mount_;
  Vec3 lo_, hi_;
  ScanPlan plan_;
};

// The model as Embree's scene, for lines of sight: is anything of the part between a sample and a
// sensor? Single precision, as Embree works; the tolerance covers it at a cell's scale. The nominal
// model knows no polished spots.
class Occluder : public SightLines {
 public:
  Occluder(const NominalModel& model, double tolerance) : tolerance_(static_cast<float>(tolerance)) {
    device_ = rtcNewDevice("threads=1");
    if (device_ == nullptr) throw std::runtime_error("Embree: cannot create a device for the model's lines of sight");
    scene_ = rtcNewScene(device_);
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
  float tolerance_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace

ScanPlan planPart(const NominalModel& model, const PartSpec& part, const CellGeometry& cell, const MachineLimits& limits,
                  const PlannerOptions& options) {
  if (!(options.strip_overlap >= 0 && options.strip_overlap < 0.9))
    throw std::invalid_argument("the strip overlap must be within 0 .. 0.9, not " + std::to_string(options.strip_overlap));
  if (!(options.sweep_speed > 0) || !(options.travel_speed > 0))
    throw std::invalid_argument("the sweep and travel speeds must be positive");
  if (!(options.depth_use > 0 && options.depth_use <= 1))
    throw std::invalid_argument("depth_use must be within (0, 1]");
  if (!(options.sample_spacing_mm > 0)) throw std::invalid_argument("the sample spacing must be positive");
  const GridSamples samples = sampleGridArea(model, options.sample_spacing_mm, options.grid_normal_z);
  if (samples.points.empty())
    throw std::invalid_argument((model.source.empty() ? std::string("the model") : model.source) +
                                ": no facet faces the sensors' side (+z of the datum frame): nothing to plan");
  return PartPlanner(samples, part, cell, limits, options).plan();
}

Coverage predictCoverage(const NominalModel& model, const ScanPlan& plan, const CellGeometry& cell,
                         const MachineLimits& limits, const CoverageOptions& options) {
  const GridSamples samples = sampleGridArea(model, options.sample_spacing_mm, options.grid_normal_z);
  const LaserSight laser = laserSight(cell.digitizer);
  StereoSight stereo = stereoSight(cell.cameras, plan.part.line_width);
  stereo.image_border_px = options.image_border_px;
  stereo.max_incidence_rad = options.camera_max_incidence_deg * kDeg;
  const PlanSight steps = planSight(plan, laser, stereo, limits.acceleration);
  std::optional<Occluder> occluder;
  if (options.occlusion) occluder.emplace(model, options.occlusion_tolerance_mm);
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

}  // namespace stampscan::acquisition
