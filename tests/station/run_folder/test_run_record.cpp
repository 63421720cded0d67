#include "stampscan/run_folder/run_record.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;
using stampscan::run_folder::RunRecord;
using stampscan::run_folder::RunRecordError;
using stampscan::run_folder::readRunRecord;
using stampscan::run_folder::runRecordFromJson;
using stampscan::run_folder::toJson;
using stampscan::run_folder::writeRunRecord;

namespace {

// A record with every section filled, as a finished scan on a virtual cell writes it.
RunRecord fullRecord() {
  RunRecord r;
  r.part_id = "P-4711";
  r.plan = "whole dome";
  r.cell = "virtual cell";
  r.completed = true;
  r.started_by = "alice (on the panel)";
  r.safety_events = {"door opened", "door closed"};
  r.devices = {{"cmm", "CartCMM", "CMM-1", "1.4.3"}, {"digitizer", "SSD-1024", "D-7", "2.1"}};
  r.fixture = {"plate fixture", {100, 200, 30}, {0, 0, 90}};
  r.calibration = stampscan::run_folder::CalibrationUsed{"calibrated on this scan's reference-sphere sweeps", "none"};
  auto& s = r.scan.emplace();
  s.sweeps = 15;
  s.wall_seconds = 133.0;
  s.motion_seconds = 130.8;
  s.profiles = 31492;
  s.positions = 1208;
  s.stereo_views = 23;
  s.spent_seconds.moving = 112.4;
  s.spent_seconds.waiting_for_frames = 10.4;
  auto& m = r.measurement.emplace();
  m.elements = 3242;
  m.measurements = 10199;
  m.seconds_after_scan = 26.5;
  m.digitizer_latency_ms = 6.102;
  m.laser_uncertainty = stampscan::run_folder::PathUncertainty{0.00133, 0.00126, 0.0004, std::nullopt, 1458};
  m.sphere_residual_mm = 0.006;
  m.surface = stampscan::run_folder::SurfaceFigures{12492750, 116638, 0, 236270, 1.37, 2.49, 83.5};
  auto& a = r.accuracy.emplace();
  a.matched = 3242;
  a.position_rms_mm = 0.0042;
  a.strain_rms = 0.0008;
  a.strain_within_expanded_uncertainty = 0.99;
  a.visible = stampscan::run_folder::VisibleFigures{3249, 3242, 0};
  a.surface_strain = stampscan::run_folder::SurfaceStrainFigures{3242, 0.0006, 0.0008, 49627, 0.0009, 112217, 0};
  a.laser_led = stampscan::run_folder::SensorAccuracyFigures{3124, 0.0040, 0.0006};
  a.stereo_led = stampscan::run_folder::SensorAccuracyFigures{118, 0.0083, 0.0005};
  r.replay = stampscan::run_folder::ReplayFigures{"recorded/trace.mcap", 10199, 10199, 0.0, 0.0};
  r.data_loss = "1 stereo views missing (no frames from a camera)";
  r.material = "DC04";
  r.program = "press 12";
  r.part_program = stampscan::run_folder::PartProgramUsed{"sim-dome-circle", "programs/sim-dome-circle"};
  return r;
}

class RunRecordFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stampscan-run-record-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void writeFile(const std::string& text) { std::ofstream(dir_ / "run.json") << text; }
  fs::path dir_;
};

}  // namespace

TEST_F(RunRecordFile, WhatIsWrittenIsReadBackWhole) {
  const RunRecord written = fullRecord();
  writeRunRecord(dir_, written);
  const auto read = readRunRecord(dir_);
  ASSERT_TRUE(read);
  EXPECT_EQ(*read, written);
  EXPECT_FALSE(fs::exists(dir_ / "run.json.tmp"));
}

