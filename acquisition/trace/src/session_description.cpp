#include "stampscan/acquisition/trace/session_description.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <vector>

namespace stampscan::trace {

namespace {

[[noreturn]] void bad(std::string_view key, const std::string& what) {
  throw SessionDescriptionError("the trace's session description (metadata '" + std::string(kSessionMetadataName) +
                                "'): '" + std::string(key) + "' " + what);
}

// Exactly `count` finite numbers separated by spaces.
std::vector<double> numbers(const std::string& text, std::string_view key, std::size_t count) {
  std::vector<double> out;
  const char* p = text.c_str();
  while (true) {
    while (*p == ' ') ++p;
    if (*p == '\0') break;
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(p, &end);
    if (end == p || errno == ERANGE || !std::isfinite(v)) bad(key, "is not a list of numbers: '" + text + "'");
    out.push_back(v);
    p = end;
    if (*p != ' ' && *p != '\0') bad(key, "is not a list of numbers: '" + text + "'");
  }
  if (out.size() != count)
    bad(key, "has " + std::to_string(out.size()) + " numbers, expected " + std::to_string(count) + ": '" + text + "'");
  return out;
}

class Reader {
 public:
  explicit Reader(const KeyValues& record) : r_(record) {}
  bool has(std::string_view key) const { return r_.count(std::string(key)) != 0; }
  const std::string& text(std::string_view key) const {
    const auto it = r_.find(std::string(key));
    if (it == r_.end()) bad(key, "is missing");
    return it->second;
  }
  std::string textOr(std::string_view key, const std::string& fallback) const { return has(key) ? text(key) : fallback; }
  double number(std::string_view key) const { return numbers(text(key), key, 1)[0]; }
  double numberOr(std::string_view key, double fallback) const { return has(key) ? number(key) : fallback; }
  int integer(std::string_view key) const {
    const double v = number(key);
    if (v != std::floor(v) || std::fabs(v) > 1e9) bad(key, "is not a whole number: '" + text(key) + "'");
    return static_cast<int>(v);
  }
  double positive(std::string_view key) const {
    const double v = number(key);
    if (!(v > 0)) bad(key, "must be positive, is " + text(key));
    return v;
  }

 private:
  const KeyValues& r_;
};

}  // namespace

std::string formatNumber(double value) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

std::string formatPose(const RigidPose& pose) {
  std::string s;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      if (!s.empty()) s.push_back(' ');
      const double v = c < 3 ? pose.rotation[static_cast<std::size_t>(3 * r + c)] : pose.translation[static_cast<std::size_t>(r)];
      s.append(formatNumber(v));
    }
  return s;
}

RigidPose parsePose(const std::string& text, std::string_view key) {
  const std::vector<double> v = numbers(text, key, 12);
  RigidPose pose;
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) pose.rotation[3 * r + c] = v[4 * r + c];
    pose.translation[r] = v[4 * r + 3];
  }
  // A rotation: orthonormal rows with determinant +1 (to the precision that 17 digits keep).
  const auto& R = pose.rotation;
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = 0; j < 3; ++j) {
      const double dot = R[3 * i] * R[3 * j] + R[3 * i + 1] * R[3 * j + 1] + R[3 * i + 2] * R[3 * j + 2];
      if (std::fabs(dot - (i == j ? 1.0 : 0.0)) > 1e-6) bad(key, "is not a rigid transform (its rotation is not orthonormal)");
    }
  const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) + R[2] * (R[3] * R[7] - R[4] * R[6]);
  if (det < 0) bad(key, "is not a rigid transform (it mirrors)");
  return pose;
}

KeyValues encodeSession(const SessionDescription& s) {
  KeyValues r = {
      {"part", s.part},
      {"grid", s.grid},
      {"grid_pitch_mm", formatNumber(s.grid_pitch_mm)},
      {"grid_circle_diameter_mm", formatNumber(s.grid_circle_diameter_mm)},
      {"grid_line_width_mm", formatNumber(s.grid_line_width_mm)},
      {"digitizer_points_per_profile", std::to_string(s.digitizer_points_per_profile)},
      {"digitizer_profile_rate_hz", formatNumber(s.digitizer_profile_rate_hz)},
      {"digitizer_standoff_mm", formatNumber(s.digitizer_standoff_mm)},
      {"digitizer_measuring_range_mm", formatNumber(s.digitizer_measuring_range_mm)},
      {"head_from_digitizer_nominal", formatPose(s.head_from_digitizer_nominal)},
      {"station_clock", s.station_clock},
  };
  if (!s.part_id.empty()) r["part_id"] = s.part_id;
  if (!s.plan.empty()) r["plan"] = s.plan;
  if (!s.fixture.empty()) r["fixture"] = s.fixture;
  if (!s.plan_toml.empty()) r["plan_toml"] = s.plan_toml;
  if (s.camera_nominal) {
    const CameraIntrinsicsRecord& c = *s.camera_nominal;
    r["camera_nominal_intrinsics"] = std::to_string(c.width) + " " + std::to_string(c.height) + " " + formatNumber(c.fx) +
                                     " " + formatNumber(c.fy) + " " + formatNumber(c.cx) + " " + formatNumber(c.cy) + " " +
                                     formatNumber(c.k1) + " " + formatNumber(c.k2) + " " + formatNumber(c.p1) + " " +
                                     formatNumber(c.p2) + " " + formatNumber(c.k3);
    r["camera_bits"] = std::to_string(s.camera_bits);
    r["stereo_half_baseline_mm"] = formatNumber(s.stereo_half_baseline_mm);
  }
  if (s.plate) {
    const PlateRecord& p = *s.plate;
    // The older free-text "plate" key is kept for people reading the trace with the mcap CLI.
    r["plate"] = "circles " + std::to_string(p.columns) + "x" + std::to_string(p.rows) + " pitch " +
                 formatNumber(p.pitch_mm) + " diameter " + formatNumber(p.dot_diameter_mm);
    r["camera_plate_spec"] = std::to_string(p.columns) + " " + std::to_string(p.rows) + " " + formatNumber(p.pitch_mm) +
                             " " + formatNumber(p.dot_diameter_mm);
  }
  if (s.reference_sphere_radius_mm) r["reference_sphere_radius_mm"] = formatNumber(*s.reference_sphere_radius_mm);
  return r;
}

