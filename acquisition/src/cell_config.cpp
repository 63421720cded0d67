#include "stampscan/acquisition/cell_config.hpp"

#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

#include <toml++/toml.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <type_traits>

namespace stampscan::acquisition {

CellConfig virtualCell() {
  CellConfig c;
  c.source = "built-in";
  c.digitizer_virtual = true;
  c.cmm_device_time = true;
  c.calibration.sphere_diameter_mm = 25.4;  // the virtual cell's ball bar (sim/scan_scenario.hpp)
  c.calibration.second_sphere_diameter_mm = 25.4;
  c.calibration.sphere_distance_mm = 120.0;
  return c;
}

namespace {

// What a key of type T holds, as a cell file's author would write it.
template <typename T>
constexpr const char* expectedKind() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_same_v<T, std::string>) return "a string";
  else return "an integer";
}

template <typename T>
T get(const toml::table& t, const std::string& section, const std::string& key, T fallback, const std::string& file) {
  const toml::node_view<const toml::node> node = t[section][key];
  if (!node) return fallback;
  if (const auto v = node.value<T>()) return *v;
  std::ostringstream type;
  type << node.type();  // toml++'s name for it: string, integer, boolean, array, ...
  const std::string found = (type.str().find_first_of("aeiou") == 0 ? "an " : "a ") + type.str();
  throw std::runtime_error(file + ": [" + section + "] " + key + " has the wrong type: expected " +
                           expectedKind<T>() + ", found " + found);
}

void checkPort(int port, const std::string& file, const std::string& section) {
  if (port < 1 || port > 65535) throw std::runtime_error(file + ": [" + section + "] port " + std::to_string(port) + " is not 1-65535");
}

// A number of a section, or the default; must be finite (and positive where asked).
double number(const toml::table& t, const char* section, const char* key, double fallback, const std::string& file,
              bool positive = false) {
  const toml::node_view<const toml::node> node = t[section][key];
  if (!node) return fallback;
  const std::optional<double> v = node.value<double>();
  if (!v || !std::isfinite(*v) || (positive && !(*v > 0)))
    throw std::runtime_error(file + ": [" + section + "] " + key +
                             (positive ? " must be a positive number" : " must be a number"));
  return *v;
}

std::array<double, 3> triple(const toml::table& t, const char* key, std::array<double, 3> fallback, const std::string& file) {
  const toml::node_view<const toml::node> node = t["machine"][key];
  if (!node) return fallback;
  const toml::array* a = node.as_array();
  std::array<double, 3> out{};
  if (a == nullptr || a->size() != 3)
    throw std::runtime_error(file + ": [machine] " + key + " must be a list of 3 numbers (x, y, z in mm)");
  for (std::size_t i = 0; i < 3; ++i) {
    const std::optional<double> v = (*a)[i].value<double>();
    if (!v || !std::isfinite(*v)) throw std::runtime_error(file + ": [machine] " + key + " must be a list of 3 numbers (x, y, z in mm)");
    out[i] = *v;
  }
  return out;
}

void readLimits(const toml::table& t, const std::string& file, MachineLimits& l) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  l.travel_min = triple(t, "travel_min", l.travel_min, file);
  l.travel_max = triple(t, "travel_max", l.travel_max, file);
  for (std::size_t i = 0; i < 3; ++i)
    if (!(l.travel_min[i] < l.travel_max[i])) throw std::runtime_error(file + ": [machine] travel_min must be below travel_max on every axis");
  l.min_speed = number(t, "machine", "min_speed", l.min_speed, file, true);
  l.max_speed = number(t, "machine", "max_speed", l.max_speed, file, true);
  if (!(l.min_speed <= l.max_speed)) throw std::runtime_error(file + ": [machine] min_speed is above max_speed");
  l.acceleration = number(t, "machine", "acceleration", l.acceleration, file, true);
  l.max_tilt = number(t, "machine", "max_tilt_deg", l.max_tilt / kDeg, file, true) * kDeg;
  l.max_turn = number(t, "machine", "max_turn_deg", l.max_turn / kDeg, file, true) * kDeg;
  l.head_rate = number(t, "machine", "head_rate_deg_s", l.head_rate / kDeg, file, true) * kDeg;
  l.head_acceleration = number(t, "machine", "head_acceleration_deg_s2", l.head_acceleration / kDeg, file, true) * kDeg;
}

