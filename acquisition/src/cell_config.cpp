#include "stampscan/acquisition/cell_config.hpp"

#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <type_traits>

namespace stampscan::acquisition {

extern const char* const kVirtualCellFile;  // virtual_cell_file.cpp (generated)

namespace {

constexpr double kDeg = std::numbers::pi / 180;

// The keys each section may hold: a misspelt key is an error, not a silently ignored value.
const std::map<std::string, std::set<std::string>>& knownKeys() {
  static const std::map<std::string, std::set<std::string>> keys{
      {"cmm", {"host", "port", "device_time"}},
      {"machine", {"travel_min", "travel_max", "min_speed", "max_speed", "acceleration"}},
      {"head", {"kind", "index_step_deg", "a_max_deg", "b_max_deg", "rate_deg_s", "acceleration_deg_s2", "body"}},
      {"plc", {"host", "port", "unit_id", "line_start", "registers"}},
      {"cameras", {"left_serial", "left_address", "right_serial", "right_address", "width", "height", "pixel_size_um",
                   "focal_length_mm", "k1", "k2", "bits", "exposure_us", "baseline_mm", "drop_mm", "convergence_mm"}},
      {"digitizer", {"vendor_id", "product_id", "serial", "virtual", "required", "points_per_profile", "profile_rate_hz",
                     "standoff_mm", "measuring_range_mm", "fan_angle_deg", "incidence_limit_deg", "latency_ms",
                     "mount_mm", "mount_rotation_deg"}},
      {"sphere", {"centre_mm", "diameter_mm"}},
      {"ball_bar", {"centre_mm", "diameter_mm", "distance_mm"}},
      {"plate", {"columns", "rows", "pitch_mm", "dot_diameter_mm", "centre_mm", "rotation_deg"}},
      {"fixture", {"name", "datum_mm", "datum_rotation_deg", "body"}},
      {"calibration", {"dir", "validity_days", "digitizer_residual_mm", "camera_reprojection_px", "head_mount_residual_mm",
                       "drift_mount_mm", "drift_latency_ms", "drift_baseline_mm", "form_mpe_mm", "size_mpe_mm",
                       "length_mpe_mm", "stereo_form_mpe_mm", "stereo_length_mpe_mm", "plate_views", "sphere_sweeps",
                       "ball_bar_sweeps"}},
      {"results", {"database"}},
      {"report", {"materials"}},
      {"programs", {"library"}},
      {"hmi", {"listen", "users", "server_names", "tls_certificate", "tls_key", "https_port", "http_port"}},
  };
  return keys;
}

// Keys that moved, and where to: an old file gets told, not ignored.
const std::map<std::string, std::string>& movedKeys() {
  static const std::map<std::string, std::string> moved{
      {"[machine] max_tilt_deg", "[head] a_max_deg"},
      {"[machine] max_turn_deg", "[head] b_max_deg"},
      {"[machine] head_rate_deg_s", "[head] rate_deg_s"},
      {"[machine] head_acceleration_deg_s2", "[head] acceleration_deg_s2"},
      {"[calibration] sphere_diameter_mm", "[sphere] diameter_mm"},
      {"[calibration] second_sphere_diameter_mm", "[ball_bar] diameter_mm"},
      {"[calibration] sphere_distance_mm", "[ball_bar] distance_mm"},
  };
  return moved;
}

std::string typeName(const toml::node& node) {
  std::ostringstream type;
  type << node.type();  // toml++'s name for it: string, integer, boolean, array, ...
  return (type.str().find_first_of("aeiou") == 0 ? "an " : "a ") + type.str();
}

// Reads one table of the file (a section, or one entry of an array of tables): each value checked,
// each error naming the file, the section and the key; the keys left out recorded as defaulted.
class SectionReader {
 public:
  SectionReader(const toml::table* table, std::string file, std::string section, std::vector<std::string>* defaulted)
      : table_(table), file_(std::move(file)), section_(std::move(section)), defaulted_(defaulted) {}

  bool present() const { return table_ != nullptr; }
  bool has(const char* key) const { return node(key) != nullptr; }

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw std::runtime_error(file_ + ": [" + section_ + "]" + (key.empty() ? "" : " " + key) + " " + what);
  }

