// Which grid elements of a part a scan plan can see at all, from the simulator's truth: the
// yardstick for the share of the visible elements a scan finds. An element is visible when its
// whole printed outline (the ring, or the square cell, out to the outer edge of its line) is seen
// by one sensor at once, in one part sweep of the plan or in one part view: what a sensor sees is
// the station's own model of it (acquisition/sensor_sight.hpp), which the planner's coverage
// prediction uses too. Here it is asked of the simulator's world: the formed part (its polished
// spots, and what hides what), the cell's true mounts and intrinsics (drawCellTruth), and the
// digitizer's returns up to the incidence where it loses 5 % of its points at random (beyond
// DigitizerSpec::steep_from, towards its limit max_incidence, it loses more and more, and an outline
// with many holes in it is not measured). The plan's head poses are taken as commanded. Nothing here looks at what was
// measured.
#pragma once

#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <cstddef>
#include <cstdint>
#include <numbers>
#include <vector>

namespace stampscan::sim {

struct VisibilityParams {
  int outline_samples = 24;          // points around each element's outline
  double image_border_px = 20;       // the outline must be this far inside each image
  // Beyond 60 degrees a ring's minor axis is under half its size and its printed line well under a
  // pixel wide in the images: the cameras cannot resolve it (the laser still may).
  double camera_max_incidence = std::numbers::pi / 3;
  double occlusion_tolerance_mm = 0.1;  // a line of sight may end this far before the point
  // A printed line narrower than a pixel in an image cannot be located in it (the stereo path wants
  // about 1.5 px): at full resolution the lines are some 1.7 px wide at the working distance, in the
  // quarter-resolution images of a quick session under half a pixel.
  double min_line_px = 1.0;
  // The share of an outline's laser returns the station's search measures it without (a lone lost
  // return is filled, a ray passes a short hole; about 6 % at random still finds 99 % of the
  // elements): beyond the incidence where the digitizer loses more, its outlines are not seen whole.
  double laser_loss_measured = 0.05;
  // The sweeps' run-ups (acquisition::sweepRunUp): the cell's position reports and acceleration.
  double report_interval_s = acquisition::kCmmReportInterval;
  double acceleration = acquisition::MachineLimits{}.acceleration;
};

struct ElementVisibility {
  // Per element of the truth cloud, in its order: 1 when seen whole by that sensor.
  std::vector<std::uint8_t> laser, stereo;
  // Per part sweep of the plan, in its order: how many elements that sweep sees whole.
  std::vector<std::uint32_t> laser_per_sweep;
  bool visible(std::size_t i) const { return laser[i] != 0 || stereo[i] != 0; }
  std::size_t visibleCount() const;
  // 1 where either sensor sees the element whole.
  std::vector<std::uint8_t> visibleOr() const;
};

// `truth` is groundTruth(makePart(world), world.grid, machineFromDatum(world)): the elements on the
// fixture (its material_u/v scalars give each element's printed outline). The plan is as the machine
// runs it (placeOnFixture): its part sweeps and part views are the poses considered.
ElementVisibility visibleElements(const ScanParams& world, const acquisition::ScanPlan& plan,
                                  const fitting::Cloud& truth, const VisibilityParams& params = {});

// The plan's part sweeps with the planner's prediction of what each sees (SweepStep::expected_elements).
void predictElements(acquisition::ScanPlan& plan, const ElementVisibility& visibility);

}  // namespace stampscan::sim