void readCalibrationPolicy(const toml::table& t, const std::string& file, CalibrationPolicy& p) {
  static constexpr const char* kSection = "calibration";
  if (const toml::node_view<const toml::node> section = t[kSection]; section && !section.is_table())
    throw std::runtime_error(file + ": [calibration] must be a table");
  p.dir = get<std::string>(t, kSection, "dir", p.dir, file);
  p.validity_days = number(t, kSection, "validity_days", p.validity_days, file, true);
  p.digitizer_residual_mm = number(t, kSection, "digitizer_residual_mm", p.digitizer_residual_mm, file, true);
  p.camera_reprojection_px = number(t, kSection, "camera_reprojection_px", p.camera_reprojection_px, file, true);
  p.head_mount_residual_mm = number(t, kSection, "head_mount_residual_mm", p.head_mount_residual_mm, file, true);
  p.drift_mount_mm = number(t, kSection, "drift_mount_mm", p.drift_mount_mm, file, true);
  p.drift_latency_ms = number(t, kSection, "drift_latency_ms", p.drift_latency_ms, file, true);
  p.drift_baseline_mm = number(t, kSection, "drift_baseline_mm", p.drift_baseline_mm, file, true);
  p.sphere_diameter_mm = number(t, kSection, "sphere_diameter_mm", p.sphere_diameter_mm, file);
  if (p.sphere_diameter_mm < 0) throw std::runtime_error(file + ": [calibration] sphere_diameter_mm must not be negative");
  p.form_mpe_mm = number(t, kSection, "form_mpe_mm", p.form_mpe_mm, file, true);
  p.size_mpe_mm = number(t, kSection, "size_mpe_mm", p.size_mpe_mm, file, true);
  p.second_sphere_diameter_mm = number(t, kSection, "second_sphere_diameter_mm", p.second_sphere_diameter_mm, file);
  p.sphere_distance_mm = number(t, kSection, "sphere_distance_mm", p.sphere_distance_mm, file);
  p.length_mpe_mm = number(t, kSection, "length_mpe_mm", p.length_mpe_mm, file, true);
  p.stereo_form_mpe_mm = number(t, kSection, "stereo_form_mpe_mm", p.stereo_form_mpe_mm, file, true);
  p.stereo_length_mpe_mm = number(t, kSection, "stereo_length_mpe_mm", p.stereo_length_mpe_mm, file, true);
  if (p.second_sphere_diameter_mm < 0 || p.sphere_distance_mm < 0)
    throw std::runtime_error(file + ": [calibration] second_sphere_diameter_mm and sphere_distance_mm must not be negative");
  if (p.sphere_distance_mm > 0 && p.second_sphere_diameter_mm <= 0)
    throw std::runtime_error(file + ": [calibration] sphere_distance_mm needs second_sphere_diameter_mm (the second sphere's certificate)");
}

}  // namespace

CellConfig loadCellConfig(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code error;
  // Only regular files: a FIFO would block the read forever.
  if (!std::filesystem::exists(path, error)) throw std::runtime_error(file + ": the cell file does not exist");
  if (!std::filesystem::is_regular_file(path, error))
    throw std::runtime_error(file + ": not a regular file (a folder, FIFO or device), not a cell file");
  toml::table t;
  try {
    t = toml::parse_file(file);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    throw std::runtime_error(file + ":" + std::to_string(where.line) + ":" + std::to_string(where.column) + ": " +
                             std::string(e.description()));
  }
  CellConfig c;
  c.source = file;
  c.name = t["name"].value_or(std::string("cell"));
  c.cmm.host = get<std::string>(t, "cmm", "host", c.cmm.host, file);
  c.cmm.port = static_cast<int>(get<std::int64_t>(t, "cmm", "port", c.cmm.port, file));
  checkPort(c.cmm.port, file, "cmm");
  c.cmm_device_time = get<bool>(t, "cmm", "device_time", false, file);
  c.plc.host = get<std::string>(t, "plc", "host", c.plc.host, file);
  c.plc.port = static_cast<int>(get<std::int64_t>(t, "plc", "port", c.plc.port, file));
  checkPort(c.plc.port, file, "plc");
  c.plc_unit_id = static_cast<int>(get<std::int64_t>(t, "plc", "unit_id", c.plc_unit_id, file));
  c.left_camera.serial = get<std::string>(t, "cameras", "left_serial", c.left_camera.serial, file);
  c.left_camera.address = get<std::string>(t, "cameras", "left_address", c.left_camera.address, file);
  c.right_camera.serial = get<std::string>(t, "cameras", "right_serial", c.right_camera.serial, file);
  c.right_camera.address = get<std::string>(t, "cameras", "right_address", c.right_camera.address, file);
  const auto vendor = get<std::int64_t>(t, "digitizer", "vendor_id", c.digitizer_vendor, file);
  const auto product = get<std::int64_t>(t, "digitizer", "product_id", c.digitizer_product, file);
  if (vendor < 0 || vendor > 0xffff || product < 0 || product > 0xffff)
    throw std::runtime_error(file + ": [digitizer] vendor_id and product_id must be 16-bit");
  c.digitizer_vendor = static_cast<std::uint16_t>(vendor);
  c.digitizer_product = static_cast<std::uint16_t>(product);
  c.digitizer_serial = get<std::string>(t, "digitizer", "serial", "", file);
  c.digitizer_virtual = get<bool>(t, "digitizer", "virtual", false, file);
  if (c.digitizer_virtual &&
      (c.digitizer_vendor != drivers::digitizer::kVendorId || c.digitizer_product != drivers::digitizer::kProductId)) {
    char ids[64];
    std::snprintf(ids, sizeof ids, "%04x:%04x is not the virtual digitizer's %04x:%04x", c.digitizer_vendor,
                  c.digitizer_product, drivers::digitizer::kVendorId, drivers::digitizer::kProductId);
    throw std::runtime_error(file + ": [digitizer] virtual = true, but vendor_id:product_id " + ids);
  }
  c.digitizer_required = get<bool>(t, "digitizer", "required", true, file);
  readLimits(t, file, c.limits);
  readCalibrationPolicy(t, file, c.calibration);
  c.results_database = get<std::string>(t, "results", "database", "", file);
  c.materials_file = get<std::string>(t, "report", "materials", "", file);
  if (!c.materials_file.empty() && std::filesystem::path(c.materials_file).is_relative())
    c.materials_file = (path.parent_path() / c.materials_file).string();
  return c;
}

}  // namespace stampscan::acquisition
