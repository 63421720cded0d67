// The probing errors of ISO 10360-8 on synthetic spheres of known radius and form deviation (seeded,
// so that a failure can be replayed), and the calibration records: round trip, errors naming the
// file and field, the history listing and the comparison of two records.
#include "stampscan/registration/calibration_record.hpp"
#include "stampscan/registration/sphere_verification.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

namespace {

using namespace stampscan;
using registration::Vec3;
namespace fs = std::filesystem;

// Points spread over the upper part of a sphere (above `lowest_polar` from the top, as a scanner
// sees a ball on a stem), each moved radially by a deviation drawn uniformly in [-form/2, form/2].
std::vector<Vec3> sphereCloud(const Vec3& centre, double radius, double form, std::size_t n, std::uint64_t seed,
                              double lowest_polar = 0.6 * std::numbers::pi) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1), dev(-0.5 * form, 0.5 * form);
  std::vector<Vec3> out;
  const double cos_min = std::cos(lowest_polar);
  while (out.size() < n) {
    const double z = cos_min + (1 - cos_min) * u(rng);  // uniform on the cap's area
    const double phi = 2 * std::numbers::pi * u(rng);
    const double s = std::sqrt(1 - z * z);
    out.push_back(centre + (radius + dev(rng)) * Vec3(s * std::cos(phi), s * std::sin(phi), z));
  }
  // The two extremes of the form deviation, so that the range is known exactly.
  out.push_back(centre + (radius + 0.5 * form) * Vec3(0, 0, 1));
  out.push_back(centre + (radius - 0.5 * form) * Vec3(1, 0, 0));
  return out;
}

TEST(SphereFit, RecoversAnExactSphereFarFromTheOrigin) {
  const Vec3 centre(250, -120, 40);
  const auto points = sphereCloud(centre, 12.7, 0, 2000, 1);
  const registration::SphereFit fit = registration::fitSphere(points);
  EXPECT_NEAR((fit.centre - centre).norm(), 0, 1e-9);
  EXPECT_NEAR(fit.radius, 12.7, 1e-9);
  EXPECT_NEAR(fit.rms_mm, 0, 1e-9);
  EXPECT_EQ(fit.points, points.size());
}

TEST(SphereFit, RefusesTooFewPointsAndAPlane) {
  EXPECT_THROW(registration::fitSphere(std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), std::invalid_argument);
  std::vector<Vec3> plane;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) plane.emplace_back(i, j, 5);
  EXPECT_THROW(registration::fitSphere(plane), std::invalid_argument);
}

TEST(SphereVerification, FormIsTheRangeAndSizeTheDiameterError) {
  const Vec3 centre(250, 0, 40);
  for (const double form : {0.005, 0.02, 0.08}) {
    const auto points = sphereCloud(centre, 12.7, form, 50000, 7);
    registration::SphereVerificationParams p;
    p.certified_diameter_mm = 25.4;
    const registration::SphereVerification v = registration::verifySphere(points, p);
    SCOPED_TRACE("form " + std::to_string(form));
    EXPECT_EQ(v.points_on_sphere, points.size());
    // Symmetric deviations over a dense cloud: the least-squares sphere is the true one to within
    // a small share of the form, so the range is the form and the size error near zero.
    EXPECT_NEAR(v.form_error_mm, form, 0.05 * form + 1e-9);
    EXPECT_NEAR(v.size_error_mm, 0, 0.02 * form + 1e-9);
    EXPECT_EQ(v.form_passed, form <= p.form_mpe_mm);
    EXPECT_TRUE(v.size_passed);
  }
}

TEST(SphereVerification, AWrongSizeFailsTheSizeCheckOnly) {
  const auto points = sphereCloud(Vec3(0, 0, 0), 12.75, 0.004, 20000, 3);  // 0.1 mm too large in diameter
  registration::SphereVerificationParams p;
  p.certified_diameter_mm = 25.4;
  const registration::SphereVerification v = registration::verifySphere(points, p);
  EXPECT_NEAR(v.size_error_mm, 0.1, 0.001);
  EXPECT_FALSE(v.size_passed);
  EXPECT_TRUE(v.form_passed);
  EXPECT_FALSE(v.passed());
}

TEST(SphereVerification, PointsOffTheSphereAreLeftOutNotFitted) {
  const Vec3 centre(250, 0, 40);
  auto points = sphereCloud(centre, 12.7, 0.01, 20000, 5);
  const std::size_t on_sphere = points.size();
  // The table the ball stands on, 30 mm below its centre, more points than on the ball.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-40, 40);
  for (int i = 0; i < 40000; ++i) points.emplace_back(centre.x() + u(rng), centre.y() + u(rng), centre.z() - 30);
  registration::SphereVerificationParams p;
  p.certified_diameter_mm = 25.4;
  const registration::SphereVerification v = registration::verifySphere(points, p);
  EXPECT_EQ(v.points_measured, points.size());
  EXPECT_EQ(v.points_on_sphere, on_sphere);
  EXPECT_NEAR((v.fit.centre - centre).norm(), 0, 0.001);
  EXPECT_NEAR(v.form_error_mm, 0.01, 0.001);
}

