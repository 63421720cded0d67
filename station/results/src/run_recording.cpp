#include "stampscan/results/run_recording.hpp"

#include "stampscan/run_folder/folder_name.hpp"
#include "stampscan/run_folder/run_record.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
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

RunRow readRunRow(const fs::path& run_dir_in) {
  const fs::path run_dir = normalFolder(run_dir_in);
  RunRow r;
  r.run_id = run_dir.filename().string();
  r.run_dir = run_dir.string();
  // run.json (the scan's record) and report.json (the report's); a damaged one makes the run failed.
  std::string run_problem, report_problem;
  std::optional<run_folder::RunRecord> run;
  try {
    run = run_folder::readRunRecord(run_dir);
  } catch (const run_folder::RunRecordError& e) {
    run_problem = e.what();
  }
  const bool has_run = run.has_value() || !run_problem.empty();
  bool has_report = false;
  const nlohmann::json report = readJson(run_dir / "report.json", has_report, report_problem);
  if (!has_run && !has_report)
    throw ResultsError(run_dir.string() + ": not a run folder (neither run.json nor report.json)");

  const std::optional<run_folder::FolderName> name = run_folder::parseRunFolderName(r.run_id);
  if (name) r.started_utc = name->started_utc;
  if (run) r.part_id = run->part_id;
  if (r.part_id.empty()) r.part_id = text(report, "part_id");
  if (r.part_id.empty() && name) r.part_id = name->part_id;
  if (!name) r.started_utc = startFromFileTime(run_dir / (has_run ? run_folder::kRunRecordFile : "report.json"));
  // The report's program and material are the ones it used (an option may override run.json's).
  r.program = text(report, "program");
  r.material = text(report, "material");
  if (run) {
    r.plan = run->plan;
    r.cell = run->cell;
    if (r.program.empty()) r.program = run->program;
    if (r.material.empty()) r.material = run->material;
    if (run->measurement) r.elements = run->measurement->elements;
    if (run->accuracy) {
      r.position_rms_mm = run->accuracy->position_rms_mm;
      r.strain_rms = run->accuracy->strain_rms;
    }
    r.data_loss = run->data_loss;
  }

  r.verdict = text(report, "verdict");
  r.max_thinning_percent = number(report, "max_thinning_percent");
  r.min_margin_percent = number(report, "min_margin_percent");
  r.marginal_band_percent = number(report, "safety_margin_percent");
  if (const auto e = number(report, "elements")) r.elements = static_cast<std::int64_t>(*e);

  // The status, most telling reason first.
  if (run && !run->completed) {
    r.status = RunStatus::Aborted;
    r.reason = run->abort_reason;
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

RunRow recordRunInResults(const fs::path& run_dir, const std::string& runs_dir_or_url,
                             const std::string& failure_reason) {
  RunRow r = readRunRow(run_dir);
  // The processing's own error is the better reason (a missing report.json is only its consequence);
  // an aborted scan keeps the abort's reason.
  if (!failure_reason.empty() && r.status != RunStatus::Aborted) {
    r.status = RunStatus::Failed;
    r.reason = failure_reason;
  }
  openResultsStore(runs_dir_or_url)->recordRun(r);
  return r;
}

RunRow recordRunInResults(const fs::path& run_dir) {
  fs::path runs = normalFolder(run_dir).parent_path();
  if (runs.empty()) runs = ".";
  return recordRunInResults(run_dir, runs.string());
}

}  // namespace stampscan::results