  std::string text(const char* key, std::string fallback) const {
    const toml::node* n = found(key);
    if (n == nullptr) return fallback;
    if (const auto v = n->value<std::string>()) return *v;
    fail(key, "has the wrong type: expected a string, found " + typeName(*n));
  }
  std::vector<std::string> texts(const char* key) const {
    const toml::node* n = found(key);
    if (n == nullptr) return {};
    const toml::array* a = n->as_array();
    if (a == nullptr) fail(key, "has the wrong type: expected a list of strings, found " + typeName(*n));
    std::vector<std::string> out;
    for (const toml::node& item : *a) {
      const auto v = item.value<std::string>();
      if (!v) fail(key, "must be a list of strings, not of " + typeName(item) + "s");
      out.push_back(*v);
    }
    return out;
  }
  bool flag(const char* key, bool fallback) const {
    const toml::node* n = found(key);
    if (n == nullptr) return fallback;
    if (const auto v = n->value<bool>()) return *v;
    fail(key, "has the wrong type: expected true or false, found " + typeName(*n));
  }
  std::int64_t integer(const char* key, std::int64_t fallback, std::int64_t min, std::int64_t max) const {
    const toml::node* n = found(key);
    if (n == nullptr) return fallback;
    if (!n->is_integer()) fail(key, "has the wrong type: expected an integer, found " + typeName(*n));
    const std::int64_t v = *n->value<std::int64_t>();
    if (v < min || v > max) fail(key, "is " + std::to_string(v) + ", not " + std::to_string(min) + ".." + std::to_string(max));
    return v;
  }
  enum class Sign { Any, Positive, NotNegative };
  double number(const char* key, double fallback, Sign sign = Sign::Any) const {
    const toml::node* n = found(key);
    if (n == nullptr) return fallback;
    const std::optional<double> v = n->value<double>();
    const char* expected = sign == Sign::Positive ? "must be a positive number"
                           : sign == Sign::NotNegative ? "must not be negative"
                                                       : "must be a number";
    if (!v || !std::isfinite(*v)) fail(key, sign == Sign::NotNegative ? "must be a number, not negative" : expected);
    if ((sign == Sign::Positive && !(*v > 0)) || (sign == Sign::NotNegative && *v < 0)) fail(key, expected);
    return *v;
  }
  std::array<double, 3> triple(const char* key, std::array<double, 3> fallback, const char* what = "x, y, z in mm") const {
    const toml::node* n = found(key);
    if (n == nullptr) return fallback;
    const toml::array* a = n->as_array();
    const std::string expected = std::string("must be a list of 3 numbers (") + what + ")";
    if (a == nullptr || a->size() != 3) fail(key, expected);
    std::array<double, 3> out{};
    for (std::size_t i = 0; i < 3; ++i) {
      const std::optional<double> v = (*a)[i].value<double>();
      if (!v || !std::isfinite(*v)) fail(key, expected);
      out[i] = *v;
    }
    return out;
  }
  Placement placement(const char* position_key, const char* rotation_key, Placement fallback) const {
    return {triple(position_key, fallback.position_mm),
            triple(rotation_key, fallback.rotation_deg, "turns about x, y, z in degrees")};
  }

  // Unknown keys are refused (a misspelt key would otherwise leave a default in force unnoticed).
  void refuseUnknown(const std::set<std::string>& known) const {
    if (table_ == nullptr) return;
    for (const auto& [key, value] : *table_) {
      const std::string name(key.str());
      if (known.count(name) != 0) continue;
      if (const auto moved = movedKeys().find("[" + section_ + "] " + name); moved != movedKeys().end())
        fail(name, "has moved: write it as " + moved->second);
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      fail(name, "is not a key of this section (known: " + list + ")");
    }
  }

 private:
  const toml::node* node(const char* key) const { return table_ == nullptr ? nullptr : table_->get(key); }
  const toml::node* found(const char* key) const {
    const toml::node* n = node(key);
    if (n == nullptr && defaulted_ != nullptr) defaulted_->push_back("[" + section_ + "] " + key);
    return n;
  }

