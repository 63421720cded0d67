#include "stampscan/acquisition/plan_collisions.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <fcl/fcl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;

Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

// The solid as FCL's shape, grown by `margin` on every side.
std::shared_ptr<fcl::CollisionGeometryd> shapeOf(const BodySolid& solid, double margin) {
  switch (solid.shape) {
    case BodySolid::Shape::Box:
      return std::make_shared<fcl::Boxd>(solid.size_mm[0] + 2 * margin, solid.size_mm[1] + 2 * margin,
                                         solid.size_mm[2] + 2 * margin);
    case BodySolid::Shape::Cylinder:
      return std::make_shared<fcl::Cylinderd>(solid.radius_mm + margin, solid.length_mm + 2 * margin);
    case BodySolid::Shape::Sphere: return std::make_shared<fcl::Sphered>(solid.radius_mm + margin);
  }
  return nullptr;
}

// The part's triangles as FCL's bounding-volume hierarchy.
std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> meshOf(const NominalModel& model) {
  std::vector<fcl::Vector3d> points;
  points.reserve(model.vertices.size());
  for (const auto& v : model.vertices) points.emplace_back(v[0], v[1], v[2]);
  std::vector<fcl::Triangle> triangles;
  triangles.reserve(model.triangles.size());
  for (const auto& t : model.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  auto mesh = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  mesh->beginModel(static_cast<int>(triangles.size()), static_cast<int>(points.size()));
  mesh->addSubModel(points, triangles);
  mesh->endModel();
  return mesh;
}

// What stands in the head's way: the part's triangles, and the fixture's solids.
struct Obstacle {
  std::string name;  // "the part", or "the fixture's NAME"
  std::shared_ptr<fcl::CollisionGeometryd> geometry;
  Eigen::Isometry3d frame_from_obstacle = Eigen::Isometry3d::Identity();
};

// FCL's collision query stops at the first overlap, its distance query must visit the whole
// neighbourhood: each pose is first tested with the head's solids grown by the clearance (cheap),
// and the distance is measured only where that test finds something.
class BodyAgainstPart {
 public:
  BodyAgainstPart(std::vector<Obstacle> obstacles, const HeadDescription& head, double clearance)
      : obstacles_(std::move(obstacles)) {
    for (const BodySolid& s : head.body)
      solids_.push_back({s.name, shapeOf(s, 0), shapeOf(s, clearance), trace::toIsometry(toRigidPose(s.placement))});
  }

  // Whether a solid comes within the clearance of an obstacle with the head at `pose`.
  bool tooClose(const HeadPose& pose) const {
    const Eigen::Isometry3d head = headAt(pose);
    for (const Solid& s : solids_)
      for (const Obstacle& o : obstacles_) {
        fcl::CollisionRequestd request;
        fcl::CollisionResultd result;
        if (fcl::collide(s.grown.get(), fcl::Transform3d(head * s.head_from_solid), o.geometry.get(),
                         fcl::Transform3d(o.frame_from_obstacle), request, result) > 0)
          return true;
      }
    return false;
  }

  struct Closest {
    double distance = std::numeric_limits<double>::infinity();
    const std::string* solid = nullptr;
    const std::string* obstacle = nullptr;
  };
  // The least distance from any solid to any obstacle with the head at `pose`, and between which.
  Closest clearance(const HeadPose& pose) const {
    const Eigen::Isometry3d head = headAt(pose);
    Closest closest;
    for (const Solid& s : solids_)
      for (const Obstacle& o : obstacles_) {
        fcl::DistanceRequestd request;
        fcl::DistanceResultd result;
        fcl::distance(s.shape.get(), fcl::Transform3d(head * s.head_from_solid), o.geometry.get(),
                      fcl::Transform3d(o.frame_from_obstacle), request, result);
        // FCL reports a negative distance for solids that overlap.
        const double d = std::max(0.0, result.min_distance);
        if (d < closest.distance) closest = {d, &s.name, &o.name};
      }
    return closest;
  }

 private:
  static Eigen::Isometry3d headAt(const HeadPose& pose) { return trace::headPose(vec(pose.position), pose.a, pose.b); }
  struct Solid {
    std::string name;
    std::shared_ptr<fcl::CollisionGeometryd> shape, grown;
    Eigen::Isometry3d head_from_solid;
  };
  std::vector<Obstacle> obstacles_;
  std::vector<Solid> solids_;
};

HeadPose between(const HeadPose& from, const HeadPose& to, double t) {
  HeadPose p;
  for (std::size_t i = 0; i < 3; ++i) p.position[i] = from.position[i] + t * (to.position[i] - from.position[i]);
  p.a = from.a + t * (to.a - from.a);
  p.b = from.b + t * (to.b - from.b);
  return p;
}

// The closest approach along a straight path, when closer than the clearance. The distance is
// measured at no more than a few of the poses found too close, spread over the stretch.
std::optional<PlanCollision> checkPath(const BodyAgainstPart& body, const HeadPose& from, const HeadPose& to,
                                       const CollisionOptions& o) {
  const double length = (vec(to.position) - vec(from.position)).norm();
  const double turn = std::max(std::abs(to.a - from.a), std::abs(to.b - from.b));
  const int n = std::max(1, static_cast<int>(std::ceil(std::max(length / o.sample_mm, turn / o.sample_rad))));
  std::vector<HeadPose> close;
  for (int k = 0; k <= n; ++k) {
    const HeadPose p = between(from, to, static_cast<double>(k) / n);
    if (body.tooClose(p)) close.push_back(p);
  }
  if (close.empty()) return std::nullopt;
  constexpr std::size_t kMeasured = 8;
  const std::size_t stride = std::max<std::size_t>(1, close.size() / kMeasured);
  std::optional<PlanCollision> worst;
  for (std::size_t i = 0; i < close.size(); i += stride) {
    const BodyAgainstPart::Closest closest = body.clearance(close[i]);
    if (worst && closest.distance >= worst->clearance_mm) continue;
    PlanCollision c;
    c.solid = closest.solid != nullptr ? *closest.solid : std::string();
    c.obstacle = closest.obstacle != nullptr ? *closest.obstacle : std::string();
    c.clearance_mm = std::min(closest.distance, o.clearance_mm);
    c.head_mm = close[i].position;
    worst = c;
  }
  return worst;
}

}  // namespace

