#include "stampscan/sim/visibility.hpp"

#include "stampscan/sim/cmm_motion.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/scene.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace stampscan::sim {

std::size_t ElementVisibility::visibleCount() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < laser.size(); ++i) n += visible(i) ? 1 : 0;
  return n;
}

std::vector<std::uint8_t> ElementVisibility::visibleOr() const {
  std::vector<std::uint8_t> out(laser.size());
  for (std::size_t i = 0; i < laser.size(); ++i) out[i] = visible(i) ? 1 : 0;
  return out;
}

namespace {

Eigen::Isometry3d headPose(const acquisition::HeadPose& p) {
  return HeadState{Vec3(p.position[0], p.position[1], p.position[2]), p.a, p.b}.pose();
}

// The element's printed outline on the formed part: the ring's outer edge, or the square cell's
// boundary out to the outer edge of its lines, mapped from the blank by the forming.
std::vector<Vec3> outline(const FormedPart& part, const GridSpec& grid, const Vec2& centre, int samples) {
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(samples));
  for (int k = 0; k < samples; ++k) {
    const double th = 2 * std::numbers::pi * k / samples;
    const Vec2 dir(std::cos(th), std::sin(th));
    Vec2 m;
    if (grid.kind == GridKind::Circle) {
      m = centre + (0.5 * grid.circle_diameter + 0.5 * grid.line_width) * dir;
    } else {
      // The square of half side pitch / 2 + line / 2, sampled along the same directions.
      const double half = 0.5 * grid.pitch + 0.5 * grid.line_width;
      m = centre + half / std::max(std::abs(dir.x()), std::abs(dir.y())) * dir;
    }
    out.push_back(part.position(m));
  }
  return out;
}

// What the line of sight from `eye` meets first, when that is `q` (nothing of the part in between).
std::optional<Hit> sightOf(const PartScene& scene, const Vec3& eye, const Vec3& q, double tolerance) {
  const Vec3 d = q - eye;
  const double distance = d.norm();
  auto hit = scene.cast({eye, d / distance}, 0.0);
  if (!hit || hit->t <= distance - tolerance) return std::nullopt;
  return hit;
}
bool inSight(const PartScene& scene, const Vec3& eye, const Vec3& q, double tolerance) {
  return sightOf(scene, eye, q, tolerance).has_value();
}

struct Sweep {
  Eigen::Isometry3d start;  // machine_from_digitizer at the sweep's start (the orientation holds)
  Vec3 travel;              // the mirror's displacement over the sweep
  double from = 0, to = 1;  // the share of the travel that measures (without the run-ups)
};

// The digitizer sees `q` during the sweep: the fan plane passes through it at some instant, where
// it lies within the fan, the measuring range and the incidence limit, in sight of the mirror.
bool laserSees(const PartScene& scene, const DigitizerSpec& d, const Sweep& s, const Vec3& q, const Vec3& normal,
               double tolerance) {
  const Eigen::Matrix3d R = s.start.linear();
  const Vec3 fan_normal = R.col(1);  // the fan is the sensor's x-z plane
  const double rate = fan_normal.dot(s.travel);
  if (std::abs(rate) < 1e-9) return false;
  const double f = fan_normal.dot(q - s.start.translation()) / rate;
  if (f < s.from || f > s.to) return false;
  const Vec3 mirror = s.start.translation() + f * s.travel;
  const Vec3 local = R.transpose() * (q - mirror);
  const double range = local.norm();
  if (range < d.standoff - 0.5 * d.measuring_range || range > d.standoff + 0.5 * d.measuring_range) return false;
  if (std::abs(std::atan2(local.x(), -local.z())) > d.half_angle) return false;
  // Whole only where every point comes back: beyond steep_from the digitizer drops points at random
  // (digitizer_model.cpp), and a ring with holes in it is not measured.
  const double cos_incidence = normal.dot((mirror - q) / range);
  if (cos_incidence <= std::cos(d.steep_from)) return false;
  const std::optional<Hit> hit = sightOf(scene, mirror, q, tolerance);
  // Glare: on a polished spot lit near normal incidence the triangulation camera is saturated and
  // sees neither the sheet nor the printed line (digitizer_model.cpp).
  return hit && !(hit->shiny && cos_incidence > std::cos(d.glare_incidence));
}

}  // namespace

