// The typed description of a scan session that every trace carries: what was scanned (part, grid,
// plan), on what (the digitizer's and the cameras' nominal geometry, the calibration artefacts),
// and which clock the station times are on. Encoded into the trace's "cell" metadata record and
// decoded from it here and nowhere else, so the writer (the simulator, the ScanRunner) and the
// readers (registration, `station trace`) cannot drift apart.
//
// The record is MCAP metadata, a map of strings: numbers are written with 17 significant digits
// (they read back exactly), a pose as 12 numbers, row-major [R | t] with t in mm. Decoding checks
// every field and names the key and what was wrong.
#pragma once

#include "stampscan/acquisition/trace/mcap_records.hpp"

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace stampscan::trace {

// What a trace's station times are (the clocks: trace_messages.hpp).
inline constexpr char kStationClockText[] = "the station computer's system clock, ns since the Unix epoch";

// A rigid transform: x' = R x + t. Row-major rotation; mm.
struct RigidPose {
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> translation{0, 0, 0};
  bool operator==(const RigidPose&) const = default;
};

// The pinhole-with-distortion model of OpenCV (k1 k2 p1 p2 k3), in pixels of a width x height image.
struct CameraIntrinsicsRecord {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0, k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
  bool operator==(const CameraIntrinsicsRecord&) const = default;
};

// The circle plate the cameras are calibrated on: columns x rows dots at `pitch`.
struct PlateRecord {
  int columns = 0, rows = 0;
  double pitch_mm = 0, dot_diameter_mm = 0;
  bool operator==(const PlateRecord&) const = default;
};

struct SessionDescription {
  // What was scanned.
  std::string part;           // the part's kind or number, e.g. "dome", "pan"
  std::string part_id;        // the operator's id of this part; may be empty
  std::string plan;           // the scan plan's name; may be empty
  std::string plan_toml;      // the whole plan as the machine ran it (placed on the fixture), so that a replay can run it again; may be empty
  std::string fixture;        // the fixture the part sits in; may be empty
  std::string grid = "circle";  // the printed grid: "circle" or "square"
  double grid_pitch_mm = 2.54;
  double grid_circle_diameter_mm = 2.54;
  double grid_line_width_mm = 0.15;

  // The digitizer: its profile format and its nominal mount on the head.
  int digitizer_points_per_profile = 0;
  double digitizer_profile_rate_hz = 0;
  double digitizer_standoff_mm = 0;
  double digitizer_measuring_range_mm = 0;
  RigidPose head_from_digitizer_nominal;

  // The stereo pair, when the session has one.
  std::optional<CameraIntrinsicsRecord> camera_nominal;
  int camera_bits = 8;
  double stereo_half_baseline_mm = 0;

  // The calibration artefacts, when the session has calibration scenes.
  std::optional<PlateRecord> plate;
  std::optional<double> reference_sphere_radius_mm;

  std::string station_clock = kStationClockText;  // what the trace's station times are (trace_messages.hpp)

  bool operator==(const SessionDescription&) const = default;
};

// The metadata record's name in the trace.
inline constexpr std::string_view kSessionMetadataName = "cell";

// Thrown when the record is missing a field or a field does not parse; the text names the key.
class SessionDescriptionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

KeyValues encodeSession(const SessionDescription& session);
SessionDescription decodeSession(const KeyValues& record);

// Shared text forms of the record's values (also used for other records, e.g. the simulator's truth).
std::string formatNumber(double value);
std::string formatPose(const RigidPose& pose);
// Throws SessionDescriptionError naming `key`.
RigidPose parsePose(const std::string& text, std::string_view key);

}  // namespace stampscan::trace
