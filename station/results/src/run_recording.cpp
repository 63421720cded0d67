#include "stampscan/results/run_recording.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <regex>
#include <sstream>

namespace stampscan::results {

namespace {

namespace fs = std::filesystem;

// The folder's own name, also for "RUNS/x/" with its trailing slash.
fs::path normalFolder(const fs::path& run_dir) {
  fs::path dir = run_dir.lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();
  return dir;
}

// A JSON file of the run folder: empty when missing; a damaged file is named in `problem`.
nlohmann::json readJson(const fs::path& file, bool& present, std::string& problem) {
  std::error_code error;
  present = fs::exists(file, error);
  if (!present) return nlohmann::json::object();
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  try {
    nlohmann::json j = nlohmann::json::parse(text.str());
    if (j.is_object()) return j;
    problem = file.filename().string() + " is damaged (not a JSON object)";
  } catch (const nlohmann::json::exception& e) {
    problem = file.filename().string() + " is damaged (not valid JSON: " + e.what() + ")";
  }
  return nlohmann::json::object();
}

std::string text(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return {};
  return it->is_string() ? it->get<std::string>() : it->dump();
}

std::optional<double> number(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return std::nullopt;
  const double v = it->get<double>();
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

// Run folders are named <yyyymmdd>-<hhmmss>-<part id>, the time in UTC (the scan's naming).
bool startFromFolderName(const std::string& name, std::string& started, std::string& part_id) {
  static const std::regex pattern(R"((\d{4})(\d{2})(\d{2})-(\d{2})(\d{2})(\d{2})-(.+))");
  std::smatch m;
  if (!std::regex_match(name, m, pattern)) return false;
  started = m[1].str() + "-" + m[2].str() + "-" + m[3].str() + "T" + m[4].str() + ":" + m[5].str() + ":" + m[6].str() + "Z";
  part_id = m[7].str();
  return true;
}

// A folder not named by the scan: the time its run.json (or the folder) was last written.
std::string startFromFileTime(const fs::path& file) {
  std::error_code error;
  const auto written = fs::last_write_time(file, error);
  if (error) return {};
  const auto system = std::chrono::file_clock::to_sys(written);
  const std::time_t t = std::chrono::system_clock::to_time_t(system);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return stamp;
}

}  // namespace

RunRecord readRunRecord(const fs::path& run_dir_in) {
  const fs::path run_dir = normalFolder(run_dir_in);
  RunRecord r;
  r.run_id = run_dir.filename().string();
  r.run_dir = run_dir.string();
  bool has_run = false, has_report = false;
  std::string run_problem, report_problem;
  const nlohmann::json run = readJson(run_dir / "run.json", has_run, run_problem);
  const nlohmann::json report = readJson(run_dir / "report.json", has_report, report_problem);
  if (!has_run && !has_report)
    throw ResultsError(run_dir.string() + ": not a run folder (neither run.json nor report.json)");

  std::string folder_part;
  const bool named = startFromFolderName(r.run_id, r.started_utc, folder_part);
  r.part_id = text(run, "part_id");
  if (r.part_id.empty()) r.part_id = text(report, "part_id");
  if (r.part_id.empty()) r.part_id = folder_part;
  if (!named) r.started_utc = startFromFileTime(run_dir / (has_run ? "run.json" : "report.json"));
  r.plan = text(run, "plan");
  r.cell = text(run, "cell");
  // The report's program and material are the ones it used (an option may override run.json's).
  r.program = text(report, "program");
  if (r.program.empty()) r.program = text(run, "program");
  r.material = text(report, "material");
  if (r.material.empty()) r.material = text(run, "material");
  if (const auto m = run.find("measurement"); m != run.end() && m->is_object())
    if (const auto e = number(*m, "elements")) r.elements = static_cast<std::int64_t>(*e);
  if (const auto a = run.find("accuracy"); a != run.end() && a->is_object()) {
    r.position_rms_mm = number(*a, "position_rms_mm");
    r.strain_rms = number(*a, "strain_rms");
  }
  r.data_loss = text(run, "data_loss");

  r.verdict = text(report, "verdict");
  r.max_thinning_percent = number(report, "max_thinning_percent");
  r.min_margin_percent = number(report, "min_margin_percent");
  r.marginal_band_percent = number(report, "safety_margin_percent");
  if (const auto e = number(report, "elements")) r.elements = static_cast<std::int64_t>(*e);

  // The status, most telling reason first.
  if (has_run && run.value("completed", true) == false) {
    r.status = RunStatus::Aborted;
    r.reason = text(run, "abort_reason");
    if (r.reason.empty()) r.reason = "the scan was aborted (run.json gives no reason)";
  } else if (!run_problem.empty() || !report_problem.empty()) {
    r.status = RunStatus::Failed;
    r.reason = !run_problem.empty() ? run_problem : report_problem;
  } else if (!has_report) {
    r.status = RunStatus::Failed;
    r.reason = "no report.json: the run was not analysed (run `station report` on it)";
  } else if (r.verdict.empty()) {
    r.status = RunStatus::Failed;
    r.reason = "report.json gives no verdict";
  }
  return r;
}

RunRecord recordRunInResults(const fs::path& run_dir, const std::string& runs_dir_or_url,
                             const std::string& failure_reason) {
  RunRecord r = readRunRecord(run_dir);
  // The processing's own error is the better reason (a missing report.json is only its consequence);
  // an aborted scan keeps the abort's reason.
  if (!failure_reason.empty() && r.status != RunStatus::Aborted) {
    r.status = RunStatus::Failed;
    r.reason = failure_reason;
  }
  openResultsStore(runs_dir_or_url)->recordRun(r);
  return r;
}

RunRecord recordRunInResults(const fs::path& run_dir) {
  fs::path runs = normalFolder(run_dir).parent_path();
  if (runs.empty()) runs = ".";
  return recordRunInResults(run_dir, runs.string());
}

}  // namespace stampscan::results