std::vector<PlanCollision> checkCollisions(const NominalModel& model, const ScanPlan& plan, const HeadDescription& head,
                                           const CollisionOptions& options) {
  return checkCollisions(model, {}, trace::RigidPose{}, plan, head, options);
}

std::vector<PlanCollision> checkCollisions(const NominalModel& model, const std::vector<BodySolid>& fixture,
                                           const trace::RigidPose& frame_from_datum, const ScanPlan& plan,
                                           const HeadDescription& head, const CollisionOptions& options) {
  std::vector<PlanCollision> found;
  std::vector<Obstacle> obstacles;
  if (!model.triangles.empty()) obstacles.push_back({"the part", meshOf(model), Eigen::Isometry3d::Identity()});
  const Eigen::Isometry3d datum = trace::toIsometry(frame_from_datum);
  for (const BodySolid& s : fixture)
    obstacles.push_back({"the fixture's " + s.name, shapeOf(s, 0), datum * trace::toIsometry(toRigidPose(s.placement))});
  if (head.body.empty() || obstacles.empty()) return found;
  const BodyAgainstPart body(std::move(obstacles), head, options.clearance_mm);
  std::optional<HeadPose> at;
  if (options.from_park) at = plan.park;
  const auto record = [&](std::optional<PlanCollision> c, std::size_t step, bool move) {
    if (!c) return;
    c->step = step;
    c->during_move = move;
    found.push_back(*c);
  };
  for (std::size_t k = 0; k < plan.steps.size(); ++k) {
    std::visit(
        [&](const auto& s) {
          using Step = std::decay_t<decltype(s)>;
          const HeadPose start = [&] {
            if constexpr (std::is_same_v<Step, SweepStep>) return s.start;
            else return s.pose;
          }();
          if (at) record(checkPath(body, *at, start, options), k, true);
          if constexpr (std::is_same_v<Step, SweepStep>) {
            record(checkPath(body, s.start, s.end, options), k, false);
            at = s.end;
          } else {
            record(checkPath(body, s.pose, s.pose, options), k, false);
            at = s.pose;
          }
        },
        plan.steps[k]);
  }
  return found;
}

std::string describe(const PlanCollision& c, const ScanPlan& plan, double clearance_mm) {
  char text[256];
  std::snprintf(text, sizeof text, "%s%s: the %s comes within %.1f mm of %s (the clearance is %.1f mm; head at %.1f, %.1f, %.1f mm)",
                c.during_move ? "the move to " : "", c.step < plan.steps.size() ? stepName(c.step, plan.steps[c.step]).c_str() : "?",
                c.solid.c_str(), c.clearance_mm, c.obstacle.empty() ? "the part" : c.obstacle.c_str(), clearance_mm,
                c.head_mm[0], c.head_mm[1], c.head_mm[2]);
  return text;
}

}  // namespace stampscan::acquisition