TEST_F(RunRecordFile, TheFileKeepsItsMembersNames) {
  // The panel's pages and the plant's scripts read run.json by these names.
  const nlohmann::json j = toJson(fullRecord());
  EXPECT_EQ(j.at("part_id"), "P-4711");
  EXPECT_EQ(j.at("scan").at("spent_seconds").at("waiting_for_frames"), 10.4);
  EXPECT_EQ(j.at("measurement").at("uncertainty").at("laser").at("twin_pairs"), 1458);
  EXPECT_TRUE(j.at("measurement").at("uncertainty").at("laser").at("position_shared_mm").is_null());
  EXPECT_TRUE(j.at("measurement").at("uncertainty").at("stereo").is_null());
  EXPECT_EQ(j.at("accuracy").at("visible").at("found"), 3242);
  EXPECT_EQ(j.at("accuracy").at("surface_strain").at("within_grid_points"), 112217);
  EXPECT_EQ(j.at("fixture").at("datum_rotation_deg")[2], 90.0);
  EXPECT_EQ(j.at("part_program").at("name"), "sim-dome-circle");
  EXPECT_EQ(j.at("started_by"), "alice (on the panel)");
  EXPECT_FALSE(j.contains("abort_reason"));  // only an aborted scan has one
}

TEST_F(RunRecordFile, AnAbortedRunWithoutMeasurementReadsWithItsReason) {
  RunRecord aborted;
  aborted.part_id = "P-1";
  aborted.completed = false;
  aborted.abort_reason = "the door was opened";
  const nlohmann::json j = toJson(aborted);
  EXPECT_EQ(j.at("abort_reason"), "the door was opened");
  EXPECT_TRUE(j.at("data_loss").is_null());
  const RunRecord read = runRecordFromJson(j, "run.json");
  EXPECT_EQ(read, aborted);
  EXPECT_FALSE(read.measurement);
}

TEST_F(RunRecordFile, AnOlderRunsMissingMembersAreLeftAtTheirDefaults) {
  writeFile(R"({"part_id": "P-2", "plan": "sample region", "measurement": {"elements": 42}, "extra": [1, 2]})");
  const auto read = readRunRecord(dir_);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->part_id, "P-2");
  EXPECT_TRUE(read->completed);
  ASSERT_TRUE(read->measurement);
  EXPECT_EQ(read->measurement->elements, 42);
  EXPECT_FALSE(read->measurement->surface);
  EXPECT_FALSE(read->accuracy);
  EXPECT_TRUE(read->data_loss.empty());
}

TEST_F(RunRecordFile, AFolderWithoutRunJsonHasNoRecord) { EXPECT_FALSE(readRunRecord(dir_)); }

TEST_F(RunRecordFile, ADamagedFileIsRefusedNamingTheFileAndTheMember) {
  const auto refusal = [&](const std::string& text) {
    writeFile(text);
    try {
      readRunRecord(dir_);
    } catch (const RunRecordError& e) {
      return std::string(e.what());
    }
    return std::string("not refused");
  };
  const std::string file = (dir_ / "run.json").string();
  EXPECT_EQ(refusal(R"({"measurement": {"elements": "many"}})"),
            file + ": measurement.elements: expected a whole number, found a text");
  EXPECT_EQ(refusal(R"({"completed": "yes"})"), file + ": completed: expected true or false, found a text");
  EXPECT_EQ(refusal(R"({"fixture": {"datum_mm": [1, 2]}})"), file + ": fixture.datum_mm: expected three numbers, found a list");
  EXPECT_EQ(refusal(R"({"devices": [{"family": "cmm"}, 3]})"), file + ": devices[1]: expected an object, found a whole number");
  EXPECT_EQ(refusal(R"({"accuracy": {"visible": {"found": 1.5}}})"),
            file + ": accuracy.visible.found: expected a whole number, found a fractional number");
  EXPECT_EQ(refusal("[1, 2]"), file + ": damaged (not a JSON object)");
  EXPECT_NE(refusal(R"({"part_id": "P-)").find(file + ": damaged (not valid JSON"), std::string::npos);
}