  const toml::table* table_;
  std::string file_, section_;
  std::vector<std::string>* defaulted_;
};

SectionReader section(const toml::table& t, const std::string& name, const std::string& file,
                      std::vector<std::string>* defaulted) {
  const toml::node* n = t.get(name);
  if (n != nullptr && !n->is_table()) throw std::runtime_error(file + ": [" + name + "] must be a table");
  return SectionReader(n == nullptr ? nullptr : n->as_table(), file, name, defaulted);
}

void checkPort(const SectionReader& s, int port) {
  if (port < 1 || port > 65535) s.fail("port", std::to_string(port) + " is not 1-65535");
}

// A path relative to the cell file is taken from its folder.
std::string besideCellFile(const std::filesystem::path& folder, const std::string& path) {
  return path.empty() || std::filesystem::path(path).is_absolute() ? path : (folder / path).string();
}

// [hmi]: the operator's panel. The certificate and key paths go into the front's configuration
// quoted: characters that would end the quote or start a variable there are refused.
void readPanel(const SectionReader& s, const std::filesystem::path& folder, CellConfig::Panel& p) {
  p.listen = s.text("listen", p.listen);
  p.users_file = besideCellFile(folder, s.text("users", ""));
  p.server_names = s.texts("server_names");
  for (const std::string& name : p.server_names)
    if (!isServerName(name))
      s.fail("server_names", "'" + name + "' is not a host name or an IPv4 address (letters, digits, '.' and '-')");
  p.tls_certificate = besideCellFile(folder, s.text("tls_certificate", ""));
  p.tls_key = besideCellFile(folder, s.text("tls_key", ""));
  for (const auto& [key, path] : {std::pair{"tls_certificate", p.tls_certificate}, std::pair{"tls_key", p.tls_key}})
    if (!isQuotablePath(path))
      s.fail(key, "'" + path + "' holds a character a path here may not have (quotes, '$', ';', braces, '\\', control)");
  if (p.tls_certificate.empty() != p.tls_key.empty())
    s.fail(p.tls_key.empty() ? "tls_key" : "tls_certificate", "is missing: the TLS front needs both the certificate and its key");
  if (p.behindTlsFront() && p.server_names.empty())
    s.fail("server_names", "is missing: the TLS front serves the panel under the names listed there");
  p.https_port = static_cast<int>(s.integer("https_port", p.https_port, 1, 65535));
  p.http_port = static_cast<int>(s.integer("http_port", p.http_port, 1, 65535));
  if (p.https_port == p.http_port) s.fail("http_port", "is the https_port: the two need their own ports");
}

// [plc.registers]: where the cell's PLC program puts each signal, by the signal's name in the register
// table (drivers/plc/REGISTER_MAP.md); the name implies the kind. A signal left out keeps its
// standard address.
drivers::plc::RegisterMap readPlcRegisters(const toml::table& t, const SectionReader& plc, const std::string& file,
                                           std::vector<std::string>* defaulted) {
  using drivers::plc::registerTable;
  const toml::node* n = t["plc"]["registers"].node();
  if (n != nullptr && !n->is_table()) plc.fail("registers", "must be a table ([plc.registers]: signal name = address)");
  const SectionReader registers(n == nullptr ? nullptr : n->as_table(), file, "plc.registers", defaulted);
  std::set<std::string> names;
  for (const drivers::plc::RegisterInfo& signal : registerTable()) names.emplace(signal.name);
  registers.refuseUnknown(names);
  drivers::plc::RegisterMap map;
  for (std::size_t row = 0; row < registerTable().size(); ++row) {
    const std::string name(registerTable()[row].name);
    map.addresses[row] = static_cast<std::uint16_t>(registers.integer(name.c_str(), map.addresses[row], 0, 65535));
  }
  if (const std::string problem = map.problem(); !problem.empty()) registers.fail("", problem);
  return map;
}

void readMachine(const SectionReader& m, const SectionReader& h, MachineLimits& l) {
  l.travel_min = m.triple("travel_min", l.travel_min);
  l.travel_max = m.triple("travel_max", l.travel_max);
  for (std::size_t i = 0; i < 3; ++i)
    if (!(l.travel_min[i] < l.travel_max[i])) m.fail("travel_min", "must be below travel_max on every axis");
  l.min_speed = m.number("min_speed", l.min_speed, SectionReader::Sign::Positive);
  l.max_speed = m.number("max_speed", l.max_speed, SectionReader::Sign::Positive);
  if (!(l.min_speed <= l.max_speed)) m.fail("min_speed", "is above max_speed");
  l.acceleration = m.number("acceleration", l.acceleration, SectionReader::Sign::Positive);
  l.max_tilt = h.number("a_max_deg", l.max_tilt / kDeg, SectionReader::Sign::Positive) * kDeg;
  l.max_turn = h.number("b_max_deg", l.max_turn / kDeg, SectionReader::Sign::Positive) * kDeg;
  if (l.max_tilt > std::numbers::pi + 1e-12) h.fail("a_max_deg", "must be at most 180");
  if (l.max_turn > std::numbers::pi + 1e-12) h.fail("b_max_deg", "must be at most 180");
  l.head_rate = h.number("rate_deg_s", l.head_rate / kDeg, SectionReader::Sign::Positive) * kDeg;
  l.head_acceleration = h.number("acceleration_deg_s2", l.head_acceleration / kDeg, SectionReader::Sign::Positive) * kDeg;
}

BodySolid readBodySolid(const SectionReader& s) {
  BodySolid b;
  b.name = s.text("name", "");
  if (b.name.empty()) s.fail("name", "is missing: each solid of the body is named");
  const std::string shape = s.text("shape", "");
  if (shape == "box") b.shape = BodySolid::Shape::Box;
  else if (shape == "cylinder") b.shape = BodySolid::Shape::Cylinder;
  else if (shape == "sphere") b.shape = BodySolid::Shape::Sphere;
  else s.fail("shape", "is \"" + shape + "\": expected box, cylinder or sphere");
  b.placement = s.placement("centre_mm", "rotation_deg", {});
  if (b.shape == BodySolid::Shape::Box) {
    b.size_mm = s.triple("size_mm", {0, 0, 0}, "the box's x, y, z extents in mm");
    if (!s.has("size_mm") || !(b.size_mm[0] > 0 && b.size_mm[1] > 0 && b.size_mm[2] > 0))
      s.fail("size_mm", "must give the box's three positive extents");
  } else {
    if (!s.has("radius_mm")) s.fail("radius_mm", "is missing");
    b.radius_mm = s.number("radius_mm", 0, SectionReader::Sign::Positive);
    if (b.shape == BodySolid::Shape::Cylinder) {
      if (!s.has("length_mm")) s.fail("length_mm", "is missing");
      b.length_mm = s.number("length_mm", 0, SectionReader::Sign::Positive);
    }
  }
  s.refuseUnknown({"name", "shape", "centre_mm", "rotation_deg", "size_mm", "radius_mm", "length_mm"});
  return b;
}

// [[SECTION.body]] entries: the solids of the head's body, or of the fixture.
std::vector<BodySolid> readBodySolids(const toml::table& t, const SectionReader& section, const std::string& file,
                                      const std::string& name) {
  std::vector<BodySolid> out;
  const toml::node* body = t[name]["body"].node();
  if (body == nullptr) return out;
  const toml::array* solids = body->as_array();
  if (solids == nullptr || !solids->is_array_of_tables())
    section.fail("body", "must be an array of tables ([[" + name + ".body]] entries)");
  for (std::size_t i = 0; i < solids->size(); ++i)
    out.push_back(readBodySolid(SectionReader((*solids)[i].as_table(), file, name + ".body " + std::to_string(i + 1), nullptr)));
  return out;
}

void readHead(const toml::table& t, const SectionReader& h, const std::string& file, HeadDescription& head,
              MachineLimits& limits) {
  const std::string kind = h.text("kind", toString(head.kind));
  if (kind == "continuous") head.kind = HeadDescription::Kind::Continuous;
  else if (kind == "indexing") head.kind = HeadDescription::Kind::Indexing;
  else h.fail("kind", "is \"" + kind + "\": expected continuous or indexing");
  head.index_step_deg = h.number("index_step_deg", head.index_step_deg, SectionReader::Sign::Positive);
  if (head.index_step_deg > 90) h.fail("index_step_deg", "must be at most 90");
  limits.index_step = head.kind == HeadDescription::Kind::Indexing ? head.index_step_deg * kDeg : 0;
  head.body = readBodySolids(t, h, file, "head");
}

void readDigitizerDrawing(const SectionReader& s, DigitizerDrawing& d) {
  using Sign = SectionReader::Sign;
  // The digitizer is configured so (acquisition::Cell): within what its protocol carries.
  d.points_per_profile = static_cast<int>(
      s.integer("points_per_profile", d.points_per_profile, drivers::digitizer::kMinPoints, drivers::digitizer::kMaxPoints));
  d.profile_rate_hz = s.number("profile_rate_hz", d.profile_rate_hz, Sign::Positive);
  if (d.profile_rate_hz < drivers::digitizer::kMinProfileRateHz || d.profile_rate_hz > drivers::digitizer::kMaxProfileRateHz)
    s.fail("profile_rate_hz", "must be within " + std::to_string(static_cast<int>(drivers::digitizer::kMinProfileRateHz)) + ".." +
                                  std::to_string(static_cast<int>(drivers::digitizer::kMaxProfileRateHz)) + " Hz");
  d.standoff_mm = s.number("standoff_mm", d.standoff_mm, Sign::Positive);
  d.measuring_range_mm = s.number("measuring_range_mm", d.measuring_range_mm, Sign::Positive);
  if (d.measuring_range_mm >= 2 * d.standoff_mm) s.fail("measuring_range_mm", "must be below twice standoff_mm");
  d.fan_angle_deg = s.number("fan_angle_deg", d.fan_angle_deg, Sign::Positive);
  if (d.fan_angle_deg >= 170) s.fail("fan_angle_deg", "must be below 170");
  d.incidence_limit_deg = s.number("incidence_limit_deg", d.incidence_limit_deg, Sign::Positive);
  if (d.incidence_limit_deg >= 90) s.fail("incidence_limit_deg", "must be below 90");
  d.latency_ms = s.number("latency_ms", d.latency_ms, Sign::NotNegative);
  d.mount = s.placement("mount_mm", "mount_rotation_deg", d.mount);
}

void readCameraDrawing(const SectionReader& s, CameraDrawing& c) {
  using Sign = SectionReader::Sign;
  c.width = static_cast<int>(s.integer("width", c.width, 16, 65535));
  c.height = static_cast<int>(s.integer("height", c.height, 16, 65535));
  c.pixel_size_um = s.number("pixel_size_um", c.pixel_size_um, Sign::Positive);
  c.focal_length_mm = s.number("focal_length_mm", c.focal_length_mm, Sign::Positive);
  c.k1 = s.number("k1", c.k1);
  c.k2 = s.number("k2", c.k2);
  c.bits = static_cast<int>(s.integer("bits", c.bits, 8, 16));
  if (c.bits != 8 && c.bits != 16) s.fail("bits", "is " + std::to_string(c.bits) + ": expected 8 (Mono8) or 16 (Mono16)");
  c.exposure_us = s.number("exposure_us", c.exposure_us, Sign::NotNegative);
  c.baseline_mm = s.number("baseline_mm", c.baseline_mm, Sign::Positive);
  c.drop_mm = s.number("drop_mm", c.drop_mm, Sign::NotNegative);
  c.convergence_mm = s.number("convergence_mm", c.convergence_mm, Sign::Positive);
}

void readArtefacts(const SectionReader& sphere, const SectionReader& bar, const SectionReader& plate, CellGeometry& g) {
  using Sign = SectionReader::Sign;
  g.sphere.centre_mm = sphere.triple("centre_mm", g.sphere.centre_mm);
  g.sphere.diameter_mm = sphere.number("diameter_mm", g.sphere.diameter_mm, Sign::Positive);
  if (bar.present()) {
    BallBar b = g.ball_bar.value_or(BallBar{});
    b.centre_mm = bar.triple("centre_mm", b.centre_mm);
    b.diameter_mm = bar.number("diameter_mm", b.diameter_mm, Sign::Positive);
    b.distance_mm = bar.number("distance_mm", b.distance_mm, Sign::Positive);
    // The centre says where the second sphere stands (to plan sweeps over it), the distance is its
    // certificate: they must tell the same story.
    const double dx = b.centre_mm[0] - g.sphere.centre_mm[0], dy = b.centre_mm[1] - g.sphere.centre_mm[1],
                 dz = b.centre_mm[2] - g.sphere.centre_mm[2];
    const double placed = std::sqrt(dx * dx + dy * dy + dz * dz);
    if (std::fabs(placed - b.distance_mm) > 5) {
      char text[160];
      std::snprintf(text, sizeof text, "is %.3f mm, but centre_mm puts the spheres %.3f mm apart ([sphere] centre_mm)",
                    b.distance_mm, placed);
      bar.fail("distance_mm", text);
    }
    g.ball_bar = b;
  }
  PlateArtefact& p = g.plate;
  p.columns = static_cast<int>(plate.integer("columns", p.columns, 3, 99));
  p.rows = static_cast<int>(plate.integer("rows", p.rows, 3, 99));
  if (p.columns % 2 == 0 || p.rows % 2 == 0)
    plate.fail(p.columns % 2 == 0 ? "columns" : "rows", "must be odd (the pattern's orientation is then unambiguous)");
  p.pitch_mm = plate.number("pitch_mm", p.pitch_mm, Sign::Positive);
  p.dot_diameter_mm = plate.number("dot_diameter_mm", p.dot_diameter_mm, Sign::Positive);
  if (p.dot_diameter_mm >= p.pitch_mm) plate.fail("dot_diameter_mm", "must be below pitch_mm");
  p.placement = plate.placement("centre_mm", "rotation_deg", p.placement);
}

void readCalibrationPolicy(const SectionReader& s, CalibrationPolicy& p) {
  using Sign = SectionReader::Sign;
  p.dir = s.text("dir", p.dir);
  p.validity_days = s.number("validity_days", p.validity_days, Sign::Positive);
  p.digitizer_residual_mm = s.number("digitizer_residual_mm", p.digitizer_residual_mm, Sign::Positive);
  p.camera_reprojection_px = s.number("camera_reprojection_px", p.camera_reprojection_px, Sign::Positive);
  p.head_mount_residual_mm = s.number("head_mount_residual_mm", p.head_mount_residual_mm, Sign::Positive);
  p.drift_mount_mm = s.number("drift_mount_mm", p.drift_mount_mm, Sign::Positive);
  p.drift_latency_ms = s.number("drift_latency_ms", p.drift_latency_ms, Sign::Positive);
  p.drift_baseline_mm = s.number("drift_baseline_mm", p.drift_baseline_mm, Sign::Positive);
  p.form_mpe_mm = s.number("form_mpe_mm", p.form_mpe_mm, Sign::Positive);
  p.size_mpe_mm = s.number("size_mpe_mm", p.size_mpe_mm, Sign::Positive);
  p.length_mpe_mm = s.number("length_mpe_mm", p.length_mpe_mm, Sign::Positive);
  p.stereo_form_mpe_mm = s.number("stereo_form_mpe_mm", p.stereo_form_mpe_mm, Sign::Positive);
  p.stereo_length_mpe_mm = s.number("stereo_length_mpe_mm", p.stereo_length_mpe_mm, Sign::Positive);
  // Fewer plate views than this leave the cameras' intrinsics underdetermined; fewer sphere sweeps
  // cannot tell the mount's turn from its shift and the latency (calibration_plan.hpp).
  p.plate_views = static_cast<int>(s.integer("plate_views", p.plate_views, 4, 200));
  p.sphere_sweeps = static_cast<int>(s.integer("sphere_sweeps", p.sphere_sweeps, 4, 200));
  p.ball_bar_sweeps = static_cast<int>(s.integer("ball_bar_sweeps", p.ball_bar_sweeps, 1, 200));
}

}  // namespace

