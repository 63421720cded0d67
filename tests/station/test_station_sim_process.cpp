// End to end: `station sim generate` writes a trace and its ground truth, `station process` measures
// it; the Cloud4D it writes is checked against the truth, and the calibration it saves is reused.
#include "station_test_support.hpp"

#include "stampscan/fitting/kdtree.hpp"

#include <cstdio>

namespace stampscan::station::test {
namespace {

TEST_F(StationTest, SimGenerateWritesATraceAndItsTruth) {
  const fs::path trace = work() / "scan.mcap", truth = work() / "truth.ply";
  const RunResult r = run("sim generate --quick --part pan --grid square --seed 4 -o " + quote(trace) + " --truth " + quote(truth));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("faster than the scan"), std::string::npos) << r.out;
  const Cloud t = fitting::readPly(truth);
  EXPECT_GT(t.size(), 1000u);
  EXPECT_TRUE(t.hasNormals());
  EXPECT_TRUE(t.scalars.count("major_strain") && t.scalars.count("minor_strain"));
  EXPECT_NE(plyHeader(truth).find("property double strain"), std::string::npos);
  // The same seed gives the same trace, byte for byte.
  const fs::path again = work() / "again.mcap";
  ASSERT_EQ(run("sim generate --quick --part pan --grid square --seed 4 -o " + quote(again)).exit_code, 0);
  EXPECT_EQ(readFile(trace), readFile(again));
}

TEST_F(StationTest, SimGenerateRefusesBadOptionsAndLeavesNothing) {
  const fs::path trace = work() / "x.mcap";
  RunResult r = run("sim generate --quick --sensors laser,radar -o " + quote(trace));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("unknown sensor set 'radar'"), std::string::npos) << r.err;
  r = run("sim generate --quick -o " + quote(work() / "missing" / "x.mcap"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  EXPECT_TRUE(workEntries().empty());
}

TEST_F(StationTest, ProcessMeasuresASimulatedTraceAgainstItsTruth) {
  const fs::path trace = work() / "dome.mcap", truth = work() / "truth.ply", out = work() / "cloud4d.ply";
  const fs::path calibration = work() / "calibration", fitted = work() / "fitted.ply";
  ASSERT_EQ(run("sim generate --quick --seed 7 -o " + quote(trace) + " --truth " + quote(truth)).exit_code, 0);
  fs::create_directories(calibration);
  const RunResult r = run("process " + quote(trace) + " -o " + quote(out) + " --fit " + quote(fitted) +
                          " --save-calibration " + quote(calibration) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("calibrated on the reference sphere"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("faster than the scan"), std::string::npos) << r.out;
  const Cloud measured = fitting::readPly(out);
  const Cloud t = fitting::readPly(truth);
  ASSERT_GT(measured.size(), 300u);
  ASSERT_TRUE(measured.hasStrain());
  for (const char* name : {"major_strain", "minor_strain", "source", "view", "quality"})
    EXPECT_TRUE(measured.scalars.count(name)) << name;
  // Every measured element sits on a true one; positions and strains within the goals.
  const fitting::KdTree tree(t.positions);
  std::vector<fitting::Neighbor> nn;
  double sq_pos = 0, sq_strain = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    tree.knn(measured.positions[i], 1, nn);
    ASSERT_LT(nn[0].distance_sq, 0.5 * 0.5) << "element " << i << " matches no true grid element";
    sq_pos += nn[0].distance_sq;
    sq_strain += std::pow(measured.strain[i] - t.strain[nn[0].index], 2);
  }
  const double n = static_cast<double>(measured.size());
  std::printf("station process: %zu elements, position RMS %.4f mm, thickness strain RMS %.4f\n", measured.size(),
              std::sqrt(sq_pos / n), std::sqrt(sq_strain / n));
  EXPECT_LE(std::sqrt(sq_pos / n), 0.05);
  EXPECT_LE(std::sqrt(sq_strain / n), 0.005);
  EXPECT_EQ(fitting::readPly(fitted).size(), measured.size());
  EXPECT_TRUE(fs::exists(calibration / "digitizer.json"));
  EXPECT_TRUE(fs::exists(calibration / "cameras.json"));
  EXPECT_NE(readFile(calibration / "digitizer.json").find("\"latency_ns\""), std::string::npos);

  // A trace without calibration scenes needs the saved calibration, and says so without it.
  const fs::path laser_only = work() / "laser.mcap", out2 = work() / "cloud4d-2.ply";
  ASSERT_EQ(run("sim generate --quick --seed 7 --sensors laser -o " + quote(laser_only)).exit_code, 0);
  RunResult missing = run("process " + quote(laser_only) + " -o " + quote(out2) + " -q");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("--calibration DIR"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(out2));
  const RunResult with = run("process " + quote(laser_only) + " -o " + quote(out2) + " --calibration " + quote(calibration) + " -q");
  ASSERT_EQ(with.exit_code, 0) << with.err;
  EXPECT_GT(fitting::readPly(out2).size(), 300u);
}

TEST_F(StationTest, ProcessMeasuresASquareGridOnThePan) {
  const fs::path trace = work() / "pan.mcap", truth = work() / "truth.ply", out = work() / "cloud4d.ply";
  ASSERT_EQ(run("sim generate --quick --part pan --grid square --seed 8 --sensors laser,calibration -o " + quote(trace) +
                " --truth " + quote(truth)).exit_code, 0);
  const RunResult r = run("process " + quote(trace) + " -o " + quote(out) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("square grid"), std::string::npos) << r.out;
  const Cloud measured = fitting::readPly(out), t = fitting::readPly(truth);
  ASSERT_GT(measured.size(), 300u);
  const fitting::KdTree tree(t.positions);
  std::vector<fitting::Neighbor> nn;
  double sq_pos = 0, sq_strain = 0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    tree.knn(measured.positions[i], 1, nn);
    ASSERT_LT(nn[0].distance_sq, 0.5 * 0.5) << "element " << i;
    sq_pos += nn[0].distance_sq;
    sq_strain += std::pow(measured.strain[i] - t.strain[nn[0].index], 2);
  }
  const double n = static_cast<double>(measured.size());
  std::printf("station process, pan with squares: %zu cells, position RMS %.4f mm, thickness strain RMS %.4f\n",
              measured.size(), std::sqrt(sq_pos / n), std::sqrt(sq_strain / n));
  EXPECT_LE(std::sqrt(sq_pos / n), 0.05);
  EXPECT_LE(std::sqrt(sq_strain / n), 0.005);
}

TEST_F(StationTest, ProcessRejectsForeignFilesAndBadCalibrations) {
  const fs::path junk = work() / "junk.mcap", out = work() / "o.ply";
  writeFile(junk, "this is not a trace\n");
  RunResult r = run("process " + quote(junk) + " -o " + quote(out));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("not an MCAP trace"), std::string::npos) << r.err;
  const fs::path trace = work() / "laser.mcap", dir = work() / "cal";
  ASSERT_EQ(run("sim generate --quick --sensors laser -o " + quote(trace)).exit_code, 0);
  fs::create_directories(dir);
  writeFile(dir / "digitizer.json", "{\"format\": \"stampscan-calibration\", \"version\": 1, \"kind\": \"digitizer\"}");
  r = run("process " + quote(trace) + " -o " + quote(out) + " --calibration " + quote(dir));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("digitizer.json"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace stampscan::station::test
