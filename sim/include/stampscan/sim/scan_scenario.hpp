// A whole simulated session of the cell, in the form the devices deliver it: calibration scenes (the
// circle plate for the cameras, the reference sphere for the digitizer), then the part scanned by
// laser sweeps and by the stereo pair from several poses, with the CMM's positions and events, the
// PLC's state and the devices' clock readings. Messages go to a TraceSink (the MCAP writer) in
// log-time order. Deterministic for a given seed.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/acquisition/trace/trace_sink.hpp"
#include "stampscan/sim/camera_model.hpp"
#include "stampscan/sim/cmm_motion.hpp"
#include "stampscan/sim/digitizer_model.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/scene.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::sim {

using trace::TraceSink;

struct ScanParams {
  // The built-in virtual cell (acquisition::virtualCell()).
  ScanParams();

  // The cell as drawn (acquisition/cell_geometry.hpp): the sensors' nominal geometry, the artefacts
  // and the fixture. The simulated cell's true sensors are these plus the seed's deviation; its
  // reference sphere, ball bar and plate stand where the cell puts them. Set it with setCell().
  acquisition::CellGeometry cell;
  // The machine's travel, speeds and head (the planner parks within the travel and uses only an
  // indexing head's stops).
  acquisition::MachineLimits limits;
  // Takes the cell's geometry and copies its drawn values into the sensor models below (the
  // digitizer's optics, the cameras' intrinsics and bits, the stereo standoff, the artefacts).
  void setCell(const acquisition::CellConfig& config);

  PartKind part = PartKind::Dome;
  DomeParams dome;          // used when part is Dome
  StampedPanParams pan;     // used when part is Pan
  GridSpec grid;
  bool laser = true, stereo = true, calibration = true;
  std::uint64_t seed = 1;

  DigitizerSpec digitizer;
  double sweep_speed = 25;      // mm/s while the digitizer scans
  double strip_overlap = 0.3;   // share of a strip's width its neighbour covers again
  CameraIntrinsics camera;      // nominal; each camera's true values differ a little (by seed)
  CameraSensor camera_sensor;
  double image_scale = 1.0;     // resolution factor for quick runs (focal length scales with it)
  double stereo_standoff = 300; // mm from the cameras to the part
  int stereo_rows = 3, stereo_columns = 3;  // poses over the part
  int plate_poses = 12;
  int sphere_sweeps = 8;
  // Sweeps over the ball bar's second sphere (the length check of `station verify`); none in a scan.
  int second_sphere_sweeps = 0;
  CirclePlate plate;
  ReferenceSphere sphere;
  // The second sphere of the ball bar (when the cell has one).
  ReferenceSphere second_sphere{Vec3(250, -120, 40), 12.7, 0.6};
  bool has_second_sphere = true;
  // A knock to the digitizer's true mount (mm, head frame), on top of the seed's: a sensor that moved
  // since it was calibrated, for checking that `station verify` sees it and `station calibrate`
  // recovers from it. The nominal mount (what the station is told) does not move.
  Vec3 digitizer_mount_shift = Vec3::Zero();
  // Limits the laser strips and stereo poses to a part of the footprint (machine xy); empty = all.
  BlankRect scan_region{Vec2::Zero(), Vec2::Zero()};

  // A small session for tests and demos: a 40 x 30 mm region of the part, quarter-resolution images,
  // few poses and sweeps; the digitizer at its full resolution (the grid needs it).
  static ScanParams quick();
};

// The cell's true geometry and clocks, which calibration has to recover. The station only ever sees
// nominal values; these go into the trace as "simulation_truth" metadata for the tests.
struct CellTruth {
  CameraIntrinsics left, right;
  Eigen::Isometry3d head_from_left, head_from_right;  // camera frames on the head
  Eigen::Isometry3d head_from_digitizer;
  Eigen::Isometry3d head_from_digitizer_nominal;
  std::int64_t digitizer_clock_offset_ns = 0;  // digitizer clock minus station clock
  std::int64_t digitizer_latency_ns = 0;       // profile stamp minus its true exposure time
  std::int64_t camera_clock_offset_ns[2] = {0, 0};
  std::vector<Eigen::Isometry3d> plate_poses;  // machine_from_plate per calibration view (the plate stays put)
  ReferenceSphere sphere;
};

// The cell's true geometry and clocks for the parameters' seed (cameras' intrinsics and mounts, the
// digitizer's mount, latency and clock offsets). The simulated session and the virtual cell of the
// same seed share them.
CellTruth drawCellTruth(const ScanParams& params);

// The session description of a cell with these sensors, as drawn (nominal values): what a trace of
// it records, whichever executor plays the plan.
trace::SessionDescription describeSession(const ScanParams& params);

struct ScanSummary {
  double scan_seconds = 0;  // simulated duration of the session
  std::size_t profiles = 0, laser_points = 0, frames = 0, positions = 0, messages = 0;
  std::size_t grid_elements = 0;
  CellTruth truth;
};

using ScanProgress = std::function<void(double fraction, std::string_view stage)>;

// The session's plan: calibration views of the plate and sweeps over the reference sphere (when
// `calibration`), laser strips over the part (`laser`) and stereo poses (`stereo`). The simulator
// plays it below; the ScanRunner plays the same plan on a cell.
acquisition::ScanPlan planScan(const ScanParams& params);

// The drawing's mount of the digitizer on the head (the cell's [digitizer] mount): what plans and
// the session description use until calibration says better.
Eigen::Isometry3d nominalDigitizerMount(const ScanParams& params);

// Where the fixture holds the part's datum frame on the table (the cell's [fixture]): the simulated
// part, modelled in its datum frame, stands there.
Eigen::Isometry3d machineFromDatum(const ScanParams& params);

// Where the calibration plate stands on the table (machine_from_plate).
Eigen::Isometry3d platePose(const ScanParams& params);

// The formed part the parameters describe.
std::unique_ptr<FormedPart> makePart(const ScanParams& params);

// Builds the part, plans the session and streams it to `sink`.
ScanSummary generateScan(const ScanParams& params, TraceSink& sink, const ScanProgress& progress = {});

// The station clock's start: 2026-01-01T00:00:00Z in nanoseconds since the Unix epoch.
inline constexpr std::int64_t kSessionStartNs = 1767225600LL * 1000000000LL;

}  // namespace stampscan::sim