TEST(SphereVerification, TooFewPointsOnTheSphereIsAnError) {
  registration::SphereVerificationParams p;
  p.certified_diameter_mm = 25.4;
  EXPECT_THROW(registration::verifySphere(sphereCloud(Vec3::Zero(), 12.7, 0, 20, 1), p), std::runtime_error);
  // Plenty of points, but on a sphere of another size: none in the evaluation shell.
  EXPECT_THROW(registration::verifySphere(sphereCloud(Vec3::Zero(), 20, 0, 5000, 1), p), std::runtime_error);
}

class CalibrationRecordTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    dir_ = fs::temp_directory_path() / ("stampscan_records_" + std::to_string(device()) + std::to_string(device()));
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  static registration::CalibrationRecord sample(const std::string& id, double latency_ms) {
    registration::CalibrationRecord r;
    r.id = id;
    r.kind = "verification";
    r.created = "2026-11-24T09:15:00Z";
    r.cell = "virtual cell";
    r.sensors = {{"digitizer", "SSD-1024 (virtual)", "VD-0001", "1.0.0"}};
    r.traces = {id + ".mcap"};
    r.calibration = "digitizer.json";
    r.parameters = {{"digitizer latency", latency_ms, "ms"}, {"fitted sphere diameter", 25.401, "mm"}};
    r.residuals = {{"points on the sphere", 1234, ""}};
    r.checks = {{"probing form error P[Form.Sph.All] (digitizer)", 0.05, 0.1, "mm", true}};
    r.verdict = registration::RecordVerdict::Passed;
    r.notes = {"length check not done"};
    return r;
  }
  fs::path dir_;
};

TEST_F(CalibrationRecordTest, SavedRecordsReadBackEqualAndListInOrder) {
  const auto a = sample("20261124-091500-verification", 4.0);
  const auto b = sample("20261125-091500-verification", 4.5);
  registration::saveCalibrationRecord(dir_, b);
  const fs::path file = registration::saveCalibrationRecord(dir_, a);
  EXPECT_EQ(registration::loadCalibrationRecord(file), a);
  EXPECT_EQ(registration::findCalibrationRecord(dir_, b.id), b);
  const auto listing = registration::listCalibrationRecords(dir_);
  ASSERT_EQ(listing.records.size(), 2u);
  EXPECT_EQ(listing.records[0].id, a.id);
  EXPECT_TRUE(listing.problems.empty());
  EXPECT_NE(registration::newRecordId(dir_, "verification"), a.id);
}

TEST_F(CalibrationRecordTest, BadRecordsAreNamedWithTheirField) {
  const auto a = sample("20261124-091500-verification", 4.0);
  const fs::path file = registration::saveCalibrationRecord(dir_, a);
  const auto expectError = [&](const std::string& text, const std::string& needle) {
    std::ofstream(file) << text;
    try {
      registration::loadCalibrationRecord(file);
      ADD_FAILURE() << "no error for " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expectError("{not json", "does not parse");
  expectError(R"({"format": "stampscan-calibration", "version": 1})", "format");
  expectError(R"({"format": "stampscan-calibration-record", "version": 9})", "version");
  expectError(R"({"format": "stampscan-calibration-record", "version": 1, "id": "x"})", "kind");
  // A corrupt file in the history is reported by the listing, not skipped silently.
  const auto listing = registration::listCalibrationRecords(dir_);
  EXPECT_TRUE(listing.records.empty());
  ASSERT_EQ(listing.problems.size(), 1u);
  EXPECT_THROW(registration::findCalibrationRecord(dir_, "no-such-record"), std::runtime_error);
}

TEST_F(CalibrationRecordTest, DiffShowsChangedValuesAndSensors) {
  const auto a = sample("a", 4.0);
  auto b = sample("b", 4.5);
  b.sensors[0].serial = "VD-0002";
  b.verdict = registration::RecordVerdict::Failed;
  b.residuals.clear();
  const auto d = registration::diffCalibrationRecords(a, b);
  const auto find = [&](const std::string& name) {
    for (const auto& x : d)
      if (x.name == name) return x;
    ADD_FAILURE() << "no line for " << name;
    return registration::RecordDifference{};
  };
  EXPECT_EQ(find("verdict").after_text, "failed");
  EXPECT_NE(find("sensor digitizer").after_text.find("VD-0002"), std::string::npos);
  const auto latency = find("digitizer latency");
  EXPECT_DOUBLE_EQ(*latency.after - *latency.before, 0.5);
  EXPECT_FALSE(find("points on the sphere").after.has_value());
}

}  // namespace
