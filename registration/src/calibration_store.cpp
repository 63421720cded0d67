#include "stampscan/registration/calibration_store.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>

namespace stampscan::registration {

using nlohmann::json;

namespace {

constexpr const char* kFormat = "stampscan-calibration";
constexpr int kVersion = 1;

json poseJson(const Eigen::Isometry3d& T) {
  json r = json::array(), t = json::array();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.push_back(T.linear()(i, j));
  for (int i = 0; i < 3; ++i) t.push_back(T.translation()(i));
  return {{"rotation", r}, {"translation_mm", t}};
}

Eigen::Isometry3d poseFrom(const json& j, const std::string& where) {
  const auto& r = j.at("rotation");
  const auto& t = j.at("translation_mm");
  if (!r.is_array() || r.size() != 9 || !t.is_array() || t.size() != 3)
    throw std::runtime_error(where + ": a pose needs 9 rotation and 3 translation numbers");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) T.linear()(i, k) = r.at(static_cast<std::size_t>(3 * i + k)).get<double>();
  for (int i = 0; i < 3; ++i) T.translation()(i) = t.at(static_cast<std::size_t>(i)).get<double>();
  if (!T.linear().isUnitary(1e-6)) throw std::runtime_error(where + ": the rotation is not orthonormal");
  return T;
}

std::string jsonText(const json& j) { return j.dump(2) + "\n"; }

json header(const char* kind, const std::string& created, const std::string& source) {
  return {{"format", kFormat}, {"version", kVersion}, {"kind", kind}, {"created", created}, {"source", source}};
}

json cameraJson(const CameraCalibration& c) {
  json views = json::array();
  for (const auto& v : c.views)
    views.push_back({{"view", v.view}, {"used", v.used}, {"rms_px", v.rms_px}, {"note", v.note}});
  json dist = json::array();
  for (int i = 0; i < c.model.distortion.cols * c.model.distortion.rows; ++i) dist.push_back(c.model.distortion.at<double>(i));
  return {{"width", c.model.size.width},     {"height", c.model.size.height}, {"fx", c.model.matrix(0, 0)},
          {"fy", c.model.matrix(1, 1)},      {"cx", c.model.matrix(0, 2)},    {"cy", c.model.matrix(1, 2)},
          {"distortion_k1_k2_p1_p2_k3", dist}, {"rms_px", c.rms_px},           {"views", views}};
}

}  // namespace

std::string utcNow() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

namespace {

void putProvenance(json& j, const CalibrationProvenance& p) {
  j["record"] = p.record_id;
  j["cell"] = p.cell;
  json sensors = json::array();
  for (const auto& s : p.sensors)
    sensors.push_back({{"family", s.family}, {"model", s.model}, {"serial", s.serial}, {"firmware", s.firmware}});
  j["sensors"] = sensors;
  j["verdict"] = p.verdict;
  j["accepted_by"] = p.accepted_by;
}

CalibrationProvenance provenanceFrom(const json& j) {
  CalibrationProvenance p;
  p.record_id = j.value("record", "");
  p.cell = j.value("cell", "");
  if (const auto it = j.find("sensors"); it != j.end())
    for (const auto& s : *it)
      p.sensors.push_back({s.at("family").get<std::string>(), s.value("model", ""), s.at("serial").get<std::string>(),
                           s.value("firmware", "")});
  p.verdict = j.value("verdict", "");
  p.accepted_by = j.value("accepted_by", "");
  return p;
}

json digitizerJson(const DigitizerCalibrationFile& c) {
  json j = header("digitizer", c.created, c.source);
  j["head_from_digitizer"] = poseJson(c.calibration.head_from_digitizer);
  j["latency_ns"] = c.calibration.latency_ns;
  j["residual_rms_mm"] = c.residual_rms_mm;
  j["points"] = c.points;
  putProvenance(j, c.provenance);
  return j;
}

json camerasJson(const CameraCalibrationFile& c) {
  json j = header("cameras", c.created, c.source);
  j["left"] = cameraJson(c.stereo.left);
  j["right"] = cameraJson(c.stereo.right);
  j["right_from_left"] = poseJson(c.stereo.right_from_left);
  j["baseline_mm"] = c.stereo.baseline_mm;
  j["stereo_rms_px"] = c.stereo.rms_px;
  j["head_from_left"] = poseJson(c.head_from_left.head_from_camera);
  j["head_from_left_residual_mm"] = c.head_from_left.residual_mm;
  j["head_from_left_residual_deg"] = c.head_from_left.residual_deg;
  putProvenance(j, c.provenance);
  return j;
}

}  // namespace

