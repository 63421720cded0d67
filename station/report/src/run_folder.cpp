// What a report reads from a run folder besides the clouds: the facts of run.json.
#include "stampscan/report/run_report.hpp"

#include "stampscan/run_folder/folder_name.hpp"
#include "stampscan/run_folder/run_record.hpp"

#include <cstdio>

namespace stampscan::report {

namespace {

std::string calibrationText(const run_folder::RunRecord& run) {
  if (const auto& c = run.calibration) {
    // Which calibration each sensor was measured with.
    std::string out;
    if (!c->digitizer.empty()) out += "digitizer: " + c->digitizer;
    if (!c->cameras.empty()) out += (out.empty() ? "" : "; ") + std::string("cameras: ") + c->cameras;
    if (!out.empty()) return out;
  }
  // Runs of the built-in plans calibrate in the run itself: the digitizer on the reference sphere,
  // the cameras on the plate.
  if (!run.measurement || !run.measurement->sphere_residual_mm) return {};
  char text[200];
  std::snprintf(text, sizeof text, "in the run: digitizer on the reference sphere, %.4f mm RMS, latency %.2f ms",
                *run.measurement->sphere_residual_mm, run.measurement->digitizer_latency_ms);
  std::string out = text;
  if (run.scan && run.scan->stereo_views > 0) out += "; cameras on the calibration plate";
  return out;
}

std::string accuracyText(const run_folder::RunRecord& run) {
  if (!run.accuracy) return {};
  const run_folder::AccuracyFigures& a = *run.accuracy;
  char text[200];
  std::snprintf(text, sizeof text,
                "against the simulated part: position %.4f mm RMS, thickness strain %.5f RMS (%lld elements matched)",
                a.position_rms_mm, a.strain_rms, static_cast<long long>(a.matched));
  return text;
}

}  // namespace

RunInfo readRunInfo(const std::filesystem::path& run_dir) {
  RunInfo info;
  const std::string folder =
      run_dir.filename().empty() ? run_dir.parent_path().filename().string() : run_dir.filename().string();
  if (const auto name = run_folder::parseRunFolderName(folder)) {
    // "2026-11-24T09:16:02Z" shown as "2026-11-24 09:16:02".
    info.date = name->started_utc.substr(0, 10) + " " + name->started_utc.substr(11, 8);
    info.part_id = name->part_id;
  }
  std::optional<run_folder::RunRecord> run;
  try {
    run = run_folder::readRunRecord(run_dir);
  } catch (const run_folder::RunRecordError& e) {
    throw ReportError(e.what());
  }
  if (!run) return info;
  if (!run->part_id.empty()) info.part_id = run->part_id;
  info.program = run->program;
  if (run->part_program) info.part_program = run->part_program->name;
  info.plan = run->plan;
  info.cell = run->cell;
  info.material = run->material;
  info.calibration = calibrationText(*run);
  info.accuracy = accuracyText(*run);
  info.data_loss = run->data_loss;
  return info;
}

}  // namespace stampscan::report
