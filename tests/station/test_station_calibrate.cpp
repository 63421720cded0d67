// `station calibrate` on the embedded virtual cell, whose simulator knows the sensors' true
// intrinsics, mounts and latency; and what a scan then does with the calibration in use: measures
// with it, or refuses it before anything moves when it is missing, failed, expired, another cell's
// or another sensor's. A digitizer knocked on its mount (the virtual cell's --shift-digitizer-mount)
// fails `station verify` and passes again after `station calibrate`, which reports the drift.
#include "station_test_support.hpp"

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/sim/scan_scenario.hpp"
#include "stampscan/jobs/calibrate_job.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <regex>

namespace stampscan::station::test {
namespace {

// The world `station calibrate` hosts for --seed 1 (calibrate_command.cpp): a full session's
// calibration scenes, the cameras at full resolution.
sim::CellTruth calibrationTruth() {
  sim::ScanParams world;
  world.seed = 1;
  return sim::drawCellTruth(world);
}

std::vector<fs::path> runFolders(const fs::path& runs) {
  std::vector<fs::path> dirs;
  if (!fs::exists(runs)) return dirs;
  for (const auto& e : fs::directory_iterator(runs))
    if (e.is_directory() && e.path().filename() != "calibration" && e.path().filename() != "programs") dirs.push_back(e.path());
  return dirs;
}

registration::CalibrationRecord onlyRecord(const fs::path& history, const std::string& kind) {
  std::vector<registration::CalibrationRecord> found;
  for (const auto& r : registration::listCalibrationRecords(history).records)
    if (r.kind == kind) found.push_back(r);
  EXPECT_EQ(found.size(), 1u) << kind;
  return found.empty() ? registration::CalibrationRecord{} : found.back();
}

nlohmann::json readJson(const fs::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

void writeJson(const fs::path& file, const nlohmann::json& j) { writeFile(file, j.dump(2)); }

// Calibrating both sensors recovers the simulated cell (the tolerances are the accuracy the scans
// need: the laser's position goal is 0.05 mm, and its latency is held to 0.3 ms as `station scan`
// holds it), gives every parameter an uncertainty, and puts both in use with their provenance.
TEST_F(StationTest, CalibrateRecoversTheVirtualCellsSensorsAndPutsThemInUse) {
  const fs::path cal = work() / "calibration";
  const RunResult r = run("calibrate -q -o " + quote(cal), 600);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("calibration in use updated"), std::string::npos) << r.out;
  const sim::CellTruth truth = calibrationTruth();

  const registration::DigitizerCalibrationFile digitizer = registration::loadDigitizerCalibration(cal / "digitizer.json");
  EXPECT_LT((digitizer.calibration.head_from_digitizer.translation() - truth.head_from_digitizer.translation()).norm(), 0.01);
  EXPECT_NEAR(static_cast<double>(digitizer.calibration.latency_ns), static_cast<double>(truth.digitizer_latency_ns), 0.3e6);
  EXPECT_EQ(digitizer.provenance.cell, "virtual cell");
  EXPECT_EQ(digitizer.provenance.verdict, "passed");
  ASSERT_EQ(digitizer.provenance.sensors.size(), 1u);
  EXPECT_FALSE(digitizer.provenance.sensors[0].serial.empty());

  const registration::CameraCalibrationFile cameras = registration::loadCameraCalibration(cal / "cameras.json");
  EXPECT_NEAR(cameras.stereo.left.model.matrix(0, 0), truth.left.fx, 0.001 * truth.left.fx);
  EXPECT_NEAR(cameras.stereo.right.model.matrix(1, 1), truth.right.fy, 0.001 * truth.right.fy);
  EXPECT_NEAR(cameras.stereo.left.model.matrix(0, 2), truth.left.cx, 2.0);
  const double true_baseline = (truth.head_from_right.translation() - truth.head_from_left.translation()).norm();
  EXPECT_NEAR(cameras.stereo.baseline_mm, true_baseline, 0.02);
  // The mount on the head: each stereo view is registered to the laser's elements afterwards (ICP),
  // so a scan needs it to a fraction of a millimetre, not to the position goal.
  EXPECT_LT((cameras.head_from_left.head_from_camera.translation() - truth.head_from_left.translation()).norm(), 0.25);
  EXPECT_EQ(cameras.provenance.sensors.size(), 2u);

  const registration::CalibrationRecord d = onlyRecord(cal / "history", "digitizer");
  const registration::CalibrationRecord c = onlyRecord(cal / "history", "cameras");
  EXPECT_EQ(d.verdict, registration::RecordVerdict::Passed);
  EXPECT_EQ(c.verdict, registration::RecordVerdict::Passed);
  EXPECT_EQ(digitizer.provenance.record_id, d.id);
  EXPECT_TRUE(fs::exists(cal / "history" / (d.id + ".calibration.json")));
  EXPECT_TRUE(fs::exists(cal / "history" / d.traces.at(0)));
  for (const char* name : {"digitizer mount x", "digitizer mount z", "digitizer latency"}) {
    ASSERT_NE(d.parameter(name), nullptr) << name;
    EXPECT_GT(d.parameter(name)->uncertainty, 0) << name;
  }
  // The jackknife's uncertainty covers the truth: within 4 of its standard uncertainties, or the
  // tolerance above when the uncertainty is smaller than the simulation's own rounding.
  EXPECT_LT(std::abs(d.parameter("digitizer mount x")->value - truth.head_from_digitizer.translation().x()),
            std::max(4 * d.parameter("digitizer mount x")->uncertainty, 0.005));
  for (const char* name : {"left fx", "stereo baseline", "left camera mount x"}) {
    ASSERT_NE(c.parameter(name), nullptr) << name;
    EXPECT_GT(c.parameter(name)->uncertainty, 0) << name;
  }
  const RunResult list = run("calibration list -d " + quote(cal));
  EXPECT_EQ(list.exit_code, 0) << list.out << list.err;
  EXPECT_NE(list.out.find(d.id), std::string::npos) << list.out;
  EXPECT_NE(list.out.find(c.id), std::string::npos) << list.out;

  // Verified with both calibrations in use: the digitizer on the ball bar, the stereo pair on the
  // plate's dots (their flat form and the lengths between them, up to the 60 mm diagonal).
  const RunResult verified = run("verify -q -o " + quote(cal), 600);
  ASSERT_EQ(verified.exit_code, 0) << verified.out << verified.err;
  EXPECT_NE(verified.out.find("PASS  flat form error F[Form.Pla] (stereo pair, plate)"), std::string::npos) << verified.out;
  EXPECT_NE(verified.out.find("PASS  length measurement error E (stereo pair, plate dots)"), std::string::npos)
      << verified.out;
  EXPECT_NE(verified.out.find("lengths up to 60.0 mm"), std::string::npos) << verified.out;
  const registration::CalibrationRecord v = onlyRecord(cal / "history", "verification");
  EXPECT_EQ(v.verdict, registration::RecordVerdict::Passed);
  EXPECT_TRUE(std::any_of(v.sensors.begin(), v.sensors.end(), [](const auto& s) { return s.family == "camera"; }));
}

// A second cell, described by its own file (an indexing head, other cameras, digitizer mount and
// latency, the artefacts elsewhere, its own counts of calibration scenes): its devices answer at the
// file's addresses, calibration recovers its sensors' true geometry and verification passes, with
// no code that knows this cell.
TEST_F(StationTest, ASecondCellIsCheckedCalibratedAndVerifiedFromItsFile) {
  const fs::path file = fs::path(STAMPSCAN_VIRTUAL_CELL_FILE).parent_path() / "virtual-indexing.toml";
  const std::string cell = quote(file);
  const fs::path cal = work() / "calibration";
  RunResult r = run("devices --cell " + cell + " --virtual", 120);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("all required devices answered"), std::string::npos) << r.out;
  // This cell's PLC unit and camera serials (hosted here, its servers take free ports).
  EXPECT_NE(r.out.find("Modbus TCP unit 3"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("CELL-B-LEFT"), std::string::npos) << r.out;

  r = run("calibrate -q --cell " + cell + " --virtual -o " + quote(cal), 900);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("calibration in use updated"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("10 sphere sweeps, 14 plate views"), std::string::npos) << r.out;  // the file's counts
  sim::ScanParams world;
  world.setCell(acquisition::loadCellConfig(file.string()));
  world.seed = 1;
  const sim::CellTruth truth = sim::drawCellTruth(world);
  const registration::DigitizerCalibrationFile digitizer = registration::loadDigitizerCalibration(cal / "digitizer.json");
  EXPECT_LT((digitizer.calibration.head_from_digitizer.translation() - truth.head_from_digitizer.translation()).norm(), 0.01);
  EXPECT_NEAR(static_cast<double>(digitizer.calibration.latency_ns), static_cast<double>(truth.digitizer_latency_ns), 0.3e6);
  EXPECT_EQ(digitizer.provenance.cell, "virtual cell B, indexing head");
  const registration::CameraCalibrationFile cameras = registration::loadCameraCalibration(cal / "cameras.json");
  EXPECT_EQ(cameras.stereo.left.model.size.width, 1600);
  EXPECT_NEAR(cameras.stereo.left.model.matrix(0, 0), truth.left.fx, 0.001 * truth.left.fx);
  const double true_baseline = (truth.head_from_right.translation() - truth.head_from_left.translation()).norm();
  EXPECT_NEAR(cameras.stereo.baseline_mm, true_baseline, 0.02);
  EXPECT_LT((cameras.head_from_left.head_from_camera.translation() - truth.head_from_left.translation()).norm(), 0.25);

  r = run("verify -q --cell " + cell + " --virtual -o " + quote(cal), 600);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("verdict     PASSED"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ball bar"), std::string::npos) << r.out;
}

// Views that spoil a fit are named and left out, and the rest still calibrate the sensors: a sphere
// sweep that passes beside the sphere (only its rim in the edge of the fan) and a plate view aimed
// away from the plate, in a calibration plan file.
TEST_F(StationTest, CalibrateLeavesOutTheViewsThatSpoilAFit) {
  sim::ScanParams world;
  world.seed = 1;
  acquisition::ScanPlan plan = jobs::calibrationScenesOf(sim::planScan(world), true, true);
  bool moved_sweep = false, moved_view = false;
  for (acquisition::PlanStep& step : plan.steps) {
    if (auto* sweep = std::get_if<acquisition::SweepStep>(&step); sweep && sweep->index == 0 && !moved_sweep) {
      // The first sweep looks straight down with the ball 12 mm to one side of the fan's middle;
      // 20 mm further, only a sliver of the ball is within the fan's 21 mm half width.
      sweep->start.position[0] += 20;
      sweep->end.position[0] += 20;
      moved_sweep = true;
    }
    if (auto* view = std::get_if<acquisition::StereoStep>(&step); view && view->index == 3 && !moved_view) {
      view->pose.position[0] += 150;  // the plate out of the cameras' view
      moved_view = true;
    }
  }
  ASSERT_TRUE(moved_sweep && moved_view);
  const fs::path plan_file = work() / "calibration-plan.toml";
  writeFile(plan_file, acquisition::toToml(plan));
  const fs::path cal = work() / "calibration";
  const RunResult r = run("calibrate -q --plan " + quote(plan_file) + " -o " + quote(cal), 600);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("left out  reference_sphere sweep 0:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the sphere mostly outside the fan"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("left out  left camera, plate view 3: plate not found"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("left out  right camera, plate view 3: plate not found"), std::string::npos) << r.out;
  const registration::CalibrationRecord d = onlyRecord(cal / "history", "digitizer");
  const auto used = std::find_if(d.residuals.begin(), d.residuals.end(),
                                 [](const registration::RecordValue& v) { return v.name == "sphere sweeps used"; });
  ASSERT_NE(used, d.residuals.end());
  EXPECT_EQ(used->value, 7.0);
  EXPECT_TRUE(std::any_of(d.notes.begin(), d.notes.end(),
                          [](const std::string& n) { return n.rfind("left out: reference_sphere sweep 0", 0) == 0; }));
  const sim::CellTruth truth = calibrationTruth();
  const auto digitizer = registration::loadDigitizerCalibration(cal / "digitizer.json");
  EXPECT_LT((digitizer.calibration.head_from_digitizer.translation() - truth.head_from_digitizer.translation()).norm(), 0.01);
  const auto cameras = registration::loadCameraCalibration(cal / "cameras.json");
  EXPECT_NEAR(cameras.stereo.left.model.matrix(0, 0), truth.left.fx, 0.001 * truth.left.fx);
}

// A calibration outside its limits is recorded and not used, unless an engineer accepts it: a cell
// whose file asks more of the cameras' mount than the quarter resolution of the default scan gives
// (the mount spreads over a few hundredths of a millimetre between the plate views).
TEST_F(StationTest, AFailedCalibrationIsKeptOutOfUseUnlessAccepted) {
  const fs::path cal = work() / "calibration";
  std::ifstream in(STAMPSCAN_VIRTUAL_CELL_FILE);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string limit = "head_mount_residual_mm = 0.05";
  ASSERT_NE(text.find(limit), std::string::npos);
  text.replace(text.find(limit), limit.size(), "head_mount_residual_mm = 0.002");
  const fs::path strict = work() / "strict.toml";
  writeFile(strict, text);
  const std::string cell = " --cell " + quote(strict) + " --virtual";
  const RunResult failed = run("calibrate cameras -q --quarter-resolution" + cell + " -o " + quote(cal), 600);
  ASSERT_EQ(failed.exit_code, 2) << failed.out << failed.err;
  EXPECT_NE(failed.out.find("FAIL  head mount residual (cameras)"), std::string::npos) << failed.out;
  EXPECT_NE(failed.out.find("NOT put in use"), std::string::npos) << failed.out;
  EXPECT_FALSE(fs::exists(cal / "cameras.json"));
  EXPECT_EQ(onlyRecord(cal / "history", "cameras").verdict, registration::RecordVerdict::Failed);

  const RunResult accepted =
      run("calibrate cameras -q --quarter-resolution --accept --engineer 'J. Smith'" + cell + " -o " + quote(cal), 600);
  ASSERT_EQ(accepted.exit_code, 0) << accepted.out << accepted.err;
  EXPECT_NE(accepted.out.find("verdict   accepted by J. Smith; now in use"), std::string::npos) << accepted.out;
  const registration::CameraCalibrationFile in_use = registration::loadCameraCalibration(cal / "cameras.json");
  EXPECT_EQ(in_use.provenance.verdict, "accepted");
  EXPECT_EQ(in_use.provenance.accepted_by, "J. Smith");
  EXPECT_FALSE(fs::exists(cal / "digitizer.json"));  // only the sensor asked for
}

// The digitizer's calibration in use, from end to end: a scan without calibration scenes measures
// with it; one that is missing, another cell's, another sensor's, failed or expired is refused before
// anything moves (no run folder); a knocked mount fails verify, and calibrate reports the drift and
// puts the new calibration in use, after which verify passes.
TEST_F(StationTest, TheCalibrationInUseIsCheckedByScanAndVerifyAndRenewedByCalibrate) {
  const fs::path runs = work() / "runs";
  const fs::path cal = runs / "calibration";
  const std::string scan = "scan -q --calibrated --laser-only -o " + quote(runs);

  const RunResult missing = run(scan, 300);
  expectCleanFailure(missing, "run `station calibrate digitizer`");
  EXPECT_NE(missing.err.find("digitizer.json does not exist"), std::string::npos) << missing.err;
  EXPECT_TRUE(runFolders(runs).empty());

  const RunResult calibrated = run("calibrate digitizer -q -o " + quote(cal), 600);
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.out << calibrated.err;
  // The status names the digitizer's record and its validity, and that the cameras have none.
  const RunResult state = run("calibration status -d " + quote(cal));
  EXPECT_EQ(state.exit_code, 2) << state.out << state.err;
  EXPECT_NE(state.out.find("record " + onlyRecord(cal / "history", "digitizer").id + " (passed)"), std::string::npos)
      << state.out;
  EXPECT_NE(state.out.find("valid 7.0 days more"), std::string::npos) << state.out;
  EXPECT_NE(state.out.find("cameras     none in use; run `station calibrate cameras`"), std::string::npos) << state.out;
  // The record is also a row of the runs folder's results database, beside the scans.
  const RunResult rows = run("calibration list --db " + quote(runs));
  ASSERT_EQ(rows.exit_code, 0) << rows.out << rows.err;
  EXPECT_NE(rows.out.find(onlyRecord(cal / "history", "digitizer").id), std::string::npos) << rows.out;
  EXPECT_NE(rows.out.find("1 of 1 checks passed"), std::string::npos) << rows.out;
  const RunResult measured = run(scan, 300);
  ASSERT_EQ(measured.exit_code, 0) << measured.out << measured.err;
  EXPECT_NE(measured.out.find("calibration in use: made on this cell with these sensors"), std::string::npos) << measured.out;
  ASSERT_EQ(runFolders(runs).size(), 1u);
  const nlohmann::json run_json = readJson(runFolders(runs)[0] / "run.json");
  EXPECT_NE(run_json.at("calibration").at("digitizer").get<std::string>().find("digitizer.json (record "), std::string::npos);
  EXPECT_LT(run_json.at("accuracy").at("position_rms_mm").get<double>(), 0.05);
  EXPECT_LT(run_json.at("accuracy").at("strain_rms").get<double>(), 0.005);
  // As `station scan`'s own test: about 350 elements on a quiet machine, fewer when a loaded one
  // delays the CMM's reports and the track filter leaves the sweeps' ends out; all of them true.
  EXPECT_GT(run_json.at("measurement").at("elements").get<int>(), 250);
  EXPECT_EQ(run_json.at("accuracy").at("matched"), run_json.at("measurement").at("elements"));

  // Each damaged variant of the file in use is refused with its reason, and nothing moves.
  const fs::path file = cal / "digitizer.json";
  const nlohmann::json good = readJson(file);
  const auto refused = [&](const std::function<void(nlohmann::json&)>& damage, const std::string& needle) {
    nlohmann::json j = good;
    damage(j);
    writeJson(file, j);
    const RunResult r = run(scan, 300);
    expectCleanFailure(r, needle);
    EXPECT_NE(r.err.find("station calibrate digitizer"), std::string::npos) << r.err;
    EXPECT_EQ(runFolders(runs).size(), 1u) << needle;
  };
  refused([](nlohmann::json& j) { j["cell"] = "line 4"; }, "made on the cell 'line 4'");
  refused([](nlohmann::json& j) { j["sensors"][0]["serial"] = "VD-9999"; }, "serial 'VD-9999'");
  refused([](nlohmann::json& j) { j["verdict"] = "failed"; }, "not an accepted calibration");
  refused([](nlohmann::json& j) { j["created"] = "2026-01-01T00:00:00Z"; }, "days old, beyond its validity of 7 days");
  refused([](nlohmann::json& j) { j.erase("cell"); }, "does not say which cell");
  writeFile(file, "{ not json");
  expectCleanFailure(run(scan, 300), "digitizer.json");
  writeJson(file, good);

  // The digitizer knocked 0.3 mm on its mount: verify with the calibration in use fails...
  const std::string knock = " --shift-digitizer-mount 0.3,0,0";
  const RunResult moved = run("verify -q -o " + quote(cal) + knock, 600);
  EXPECT_EQ(moved.exit_code, 2) << moved.out << moved.err;
  EXPECT_NE(moved.out.find("FAIL  probing form error"), std::string::npos) << moved.out;
  // ...calibrate finds it moved, says so, and puts the new calibration in use...
  const RunResult recalibrated = run("calibrate digitizer -q -o " + quote(cal) + knock, 600);
  ASSERT_EQ(recalibrated.exit_code, 0) << recalibrated.out << recalibrated.err;
  std::smatch drift;
  ASSERT_TRUE(std::regex_search(recalibrated.out, drift, std::regex("DRIFT the digitizer's mount moved ([0-9.]+) mm")))
      << recalibrated.out;
  EXPECT_NEAR(std::stod(drift[1].str()), 0.3, 0.01) << recalibrated.out;
  EXPECT_NE(recalibrated.out.find("kept in the history"), std::string::npos) << recalibrated.out;
  const sim::CellTruth truth = calibrationTruth();
  const Eigen::Vector3d knocked = truth.head_from_digitizer.translation() + Eigen::Vector3d(0.3, 0, 0);
  EXPECT_LT((registration::loadDigitizerCalibration(file).calibration.head_from_digitizer.translation() - knocked).norm(), 0.01);
  // ...and verify passes again.
  const RunResult after = run("verify -q -o " + quote(cal) + knock, 600);
  EXPECT_EQ(after.exit_code, 0) << after.out << after.err;
  EXPECT_NE(after.out.find("verdict     PASSED"), std::string::npos) << after.out;
  // Both digitizer calibrations are in the history, each with the calibration it made.
  std::size_t digitizer_records = 0;
  for (const auto& r : registration::listCalibrationRecords(cal / "history").records)
    if (r.kind == "digitizer") {
      ++digitizer_records;
      EXPECT_TRUE(fs::exists(cal / "history" / (r.id + ".calibration.json"))) << r.id;
    }
  EXPECT_EQ(digitizer_records, 2u);
  const RunResult verifications = run("calibration list --db " + quote(runs) + " --kind verification");
  EXPECT_NE(verifications.out.find("failed"), std::string::npos) << verifications.out;
  EXPECT_NE(verifications.out.find("passed"), std::string::npos) << verifications.out;
}

}  // namespace
}  // namespace stampscan::station::test
