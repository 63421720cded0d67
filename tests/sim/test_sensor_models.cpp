// The sensor models against the ground truth: a printed circle's ellipse, measured on a rendered
// camera image and in the laser digitizer's intensity, has the axes the strain field says.
#include "stampscan/sim/camera_model.hpp"
#include "stampscan/sim/cmm_motion.hpp"
#include "stampscan/sim/digitizer_model.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>

namespace {

using namespace stampscan::sim;

struct EllipseAxes {
  double major = 0, minor = 0;
  double major_angle = 0;  // rad, in the plane frame
};

// The ring's ellipse from its inner edge: along rays from the element's centre (in the tangent
// plane), where the intensity first falls below the mid level between sheet and ink. The inner edge
// of a ring of centre-line radius r0 and width w is the image of radius r0 - w/2, so the centre
// line's axes are the edge's times r0 / (r0 - w/2). (The outer edge touches the neighbouring rings.)
EllipseAxes ringFromInnerEdge(const std::function<double(const Vec2&)>& intensity, double r0, double w) {
  std::vector<cv::Point2f> edge;
  for (int k = 0; k < 180; ++k) {
    const double a = 2 * std::numbers::pi * k / 180;
    const Vec2 dir(std::cos(a), std::sin(a));
    std::vector<double> values;
    for (double rho = 0.3; rho <= 2.4; rho += 0.004) values.push_back(intensity(rho * dir));
    // Rays through a gap in the data (dropouts) are left out.
    if (std::any_of(values.begin(), values.end(), [](double v) { return std::isnan(v); })) continue;
    const double sheet = values.front();
    const double ink = *std::min_element(values.begin(), values.end());
    const double mid = 0.5 * (sheet + ink);
    for (std::size_t i = 1; i < values.size(); ++i)
      if (values[i] < mid) {
        const double f = (values[i - 1] - mid) / (values[i - 1] - values[i]);
        const double rho = 0.3 + 0.004 * (static_cast<double>(i - 1) + f);
        edge.emplace_back(static_cast<float>(1000 * rho * dir.x()), static_cast<float>(1000 * rho * dir.y()));
        break;
      }
  }
  EXPECT_GT(edge.size(), 60u) << "too few rays found the ring's edge";
  const cv::RotatedRect e = cv::fitEllipseDirect(edge);
  const double scale = r0 / (r0 - 0.5 * w) / 2000.0;  // um -> mm, full axes -> semi-axes
  EllipseAxes out;
  out.major = std::max(e.size.width, e.size.height) * scale;
  out.minor = std::min(e.size.width, e.size.height) * scale;
  out.major_angle = (e.size.width >= e.size.height ? e.angle : e.angle + 90) * std::numbers::pi / 180;
  return out;
}

// The angle between two axis directions (sign-free), in radians.
double axisAngle(double a, double b) {
  const double d = std::fmod(std::abs(a - b), std::numbers::pi);
  return std::min(d, std::numbers::pi - d);
}

TEST(CameraIntrinsics, RayAndProjectionAreInverse) {
  CameraIntrinsics c;
  c.p1 = 3e-4;
  c.p2 = -2e-4;
  c.k3 = 0.01;
  for (const Vec2& px : {Vec2(0, 0), Vec2(1023.5, 767.5), Vec2(2047, 1535), Vec2(100, 1400), Vec2(1800, 30)}) {
    const Vec3 r = c.ray(px.x(), px.y());
    EXPECT_LT((c.project(r * 250.0) - px).norm(), 1e-6) << px.transpose();
  }
  const CameraIntrinsics q = c.scaled(0.25);
  EXPECT_EQ(q.width, 512);
  EXPECT_EQ(q.height, 384);
  EXPECT_NEAR(q.cx, 255.5, 1e-12);
}

class SensorsSeeStrain : public ::testing::TestWithParam<Vec2> {};

TEST_P(SensorsSeeStrain, CameraImageRingHasTheTrueAxes) {
  const DomePart dome;
  GridSpec grid;
  const PartScene scene(dome, grid);
  const Deformation d = dome.deformationOfMaterial(GetParam());
  // A camera 150 mm out along the normal, looking back at the element, its x along the major axis.
  Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  camera.linear().col(2) = -d.normal;
  camera.linear().col(0) = d.major_direction;
  camera.linear().col(1) = (-d.normal).cross(d.major_direction);
  camera.translation() = d.point + 150 * d.normal;
  CameraIntrinsics in;
  in.width = in.height = 600;
  in.cx = in.cy = 299.5;
  in.fx = in.fy = 4000;
  in.k1 = -0.05;
  CameraSensor sensor;
  sensor.bits = 16;
  sensor.standoff = 150;
  const GrayImage image = renderImage(scene, in, sensor, camera, 7);
  // Sample the image at tangent-plane points around the element (bilinear).
  const Eigen::Isometry3d to_camera = camera.inverse();
  const Vec3 t1 = d.major_direction, t2 = d.normal.cross(d.major_direction);
  const auto intensity = [&](const Vec2& q) {
    const Vec2 px = in.project(to_camera * (d.point + q.x() * t1 + q.y() * t2));
    const int x = static_cast<int>(std::floor(px.x())), y = static_cast<int>(std::floor(px.y()));
    const double fx = px.x() - x, fy = px.y() - y;
    return (1 - fy) * ((1 - fx) * image.at(x, y) + fx * image.at(x + 1, y)) +
           fy * ((1 - fx) * image.at(x, y + 1) + fx * image.at(x + 1, y + 1));
  };
  const EllipseAxes e = ringFromInnerEdge(intensity, 1.27, grid.line_width);
  EXPECT_NEAR(std::log(e.major / 1.27), d.major_strain, 0.006) << "true major " << d.major_strain;
  EXPECT_NEAR(std::log(e.minor / 1.27), d.minor_strain, 0.006) << "true minor " << d.minor_strain;
  if (d.major_strain - d.minor_strain > 0.02) {
    EXPECT_LT(axisAngle(e.major_angle, 0.0), 0.05);
  }
}

TEST_P(SensorsSeeStrain, LaserIntensityRingHasTheTrueAxes) {
  const DomePart dome;
  GridSpec grid;
  const PartScene scene(dome, grid);
  const Deformation d = dome.deformationOfMaterial(GetParam());
  DigitizerSpec spec;
  // Sweep the digitizer over the element, looking straight down, profiles 0.04 mm apart.
  const Vec3 t1 = d.major_direction, t2 = d.normal.cross(d.major_direction);
  std::vector<Vec2> plane;
  std::vector<double> value;
  std::mt19937_64 rng(3);
  for (double s = -3.5; s <= 3.5; s += 0.04) {
    Eigen::Isometry3d sensor = Eigen::Isometry3d::Identity();
    sensor.translation() = d.point + Vec3(0, s, spec.standoff);
    const ProfileMeasurement m = measureProfile(scene, spec, sensor, rng);
    for (int i = 0; i < spec.points_per_profile; ++i) {
      // Lost points, and saturated ones (glare off a polished spot) carry no grid information.
      if (m.range[i] <= 0 || m.intensity[i] == 65535) continue;
      const Vec3 p = sensor * (static_cast<double>(m.range[i]) * digitizerRay(spec, i)) - d.point;
      const Vec2 q(p.dot(t1), p.dot(t2));
      if (q.norm() > 2.6) continue;
      plane.push_back(q);
      value.push_back(m.intensity[i]);
    }
  }
  ASSERT_GT(plane.size(), 3000u);
  // Intensity at any plane point: a Gaussian-weighted mean of the samples within 0.05 mm, from a
  // bucket grid.
  const double cell = 0.05;
  const int n = static_cast<int>(std::ceil(5.4 / cell));
  std::vector<std::vector<std::size_t>> buckets(static_cast<std::size_t>(n * n));
  const auto bucket = [&](double v) { return std::clamp(static_cast<int>(std::floor((v + 2.7) / cell)), 0, n - 1); };
  for (std::size_t k = 0; k < plane.size(); ++k)
    buckets[static_cast<std::size_t>(bucket(plane[k].y()) * n + bucket(plane[k].x()))].push_back(k);
  const auto intensity = [&](const Vec2& q) {
    double sum = 0, weight = 0;
    const int bx = bucket(q.x()), by = bucket(q.y());
    for (int j = std::max(0, by - 1); j <= std::min(n - 1, by + 1); ++j)
      for (int i = std::max(0, bx - 1); i <= std::min(n - 1, bx + 1); ++i)
        for (std::size_t k : buckets[static_cast<std::size_t>(j * n + i)]) {
          const double w = std::exp(-(plane[k] - q).squaredNorm() / (2 * 0.025 * 0.025));
          sum += w * value[k];
          weight += w;
        }
    return weight > 1e-3 ? sum / weight : std::numeric_limits<double>::quiet_NaN();  // a gap in the data
  };
  const EllipseAxes e = ringFromInnerEdge(intensity, 1.27, grid.line_width);
  EXPECT_NEAR(std::log(e.major / 1.27), d.major_strain, 0.015) << "true major " << d.major_strain;
  EXPECT_NEAR(std::log(e.minor / 1.27), d.minor_strain, 0.015) << "true minor " << d.minor_strain;
}

// The pole (equibiaxial), the upper wall and the steep wall of the dome.
INSTANTIATE_TEST_SUITE_P(DomeElements, SensorsSeeStrain,
                         ::testing::Values(Vec2(0, 0), Vec2(2.54 * 4, 2.54 * 3), Vec2(0, 2.54 * 10)));

// The part stands where the fixture holds its datum frame: a ray of the machine meets it where the
// same ray, carried into the datum frame, meets the part at the origin; the table stays put.
TEST(PartScene, APartOnAFixtureIsThePartAtTheOriginMoved) {
  const DomePart dome;
  const GridSpec grid;
  Eigen::Isometry3d machine_from_datum = Eigen::Isometry3d::Identity();
  machine_from_datum.rotate(Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitX()));
  machine_from_datum.pretranslate(Eigen::Vector3d(35, -20, 4));
  const PartScene at_origin(dome, grid), on_fixture(dome, grid, machine_from_datum);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-60, 60);
  int hits = 0;
  for (int k = 0; k < 200; ++k) {
    const Ray machine_ray{Vec3(u(rng), u(rng), 200), Vec3(0.1 * u(rng) / 60, 0.1 * u(rng) / 60, -1).normalized()};
    const Ray datum_ray{machine_from_datum.inverse() * machine_ray.origin, machine_from_datum.linear().transpose() * machine_ray.direction};
    const std::optional<Hit> got = on_fixture.cast(machine_ray, 0.001);
    const std::optional<Hit> want = at_origin.cast(datum_ray, 0.001);
    ASSERT_TRUE(got.has_value());
    if (want && want->normal != Vec3::UnitZ()) {  // on the part (not the table)
      ++hits;
      EXPECT_NEAR(got->t, want->t, 1e-6);
      EXPECT_LT((got->point - machine_from_datum * want->point).norm(), 1e-6);
      EXPECT_LT((got->normal - machine_from_datum.linear() * want->normal).norm(), 1e-9);
      EXPECT_NEAR(got->albedo, want->albedo, 1e-9);
    }
  }
  EXPECT_GT(hits, 50);
  // Past the part, the table is where it is in the machine (not tilted with the datum).
  const std::optional<Hit> table = on_fixture.cast(Ray{Vec3(400, 400, 100), Vec3(0, 0, -1)}, 0.001);
  ASSERT_TRUE(table.has_value());
  EXPECT_EQ(table->normal, Vec3::UnitZ());
}

