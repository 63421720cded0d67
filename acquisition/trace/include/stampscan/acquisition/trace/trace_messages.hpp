// The messages of a scan trace: one type per device stream, encoded as ROS 2 CDR (little endian)
// with `ros2msg` schemas, so that MCAP tools (the mcap CLI, Foxglove) decode them without our code.
//
// Clocks, one name each:
//   - the station clock (`station_time_ns`, and every trace's log time): the station computer's
//     system clock in ns since the Unix epoch (acquisition/station_clock.hpp), the one time base of
//     a scan. The CMM's position reports stamped by the CMM controller's clock are put on it by the
//     smallest arrival delay seen (acquisition/scan_runner.cpp); the drivers' arrival stamps, taken
//     on std::chrono::steady_clock, by StationClock::fromSteady.
//   - a device clock (`device_time_ns`): the clock of the device that produced the message (the
//     digitizer's, a camera's); ClockSync messages pair it with the station clock.
//   - std::chrono::steady_clock: deadlines and intervals only (timeouts, arrival stamps in the
//     drivers), never written as a time of its own.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <iosfwd>
#include <optional>
#include <vector>

namespace stampscan::trace {

// Thrown when a message's bytes do not decode; the text names the type and the field.
class MessageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A CMM position report: the probe head's reference point and the indexing head's angles.
struct CmmPosition {
  std::int64_t station_time_ns = 0;
  double x = 0, y = 0, z = 0;        // mm, machine frame
  double head_a = 0, head_b = 0;     // rad: tilt about the ram's x axis, then turn about z
};

// The scenes a scan looks at. They bracket the recorded data (SceneMarker) and tell the measuring
// path which sweeps calibrate the digitizer and which measure the part; a plan's steps name theirs.
// In a trace and in a plan file each is its text, toString().
enum class Scene : std::uint8_t {
  Part,              // "part"
  ReferenceSphere,   // "reference_sphere"
  CalibrationPlate,  // "calibration_plate"
  // "second_sphere": the ball bar's second sphere, at a certified distance from the reference
  // sphere (the length check of `station verify`, ISO 10360-8's length measurement error).
  SecondSphere,
};
std::string_view toString(Scene scene);
std::optional<Scene> sceneFromString(std::string_view text);
std::ostream& operator<<(std::ostream& out, Scene scene);  // its text
// Every scene's text, for messages: "part, reference_sphere, calibration_plate, second_sphere".
std::string sceneNames();

// What a CMM event says. On the wire (the trace) each kind is its text, toString(); a trace that
// holds a kind this station does not know reads as Unknown.
enum class CmmEventKind : std::uint8_t {
  MoveBegin,       // "move_begin": a move between steps starts; detail: "home", "travel", "park"
  MoveEnd,         // "move_end"
  SweepBegin,      // "sweep_begin": a laser sweep starts; detail: the sweep's label
  SweepEnd,        // "sweep_end"
  SweepDiscarded,  // "sweep_discarded": the sweep of that label lost too many profiles and is run again
  ViewMissing,     // "view_missing": a stereo view got no frames from a camera; detail: which
  Abort,           // "abort": the scan stopped early; detail: why
  Unknown,         // any other text
};
std::string_view toString(CmmEventKind kind);
CmmEventKind cmmEventKindFromString(std::string_view text);
std::ostream& operator<<(std::ostream& out, CmmEventKind kind);  // its text

// A sweep's label, the detail of its events: "<scene> sweep <index>" ("part sweep 3").
std::string sweepLabel(Scene scene, std::uint32_t index);
// Whether a label is a sweep of that scene.
bool isSweepOf(const std::string& label, Scene scene);

// A CMM event: a move or a sweep started or ended, a view missing, an abort.
struct CmmEvent {
  std::int64_t station_time_ns = 0;
  CmmEventKind kind = CmmEventKind::Unknown;
  std::string detail;  // free text, e.g. the sweep's label or the abort's reason
};

// One profile of the laser digitizer: the fan swept once by the internal mirror. Point i was
// measured along the ray at angle angle_min + i * angle_increment in the sensor's x-z plane,
// measured from the sensor's -z axis towards +x. A range of 0 means no return.
struct LaserProfile {
  std::uint32_t sequence = 0;
  std::int64_t device_time_ns = 0;  // digitizer clock
  std::uint32_t status = 0;         // bit flags, see kProfile* below
  float angle_min = 0, angle_increment = 0;  // rad
  std::vector<float> range;                  // mm along the ray
  std::vector<std::uint16_t> intensity;      // 0..65535
};
inline constexpr std::uint32_t kProfileOk = 0;
inline constexpr std::uint32_t kProfileOverexposed = 1u << 0;
inline constexpr std::uint32_t kProfileMirrorFault = 1u << 1;

// A pair of readings of the station clock and a device clock taken together.
struct ClockSync {
  std::string device;  // "digitizer", "camera_left", ...
  std::int64_t station_time_ns = 0;
  std::int64_t device_time_ns = 0;
};

// A camera image, as the camera delivered it.
struct CameraFrame {
  std::string camera;               // "left" or "right"
  std::uint64_t frame_id = 0;       // the camera's block id
  std::uint64_t trigger_id = 0;     // the trigger pulse both cameras of a pair received
  std::int64_t device_time_ns = 0;  // camera clock, at exposure start
  std::uint32_t width = 0, height = 0;
  std::string encoding;             // "mono8" or "mono16" (little endian)
  std::uint32_t step = 0;           // bytes per row
  std::vector<std::uint8_t> data;
};

// The cell PLC's safety and I/O state.
struct PlcState {
  std::int64_t station_time_ns = 0;
  bool door_closed = false;
  bool estop_ok = false;
  bool light_curtain_clear = false;
  bool part_clamped = false;
  bool laser_shutter_open = false;
  std::uint8_t stack_light = 0;  // bit 0 green, 1 amber, 2 red
  std::uint32_t heartbeat = 0;
};

// Brackets the phases of a trace: which scene the sensors are looking at. A marker naming another
// scene does not decode (MessageError).
struct SceneMarker {
  std::int64_t station_time_ns = 0;
  Scene scene = Scene::Part;
  std::string phase;   // "begin" or "end"
  std::uint32_t index = 0;  // pose or sweep number within the scene
  std::string detail;
};

// Schema (ros2msg text) of each type, and its name, e.g. "stampscan_msgs/msg/LaserProfile".
struct MessageSchema {
  std::string_view name;
  std::string_view definition;
};
template <typename T>
MessageSchema schemaOf();

// CDR encoding with the 4-byte encapsulation header (CDR little endian).
std::vector<std::byte> encode(const CmmPosition& m);
std::vector<std::byte> encode(const CmmEvent& m);
std::vector<std::byte> encode(const LaserProfile& m);
std::vector<std::byte> encode(const ClockSync& m);
std::vector<std::byte> encode(const CameraFrame& m);
std::vector<std::byte> encode(const PlcState& m);
std::vector<std::byte> encode(const SceneMarker& m);

// Decoding; throws MessageError naming the type and field when the bytes are short or malformed.
template <typename T>
T decode(std::span<const std::byte> bytes);

// The trace's topics.
namespace topics {
inline constexpr std::string_view kCmmPosition = "/cmm/position";
inline constexpr std::string_view kCmmEvent = "/cmm/event";
inline constexpr std::string_view kLaserProfile = "/digitizer/profile";
inline constexpr std::string_view kClockSync = "/clock_sync";
inline constexpr std::string_view kCameraLeft = "/camera/left/frame";
inline constexpr std::string_view kCameraRight = "/camera/right/frame";
inline constexpr std::string_view kPlcState = "/plc/state";
inline constexpr std::string_view kScene = "/scan/scene";
// The schema of the messages on each of the topics above; throws std::invalid_argument otherwise.
MessageSchema schemaOfTopic(std::string_view topic);
}  // namespace topics

}  // namespace stampscan::trace
