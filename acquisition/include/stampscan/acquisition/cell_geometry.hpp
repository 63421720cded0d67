// The cell as drawn: its head, its sensors, the calibration artefacts on its table and the fixture
// that holds the part, with the values of their drawings and certificates. Part of the cell file
// (cell_config.hpp reads them from its [head], [digitizer], [cameras], [sphere], [ball_bar], [plate]
// and [fixture] sections). Calibration starts from these values and measures the true ones; plans
// are made with them; the virtual cell is built from them (its true sensors are the drawn ones
// plus the seed's deviation).
//
// Units: mm and degrees in the file (as the names say), mm and radians in code except where a name
// says `_deg`.
#pragma once

#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::acquisition {

// Where a thing stands in a parent frame: x_parent = R x + position, with R = Rz(rz) Ry(ry) Rx(rx)
// of rotation_deg = [rx, ry, rz] (turns about the parent's fixed x, then y, then z axes).
struct Placement {
  std::array<double, 3> position_mm{0, 0, 0};
  std::array<double, 3> rotation_deg{0, 0, 0};
  bool operator==(const Placement&) const = default;
};
trace::RigidPose toRigidPose(const Placement& placement);

// One simple solid of the head-and-sensor body, in the head frame (the CMM's reference point), or of
// the fixture, in the part's datum frame, for collision checks of the plans: a box (size_mm: its x, y, z extents, centred on the placement), a
// cylinder (radius_mm, length_mm along the placement's z, centred on it) or a sphere (radius_mm).
struct BodySolid {
  enum class Shape : std::uint8_t { Box, Cylinder, Sphere };
  std::string name;
  Shape shape = Shape::Box;
  Placement placement;
  std::array<double, 3> size_mm{0, 0, 0};
  double radius_mm = 0, length_mm = 0;
  bool operator==(const BodySolid&) const = default;
};
const char* toString(BodySolid::Shape shape);

// The CMM's articulating head ([head]). Its angle ranges, turning rate and acceleration are the
// machine's limits (MachineLimits), read from the same section.
struct HeadDescription {
  enum class Kind : std::uint8_t { Continuous, Indexing };
  Kind kind = Kind::Continuous;
  double index_step_deg = 7.5;  // an indexing head's step: it stops only at multiples of it
  std::vector<BodySolid> body;
  bool operator==(const HeadDescription&) const = default;
};
const char* toString(HeadDescription::Kind kind);

// The laser digitizer as its data sheet and the drawing of its mount give it ([digitizer]).
struct DigitizerDrawing {
  int points_per_profile = 1024;
  double profile_rate_hz = 500;
  double standoff_mm = 100;            // from the mirror to the middle of the measuring range
  double measuring_range_mm = 60;      // deep, centred on the standoff
  double fan_angle_deg = 24.064;       // the laser fan's full angle
  double incidence_limit_deg = 75;     // beyond it the sensor returns nothing
  double latency_ms = 3;               // nominal: a profile's stamp minus its exposure time
  Placement mount{{0, 0, -120}, {0, 0, 0}};  // head_from_digitizer: the mirror, looking down its -z
  bool operator==(const DigitizerDrawing&) const = default;
};

// The width of the laser's stripe on a surface at the standoff (mm): what one pass covers.
double stripeWidth(const DigitizerDrawing& digitizer);

// The stereo pair as drawn ([cameras]): one camera model for both, and the rig on the head. The
// cameras sit at x = -+baseline/2, drop_mm below the head's reference point, their optical axes
// crossing convergence_mm below the rig (OpenCV camera axes: x right, y down, z along the view).
struct CameraDrawing {
  int width = 2048, height = 1536;  // px
  double pixel_size_um = 3.45;
  double focal_length_mm = 16;
  double k1 = -0.08, k2 = 0.12;     // the lens's nominal radial distortion (OpenCV's model)
  int bits = 8;                     // 8 (Mono8) or 16 (Mono16)
  double exposure_us = 0;           // 0: the camera's own setting
  double baseline_mm = 120;
  double drop_mm = 60;
  double convergence_mm = 300;      // also the working distance the stereo views are planned at
  bool operator==(const CameraDrawing&) const = default;
};
trace::CameraIntrinsicsRecord nominalIntrinsics(const CameraDrawing& cameras);
// The same cameras binned by `factor` (0.25: a quarter of the width and height, pixels four times
// as large): the same field of view at a lower resolution. The virtual cell's quick scans use it.
CameraDrawing atResolution(const CameraDrawing& cameras, double factor);
// head_from_camera of the left (0) and right (1) camera as drawn.
trace::RigidPose nominalCameraMount(const CameraDrawing& cameras, int which);