TEST(CmmTrajectory, RespectsSpeedAccelerationAndTravel) {
  CmmLimits limits;
  CmmTrajectory traj(limits, HeadState{Vec3(0, 0, 300), 0, 0, 0});
  traj.moveTo(Vec3(200, 0, 300), 0, 0, 100);  // long: trapezoid
  traj.moveTo(Vec3(200, 2, 300), 0, 0, 100);  // short: triangle
  traj.dwell(0.5);
  const auto& s = traj.segments();
  ASSERT_EQ(s.size(), 3u);
  EXPECT_NEAR(s[0].t1 - s[0].t0, 200.0 / 100 + 100.0 / limits.max_accel, 1e-9);
  EXPECT_NEAR(s[1].t1 - s[1].t0, 2 * std::sqrt(2.0 / limits.max_accel), 1e-9);
  double prev_speed = 0;
  Vec3 prev = traj.at(0).position;
  const double dt = 1e-3;
  for (double t = dt; t <= traj.duration(); t += dt) {
    const HeadState h = traj.at(t);
    const double speed = (h.position - prev).norm() / dt;
    EXPECT_LE(speed, 100 * 1.0001);
    EXPECT_LE(std::abs(speed - prev_speed) / dt, limits.max_accel * 1.05 + 1e-6) << "at t = " << t;
    prev_speed = speed;
    prev = h.position;
  }
  EXPECT_NEAR((traj.at(traj.duration()).position - Vec3(200, 2, 300)).norm(), 0, 1e-12);
  EXPECT_THROW(traj.moveTo(Vec3(0, 0, 900), 0, 0, 10), std::invalid_argument);
}

}  // namespace