SessionDescription decodeSession(const KeyValues& record) {
  const Reader in(record);
  SessionDescription s;
  s.part = in.text("part");
  s.part_id = in.textOr("part_id", "");
  s.plan = in.textOr("plan", "");
  s.fixture = in.textOr("fixture", "");
  s.plan_toml = in.textOr("plan_toml", "");
  s.grid = in.textOr("grid", "circle");
  if (s.grid != "circle" && s.grid != "square") bad("grid", "is '" + s.grid + "': expected circle or square");
  s.grid_pitch_mm = in.has("grid_pitch_mm") ? in.positive("grid_pitch_mm") : s.grid_pitch_mm;
  s.grid_circle_diameter_mm = in.has("grid_circle_diameter_mm") ? in.positive("grid_circle_diameter_mm") : s.grid_circle_diameter_mm;
  s.grid_line_width_mm = in.has("grid_line_width_mm") ? in.positive("grid_line_width_mm") : s.grid_line_width_mm;
  s.digitizer_points_per_profile = in.integer("digitizer_points_per_profile");
  s.digitizer_profile_rate_hz = in.positive("digitizer_profile_rate_hz");
  s.digitizer_standoff_mm = in.positive("digitizer_standoff_mm");
  s.digitizer_measuring_range_mm = in.positive("digitizer_measuring_range_mm");
  s.head_from_digitizer_nominal = parsePose(in.text("head_from_digitizer_nominal"), "head_from_digitizer_nominal");
  if (in.has("camera_nominal_intrinsics")) {
    const std::vector<double> v = numbers(in.text("camera_nominal_intrinsics"), "camera_nominal_intrinsics", 11);
    CameraIntrinsicsRecord c;
    c.width = static_cast<int>(v[0]);
    c.height = static_cast<int>(v[1]);
    if (c.width <= 0 || c.height <= 0 || v[0] != c.width || v[1] != c.height)
      bad("camera_nominal_intrinsics", "has an image size that is not a positive whole number");
    c.fx = v[2], c.fy = v[3], c.cx = v[4], c.cy = v[5], c.k1 = v[6], c.k2 = v[7], c.p1 = v[8], c.p2 = v[9], c.k3 = v[10];
    s.camera_nominal = c;
    s.camera_bits = in.has("camera_bits") ? in.integer("camera_bits") : 8;
    s.stereo_half_baseline_mm = in.numberOr("stereo_half_baseline_mm", 0);
  }
  if (in.has("camera_plate_spec")) {
    // Columns, rows, pitch, and (since the dot diameter was added) the dot diameter.
    const std::string& text = in.text("camera_plate_spec");
    const std::size_t fields = static_cast<std::size_t>(std::count(text.begin(), text.end(), ' ') + 1);
    const std::vector<double> v = numbers(text, "camera_plate_spec", fields == 3 ? 3 : 4);
    PlateRecord p;
    p.columns = static_cast<int>(v[0]);
    p.rows = static_cast<int>(v[1]);
    if (p.columns < 2 || p.rows < 2 || v[0] != p.columns || v[1] != p.rows || !(v[2] > 0))
      bad("camera_plate_spec", "is not 'columns rows pitch [diameter]' with at least 2 x 2 dots: '" + text + "'");
    p.pitch_mm = v[2];
    p.dot_diameter_mm = v.size() > 3 ? v[3] : 0.5 * v[2];
    s.plate = p;
  }
  if (in.has("reference_sphere_radius_mm")) s.reference_sphere_radius_mm = in.positive("reference_sphere_radius_mm");
  s.station_clock = in.textOr("station_clock", s.station_clock);
  return s;
}

}  // namespace stampscan::trace