void saveDigitizerCalibration(const std::filesystem::path& file, const DigitizerCalibrationFile& c) {
  fitting::writeFileAtomically(file, jsonText(digitizerJson(c)));
}

void saveCameraCalibration(const std::filesystem::path& file, const CameraCalibrationFile& c) {
  fitting::writeFileAtomically(file, jsonText(camerasJson(c)));
}

namespace {

// Writes the given files into `dir` together; with `whole_set`, a file not given is removed with them.
void writeCalibrations(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                       const CameraCalibrationFile* cameras, bool whole_set) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw std::runtime_error(dir.string() + ": cannot create the calibration folder (" + error.message() + ")");
  const std::filesystem::path digitizer_file = dir / "digitizer.json", cameras_file = dir / "cameras.json";
  fitting::AtomicFile new_digitizer(digitizer_file), new_cameras(cameras_file);
  std::vector<fitting::AtomicFile*> written;
  std::vector<std::filesystem::path> stale;
  const auto stage = [&](fitting::AtomicFile& file, const json& j) {
    std::ofstream out(file.temporaryPath(), std::ios::trunc);
    out << jsonText(j);
    out.close();
    if (!out) throw std::runtime_error(file.target().string() + ": cannot be written");
    written.push_back(&file);
  };
  if (digitizer != nullptr) stage(new_digitizer, digitizerJson(*digitizer));
  else if (whole_set) stale.push_back(digitizer_file);
  if (cameras != nullptr) stage(new_cameras, camerasJson(*cameras));
  else if (whole_set) stale.push_back(cameras_file);
  fitting::commitTogether(written, stale);
}

}  // namespace

void saveCalibrationSet(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                        const CameraCalibrationFile* cameras) {
  writeCalibrations(dir, digitizer, cameras, true);
}

void putCalibrationsInUse(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                          const CameraCalibrationFile* cameras) {
  writeCalibrations(dir, digitizer, cameras, false);
}

namespace {

// The JSON of a calibration file of `kind`, its format and version checked. Only regular files: a
// FIFO would block the read forever.
json readCalibrationJson(const std::filesystem::path& file, const char* kind) {
  std::error_code error;
  if (std::filesystem::exists(file, error) && !std::filesystem::is_regular_file(file, error))
    throw std::runtime_error(file.string() + ": not a regular file (a folder, FIFO or device)");
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open the " + kind + " calibration");
  const std::string where = file.string();
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  if (!j.is_object() || j.value("format", "") != kFormat || j.value("kind", "") != kind)
    throw std::runtime_error(where + ": not a StampScan " + kind + " calibration");
  if (j.value("version", 0) != kVersion)
    throw std::runtime_error(where + ": calibration version " + std::to_string(j.value("version", 0)) +
                             " (this station reads version " + std::to_string(kVersion) + ")");
  return j;
}

double finite(const json& j, const char* key, const std::string& where) {
  const double v = j.at(key).get<double>();
  if (!std::isfinite(v)) throw std::runtime_error(where + ": " + key + " is not a finite number");
  return v;
}

CameraCalibration cameraFrom(const json& j, const std::string& where) {
  CameraCalibration c;
  c.model.size = cv::Size(j.at("width").get<int>(), j.at("height").get<int>());
  if (c.model.size.width <= 0 || c.model.size.height <= 0) throw std::runtime_error(where + ": the image size is not positive");
  const double fx = finite(j, "fx", where), fy = finite(j, "fy", where);
  if (!(fx > 0) || !(fy > 0)) throw std::runtime_error(where + ": the focal lengths must be positive");
  c.model.matrix = cv::Matx33d(fx, 0, finite(j, "cx", where), 0, fy, finite(j, "cy", where), 0, 0, 1);
  const json& d = j.at("distortion_k1_k2_p1_p2_k3");
  if (!d.is_array() || d.size() != 5) throw std::runtime_error(where + ": distortion_k1_k2_p1_p2_k3 needs 5 numbers");
  c.model.distortion = cv::Mat(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) c.model.distortion.at<double>(i) = d.at(static_cast<std::size_t>(i)).get<double>();
  c.rms_px = j.value("rms_px", 0.0);
  if (const auto it = j.find("views"); it != j.end())
    for (const auto& v : *it)
      c.views.push_back({v.value("view", std::size_t{0}), v.value("used", false), v.value("rms_px", 0.0), v.value("note", "")});
  return c;
}

}  // namespace

