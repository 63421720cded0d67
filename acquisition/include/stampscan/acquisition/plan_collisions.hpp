// Does the head-and-sensor body keep clear of the part and the fixture along a plan? The body is the
// cell file's simple solids ([[head.body]]: boxes, cylinders, spheres in the head frame); the part is
// its nominal model, the fixture the cell file's solids of it ([[fixture.body]], in the part's datum
// frame). All are handed to FCL (the Flexible Collision Library motion planners use), which measures
// the least distance between each solid and the model's triangles. The head is followed along each
// sweep and each move between steps (the CMM moves all axes together, in a straight line, the head's
// angles turning with it) at poses a few millimetres apart, and every stretch that comes closer than
// the clearance is reported once, at its closest.
#pragma once

#include "stampscan/acquisition/cell_geometry.hpp"
#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/scan_plan.hpp"

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace stampscan::acquisition {

struct CollisionOptions {
  double clearance_mm = 5;      // the body must stay at least this far from the part
  double sample_mm = 2;         // poses along a path at most this far apart
  double sample_rad = 0.02;     // and at most this much turn of the head apart
  bool from_park = true;        // the move from the park to the first step (plan and model in one frame)
};

struct PlanCollision {
  std::size_t step = 0;       // index into plan.steps
  bool during_move = false;   // the move that reaches the step; else the step itself (its sweep, its view's pose)
  std::string solid;          // the body solid's name
  std::string obstacle;       // what it comes near: "the part", or "the fixture's NAME"
  double clearance_mm = 0;    // the least distance found there (0: touching or inside)
  std::array<double, 3> head_mm{0, 0, 0};  // the head's reference point at that pose
};

// The stretches of `plan` where a solid of `head.body` comes closer to `model` than the clearance;
// the plan and the model in one frame (both the datum frame, or both placed on the fixture). Empty
// when the head has no body solids.
std::vector<PlanCollision> checkCollisions(const NominalModel& model, const ScanPlan& plan, const HeadDescription& head,
                                           const CollisionOptions& options = {});
// The same with the fixture's solids (in the datum frame) as obstacles too: `frame_from_datum` carries
// them into the frame of the plan and the model (identity for the datum frame; the fixture's datum
// when both are placed on the fixture).
std::vector<PlanCollision> checkCollisions(const NominalModel& model, const std::vector<BodySolid>& fixture,
                                           const trace::RigidPose& frame_from_datum, const ScanPlan& plan,
                                           const HeadDescription& head, const CollisionOptions& options = {});

// "sweep part 3 (step 5): the sensor carrier comes within 1.2 mm of the part (the clearance is 5.0 mm;
// head at 10.0, -4.0, 152.3 mm)"; or "... of the fixture's clamp 2 ...".
std::string describe(const PlanCollision& collision, const ScanPlan& plan, double clearance_mm);

}  // namespace stampscan::acquisition
