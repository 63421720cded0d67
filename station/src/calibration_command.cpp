// `station calibration status|list|show ID|diff ID1 ID2`: the calibration in use, and the cell's
// calibration history, the records that `station calibrate` and `station verify` write
// (registration/calibration_record.hpp).
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/jobs/calibration_status.hpp"
#include "stampscan/results/results_store.hpp"
#include "stampscan/station/commands.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace stampscan::station {

namespace {

namespace fs = std::filesystem;
using registration::CalibrationRecord;

struct CalibrationOptions {
  std::string calibration_dir = "stampscan-runs/calibration";
  std::string id, other, database, kind, cell;
  std::size_t last = 0;
};

// The records' sub-folder of a calibration folder (see verify_job.hpp).
fs::path historyOf(const std::string& calibration_dir) { return fs::path(calibration_dir) / "history"; }

std::string checksSummary(const CalibrationRecord& r) {
  std::size_t passed = 0;
  for (const auto& c : r.checks) passed += c.passed ? 1 : 0;
  return std::to_string(passed) + "/" + std::to_string(r.checks.size()) + " checks";
}

int list(const CalibrationOptions& o) {
  const fs::path history = historyOf(o.calibration_dir);
  const registration::RecordListing listing = registration::listCalibrationRecords(history);
  if (listing.records.empty() && listing.problems.empty()) {
    std::printf("no calibration records in %s (`station calibrate` and `station verify` write them)\n", history.c_str());
    return 0;
  }
  std::printf("%-36s %-13s %-21s %-9s %-11s %s\n", "id", "kind", "created", "verdict", "checks", "cell");
  for (const auto& r : listing.records)
    std::printf("%-36s %-13s %-21s %-9s %-11s %s\n", r.id.c_str(), r.kind.c_str(), r.created.c_str(),
                registration::toString(r.verdict), checksSummary(r).c_str(), r.cell.c_str());
  for (const auto& p : listing.problems) std::fprintf(stderr, "station: warning: %s\n", p.c_str());
  return listing.problems.empty() ? 0 : 1;
}

// The rows of a results database (every cell that writes to it), rather than one cell's folder.
int listDatabase(const CalibrationOptions& o) {
  results::StoreOptions read_only;
  read_only.read_only = true;
  const auto rows = results::openResultsStore(o.database, read_only)->queryCalibrations(o.kind, o.last);
  if (rows.empty()) {
    std::printf("no calibration records in the results database of %s\n", o.database.c_str());
    return 0;
  }
  std::printf("%-36s %-13s %-21s %-9s %-16s %s\n", "id", "kind", "created", "verdict", "cell", "checks");
  for (const auto& r : rows)
    std::printf("%-36s %-13s %-21s %-9s %-16s %s%s\n", r.record_id.c_str(), r.kind.c_str(), r.created_utc.c_str(),
                r.verdict.c_str(), r.cell.c_str(), r.summary.c_str(),
                r.accepted_by.empty() ? "" : ("; accepted by " + r.accepted_by).c_str());
  return 0;
}

int show(const CalibrationOptions& o) {
  const CalibrationRecord r = registration::findCalibrationRecord(historyOf(o.calibration_dir), o.id);
  std::printf("record      %s (%s, version %d)\n", r.id.c_str(), r.kind.c_str(), CalibrationRecord::kVersion);
  std::printf("created     %s\n", r.created.c_str());
  std::printf("cell        %s\n", r.cell.c_str());
  for (const auto& s : r.sensors)
    std::printf("sensor      %-10s %s, serial %s, firmware %s\n", s.family.c_str(), s.model.c_str(),
                s.serial.empty() ? "(none)" : s.serial.c_str(), s.firmware.c_str());
  for (const auto& t : r.traces) std::printf("trace       %s\n", t.c_str());
  std::printf("calibration %s\n", r.calibration.c_str());
  // Counts (no unit) as whole numbers, measures to the micrometre's hundredth.
  const auto value = [](const char* what, const registration::RecordValue& v) {
    if (v.unit.empty())
      std::printf("%-11s %-40s %12.0f\n", what, v.name.c_str(), v.value);
    else if (v.uncertainty > 0)
      std::printf("%-11s %-40s %12.5f %-3s +- %.5f\n", what, v.name.c_str(), v.value, v.unit.c_str(), v.uncertainty);
    else
      std::printf("%-11s %-40s %12.5f %s\n", what, v.name.c_str(), v.value, v.unit.c_str());
  };
  for (const auto& v : r.parameters) value("parameter", v);
  for (const auto& v : r.residuals) value("residual", v);
  for (const auto& c : r.checks)
    std::printf("check       %-4s %-47s %+.4f %s (limit %.4f)\n", c.passed ? "PASS" : "FAIL", c.name.c_str(), c.value,
                c.unit.c_str(), c.limit);
  std::printf("verdict     %s%s\n", registration::toString(r.verdict),
              r.accepted_by.empty() ? "" : (" by " + r.accepted_by).c_str());
  for (const auto& n : r.notes) std::printf("note        %s\n", n.c_str());
  return 0;
}

int diff(const CalibrationOptions& o) {
  const fs::path history = historyOf(o.calibration_dir);
  const CalibrationRecord a = registration::findCalibrationRecord(history, o.id);
  const CalibrationRecord b = registration::findCalibrationRecord(history, o.other);
  std::printf("%s -> %s\n", a.id.c_str(), b.id.c_str());
  for (const auto& d : registration::diffCalibrationRecords(a, b)) {
    if (!d.before && !d.after) {
      std::printf("  %-47s %s -> %s\n", d.name.c_str(), d.before_text.c_str(), d.after_text.c_str());
      continue;
    }
    const auto number = [](const std::optional<double>& x) {
      char text[32];
      if (x)
        std::snprintf(text, sizeof text, "%.5f", *x);
      else
        std::snprintf(text, sizeof text, "%s", "(absent)");
      return std::string(text);
    };
    std::string change = "";
    if (d.before && d.after) {
      char text[48];
      std::snprintf(text, sizeof text, "%+.5f %s", *d.after - *d.before, d.unit.c_str());
      change = text;
    }
    std::printf("  %-47s %12s -> %12s  %s\n", d.name.c_str(), number(d.before).c_str(), number(d.after).c_str(),
                change.c_str());
  }
  return 0;
}

// The calibration in use, sensor by sensor (calibration_status.hpp). Exit 2 when a sensor has none
// that a scan would accept.
int status(const CalibrationOptions& o) {
  const acquisition::CellConfig cell = o.cell.empty() ? acquisition::virtualCell() : acquisition::loadCellConfig(o.cell);
  const jobs::CalibrationStatus st = jobs::calibrationStatus(o.calibration_dir, cell);
  std::printf("calibration in use in %s (cell '%s', valid %g days)\n", o.calibration_dir.c_str(), cell.name.c_str(),
              cell.calibration.validity_days);
  for (const jobs::SensorCalibrationStatus& s : st.sensors) {
    if (s.usable())
      std::printf("  %-11s record %s (%s), created %s: %.1f days old, valid %.1f days more\n", s.sensor.c_str(),
                  s.record_id.c_str(), s.verdict.c_str(), s.created.c_str(), s.age_days,
                  cell.calibration.validity_days - s.age_days);
    else if (!s.problem)
      std::printf("  %-11s none in use; run `station calibrate %s`\n", s.sensor.c_str(), s.sensor.c_str());
    else
      std::printf("  %-11s NOT USABLE: %s; run `station calibrate %s`\n", s.sensor.c_str(), s.problem->c_str(),
                  s.sensor.c_str());
  }
  if (st.last_verification)
    std::printf("  %-11s last %s: %s\n", "verified", st.last_verification->id.c_str(),
                registration::toString(st.last_verification->verdict));
  else
    std::printf("  %-11s never (`station verify` checks the calibration in use)\n", "verified");
  return st.allUsable() ? 0 : 2;
}

}  // namespace