namespace {

// A cell file's text, read: `file` names it in errors, `folder` is where its relative paths start.
CellConfig parseCellConfig(const std::string& text, const std::string& file, const std::filesystem::path& folder) {
  toml::table t;
  try {
    t = toml::parse(text, file);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    throw std::runtime_error(file + ":" + std::to_string(where.line) + ":" + std::to_string(where.column) + ": " +
                             std::string(e.description()));
  }
  CellConfig c;
  c.source = file;
  std::vector<std::string>* defaulted = &c.defaulted;
  for (const auto& [key, value] : t) {
    const std::string name(key.str());
    if (name == "name" || knownKeys().count(name) != 0) continue;
    throw std::runtime_error(file + ": [" + name + "] is not a section of a cell file");
  }
  if (const toml::node* n = t.get("name"); n != nullptr && !n->is_string())
    throw std::runtime_error(file + ": name has the wrong type: expected a string, found " + typeName(*n));
  c.name = t["name"].value_or(std::string("cell"));
  // It goes into reports, logs and configuration files, one line each.
  if (std::any_of(c.name.begin(), c.name.end(), [](char ch) { return static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f; }))
    throw std::runtime_error(file + ": name holds a line break or another control character");
  auto sectionNamed = [&](const char* name) {
    SectionReader s = section(t, name, file, defaulted);
    s.refuseUnknown(knownKeys().at(name));
    return s;
  };

  const SectionReader cmm = sectionNamed("cmm");
  c.cmm.host = cmm.text("host", c.cmm.host);
  c.cmm.port = static_cast<int>(cmm.integer("port", c.cmm.port, INT32_MIN, INT32_MAX));
  checkPort(cmm, c.cmm.port);
  c.cmm_device_time = cmm.flag("device_time", false);

  readMachine(sectionNamed("machine"), sectionNamed("head"), c.limits);
  readHead(t, sectionNamed("head"), file, c.geometry.head, c.limits);

  const SectionReader plc = sectionNamed("plc");
  c.plc.host = plc.text("host", c.plc.host);
  c.plc.port = static_cast<int>(plc.integer("port", c.plc.port, INT32_MIN, INT32_MAX));
  checkPort(plc, c.plc.port);
  c.plc_unit_id = static_cast<int>(plc.integer("unit_id", c.plc_unit_id, 0, 255));
  c.plc_line_start = plc.flag("line_start", c.plc_line_start);
  c.plc_registers = readPlcRegisters(t, plc, file, defaulted);

  const SectionReader cameras = sectionNamed("cameras");
  c.left_camera.serial = cameras.text("left_serial", c.left_camera.serial);
  c.left_camera.address = cameras.text("left_address", c.left_camera.address);
  c.right_camera.serial = cameras.text("right_serial", c.right_camera.serial);
  c.right_camera.address = cameras.text("right_address", c.right_camera.address);
  readCameraDrawing(cameras, c.geometry.cameras);

  const SectionReader digitizer = sectionNamed("digitizer");
  c.digitizer_vendor = static_cast<std::uint16_t>(digitizer.integer("vendor_id", c.digitizer_vendor, 0, 0xffff));
  c.digitizer_product = static_cast<std::uint16_t>(digitizer.integer("product_id", c.digitizer_product, 0, 0xffff));
  c.digitizer_serial = digitizer.text("serial", "");
  c.digitizer_virtual = digitizer.flag("virtual", false);
  if (c.digitizer_virtual &&
      (c.digitizer_vendor != drivers::digitizer::kVendorId || c.digitizer_product != drivers::digitizer::kProductId)) {
    char ids[64];
    std::snprintf(ids, sizeof ids, "%04x:%04x is not the virtual digitizer's %04x:%04x", c.digitizer_vendor,
                  c.digitizer_product, drivers::digitizer::kVendorId, drivers::digitizer::kProductId);
    digitizer.fail("virtual", std::string("= true, but vendor_id:product_id ") + ids);
  }
  c.digitizer_required = digitizer.flag("required", true);
  readDigitizerDrawing(digitizer, c.geometry.digitizer);

  const SectionReader bar = sectionNamed("ball_bar");
  if (!bar.present()) c.geometry.ball_bar.reset();  // a cell's file without [ball_bar]: the cell has none
  readArtefacts(sectionNamed("sphere"), bar, sectionNamed("plate"), c.geometry);

  const SectionReader fixture = sectionNamed("fixture");
  c.geometry.fixture.name = fixture.text("name", "");
  c.geometry.fixture.datum = fixture.placement("datum_mm", "datum_rotation_deg", {});
  c.geometry.fixture.body = readBodySolids(t, fixture, file, "fixture");

  readCalibrationPolicy(sectionNamed("calibration"), c.calibration);
  c.results_database = sectionNamed("results").text("database", "");
  c.materials_file = sectionNamed("report").text("materials", "");
  if (!c.materials_file.empty() && std::filesystem::path(c.materials_file).is_relative())
    c.materials_file = (folder / c.materials_file).string();
  c.program_library = sectionNamed("programs").text("library", "");
  if (!c.program_library.empty() && std::filesystem::path(c.program_library).is_relative())
    c.program_library = (folder / c.program_library).string();
  readPanel(sectionNamed("hmi"), folder, c.panel);
  std::sort(c.defaulted.begin(), c.defaulted.end());
  c.defaulted.erase(std::unique(c.defaulted.begin(), c.defaulted.end()), c.defaulted.end());
  return c;
}

}  // namespace

