#include "stampscan/registration/calibration_store.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <ctime>
#include <fstream>
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

json digitizerJson(const DigitizerCalibrationFile& c) {
  json j = header("digitizer", c.created, c.source);
  j["head_from_digitizer"] = poseJson(c.calibration.head_from_digitizer);
  j["latency_ns"] = c.calibration.latency_ns;
  j["residual_rms_mm"] = c.residual_rms_mm;
  j["points"] = c.points;
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
  return j;
}

}  // namespace

void saveDigitizerCalibration(const std::filesystem::path& file, const DigitizerCalibrationFile& c) {
  fitting::writeFileAtomically(file, jsonText(digitizerJson(c)));
}

void saveCameraCalibration(const std::filesystem::path& file, const CameraCalibrationFile& c) {
  fitting::writeFileAtomically(file, jsonText(camerasJson(c)));
}

void saveCalibrationSet(const std::filesystem::path& dir, const DigitizerCalibrationFile* digitizer,
                        const CameraCalibrationFile* cameras) {
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
  else stale.push_back(digitizer_file);
  if (cameras != nullptr) stage(new_cameras, camerasJson(*cameras));
  else stale.push_back(cameras_file);
  fitting::commitTogether(written, stale);
}

DigitizerCalibrationFile loadDigitizerCalibration(const std::filesystem::path& file) {
  std::error_code error;
  // Only regular files: a FIFO would block the read forever.
  if (std::filesystem::exists(file, error) && !std::filesystem::is_regular_file(file, error))
    throw std::runtime_error(file.string() + ": not a regular file (a folder, FIFO or device)");
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open the digitizer calibration");
  const std::string where = file.string();
  try {
    const json j = json::parse(in);
    if (j.value("format", "") != kFormat || j.value("kind", "") != "digitizer")
      throw std::runtime_error(where + ": not a StampScan digitizer calibration");
    if (j.value("version", 0) != kVersion)
      throw std::runtime_error(where + ": calibration version " + std::to_string(j.value("version", 0)) +
                               " (this station reads version " + std::to_string(kVersion) + ")");
    DigitizerCalibrationFile c;
    c.calibration.head_from_digitizer = poseFrom(j.at("head_from_digitizer"), where + ": head_from_digitizer");
    c.calibration.latency_ns = j.at("latency_ns").get<std::int64_t>();
    c.residual_rms_mm = j.value("residual_rms_mm", 0.0);
    c.points = j.value("points", std::size_t{0});
    c.created = j.value("created", "");
    c.source = j.value("source", "");
    return c;
  } catch (const json::exception& e) {
    throw std::runtime_error(where + ": " + e.what());
  }
}

}  // namespace stampscan::registration
