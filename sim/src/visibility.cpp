#include "stampscan/sim/visibility.hpp"

#include "stampscan/acquisition/sensor_sight.hpp"

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

// The formed part's lines of sight: what the line from the eye meets first is the point itself
// (within the tolerance), and whether that spot is polished.
class PartSightLines : public acquisition::SightLines {
 public:
  PartSightLines(const PartScene& scene, double tolerance) : scene_(scene), tolerance_(tolerance) {}
  Sight sight(const Vec3& eye, const Vec3& q) const override {
    const Vec3 d = q - eye;
    const double distance = d.norm();
    const auto hit = scene_.cast({eye, d / distance}, 0.0);
    if (!hit || hit->t <= distance - tolerance_) return {};
    return {true, hit->shiny};
  }

 private:
  const PartScene& scene_;
  double tolerance_;
};

}  // namespace

ElementVisibility visibleElements(const ScanParams& world, const acquisition::ScanPlan& plan, const fitting::Cloud& truth,
                                  const VisibilityParams& params) {
  const auto mu = truth.scalars.find(kMaterialU), mv = truth.scalars.find(kMaterialV);
  if (mu == truth.scalars.end() || mv == truth.scalars.end() || truth.normals.size() != truth.size())
    throw std::invalid_argument("visibleElements: the truth cloud needs normals and material_u/v (sim::groundTruth)");
  const std::unique_ptr<FormedPart> part = makePart(world);
  const Eigen::Isometry3d machine_from_datum = machineFromDatum(world);
  const PartScene scene(*part, world.grid, machine_from_datum);
  const PartSightLines lines(scene, params.occlusion_tolerance_mm);
  const CellTruth cell = drawCellTruth(world);
  // The sensors as the simulator drew them: true mounts and intrinsics; the digitizer's outlines are
  // seen whole up to the incidence where it loses laser_loss_measured of the points at random (beyond
  // steep_from it drops more and more towards its limit).
  acquisition::LaserSight laser;
  laser.head_from_mirror = cell.head_from_digitizer;
  laser.standoff_mm = world.digitizer.standoff;
  laser.measuring_range_mm = world.digitizer.measuring_range;
  laser.half_fan_rad = world.digitizer.half_angle;
  laser.measurable_incidence_rad = world.digitizer.incidenceLosing(params.laser_loss_measured);
  laser.glare_incidence_rad = world.digitizer.glare_incidence;
  acquisition::StereoSight stereo;
  stereo.head_from_camera = {cell.head_from_left, cell.head_from_right};
  stereo.intrinsics = {cell.left.record(), cell.right.record()};
  stereo.image_border_px = params.image_border_px;
  stereo.max_incidence_rad = params.camera_max_incidence;
  stereo.line_width_mm = world.grid.line_width;
  stereo.min_line_px = params.min_line_px;
  const acquisition::PlanSight steps =
      acquisition::planSight(plan, laser, stereo, params.acceleration, params.report_interval_s);

  ElementVisibility out;
  out.laser.assign(truth.size(), 0);
  out.stereo.assign(truth.size(), 0);
  std::vector<std::atomic<std::uint32_t>> per_sweep(steps.sweeps.size());
  tbb::parallel_for(std::size_t{0}, truth.size(), [&](std::size_t i) {
    std::vector<Vec3> ring = outline(*part, world.grid, Vec2(mu->second[i], mv->second[i]), params.outline_samples);
    std::vector<Vec3> normals;
    for (Vec3& q : ring) {  // from the part's datum frame onto the fixture
      normals.push_back(machine_from_datum.linear() * part->normal(q.x(), q.y()));
      q = machine_from_datum * q;
    }
    for (std::size_t w = 0; w < steps.sweeps.size(); ++w)
      if (acquisition::laserSees(steps.sweeps[w], laser, ring, normals, &lines)) {
        out.laser[i] = 1;
        per_sweep[w].fetch_add(1, std::memory_order_relaxed);
      }
    for (const acquisition::ViewSight& view : steps.views)
      if (acquisition::stereoSees(view, stereo, truth.positions[i], truth.normals[i], ring, &lines)) {
        out.stereo[i] = 1;
        break;
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
