// End to end: `station sim generate` writes a trace and its ground truth, `station process` measures
// it; the Cloud4D it writes is checked against the truth, and the calibration it saves is reused.
#include "station_test_support.hpp"

#include "stampscan/acquisition/part_program.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <algorithm>
#include <cmath>
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

TEST_F(StationTest, SimPartWritesAProgramFolder) {
  const fs::path dir = work() / "programs" / "sim-pan";
  const RunResult r = run("sim part pan --grid square -o " + quote(dir));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("sim-pan-square"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("model.stl"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("laser sweeps"), std::string::npos) << r.out;
  const acquisition::PartProgram p = acquisition::loadPartProgram(dir);
  EXPECT_EQ(p.simulated_part, "pan");
  EXPECT_EQ(p.grid.kind, "square");
  EXPECT_EQ(acquisition::findProgram(work() / "programs", "sim-pan-square"), dir);
  EXPECT_NE(run("sim part cube -o " + quote(work() / "cube")).exit_code, 0);
  EXPECT_FALSE(fs::exists(work() / "cube"));
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

// Two runs to one output each write under a temporary name of their own: both succeed and the
// output is one whole trace, never a mixture of the two.
TEST_F(StationTest, SimGenerateRunsToOneOutputLeaveOneWholeTrace) {
  const fs::path trace = work() / "shared.mcap";
  const std::string exe = quote(std::string(STATION_EXE));
  const std::string one = exe + " sim generate --quick --seed 1 -o " + quote(trace) + " >/dev/null 2>&1; echo $? >";
  const std::string command = "(" + one + quote(work() / "rc1") + ") & (" + one + quote(work() / "rc2") + ") & wait";
  ASSERT_EQ(std::system(command.c_str()), 0);
  EXPECT_EQ(readFile(work() / "rc1"), "0\n");
  EXPECT_EQ(readFile(work() / "rc2"), "0\n");
  const RunResult info = run("trace info " + quote(trace));
  EXPECT_EQ(info.exit_code, 0) << info.out;
  EXPECT_EQ(workEntries(), (std::vector<std::string>{"rc1", "rc2", "shared.mcap"}));
}

// Ctrl-C or a kill in the middle of writing leaves neither the output nor a temporary file.
TEST_F(StationTest, SimGenerateInterruptedLeavesNoFiles) {
  for (const char* signal_name : {"INT", "TERM"}) {
    const std::string command = "timeout -s " + std::string(signal_name) + " 1.5 " + quote(std::string(STATION_EXE)) +
                                " sim generate --seed 3 -o " + quote(work() / "long.mcap") + " >/dev/null 2>&1";
    const int status = std::system(command.c_str());
    ASSERT_TRUE(WIFEXITED(status));
    ASSERT_EQ(WEXITSTATUS(status), 124) << "the generator must still be running after 1.5 s for this test";
    EXPECT_TRUE(workEntries().empty()) << "SIG" << signal_name << " left " << workEntries().front();
  }
}

// A trace with a damaged chunk lost messages: its result would miss elements without saying so.
TEST_F(StationTest, ProcessRefusesADamagedTraceUnlessAccepted) {
  const fs::path trace = work() / "scan.mcap", out = work() / "cloud4d.ply";
  ASSERT_EQ(run("sim generate --quick --seed 5 -o " + quote(trace)).exit_code, 0);
  std::string bytes = readFile(trace);
  for (std::size_t at = bytes.size() * 6 / 10; at < bytes.size() * 6 / 10 + 64; ++at) bytes[at] = static_cast<char>(bytes[at] ^ 0x5a);
  const fs::path damaged = work() / "damaged.mcap";
  writeFile(damaged, bytes);
  const RunResult refused = run("process " + quote(damaged) + " -o " + quote(out) + " -q");
  EXPECT_EQ(refused.exit_code, 1) << refused.out << refused.err;
  EXPECT_NE(refused.err.find("is damaged: "), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("lost (damage at byte"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("--accept-damaged"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(out));
  const RunResult accepted = run("process " + quote(damaged) + " -o " + quote(out) + " -q --accept-damaged");
  EXPECT_EQ(accepted.exit_code, 0) << accepted.out << accepted.err;
  EXPECT_NE(accepted.out.find("accepted    a damaged trace"), std::string::npos) << accepted.out;
  EXPECT_GT(fitting::readPly(out).size(), 0u);
}

TEST_F(StationTest, ProcessMeasuresASimulatedTraceAgainstItsTruth) {
  const fs::path trace = work() / "dome.mcap", truth = work() / "truth.ply", out = work() / "cloud4d.ply";
  const fs::path calibration = work() / "calibration", fitted = work() / "fitted.ply", mesh = work() / "mesh.ply";
  ASSERT_EQ(run("sim generate --quick --seed 7 -o " + quote(trace) + " --truth " + quote(truth)).exit_code, 0);
  fs::create_directories(calibration);
  const RunResult r = run("process " + quote(trace) + " -o " + quote(out) + " --fit " + quote(fitted) + " --mesh " +
                          quote(mesh) + " --save-calibration " + quote(calibration) + " -q");
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
  // The fitted surface: its shape from the laser's returns, the elements' strain on it. At each
  // true element, the surface passes through it and carries its strain.
  const Cloud surface = fitting::readPly(fitted);
  ASSERT_GT(surface.size(), 10 * measured.size()) << "one point per 0.5 mm, not per element";
  ASSERT_TRUE(surface.hasStrain());
  ASSERT_TRUE(surface.hasNormals());
  const fitting::KdTree surface_tree(surface.positions);
  const fitting::KdTree measured_tree(measured.positions);
  double sq_off = 0, sq_surface_strain = 0;
  std::size_t at_elements = 0, with_strain = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    measured_tree.knn(t.positions[i], 1, nn);
    if (nn[0].distance_sq > 0.5 * 0.5) continue;  // an element the scan did not find
    surface_tree.knn(t.positions[i], 1, nn);
    ASSERT_LT(nn[0].distance_sq, 0.5 * 0.5);
    const std::size_t k = nn[0].index;
    sq_off += std::pow(surface.normals[k].dot(t.positions[i] - surface.positions[k]), 2);
    ++at_elements;
    if (std::isfinite(surface.strain[k])) {
      sq_surface_strain += std::pow(surface.strain[k] - t.strain[i], 2);
      ++with_strain;
    }
  }
  ASSERT_GT(at_elements, 300u);
  std::printf("fitted surface: %zu points; at %zu true elements %.4f mm off, strain RMS %.4f over %zu\n", surface.size(),
              at_elements, std::sqrt(sq_off / static_cast<double>(at_elements)),
              std::sqrt(sq_surface_strain / static_cast<double>(with_strain)), with_strain);
  EXPECT_LE(std::sqrt(sq_off / static_cast<double>(at_elements)), 0.01);
  EXPECT_GE(with_strain, at_elements * 95 / 100);
  EXPECT_LE(std::sqrt(sq_surface_strain / static_cast<double>(with_strain)), 0.005);
  const fitting::Mesh triangles = fitting::readPlyMesh(mesh);
  EXPECT_GT(triangles.triangles.size(), surface.size());
  EXPECT_EQ(triangles.vertices.strain.size(), triangles.vertices.size());
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

// Laser and full-resolution stereo measure most elements several times, a few hundredths of a
// millimetre apart: the Cloud4D holds each printed element once, with its uncertainty, and the
// fitted surface carries strain everywhere within the grid, its strain at the elements as true as
// the elements'.
TEST_F(StationTest, ProcessWithStereoGivesOneElementEachAndStrainOverTheWholeGrid) {
  const fs::path trace = work() / "pan.mcap", truth = work() / "truth.ply", out = work() / "cloud4d.ply";
  const fs::path measurements = work() / "measurements.ply", fitted = work() / "fitted.ply";
  ASSERT_EQ(run("sim generate --quick --image-scale 1 --part pan --grid square --seed 21 -o " + quote(trace) + " --truth " +
                quote(truth)).exit_code, 0);
  const RunResult r = run("process " + quote(trace) + " --with-stereo -o " + quote(out) + " --measurements " +
                          quote(measurements) + " --fit " + quote(fitted) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const Cloud elements = fitting::readPly(out), all = fitting::readPly(measurements), t = fitting::readPly(truth);
  const Cloud surface = fitting::readPly(fitted);
  // Both paths measured, most elements more than once; the Cloud4D holds each once.
  const auto& source = all.scalars.at("source");
  ASSERT_GT(std::count(source.begin(), source.end(), 1.0), 300) << "the stereo views found too few elements";
  ASSERT_GT(all.size(), 2 * elements.size());
  ASSERT_TRUE(elements.scalars.count(fitting::kStrainUncertainty));
  ASSERT_TRUE(elements.scalars.count(fitting::kFittedStrain));
  const fitting::KdTree element_tree(elements.positions);
  std::vector<fitting::Neighbor> nn;
  for (std::size_t i = 0; i < elements.size(); ++i) {
    element_tree.knn(elements.positions[i], 2, nn);
    ASSERT_EQ(nn.size(), 2u);
    EXPECT_GT(std::sqrt(nn[1].distance_sq), 1.5) << "element " << i << " twice in the Cloud4D";
  }
  // Every point of the surface within the grid (within a pitch of an element) carries strain.
  std::size_t within = 0, without = 0;
  for (std::size_t i = 0; i < surface.size(); ++i) {
    element_tree.knn(surface.positions[i], 1, nn);
    if (nn[0].distance_sq > 2.54 * 2.54) continue;
    ++within;
    without += !std::isfinite(surface.strain[i]);
  }
  ASSERT_GT(within, 10000u);
  EXPECT_EQ(without, 0u) << "of " << within << " surface points within the grid";
  // The surface's strain at the elements against the truth, beside the elements' own.
  const fitting::KdTree true_tree(t.positions);
  double sq_element = 0, sq_surface = 0;
  std::size_t n = 0;
  const auto& on_surface = elements.scalars.at(fitting::kFittedStrain);
  for (std::size_t i = 0; i < elements.size(); ++i) {
    if (!std::isfinite(on_surface[i])) continue;  // beyond the laser's surface
    true_tree.knn(elements.positions[i], 1, nn);
    if (nn[0].distance_sq > 0.5 * 0.5) continue;
    sq_element += std::pow(elements.strain[i] - t.strain[nn[0].index], 2);
    sq_surface += std::pow(on_surface[i] - t.strain[nn[0].index], 2);
    ++n;
  }
  ASSERT_GT(n, 400u);
  const double element_rms = std::sqrt(sq_element / static_cast<double>(n));
  const double surface_rms = std::sqrt(sq_surface / static_cast<double>(n));
  std::printf("with stereo: %zu measurements of %zu elements; at %zu elements strain RMS %.4f, the surface's %.4f\n",
              all.size(), elements.size(), n, element_rms, surface_rms);
  // The goal is the elements' own RMS: at an element the field keeps the element's best estimate.
  EXPECT_LE(surface_rms, 1.15 * element_rms);
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
