// A scan plan: what the cell does for one scan, as a plain value. The head's path through laser
// sweeps over the part and the calibration artefacts, and the poses at which the stereo pair is
// triggered, in the order they run. Two executors play the same plan: the ScanRunner on a cell
// (real or virtual) and the simulator (sim/scan_scenario.hpp), so a plan tried in simulation is the
// plan the cell runs.
//
// Plans come from the simulator's planner for the built-in parts (sim::planScan) or from a TOML
// file (loadScanPlan; `station sim part dome -o DIR` writes one, DIR/plan.toml):
//
//   name = "pan, laser"
//   travel_speed = 200            # mm/s between steps
//   park = [0, 0, 450]            # mm: where the head waits before and after
//   [part]
//   kind = "pan"                  # what is on the fixture
//   grid = "circle"               # the printed grid: circle or square
//   pitch = 2.54                  # mm; also circle_diameter and line_width
//   [[step]]
//   kind = "sweep"                # the digitizer scans from start to end at speed
//   scene = "part"                # part, reference_sphere, calibration_plate, second_sphere
//   start = [-30, -40, 160]       # mm: the head's reference point
//   end = [-30, 40, 160]
//   head = [0, -2]                # degrees: tilt a, turn b (see trace::headPose)
//   speed = 25                    # mm/s
//   expected_elements = 120       # optional: grid elements the planner predicts the sweep sees whole
//   [[step]]
//   kind = "stereo"               # the stereo pair is triggered at pose, after settling
//   scene = "part"
//   pose = [0, 0, 420]
//   head = [0, 0]
//
// Frames: a plan file gives the part's steps (scene = "part") in the part's datum frame, the frame of
// its nominal model, and the calibration artefacts' steps in the machine frame.
// acquisition::placeOnFixture (cell_geometry.hpp) carries the part's steps onto the cell's fixture;
// the executors play plans so placed. With the fixture's datum at the table's origin the two agree.
//
// Errors name the file, the line and the field.
#pragma once

#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace stampscan::acquisition {

// Where the CMM puts its head: the reference point (mm, machine frame; see Frames above) and the articulating head's
// angles (rad): tilt a about the ram's x axis, turn b about z.
struct HeadPose {
  std::array<double, 3> position{0, 0, 0};
  double a = 0, b = 0;
  bool operator==(const HeadPose&) const = default;
};

// The scenes a plan looks at (trace/trace_messages.hpp says what each is).
using trace::Scene;

struct SweepStep {
  Scene scene = Scene::Part;
  std::uint32_t index = 0;  // within the scene
  HeadPose start, end;      // the head moves from start to end in a straight line, angles fixed
  double speed = 25;        // mm/s
  // The grid elements the planner predicts this sweep sees whole (a part sweep); 0 when the plan
  // does not say. A scan that finds clearly fewer has not measured what it was planned to.
  std::uint32_t expected_elements = 0;
  bool operator==(const SweepStep&) const = default;
};

struct StereoStep {
  Scene scene = Scene::Part;
  std::uint32_t index = 0;
  HeadPose pose;
  double settle_s = 0.4;  // wait after arriving before the trigger
  bool operator==(const StereoStep&) const = default;
};

using PlanStep = std::variant<SweepStep, StereoStep>;

struct PartSpec {
  std::string kind = "pan";
  std::string grid = "circle";
  double pitch = 2.54, circle_diameter = 2.54, line_width = 0.15;  // mm
  bool operator==(const PartSpec&) const = default;
};

struct ScanPlan {
  std::string name;
  PartSpec part;
  double travel_speed = 200;  // mm/s
  HeadPose park{{0, 0, 450}, 0, 0};
  std::vector<PlanStep> steps;

  // Of one scene, or of all.
  std::size_t sweepCount(std::optional<Scene> scene = std::nullopt) const;
  std::size_t stereoCount(std::optional<Scene> scene = std::nullopt) const;
  bool operator==(const ScanPlan&) const = default;
};

// What the machine can do; a plan outside it is refused before anything moves.
struct MachineLimits {
  std::array<double, 3> travel_min{-400, -300, -100}, travel_max{400, 300, 600};  // mm
  double min_speed = 1, max_speed = 500;      // mm/s
  double acceleration = 1000;                 // mm/s^2, for the motion time
  // The articulating head's turning rate and acceleration, for the motion time: a move that turns
  // the head takes as long as its slowest axis needs (all axes of a GoTo start and finish together).
  double head_rate = 90 * 3.14159265358979323846 / 180;           // rad/s
  double head_acceleration = 360 * 3.14159265358979323846 / 180;  // rad/s^2
  double max_tilt = 115 * 3.14159265358979323846 / 180;  // |a|, rad
  double max_turn = 3.14159265358979323846;              // |b|, rad
  // An indexing head stops only at multiples of its step (rad); 0: a continuous head.
  double index_step = 0;
};

// Where a generated plan starts and ends, clear of everything on the table: the middle of the
// travel in x and y, 150 mm below its top (or its middle, on a machine less than 300 mm high), the
// head level.
HeadPose parkingPose(const MachineLimits& limits);

// How messages name the plan's step k (0-based): "step 3 (sweep part 2)".
std::string stepName(std::size_t k, const PlanStep& step);

// The head angle (rad) the head can take nearest to `angle`: the angle itself on a continuous head,
// the nearest multiple of its step on an indexing head (limits.index_step). Planners use it.
double nearestHeadStop(double angle, const MachineLimits& limits);

// The plan's problems against the limits, one line each ("step 3 (sweep part 2): end x = 450 mm is
// outside the travel -400..400"); empty when it can run.
std::vector<std::string> checkPlan(const ScanPlan& plan, const MachineLimits& limits);

// The time the machine needs for the plan: trapezoidal moves at the plan's speeds, settling times.
double motionSeconds(const ScanPlan& plan, const MachineLimits& limits);
// One straight move's time at up to `speed`: accelerate, cruise, brake (a triangle when short); a
// move that turns the head is as slow as the turn needs at the head's rate and acceleration.
double moveSeconds(const HeadPose& from, const HeadPose& to, double speed, const MachineLimits& limits);

// The CMM's position reports during a move: I++ DME sends at most ten a second (§6.3.2.7).
inline constexpr double kCmmReportInterval = 0.1;  // s
// How far a sweep travels at each end before the head's track can be trusted. The track is
// interpolated between the CMM's position reports; across the report interval in which the head
// starts (or stops), and the one next to it, the velocity changes and a straight line between two
// reports is off by up to a tenth of a millimetre, so the measurement leaves those intervals out
// (registration's HeadTrack::chordError): at most two report intervals of travel at the sweep's
// speed, to which the distance to reach that speed is added as a margin. A plan starts and ends its
// sweeps at least this far beyond what they are to measure.
double sweepRunUp(double speed, double acceleration, double report_interval_s = kCmmReportInterval);

class PlanError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads a plan file; throws PlanError naming the file, line and field.
ScanPlan loadScanPlan(const std::filesystem::path& file);
ScanPlan parseScanPlan(const std::string& toml_text, const std::string& source_name);
// The plan as a plan file (parseScanPlan reads it back equal).
std::string toToml(const ScanPlan& plan);

}  // namespace stampscan::acquisition
