// The calibration in use as files: what a scan checks before it measures with one (the cell, the
// sensors' serials, the verdict, the age), the cameras' file read back, calibrations put in use one
// sensor at a time, records with uncertainties, and the jackknife behind those uncertainties.
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/calibration_store.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

namespace stampscan::registration {
namespace {

namespace fs = std::filesystem;
using std::chrono::hours;

class CalibrationStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    dir_ = fs::temp_directory_path() / ("stampscan_store_" + std::to_string(device()) + std::to_string(device()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }

  static CalibrationProvenance provenance() {
    return {"20261124-080000-digitizer", "line 3", {{"digitizer", "SSD-1024", "VD-0001", "1.0.0"}}, "passed", ""};
  }
  static CalibrationExpectation expectation() {
    CalibrationExpectation e;
    e.cell = "line 3";
    e.sensors = {{"cmm", "CartCMM", "C-1", ""}, {"digitizer", "SSD-1024", "VD-0001", "1.0.1"}};
    e.validity_days = 7;
    e.now = *parseUtc("2026-11-25T08:00:00Z");
    return e;
  }
  static CameraCalibrationFile cameras() {
    CameraCalibrationFile c;
    for (CameraCalibration* cam : {&c.stereo.left, &c.stereo.right}) {
      cam->model.size = cv::Size(2048, 1536);
      cam->model.matrix = cv::Matx33d(4630.5, 0, 1024.25, 0, 4631.0, 767.5, 0, 0, 1);
      cam->model.distortion = (cv::Mat_<double>(1, 5) << -0.08, 0.1, 1e-4, -2e-4, 0);
      cam->rms_px = 0.013;
      cam->views = {{0, true, 0.012, ""}, {1, false, 0, "plate not found"}};
    }
    c.stereo.right_from_left.translation() = Eigen::Vector3d(-120.4, 0.01, 0.02);
    c.stereo.right_from_left.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY()).toRotationMatrix();
    c.stereo.baseline_mm = c.stereo.right_from_left.translation().norm();
    c.stereo.rms_px = 0.014;
    c.head_from_left.head_from_camera.translation() = Eigen::Vector3d(-60.2, -0.1, -60.7);
    c.head_from_left.residual_mm = 0.012;
    c.created = "2026-11-24T08:00:00Z";
    c.source = "test";
    c.provenance = {"20261124-080000-cameras", "line 3", {{"camera", "Fake", "L-1", ""}, {"camera", "Fake", "R-1", ""}},
                    "accepted", "J. Smith"};
    return c;
  }
  fs::path dir_;
};

TEST_F(CalibrationStoreTest, AStoredCalibrationIsUsableOnlyOnItsCellWithItsSensorsWithinItsValidity) {
  const fs::path file = dir_ / "digitizer.json";
  const std::string created = "2026-11-24T08:00:00Z";
  EXPECT_FALSE(calibrationProblem(file, created, provenance(), expectation()));

  const auto refused = [&](CalibrationProvenance p, CalibrationExpectation e, const std::string& created_at,
                           const std::string& needle) {
    const auto problem = calibrationProblem(file, created_at, p, e);
    ASSERT_TRUE(problem) << needle;
    EXPECT_NE(problem->find(file.string()), std::string::npos) << *problem;
    EXPECT_NE(problem->find(needle), std::string::npos) << *problem;
  };
  CalibrationProvenance p = provenance();
  p.cell = "";
  refused(p, expectation(), created, "does not say which cell");
  p = provenance();
  p.cell = "line 4";
  refused(p, expectation(), created, "'line 4', not on 'line 3'");
  p = provenance();
  p.verdict = "failed";
  refused(p, expectation(), created, "not an accepted calibration");
  CalibrationExpectation e = expectation();
  e.sensors[1].serial = "VD-0002";
  refused(provenance(), e, created, "serial 'VD-0001', but the cell's has serial 'VD-0002'");
  e.sensors.pop_back();
  refused(provenance(), e, created, "which does not answer");
  refused(provenance(), expectation(), "2026-11-10T08:00:00Z", "15.0 days old, beyond its validity of 7 days");
  refused(provenance(), expectation(), "2026-11-26T08:00:00Z", "in the future");
  refused(provenance(), expectation(), "yesterday", "is not a UTC time");
  // An accepted calibration is usable; the firmware may change without a new calibration.
  p = provenance();
  p.verdict = "accepted";
  EXPECT_FALSE(calibrationProblem(file, created, p, expectation()));
}

TEST_F(CalibrationStoreTest, SwappedCamerasAreAnotherCalibration) {
  const CameraCalibrationFile c = cameras();
  CalibrationExpectation e = expectation();
  e.sensors = {{"camera", "Fake", "L-1", ""}, {"camera", "Fake", "R-1", ""}};
  EXPECT_FALSE(calibrationProblem(dir_ / "cameras.json", c.created, c.provenance, e));
  std::swap(e.sensors[0], e.sensors[1]);
  const auto problem = calibrationProblem(dir_ / "cameras.json", c.created, c.provenance, e);
  ASSERT_TRUE(problem);
  EXPECT_NE(problem->find("serial 'L-1', but the cell's has serial 'R-1'"), std::string::npos) << *problem;
}

TEST_F(CalibrationStoreTest, UtcTimesAreReadStrictly) {
  const auto t = parseUtc("2026-11-24T08:00:00Z");
  ASSERT_TRUE(t);
  EXPECT_EQ(std::chrono::duration_cast<hours>(*parseUtc("2026-11-25T08:00:00Z") - *t).count(), 24);
  for (const char* bad : {"", "2026-11-24", "2026-11-24T08:00:00", "2026-13-01T00:00:00Z", "2026-11-24T08:00:00Zjunk",
                          "2026-11-24T25:00:00Z"})
    EXPECT_FALSE(parseUtc(bad)) << bad;
}

TEST_F(CalibrationStoreTest, TheCamerasFileReadsBackWithItsProvenance) {
  const CameraCalibrationFile c = cameras();
  saveCameraCalibration(dir_ / "cameras.json", c);
  const CameraCalibrationFile back = loadCameraCalibration(dir_ / "cameras.json");
  EXPECT_EQ(back.stereo.left.model.size, c.stereo.left.model.size);
  EXPECT_EQ(back.stereo.right.model.matrix, c.stereo.right.model.matrix);
  EXPECT_EQ(cv::norm(back.stereo.left.model.distortion, c.stereo.left.model.distortion), 0.0);
  EXPECT_TRUE(back.stereo.right_from_left.isApprox(c.stereo.right_from_left, 1e-12));
  EXPECT_NEAR(back.stereo.baseline_mm, c.stereo.baseline_mm, 1e-12);
  EXPECT_TRUE(back.head_from_left.head_from_camera.isApprox(c.head_from_left.head_from_camera, 1e-12));
  EXPECT_EQ(back.stereo.left.views.size(), 2u);
  EXPECT_EQ(back.stereo.left.views[1].note, "plate not found");
  EXPECT_EQ(back.provenance.record_id, c.provenance.record_id);
  EXPECT_EQ(back.provenance.cell, "line 3");
  EXPECT_EQ(back.provenance.sensors, c.provenance.sensors);
  EXPECT_EQ(back.provenance.verdict, "accepted");
  EXPECT_EQ(back.provenance.accepted_by, "J. Smith");

  // Damaged files are named with what is wrong.
  const auto expectError = [&](const std::string& text, const std::string& needle) {
    std::ofstream(dir_ / "bad.json") << text;
    try {
      (void)loadCameraCalibration(dir_ / "bad.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expectError("{", "parse error");
  expectError(R"({"format": "stampscan-calibration", "version": 1, "kind": "digitizer"})", "not a StampScan cameras calibration");
  expectError(R"({"format": "stampscan-calibration", "version": 9, "kind": "cameras"})", "calibration version 9");
  std::string text = std::string(std::istreambuf_iterator<char>(std::ifstream(dir_ / "cameras.json").rdbuf()), {});
  text.replace(text.find("\"fx\""), 4, "\"fz\"");
  expectError(text, "fx");
}

TEST_F(CalibrationStoreTest, PuttingOneSensorInUseLeavesTheOthersFile) {
  DigitizerCalibrationFile d;
  d.created = "2026-11-24T08:00:00Z";
  d.provenance = provenance();
  const CameraCalibrationFile c = cameras();
  putCalibrationsInUse(dir_, &d, &c);
  d.calibration.latency_ns = 4'000'000;
  d.created = "2026-11-25T08:00:00Z";
  putCalibrationsInUse(dir_, &d, nullptr);
  EXPECT_EQ(loadDigitizerCalibration(dir_ / "digitizer.json").calibration.latency_ns, 4'000'000);
  EXPECT_EQ(loadCameraCalibration(dir_ / "cameras.json").created, c.created);
  // A whole set replaces both, and removes the one it lacks.
  saveCalibrationSet(dir_, &d, nullptr);
  EXPECT_FALSE(fs::exists(dir_ / "cameras.json"));
}

TEST_F(CalibrationStoreTest, RecordsKeepUncertaintiesAndListingSkipsTheCalibrationsBeside) {
  CalibrationRecord r;
  r.id = "20261124-080000-digitizer";
  r.kind = "digitizer";
  r.created = "2026-11-24T08:00:00Z";
  r.cell = "line 3";
  r.parameters = {{"digitizer mount x", -0.394, "mm", 0.0013}, {"sphere centre x", 250, "mm", 0}};
  r.verdict = RecordVerdict::Accepted;
  r.accepted_by = "J. Smith";
  const fs::path file = saveCalibrationRecord(dir_, r);
  EXPECT_EQ(loadCalibrationRecord(file), r);
  DigitizerCalibrationFile d;
  saveDigitizerCalibration(dir_ / (r.id + ".calibration.json"), d);
  const RecordListing listing = listCalibrationRecords(dir_);
  EXPECT_EQ(listing.records.size(), 1u);
  EXPECT_TRUE(listing.problems.empty()) << listing.problems.front();
}

TEST(Jackknife, StandardErrorOfTheMeanIsTheClassicalOne) {
  // For the mean, the leave-one-out values give exactly s / sqrt(n).
  const std::vector<double> x{1.0, 4.0, 2.5, 3.0, 7.0, 0.5};
  const double n = static_cast<double>(x.size());
  double mean = 0;
  for (double v : x) mean += v / n;
  double ss = 0;
  for (double v : x) ss += (v - mean) * (v - mean);
  const double se = std::sqrt(ss / (n - 1) / n);
  std::vector<double> loo;
  for (std::size_t i = 0; i < x.size(); ++i) loo.push_back((mean * n - x[i]) / (n - 1));
  EXPECT_NEAR(jackknifeSd(loo), se, 1e-12);
  EXPECT_EQ(jackknifeSd({3.0}), 0.0);
}

}  // namespace
}  // namespace stampscan::registration