bool isServerName(const std::string& name) {
  if (name.empty() || name.size() > 253 || name.front() == '.' || name.front() == '-') return false;
  return std::all_of(name.begin(), name.end(), [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '.' || ch == '-';
  });
}

bool isQuotablePath(const std::string& path) { return path.find_first_of("\"$;{}'\\\n\r\t") == std::string::npos; }

CellConfig virtualCell() {
  // station/cells/virtual.toml, built in (virtual_cell_file.cpp is generated from it), read once.
  static const CellConfig cell = [] {
    CellConfig c = parseCellConfig(std::string(kVirtualCellFile), "built-in virtual cell (station/cells/virtual.toml)", {});
    c.source = "built-in";
    c.defaulted.clear();
    return c;
  }();
  return cell;
}

CellConfig loadCellConfig(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code error;
  // Only regular files: a FIFO would block the read forever.
  if (!std::filesystem::exists(path, error)) throw std::runtime_error(file + ": the cell file does not exist");
  if (!std::filesystem::is_regular_file(path, error))
    throw std::runtime_error(file + ": not a regular file (a folder, FIFO or device), not a cell file");
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in && !in.eof()) throw std::runtime_error(file + ": cannot be read");
  return parseCellConfig(text.str(), file, path.parent_path());
}

}  // namespace stampscan::acquisition

