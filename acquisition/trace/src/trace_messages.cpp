// CDR (OMG XCDR version 1, little endian, as ROS 2 writes it): a 4-byte encapsulation header, then
// each primitive aligned to its own size counted from the end of the header; strings are a uint32
// length that includes the terminating NUL, then the bytes and the NUL; sequences a uint32 count then
// the elements.
#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <ostream>

#include <bit>
#include <cstring>
#include <type_traits>

namespace stampscan::trace {

static_assert(std::endian::native == std::endian::little, "the CDR codec assumes a little-endian host");

namespace {

constexpr std::byte kHeader[4] = {std::byte{0x00}, std::byte{0x01}, std::byte{0x00}, std::byte{0x00}};

class CdrWriter {
 public:
  CdrWriter() { out_.assign(std::begin(kHeader), std::end(kHeader)); }
  template <typename T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    append(&value, sizeof(T));
  }
  void put(bool value) { put(static_cast<std::uint8_t>(value ? 1 : 0)); }
  void put(const std::string& s) {
    put(static_cast<std::uint32_t>(s.size() + 1));
    append(s.data(), s.size());
    out_.push_back(std::byte{0});
  }
  template <typename T>
  void put(const std::vector<T>& v) {
    put(static_cast<std::uint32_t>(v.size()));
    if (v.empty()) return;
    align(sizeof(T));
    append(v.data(), v.size() * sizeof(T));
  }
  std::vector<std::byte> take() { return std::move(out_); }

