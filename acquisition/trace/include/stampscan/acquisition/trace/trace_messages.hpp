// The messages of a scan trace: one type per device stream, encoded as ROS 2 CDR (little endian)
// with `ros2msg` schemas, so that MCAP tools (the mcap CLI, Foxglove) decode them without our code.
//
// Clocks: `station_time_ns` is the station clock, which is the CMM controller's clock (the station
// takes its time base from the CMM's position reports). `device_time_ns` is the clock of the device
// that produced the message; ClockSync messages pair the two.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
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

// A CMM event: move started or ended, sweep started or ended, error, abort.
struct CmmEvent {
  std::int64_t station_time_ns = 0;
  std::string kind;    // e.g. "move_begin", "move_end", "sweep_begin", "sweep_end", "error"
  std::string detail;  // free text, e.g. the sweep id or the error
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

// Brackets the phases of a trace: which scene the sensors are looking at.
struct SceneMarker {
  std::int64_t station_time_ns = 0;
  std::string scene;   // "calibration_plate", "reference_sphere", "part"
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
