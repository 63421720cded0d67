// What a report reads from a run folder besides the clouds: the facts of run.json.
#include "stampscan/report/run_report.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>

namespace stampscan::report {

namespace {

std::string textOf(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return {};
  return it->is_string() ? it->get<std::string>() : it->dump();
}

// Run folders are named <yyyymmdd>-<hhmmss>-<part id> (acquisition's run folder naming).
bool parseFolderName(const std::string& name, std::string& date, std::string& part_id) {
  static const std::regex pattern(R"((\d{4})(\d{2})(\d{2})-(\d{2})(\d{2})(\d{2})-(.+))");
  std::smatch m;
  if (!std::regex_match(name, m, pattern)) return false;
  date = m[1].str() + "-" + m[2].str() + "-" + m[3].str() + " " + m[4].str() + ":" + m[5].str() + ":" + m[6].str();
  part_id = m[7].str();
  return true;
}

std::string calibrationText(const nlohmann::json& run) {
  if (const auto it = run.find("calibration"); it != run.end() && !it->is_null()) {
    if (it->is_string()) return it->get<std::string>();
    // {"digitizer": "...", "cameras": "..."}: which calibration each sensor was measured with.
    std::string out;
    if (it->is_object())
      for (const auto& [sensor, text] : it->items())
        if (text.is_string()) out += (out.empty() ? "" : "; ") + sensor + ": " + text.get<std::string>();
    if (!out.empty()) return out;
    return it->dump();
  }
  // Runs of the built-in plans calibrate in the run itself: the digitizer on the reference sphere,
  // the cameras on the plate.
  const auto measurement = run.find("measurement");
  if (measurement == run.end() || !measurement->contains("sphere_residual_mm")) return {};
  char text[200];
  std::snprintf(text, sizeof text, "in the run: digitizer on the reference sphere, %.4f mm RMS",
                (*measurement)["sphere_residual_mm"].get<double>());
  std::string out = text;
  if (measurement->contains("digitizer_latency_ms")) {
    std::snprintf(text, sizeof text, ", latency %.2f ms", (*measurement)["digitizer_latency_ms"].get<double>());
    out += text;
  }
  const auto scan = run.find("scan");
  if (scan != run.end() && scan->value("stereo_views", 0) > 0) out += "; cameras on the calibration plate";
  return out;
}

std::string accuracyText(const nlohmann::json& run) {
  const auto it = run.find("accuracy");
  if (it == run.end() || !it->is_object()) return {};
  char text[200];
  std::snprintf(text, sizeof text,
                "against the simulated part: position %.4f mm RMS, thickness strain %.5f RMS (%s elements matched)",
                it->value("position_rms_mm", 0.0), it->value("strain_rms", 0.0),
                it->contains("matched") ? (*it)["matched"].dump().c_str() : "?");
  return text;
}

}  // namespace

RunInfo readRunInfo(const std::filesystem::path& run_dir) {
  RunInfo info;
  const std::string folder =
      run_dir.filename().empty() ? run_dir.parent_path().filename().string() : run_dir.filename().string();
  parseFolderName(folder, info.date, info.part_id);
  const std::filesystem::path file = run_dir / "run.json";
  std::error_code error;
  if (!std::filesystem::exists(file, error)) return info;
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  nlohmann::json run;
  try {
    run = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::exception& e) {
    throw ReportError(file.string() + ": damaged (not valid JSON: " + e.what() + ")");
  }
  if (!run.is_object()) throw ReportError(file.string() + ": damaged (not a JSON object)");
  try {
    if (const std::string id = textOf(run, "part_id"); !id.empty()) info.part_id = id;
    if (const std::string date = textOf(run, "date"); !date.empty()) info.date = date;
    info.program = textOf(run, "program");
    if (run.contains("part_program") && run["part_program"].is_object()) info.part_program = textOf(run["part_program"], "name");
    info.plan = textOf(run, "plan");
    info.cell = textOf(run, "cell");
    info.material = textOf(run, "material");
    info.calibration = calibrationText(run);
    info.accuracy = accuracyText(run);
    info.data_loss = textOf(run, "data_loss");
  } catch (const nlohmann::json::exception& e) {
    throw ReportError(file.string() + ": damaged (" + e.what() + ")");
  }
  return info;
}

}  // namespace stampscan::report