DigitizerCalibrationFile loadDigitizerCalibration(const std::filesystem::path& file) {
  const json j = readCalibrationJson(file, "digitizer");
  const std::string where = file.string();
  try {
    DigitizerCalibrationFile c;
    c.calibration.head_from_digitizer = poseFrom(j.at("head_from_digitizer"), where + ": head_from_digitizer");
    c.calibration.latency_ns = j.at("latency_ns").get<std::int64_t>();
    c.residual_rms_mm = j.value("residual_rms_mm", 0.0);
    c.points = j.value("points", std::size_t{0});
    c.created = j.value("created", "");
    c.source = j.value("source", "");
    c.provenance = provenanceFrom(j);
    return c;
  } catch (const json::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
}

CameraCalibrationFile loadCameraCalibration(const std::filesystem::path& file) {
  const json j = readCalibrationJson(file, "cameras");
  const std::string where = file.string();
  try {
    CameraCalibrationFile c;
    c.stereo.left = cameraFrom(j.at("left"), where + ": left");
    c.stereo.right = cameraFrom(j.at("right"), where + ": right");
    c.stereo.right_from_left = poseFrom(j.at("right_from_left"), where + ": right_from_left");
    c.stereo.baseline_mm = c.stereo.right_from_left.translation().norm();
    c.stereo.rms_px = j.value("stereo_rms_px", 0.0);
    c.head_from_left.head_from_camera = poseFrom(j.at("head_from_left"), where + ": head_from_left");
    c.head_from_left.residual_mm = j.value("head_from_left_residual_mm", 0.0);
    c.head_from_left.residual_deg = j.value("head_from_left_residual_deg", 0.0);
    c.created = j.value("created", "");
    c.source = j.value("source", "");
    c.provenance = provenanceFrom(j);
    return c;
  } catch (const json::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
}

std::optional<std::chrono::system_clock::time_point> parseUtc(const std::string& text) {
  std::tm tm{};
  int used = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%2dZ%n", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour, &tm.tm_min,
                  &tm.tm_sec, &used) != 6 ||
      used != static_cast<int>(text.size()))
    return std::nullopt;
  if (tm.tm_mon < 1 || tm.tm_mon > 12 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 || tm.tm_min > 59 ||
      tm.tm_sec > 60)
    return std::nullopt;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  const std::time_t t = timegm(&tm);
  if (t == static_cast<std::time_t>(-1)) return std::nullopt;
  return std::chrono::system_clock::from_time_t(t);
}

std::optional<std::string> calibrationProblem(const std::filesystem::path& file, const std::string& created,
                                              const CalibrationProvenance& p, const CalibrationExpectation& e) {
  const std::string name = file.string();
  if (p.cell.empty()) return name + " does not say which cell it was made on (written before calibrations named their cell)";
  if (p.cell != e.cell) return name + " was made on the cell '" + p.cell + "', not on '" + e.cell + "'";
  if (p.verdict != "passed" && p.verdict != "accepted")
    return name + " is not an accepted calibration (verdict '" + (p.verdict.empty() ? "none" : p.verdict) + "')";
  // Each calibrated sensor must answer now with the same serial, in the same order within its
  // family (cameras left, then right: a swapped pair is another calibration).
  std::map<std::string, std::size_t> seen;
  for (const SensorIdentity& s : p.sensors) {
    const std::size_t k = seen[s.family]++;
    std::size_t n = 0;
    const SensorIdentity* now = nullptr;
    for (const SensorIdentity& c : e.sensors)
      if (c.family == s.family && n++ == k) now = &c;
    if (now == nullptr) return name + " is for the " + s.family + " " + s.serial + ", which does not answer";
    if (now->serial != s.serial)
      return name + " is for the " + s.family + " with serial '" + s.serial + "', but the cell's has serial '" + now->serial + "'";
  }
  const auto when = parseUtc(created);
  if (!when) return name + ": its creation time '" + created + "' is not a UTC time";
  const double age_days = std::chrono::duration<double>(e.now - *when).count() / 86400.0;
  if (age_days < -1.0 / 24) return name + " was created in the future (" + created + "): check the station's clock";
  if (age_days > e.validity_days) {
    char text[160];
    std::snprintf(text, sizeof text, " is %.1f days old, beyond its validity of %g days", age_days, e.validity_days);
    return name + text;
  }
  return std::nullopt;
}

}  // namespace stampscan::registration