// The calibration artefacts on the table ([sphere], [ball_bar], [plate]).
struct SphereArtefact {
  std::array<double, 3> centre_mm{250, 0, 40};  // where it stands, machine frame (to plan sweeps)
  double diameter_mm = 25.4;                    // its certificate
  bool operator==(const SphereArtefact&) const = default;
};
// The ball bar: a second sphere at a certified centre distance from the reference sphere, for the
// length check of `station verify`. A cell without one leaves [ball_bar] out.
struct BallBar {
  std::array<double, 3> centre_mm{250, -120, 40};  // the second sphere, machine frame
  double diameter_mm = 25.4;                       // its certificate
  double distance_mm = 120;                        // certified, between the two centres
  bool operator==(const BallBar&) const = default;
};
// The circle plate the cameras are calibrated on: columns x rows dots at pitch_mm; `placement` puts
// the dot pattern's centre on the table (machine frame), the plate facing its own +z.
struct PlateArtefact {
  int columns = 9, rows = 7;  // odd counts keep the pattern's orientation unambiguous
  double pitch_mm = 6, dot_diameter_mm = 3;
  Placement placement{{-250, 0, -40}, {8.6369, -5.665, 10.6001}};
  bool operator==(const PlateArtefact&) const = default;
};
trace::RigidPose machineFromPlate(const PlateArtefact& plate);  // dot (i, j) at (i, j) * pitch in the plate frame

// The fixture that holds the part ([fixture]): where the part's datum frame (the frame of its
// nominal model) is on the table, and what of it stands in the head's way ([[fixture.body]]: its
// base, clamps, locators as simple solids in the datum frame, checked against the head's body).
struct Fixture {
  std::string name;
  Placement datum;  // machine_from_datum
  std::vector<BodySolid> body;
  bool operator==(const Fixture&) const = default;
};

struct CellGeometry {
  HeadDescription head;
  DigitizerDrawing digitizer;
  CameraDrawing cameras;
  SphereArtefact sphere;
  std::optional<BallBar> ball_bar = BallBar{};
  PlateArtefact plate;
  Fixture fixture;
  bool operator==(const CellGeometry&) const = default;
};

// A plan's steps carried from the part's datum frame onto the cell's fixture. A part program's
// plan is written in the datum frame (the frame of its nominal model), so that one plan serves every
// cell; the fixture says where that frame is on the table. The part's sweeps and views (scene
// "part") move with the datum: the head's reference point, and its angles turned with it. The other
// scenes' steps (the calibration artefacts, already in the machine frame) and the park pose stay.
// A turn of the datum about z is carried exactly (b turns with it). A tilted datum, or a turn an
// indexing head cannot follow exactly (`index_step` > 0, rad), is matched by the nearest angles the
// head can take (the fan not rolled, the beam within the tilt), with the reference point moved so
// that a sweep's digitizer mirror, or the point a view's cameras aim at, stays where the datum puts it.
ScanPlan placeOnFixture(const ScanPlan& plan, const CellGeometry& cell, double index_step);
// A part's nominal model where the cell's fixture holds it: its vertices in the machine frame, the
// frame the scan's cloud and surface are in.
NominalModel placeOnFixture(const NominalModel& model, const CellGeometry& cell);

// The session description's part about the cell (digitizer, cameras, plate, sphere): what a trace
// of a session on this cell records as drawn. The part's fields are left to the caller.
trace::SessionDescription describeCell(const CellGeometry& cell);
// The description of a session of `plan` on this cell: the cell's part, and the plan's part, grid
// and name.
trace::SessionDescription describeSession(const CellGeometry& cell, const ScanPlan& plan);

}  // namespace stampscan::acquisition