CommandRunner addCalibrationCommand(CLI::App& app) {
  auto opt = std::make_shared<CalibrationOptions>();
  CLI::App* cmd = app.add_subcommand("calibration", "The cell's calibration history: list, show or compare records");
  cmd->require_subcommand(1);
  cmd->fallthrough();  // -d may come after the subcommand too
  cmd->add_option("-d,--calibration-dir", opt->calibration_dir, "The cell's calibration folder (records in its history/)");
  CLI::App* list_cmd = cmd->add_subcommand("list", "The records, oldest first");
  list_cmd->add_option("--db", opt->database,
                       "List the rows of a results database instead (a runs folder or a postgresql:// URL): every "
                       "cell that records there");
  list_cmd->add_option("--kind", opt->kind, "With --db: only this kind (digitizer, cameras, verification)");
  list_cmd->add_option("--last", opt->last, "With --db: only the newest N");
  CLI::App* status_cmd = cmd->add_subcommand(
      "status", "The calibration in use: each sensor's record, verdict and age against the cell's validity, and the last "
                "verification (exit 2 when a sensor has none a scan would accept)");
  status_cmd->add_option("--cell", opt->cell, "Cell configuration (its name and [calibration] validity_days); default: "
                                              "the built-in virtual cell");
  CLI::App* show_cmd = cmd->add_subcommand("show", "One record in full");
  show_cmd->add_option("ID", opt->id, "The record's id (see `station calibration list`)")->required();
  CLI::App* diff_cmd = cmd->add_subcommand("diff", "Two records side by side: what changed, value by value");
  diff_cmd->add_option("ID1", opt->id, "The earlier record")->required();
  diff_cmd->add_option("ID2", opt->other, "The later record")->required();
  return [opt, list_cmd, status_cmd, show_cmd, diff_cmd]() {
    if (list_cmd->parsed()) return opt->database.empty() ? list(*opt) : listDatabase(*opt);
    if (status_cmd->parsed()) return status(*opt);
    if (show_cmd->parsed()) return show(*opt);
    if (diff_cmd->parsed()) return diff(*opt);
    return 2;
  };
}

}  // namespace stampscan::station