 private:
  void align(std::size_t n) {
    while ((out_.size() - 4) % n) out_.push_back(std::byte{0});
  }
  // resize + memcpy rather than insert: GCC 12 warns falsely (stringop-overflow) on the latter.
  void append(const void* data, std::size_t n) {
    if (n == 0) return;
    const std::size_t at = out_.size();
    out_.resize(at + n);
    std::memcpy(out_.data() + at, data, n);
  }
  std::vector<std::byte> out_;
};

class CdrReader {
 public:
  CdrReader(std::span<const std::byte> bytes, const char* type) : in_(bytes), type_(type) {
    if (in_.size() < 4) fail("header", "message shorter than the 4-byte CDR header");
    if (in_[1] != std::byte{0x01}) fail("header", "not little-endian CDR (representation id 0x0001)");
    pos_ = 4;
  }
  template <typename T>
  T get(const char* field) {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    need(sizeof(T), field);
    T value;
    std::memcpy(&value, in_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  bool getBool(const char* field) {
    const auto v = get<std::uint8_t>(field);
    if (v > 1) fail(field, "boolean is neither 0 nor 1");
    return v == 1;
  }
  std::string getString(const char* field) {
    const auto n = get<std::uint32_t>(field);
    if (n == 0) fail(field, "string length 0 (must count the NUL)");
    need(n, field);
    if (in_[pos_ + n - 1] != std::byte{0}) fail(field, "string not NUL-terminated");
    std::string s(reinterpret_cast<const char*>(in_.data() + pos_), n - 1);
    pos_ += n;
    return s;
  }
  template <typename T>
  std::vector<T> getVector(const char* field) {
    const auto n = get<std::uint32_t>(field);
    std::vector<T> v;
    if (n == 0) return v;
    align(sizeof(T));
    if (static_cast<std::size_t>(n) > (in_.size() - pos_) / sizeof(T)) fail(field, "sequence longer than the message");
    v.resize(n);
    std::memcpy(v.data(), in_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    return v;
  }

 private:
  void align(std::size_t n) {
    while ((pos_ - 4) % n) ++pos_;
  }
  void need(std::size_t n, const char* field) {
    if (pos_ > in_.size() || n > in_.size() - pos_) fail(field, "message ends early");
  }
  [[noreturn]] void fail(const char* field, const char* what) {
    throw MessageError(std::string(type_) + "." + field + ": " + what);
  }
  std::span<const std::byte> in_;
  std::size_t pos_ = 0;
  const char* type_;
};

}  // namespace

// ---- Schemas -------------------------------------------------------------------------------------

template <>
MessageSchema schemaOf<CmmPosition>() {
  return {"stampscan_msgs/msg/CmmPosition",
          "# CMM position report: probe head reference point (mm, machine frame) and head angles (rad).\n"
          "int64 station_time_ns\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 head_a\nfloat64 head_b\n"};
}
template <>
MessageSchema schemaOf<CmmEvent>() {
  return {"stampscan_msgs/msg/CmmEvent", "# CMM event: move_begin, move_end, sweep_begin, sweep_end, sweep_discarded, view_missing, abort.\n"
                                         "int64 station_time_ns\nstring kind\nstring detail\n"};
}
template <>
MessageSchema schemaOf<LaserProfile>() {
  return {"stampscan_msgs/msg/LaserProfile",
          "# One laser digitizer profile. Point i lies along the ray at angle_min + i * angle_increment\n"
          "# (rad, in the sensor x-z plane, from -z towards +x), at `range` mm; range 0 is no return.\n"
          "uint32 sequence\nint64 device_time_ns\nuint32 status\nfloat32 angle_min\nfloat32 angle_increment\n"
          "float32[] range\nuint16[] intensity\n"};
}
template <>
MessageSchema schemaOf<ClockSync>() {
  return {"stampscan_msgs/msg/ClockSync", "# A station clock reading and a device clock reading taken together.\n"
                                          "string device\nint64 station_time_ns\nint64 device_time_ns\n"};
}
template <>
MessageSchema schemaOf<CameraFrame>() {
  return {"stampscan_msgs/msg/CameraFrame",
          "# A camera image as delivered: block id, trigger pulse id, camera clock at exposure start.\n"
          "string camera\nuint64 frame_id\nuint64 trigger_id\nint64 device_time_ns\nuint32 width\nuint32 height\n"
          "string encoding\nuint32 step\nuint8[] data\n"};
}
template <>
MessageSchema schemaOf<PlcState>() {
  return {"stampscan_msgs/msg/PlcState",
          "# Cell PLC safety and I/O state. stack_light: bit 0 green, 1 amber, 2 red.\n"
          "int64 station_time_ns\nbool door_closed\nbool estop_ok\nbool light_curtain_clear\nbool part_clamped\n"
          "bool laser_shutter_open\nuint8 stack_light\nuint32 heartbeat\n"};
}
template <>
MessageSchema schemaOf<SceneMarker>() {
  return {"stampscan_msgs/msg/SceneMarker",
          "# Brackets a phase of the scan: scene is part, reference_sphere, calibration_plate or second_sphere.\n"
          "int64 station_time_ns\nstring scene\nstring phase\nuint32 index\nstring detail\n"};
}

MessageSchema topics::schemaOfTopic(std::string_view topic) {
  if (topic == kCmmPosition) return schemaOf<CmmPosition>();
  if (topic == kCmmEvent) return schemaOf<CmmEvent>();
  if (topic == kLaserProfile) return schemaOf<LaserProfile>();
  if (topic == kClockSync) return schemaOf<ClockSync>();
  if (topic == kCameraLeft || topic == kCameraRight) return schemaOf<CameraFrame>();
  if (topic == kPlcState) return schemaOf<PlcState>();
  if (topic == kScene) return schemaOf<SceneMarker>();
  throw std::invalid_argument("no schema for topic '" + std::string(topic) + "'");
}

// ---- Encoding ------------------------------------------------------------------------------------

std::vector<std::byte> encode(const CmmPosition& m) {
  CdrWriter w;
  w.put(m.station_time_ns);
  w.put(m.x);
  w.put(m.y);
  w.put(m.z);
  w.put(m.head_a);
  w.put(m.head_b);
  return w.take();
}
namespace {
constexpr std::pair<CmmEventKind, std::string_view> kCmmEventKinds[] = {
    {CmmEventKind::MoveBegin, "move_begin"},   {CmmEventKind::MoveEnd, "move_end"},
    {CmmEventKind::SweepBegin, "sweep_begin"}, {CmmEventKind::SweepEnd, "sweep_end"},
    {CmmEventKind::SweepDiscarded, "sweep_discarded"}, {CmmEventKind::ViewMissing, "view_missing"},
    {CmmEventKind::Abort, "abort"},
};
}  // namespace

std::string_view toString(CmmEventKind kind) {
  for (const auto& [k, text] : kCmmEventKinds)
    if (k == kind) return text;
  return "unknown";
}

CmmEventKind cmmEventKindFromString(std::string_view text) {
  for (const auto& [k, name] : kCmmEventKinds)
    if (name == text) return k;
  return CmmEventKind::Unknown;
}

namespace {
constexpr std::pair<Scene, std::string_view> kScenes[] = {
    {Scene::Part, "part"},
    {Scene::ReferenceSphere, "reference_sphere"},
    {Scene::CalibrationPlate, "calibration_plate"},
    {Scene::SecondSphere, "second_sphere"},
};
}  // namespace

std::string_view toString(Scene scene) {
  for (const auto& [s, text] : kScenes)
    if (s == scene) return text;
  return "part";  // every enumerator is listed above
}

std::optional<Scene> sceneFromString(std::string_view text) {
  for (const auto& [s, name] : kScenes)
    if (name == text) return s;
  return std::nullopt;
}

std::ostream& operator<<(std::ostream& out, Scene scene) { return out << toString(scene); }
std::ostream& operator<<(std::ostream& out, CmmEventKind kind) { return out << toString(kind); }

std::string sceneNames() {
  std::string names;
  for (const auto& [s, name] : kScenes) {
    if (!names.empty()) names += ", ";
    names += name;
  }
  return names;
}

std::string sweepLabel(Scene scene, std::uint32_t index) {
  std::string label(toString(scene));
  label += " sweep ";
  label += std::to_string(index);
  return label;
}

bool isSweepOf(const std::string& label, Scene scene) {
  std::string prefix(toString(scene));
  prefix += " sweep ";
  return label.rfind(prefix, 0) == 0;
}

std::vector<std::byte> encode(const CmmEvent& m) {
  CdrWriter w;
  w.put(m.station_time_ns);
  w.put(std::string(toString(m.kind)));
  w.put(m.detail);
  return w.take();
}
std::vector<std::byte> encode(const LaserProfile& m) {
  CdrWriter w;
  w.put(m.sequence);
  w.put(m.device_time_ns);
  w.put(m.status);
  w.put(m.angle_min);
  w.put(m.angle_increment);
  w.put(m.range);
  w.put(m.intensity);
  return w.take();
}
std::vector<std::byte> encode(const ClockSync& m) {
  CdrWriter w;
  w.put(m.device);
  w.put(m.station_time_ns);
  w.put(m.device_time_ns);
  return w.take();
}
std::vector<std::byte> encode(const CameraFrame& m) {
  CdrWriter w;
  w.put(m.camera);
  w.put(m.frame_id);
  w.put(m.trigger_id);
  w.put(m.device_time_ns);
  w.put(m.width);
  w.put(m.height);
  w.put(m.encoding);
  w.put(m.step);
  w.put(m.data);
  return w.take();
}
std::vector<std::byte> encode(const PlcState& m) {
  CdrWriter w;
  w.put(m.station_time_ns);
  w.put(m.door_closed);
  w.put(m.estop_ok);
  w.put(m.light_curtain_clear);
  w.put(m.part_clamped);
  w.put(m.laser_shutter_open);
  w.put(m.stack_light);
  w.put(m.heartbeat);
  return w.take();
}
std::vector<std::byte> encode(const SceneMarker& m) {
  CdrWriter w;
  w.put(m.station_time_ns);
  w.put(std::string(toString(m.scene)));
  w.put(m.phase);
  w.put(m.index);
  w.put(m.detail);
  return w.take();
}

// ---- Decoding ------------------------------------------------------------------------------------

template <>
CmmPosition decode<CmmPosition>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "CmmPosition");
  CmmPosition m;
  m.station_time_ns = r.get<std::int64_t>("station_time_ns");
  m.x = r.get<double>("x");
  m.y = r.get<double>("y");
  m.z = r.get<double>("z");
  m.head_a = r.get<double>("head_a");
  m.head_b = r.get<double>("head_b");
  return m;
}
template <>
CmmEvent decode<CmmEvent>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "CmmEvent");
  CmmEvent m;
  m.station_time_ns = r.get<std::int64_t>("station_time_ns");
  m.kind = cmmEventKindFromString(r.getString("kind"));
  m.detail = r.getString("detail");
  return m;
}
template <>
LaserProfile decode<LaserProfile>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "LaserProfile");
  LaserProfile m;
  m.sequence = r.get<std::uint32_t>("sequence");
  m.device_time_ns = r.get<std::int64_t>("device_time_ns");
  m.status = r.get<std::uint32_t>("status");
  m.angle_min = r.get<float>("angle_min");
  m.angle_increment = r.get<float>("angle_increment");
  m.range = r.getVector<float>("range");
  m.intensity = r.getVector<std::uint16_t>("intensity");
  if (m.intensity.size() != m.range.size())
    throw MessageError("LaserProfile.intensity: " + std::to_string(m.intensity.size()) + " values for " +
                       std::to_string(m.range.size()) + " ranges");
  return m;
}
template <>
ClockSync decode<ClockSync>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "ClockSync");
  ClockSync m;
  m.device = r.getString("device");
  m.station_time_ns = r.get<std::int64_t>("station_time_ns");
  m.device_time_ns = r.get<std::int64_t>("device_time_ns");
  return m;
}
template <>
CameraFrame decode<CameraFrame>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "CameraFrame");
  CameraFrame m;
  m.camera = r.getString("camera");
  m.frame_id = r.get<std::uint64_t>("frame_id");
  m.trigger_id = r.get<std::uint64_t>("trigger_id");
  m.device_time_ns = r.get<std::int64_t>("device_time_ns");
  m.width = r.get<std::uint32_t>("width");
  m.height = r.get<std::uint32_t>("height");
  m.encoding = r.getString("encoding");
  m.step = r.get<std::uint32_t>("step");
  m.data = r.getVector<std::uint8_t>("data");
  const std::uint32_t bytes_per_pixel = m.encoding == "mono8" ? 1 : m.encoding == "mono16" ? 2 : 0;
  if (bytes_per_pixel == 0) throw MessageError("CameraFrame.encoding: '" + m.encoding + "' is not mono8 or mono16");
  if (static_cast<std::uint64_t>(m.step) < static_cast<std::uint64_t>(m.width) * bytes_per_pixel ||
      m.data.size() != static_cast<std::uint64_t>(m.step) * m.height)
    throw MessageError("CameraFrame.data: " + std::to_string(m.data.size()) + " bytes do not fit " +
                       std::to_string(m.width) + "x" + std::to_string(m.height) + " " + m.encoding + " step " +
                       std::to_string(m.step));
  return m;
}
template <>
PlcState decode<PlcState>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "PlcState");
  PlcState m;
  m.station_time_ns = r.get<std::int64_t>("station_time_ns");
  m.door_closed = r.getBool("door_closed");
  m.estop_ok = r.getBool("estop_ok");
  m.light_curtain_clear = r.getBool("light_curtain_clear");
  m.part_clamped = r.getBool("part_clamped");
  m.laser_shutter_open = r.getBool("laser_shutter_open");
  m.stack_light = r.get<std::uint8_t>("stack_light");
  m.heartbeat = r.get<std::uint32_t>("heartbeat");
  return m;
}
template <>
SceneMarker decode<SceneMarker>(std::span<const std::byte> bytes) {
  CdrReader r(bytes, "SceneMarker");
  SceneMarker m;
  m.station_time_ns = r.get<std::int64_t>("station_time_ns");
  const std::string scene = r.getString("scene");
  const std::optional<Scene> known = sceneFromString(scene);
  if (!known) throw MessageError("SceneMarker.scene: '" + scene + "' is none of " + sceneNames());
  m.scene = *known;
  m.phase = r.getString("phase");
  m.index = r.get<std::uint32_t>("index");
  m.detail = r.getString("detail");
  return m;
}

}  // namespace stampscan::trace