namespace stampscan::acquisition {

namespace {

// The cell as a cell file: every key of every section with its value in the file's units, those
// the file left out marked; a complete file the station would read back to the same cell.
class CellListing {
 public:
  explicit CellListing(const std::vector<std::string>& defaulted) : defaulted_(defaulted.begin(), defaulted.end()) {}

  void section(const std::string& name) {
    section_ = name;
    out_ << "\n[" << name << "]\n";
  }
  void value(const std::string& key, const std::string& text) {
    std::string line = key + " = " + text;
    if (defaulted_.count("[" + section_ + "] " + key) != 0) line += std::string(std::max<std::size_t>(1, 44 - std::min<std::size_t>(44, line.size())), ' ') + "# default";
    out_ << line << '\n';
  }
  void text(const std::string& key, const std::string& v) { value(key, quoted(v)); }
  void number(const std::string& key, double v) { value(key, shown(v)); }
  void integer(const std::string& key, long long v) { value(key, std::to_string(v)); }
  void flag(const std::string& key, bool v) { value(key, v ? "true" : "false"); }
  void triple(const std::string& key, const std::array<double, 3>& v) {
    value(key, "[" + shown(v[0]) + ", " + shown(v[1]) + ", " + shown(v[2]) + "]");
  }
  void raw(const std::string& line) { out_ << line << '\n'; }
  std::string str() const { return out_.str(); }

