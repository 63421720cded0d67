// Scan plans from a part's nominal model and the cell's sensors, and what a plan is predicted to see.
//
// The planner works in the part's datum frame (the nominal model's frame, where a part program's
// plan is written; placeOnFixture carries it onto a cell's table). It lays laser passes across the
// model's grid area from one side to the other, each a straight sweep at one height: where the
// model's surface under a pass spans more than the sensor's measuring range (a deep pan), the pass is
// flown at several heights, each covering a band of the depth. The fan widens with the distance, so
// each pass flies as high as keeps the lowest surface of its band within the share of the measuring
// range a band may take. Each pass claims the samples of the grid area its fan meets within the
// band's depth and the incidence limit, but for a margin at either edge of the fan, and the passes
// are laid greedily from one side: each as far on as still claims everything left of it. So they lie
// wider apart over low and flat ground than over crowns and slopes. The margin makes neighbouring
// stripes overlap by the stated share of the fan and never by less than a formed element and the
// part's placement tolerance (every element lies whole within one stripe); where less overlap, down to
// that least, saves passes, the passes are as few as it allows and spread with the most overlap that
// count leaves. Passes cross at +-2 degrees (the paper's Sec. 3.1; each pass takes the turn that lets
// it reach further, the stripe slanted by it) and are flown in alternate directions, so that the move
// from one pass's end to the next's start is short. The stereo pair looks at the grid area from a
// rows x columns lattice of poses, the outer ones tilted inwards so that the walls are seen. Head
// angles are the head's nearest stops (an indexing head).
//
// The prediction samples the model's grid area (its facets facing the sensors' side) at a stated
// spacing and asks of each sample what the cell's sensors see of it in each part step
// (sensor_sight.hpp, the model the virtual cell's yardstick uses too): whether one part sweep
// crosses it with the fan within the measuring range and the incidence limit, away from the sweep's
// run-ups; and whether both cameras of one part view have it inside their images at an angle they
// can resolve, its printed line wide enough. Each line of sight (to the digitizer's mirror, to each
// camera) is cast with Embree against the model itself and the fixture's solids (the cell's
// [[fixture.body]], in the datum frame), so a wall that hides a pocket's floor, or a clamp over the
// part, hides it here too.
#pragma once

#include "stampscan/acquisition/cell_geometry.hpp"
#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/scan_plan.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace stampscan::acquisition {

struct PlannerOptions {
  bool laser = true, stereo = true;
  // The share of a pass's fan that overlaps its neighbour's. Where less overlap saves passes the
  // planner takes it, down to what keeps every element whole within one stripe: on each side half a
  // formed element (the printed one stretched by 40 %) and the tolerance of the part's place.
  double strip_overlap = 0.1;
  double placement_tolerance_mm = 0.5;
  // A sweep along which the head's body (the cell's [[head.body]]) would come nearer the part or the
  // fixture than the clearance is left out, and what only it would have seen is predicted unseen.
  bool leave_out_colliding_sweeps = true;
  double clearance_mm = 5;
  // How far the head moves between two of the digitizer's profiles while it sweeps (mm). The sweep
  // speed follows from it and the digitizer's drawn profile rate, so that a slower or faster
  // digitizer lays its profiles as densely as any other (25 mm/s at 500 Hz). A sweep speed set
  // here (mm/s, > 0) is taken as it is instead.
  double profile_spacing_mm = 0.05;
  double sweep_speed = 0;
  double travel_speed = 200;    // mm/s between steps
  double depth_use = 0.8;       // the share of the measuring range one pass's depth band may take
  int stereo_rows = 3, stereo_columns = 3;
  // The grid area: facets whose normal points to the sensors' side (+z of the datum frame) at least
  // this much (its z component). Sheet parts are printed on their open side.
  double grid_normal_z = 0.05;
  double sample_spacing_mm = 1.0;  // how densely the grid area is sampled to plan and predict
};

// The speed of the part sweeps (mm/s): options.sweep_speed when set, else the profile spacing times
// the digitizer's profile rate, within the machine's speeds.
double sweepSpeed(const PlannerOptions& options, const CellGeometry& cell, const MachineLimits& limits);

// A plan of laser passes and stereo views over `model` (datum frame) for the cell's sensors; the part
// section says the grid. Throws std::invalid_argument for a model with no grid area or options out of
// range.
ScanPlan planPart(const NominalModel& model, const PartSpec& part, const CellGeometry& cell, const MachineLimits& limits,
                  const PlannerOptions& options = {});

struct CoverageOptions {
  double sample_spacing_mm = 1.0;
  double grid_normal_z = 0.05;
  double image_border_px = 20;          // a sample must be this far inside each image
  double camera_max_incidence_deg = 60; // beyond it a camera cannot resolve the printed line
  bool occlusion = true;                // cast each line of sight against the model
  double occlusion_tolerance_mm = 0.1;  // a line of sight may end this far before the sample
};

struct Coverage {
  // The samples of the grid area (datum frame), each standing for `sample_area` mm^2 around it.
  std::vector<std::array<double, 3>> points;
  std::vector<double> sample_area;
  // Per sample: the part sweeps that see it (a count), and whether a part view's both cameras do.
  std::vector<std::uint16_t> laser_passes;
  std::vector<std::uint8_t> stereo;
  // Per part sweep of the plan, in its order: the grid area it sees (mm^2).
  std::vector<double> sweep_area;
  double grid_area = 0;                          // mm^2
  double laser_area = 0, stereo_area = 0, either_area = 0;
  double overlap_area = 0;                       // seen by two or more sweeps
  double share(double area) const { return grid_area > 0 ? area / grid_area : 0; }
};

// What the part steps of `plan` are predicted to see of the model's grid area (the plan and the model
// in one frame). The limits give the sweeps' run-ups (the machine's acceleration).
Coverage predictCoverage(const NominalModel& model, const ScanPlan& plan, const CellGeometry& cell,
                         const MachineLimits& limits, const CoverageOptions& options = {});

// A lower bound of the part's scanning time: the grid area over the stripe's width (at the standoff)
// times the sweep speed. The head's moves (from the park, between the sweeps, back) come on top:
// compare a plan's motion with this plus its moves, and its sweeping (sweepingSeconds) with this.
double scanTimeLowerBound(double grid_area, const CellGeometry& cell, double sweep_speed);
// The same with the widest stripe the digitizer lays (at the far end of its measuring range): no
// plan can scan the grid area faster. A plan that flies higher than the standoff over flat ground
// can beat the bound above, not this one.
double scanTimeFloor(double grid_area, const CellGeometry& cell, double sweep_speed);
// The time a plan's part sweeps take themselves, from start to end with their run-ups; the rest of
// its motion time is the head's moves and the stereo views.
double sweepingSeconds(const ScanPlan& plan, const MachineLimits& limits);

}  // namespace stampscan::acquisition
