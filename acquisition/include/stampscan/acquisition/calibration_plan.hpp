// The calibration scenes of a cell, planned from its file: views of the calibration plate for the
// stereo pair and sweeps over the reference sphere (and the ball bar's second sphere) for the
// digitizer, at head angles the head can take. What `station calibrate` and `station verify` run,
// and what a scan runs around its part when it calibrates itself.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_plan.hpp"

#include <cstdint>

namespace stampscan::acquisition {

struct CalibrationScenes {
  int plate_views = 12;
  int sphere_sweeps = 8;
  int second_sphere_sweeps = 0;  // over the ball bar's second sphere (verify's length check)
  std::uint64_t seed = 1;        // draws the plate views' directions
};

// The scenes the cell's calibration policy asks for ([calibration] plate_views, sphere_sweeps;
// `station verify` adds ball_bar_sweeps itself); `share` of them for a quick session (at least the
// fewest that calibrate: 4 of each).
CalibrationScenes calibrationScenes(const CalibrationPolicy& policy, double share = 1.0, std::uint64_t seed = 1);

// Appends the scenes to `plan`: the plate views, then the sphere sweeps, then the second sphere's.
// The plate views look at the plate from many directions and distances (the view diversity intrinsic
// calibration needs; with the plate fixed, the cameras' mount on the head is observable too). The
// sphere sweeps pass the ball through the left, middle and right of the fan and near and far in the
// measuring range (otherwise a turn of the mount could not be told from a shift), turn and tilt the
// head between sweeps (otherwise the mount's offset could not be told from the ball's position), and
// vary speed and direction (the latency shifts points along the sweep by speed times latency).
// Positions use the sensors' drawn mounts; angles are the head's nearest stops (limits.index_step).
void appendCalibrationScenes(const CellGeometry& cell, const MachineLimits& limits, const CalibrationScenes& scenes,
                             ScanPlan& plan);

// A plan of the scenes alone (parked and travelling as the built-in plans do).
ScanPlan calibrationPlan(const CellConfig& cell, const CalibrationScenes& scenes);

// The plan a scan that calibrates itself runs: the part's plan with the scenes where their
// computing overlaps the part's. The sphere's sweeps come first (every part sweep is measured with
// their calibration), then the part's sweeps, then the plate's views, then the part's views: the
// cameras calibrate just before the part's views need them, and while the head visits the plate
// the computer fits the sweeps' surface instead of sharing the cores with the views' images.
ScanPlan withCalibrationScenes(ScanPlan part_plan, const CellGeometry& cell, const MachineLimits& limits,
                               const CalibrationScenes& scenes);

}  // namespace stampscan::acquisition