ElementVisibility visibleElements(const ScanParams& world, const acquisition::ScanPlan& plan, const fitting::Cloud& truth,
                                  const VisibilityParams& params) {
  const auto mu = truth.scalars.find(kMaterialU), mv = truth.scalars.find(kMaterialV);
  if (mu == truth.scalars.end() || mv == truth.scalars.end() || truth.normals.size() != truth.size())
    throw std::invalid_argument("visibleElements: the truth cloud needs normals and material_u/v (sim::groundTruth)");
  const std::unique_ptr<FormedPart> part = makePart(world);
  const Eigen::Isometry3d machine_from_datum = machineFromDatum(world);
  const PartScene scene(*part, world.grid, machine_from_datum);
  const CellTruth cell = drawCellTruth(world);

  std::vector<Sweep> sweeps;
  std::vector<std::array<Eigen::Isometry3d, 2>> views;
  for (const acquisition::PlanStep& step : plan.steps) {
    if (const auto* s = std::get_if<acquisition::SweepStep>(&step); s && s->scene == acquisition::Scene::Part) {
      const Eigen::Isometry3d a = headPose(s->start) * cell.head_from_digitizer;
      const Eigen::Isometry3d b = headPose(s->end) * cell.head_from_digitizer;
      const Vec3 travel = b.translation() - a.translation();
      const double run_up = acquisition::sweepRunUp(s->speed, params.acceleration, params.report_interval_s);
      const double share = travel.norm() > 0 ? run_up / travel.norm() : 1.0;
      sweeps.push_back({a, travel, share, 1.0 - share});
    } else if (const auto* v = std::get_if<acquisition::StereoStep>(&step); v && v->scene == acquisition::Scene::Part) {
      const Eigen::Isometry3d head = headPose(v->pose);
      views.push_back({head * cell.head_from_left, head * cell.head_from_right});
    }
  }
  const CameraIntrinsics* cameras[2] = {&cell.left, &cell.right};
  const double cos_camera = std::cos(params.camera_max_incidence);
  const double tol = params.occlusion_tolerance_mm;

  ElementVisibility out;
  out.laser.assign(truth.size(), 0);
  out.stereo.assign(truth.size(), 0);
  std::vector<std::atomic<std::uint32_t>> per_sweep(sweeps.size());
  tbb::parallel_for(std::size_t{0}, truth.size(), [&](std::size_t i) {
    std::vector<Vec3> ring = outline(*part, world.grid, Vec2(mu->second[i], mv->second[i]), params.outline_samples);
    std::vector<Vec3> normals;
    for (Vec3& q : ring) {  // from the part's datum frame onto the fixture
      normals.push_back(machine_from_datum.linear() * part->normal(q.x(), q.y()));
      q = machine_from_datum * q;
    }
    for (std::size_t w = 0; w < sweeps.size(); ++w) {
      bool all = true;
      for (std::size_t k = 0; k < ring.size() && all; ++k)
        all = laserSees(scene, world.digitizer, sweeps[w], ring[k], normals[k], tol);
      if (all) {
        out.laser[i] = 1;
        per_sweep[w].fetch_add(1, std::memory_order_relaxed);
      }
    }
    const Vec3& centre = truth.positions[i];
    const Vec3& normal = truth.normals[i];
    for (const auto& poses : views) {
      bool all = true;
      for (int c = 0; c < 2 && all; ++c) {
        const Vec3 eye = poses[static_cast<std::size_t>(c)].translation();
        const double cos_view = normal.dot((eye - centre).normalized());
        all = cos_view >= cos_camera;
        const Eigen::Isometry3d camera_from_machine = poses[static_cast<std::size_t>(c)].inverse();
        const double depth = (camera_from_machine * centre).z();
        // The line across the direction the element tilts away in is foreshortened by the view's
        // obliquity: the ring's thinnest line in the image.
        all = all && depth > 0 && world.grid.line_width * cos_view * cameras[c]->fx / depth >= params.min_line_px;
        for (std::size_t k = 0; k < ring.size() && all; ++k) {
          const Vec3 in_camera = camera_from_machine * ring[k];
          if (in_camera.z() <= 0) {
            all = false;
            break;
          }
          const Vec2 px = cameras[c]->project(in_camera);
          const double border = params.image_border_px;
          all = px.x() >= border && px.y() >= border && px.x() <= cameras[c]->width - 1 - border &&
                px.y() <= cameras[c]->height - 1 - border && inSight(scene, eye, ring[k], tol);
        }
      }
      if (all) {
        out.stereo[i] = 1;
        break;
      }
    }
  });
  for (const auto& n : per_sweep) out.laser_per_sweep.push_back(n.load());
  return out;
}

void predictElements(acquisition::ScanPlan& plan, const ElementVisibility& visibility) {
  std::size_t k = 0;
  for (acquisition::PlanStep& step : plan.steps)
    if (auto* s = std::get_if<acquisition::SweepStep>(&step); s && s->scene == acquisition::Scene::Part)
      s->expected_elements = k < visibility.laser_per_sweep.size() ? visibility.laser_per_sweep[k++] : 0;
}

}  // namespace stampscan::sim