  static std::string shown(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.10g", v);
    std::string s = text;
    if (s.find_first_of(".eEn") == std::string::npos) s += ".0";  // a TOML float
    return s;
  }
  static std::string quoted(const std::string& v) {
    std::string q = "\"";
    for (const char ch : v) {
      if (ch == '"' || ch == '\\') q += '\\';
      q += ch;
    }
    return q + "\"";
  }

 private:
  std::set<std::string> defaulted_;
  std::string section_;
  std::ostringstream out_;
};

std::string hex(unsigned v) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%04x", v);
  return text;
}

}  // namespace

namespace {

// [cmm], [machine], [head]: the machine and its head.
// [[SECTION.body]] entries.
void listBodySolids(CellListing& l, const std::string& section, const std::vector<BodySolid>& solids) {
  for (const BodySolid& b : solids) {
    l.raw("[[" + section + ".body]]");
    l.raw("name = " + CellListing::quoted(b.name));
    l.raw(std::string("shape = \"") + toString(b.shape) + "\"");
    const auto& p = b.placement;
    l.raw("centre_mm = [" + CellListing::shown(p.position_mm[0]) + ", " + CellListing::shown(p.position_mm[1]) + ", " +
          CellListing::shown(p.position_mm[2]) + "]");
    l.raw("rotation_deg = [" + CellListing::shown(p.rotation_deg[0]) + ", " + CellListing::shown(p.rotation_deg[1]) + ", " +
          CellListing::shown(p.rotation_deg[2]) + "]");
    if (b.shape == BodySolid::Shape::Box)
      l.raw("size_mm = [" + CellListing::shown(b.size_mm[0]) + ", " + CellListing::shown(b.size_mm[1]) + ", " +
            CellListing::shown(b.size_mm[2]) + "]");
    else l.raw("radius_mm = " + CellListing::shown(b.radius_mm));
    if (b.shape == BodySolid::Shape::Cylinder) l.raw("length_mm = " + CellListing::shown(b.length_mm));
  }
}

void listMachine(CellListing& l, const CellConfig& c) {
  const CellGeometry& g = c.geometry;
  l.section("cmm");
  l.text("host", c.cmm.host);
  l.integer("port", c.cmm.port);
  l.flag("device_time", c.cmm_device_time);
  l.section("machine");
  l.triple("travel_min", c.limits.travel_min);
  l.triple("travel_max", c.limits.travel_max);
  l.number("min_speed", c.limits.min_speed);
  l.number("max_speed", c.limits.max_speed);
  l.number("acceleration", c.limits.acceleration);
  l.section("head");
  l.text("kind", toString(g.head.kind));
  l.number("index_step_deg", g.head.index_step_deg);
  l.number("a_max_deg", c.limits.max_tilt / kDeg);
  l.number("b_max_deg", c.limits.max_turn / kDeg);
  l.number("rate_deg_s", c.limits.head_rate / kDeg);
  l.number("acceleration_deg_s2", c.limits.head_acceleration / kDeg);
  listBodySolids(l, "head", g.head.body);
}

// [plc], [plc.registers], [cameras], [digitizer]: the devices.
void listDevices(CellListing& l, const CellConfig& c) {
  const CellGeometry& g = c.geometry;
  l.section("plc");
  l.text("host", c.plc.host);
  l.integer("port", c.plc.port);
  l.integer("unit_id", c.plc_unit_id);
  l.flag("line_start", c.plc_line_start);
  l.section("plc.registers");
  for (std::size_t row = 0; row < drivers::plc::registerTable().size(); ++row)
    l.integer(std::string(drivers::plc::registerTable()[row].name), c.plc_registers.addresses[row]);
  l.section("cameras");
  l.text("left_serial", c.left_camera.serial);
  l.text("left_address", c.left_camera.address);
  l.text("right_serial", c.right_camera.serial);
  l.text("right_address", c.right_camera.address);
  l.integer("width", g.cameras.width);
  l.integer("height", g.cameras.height);
  l.number("pixel_size_um", g.cameras.pixel_size_um);
  l.number("focal_length_mm", g.cameras.focal_length_mm);
  l.number("k1", g.cameras.k1);
  l.number("k2", g.cameras.k2);
  l.integer("bits", g.cameras.bits);
  l.number("exposure_us", g.cameras.exposure_us);
  l.number("baseline_mm", g.cameras.baseline_mm);
  l.number("drop_mm", g.cameras.drop_mm);
  l.number("convergence_mm", g.cameras.convergence_mm);
  l.section("digitizer");
  l.value("vendor_id", hex(c.digitizer_vendor));
  l.value("product_id", hex(c.digitizer_product));
  l.text("serial", c.digitizer_serial);
  l.flag("virtual", c.digitizer_virtual);
  l.flag("required", c.digitizer_required);
  l.integer("points_per_profile", g.digitizer.points_per_profile);
  l.number("profile_rate_hz", g.digitizer.profile_rate_hz);
  l.number("standoff_mm", g.digitizer.standoff_mm);
  l.number("measuring_range_mm", g.digitizer.measuring_range_mm);
  l.number("fan_angle_deg", g.digitizer.fan_angle_deg);
  l.number("incidence_limit_deg", g.digitizer.incidence_limit_deg);
  l.number("latency_ms", g.digitizer.latency_ms);
  l.triple("mount_mm", g.digitizer.mount.position_mm);
  l.triple("mount_rotation_deg", g.digitizer.mount.rotation_deg);
}

// [sphere], [ball_bar], [plate], [fixture]: what stands on the table.
void listArtefacts(CellListing& l, const CellConfig& c) {
  const CellGeometry& g = c.geometry;
  l.section("sphere");
  l.triple("centre_mm", g.sphere.centre_mm);
  l.number("diameter_mm", g.sphere.diameter_mm);
  if (g.ball_bar) {
    l.section("ball_bar");
    l.triple("centre_mm", g.ball_bar->centre_mm);
    l.number("diameter_mm", g.ball_bar->diameter_mm);
    l.number("distance_mm", g.ball_bar->distance_mm);
  } else {
    l.raw("\n# no [ball_bar]: `station verify` has no length check");
  }
  l.section("plate");
  l.integer("columns", g.plate.columns);
  l.integer("rows", g.plate.rows);
  l.number("pitch_mm", g.plate.pitch_mm);
  l.number("dot_diameter_mm", g.plate.dot_diameter_mm);
  l.triple("centre_mm", g.plate.placement.position_mm);
  l.triple("rotation_deg", g.plate.placement.rotation_deg);
  l.section("fixture");
  l.text("name", g.fixture.name);
  l.triple("datum_mm", g.fixture.datum.position_mm);
  l.triple("datum_rotation_deg", g.fixture.datum.rotation_deg);
  listBodySolids(l, "fixture", g.fixture.body);
}

// [calibration], [results], [report], [programs], [hmi]: the cell's rules and places.
void listPolicies(CellListing& l, const CellConfig& c) {
  l.section("calibration");
  const CalibrationPolicy& p = c.calibration;
  l.text("dir", p.dir);
  l.number("validity_days", p.validity_days);
  l.number("digitizer_residual_mm", p.digitizer_residual_mm);
  l.number("camera_reprojection_px", p.camera_reprojection_px);
  l.number("head_mount_residual_mm", p.head_mount_residual_mm);
  l.number("drift_mount_mm", p.drift_mount_mm);
  l.number("drift_latency_ms", p.drift_latency_ms);
  l.number("drift_baseline_mm", p.drift_baseline_mm);
  l.number("form_mpe_mm", p.form_mpe_mm);
  l.number("size_mpe_mm", p.size_mpe_mm);
  l.number("length_mpe_mm", p.length_mpe_mm);
  l.number("stereo_form_mpe_mm", p.stereo_form_mpe_mm);
  l.number("stereo_length_mpe_mm", p.stereo_length_mpe_mm);
  l.integer("plate_views", p.plate_views);
  l.integer("sphere_sweeps", p.sphere_sweeps);
  l.integer("ball_bar_sweeps", p.ball_bar_sweeps);
  l.section("results");
  l.text("database", c.results_database);
  l.section("report");
  l.text("materials", c.materials_file);
  l.section("programs");
  l.text("library", c.program_library);
  l.section("hmi");
  l.text("listen", c.panel.listen);
  l.text("users", c.panel.users_file);
  std::string names;
  for (const std::string& n : c.panel.server_names) names += (names.empty() ? "" : ", ") + CellListing::quoted(n);
  l.value("server_names", "[" + names + "]");
  l.text("tls_certificate", c.panel.tls_certificate);
  l.text("tls_key", c.panel.tls_key);
  l.integer("https_port", c.panel.https_port);
  l.integer("http_port", c.panel.http_port);
}

}  // namespace

std::string describeCellConfig(const CellConfig& c) {
  CellListing l(c.defaulted);
  l.raw("# The cell as understood from " + c.source + "; \"# default\": the file left the key out.");
  l.raw("name = " + CellListing::quoted(c.name));
  listMachine(l, c);
  listDevices(l, c);
  listArtefacts(l, c);
  listPolicies(l, c);
  return l.str();
}

}  // namespace stampscan::acquisition
