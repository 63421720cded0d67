// `station report` as the operator runs it: what it prints, the exit code and the untouched folder on
// bad input, and end to end on a simulated scan measured by `station process`.
#include "../station_test_support.hpp"
#include "report_test_support.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/report/forming_limit.hpp"

#include <cmath>
#include <set>
#include <sstream>

namespace stampscan::station::test {
namespace {

// The station program's test fixture (scratch folder, running the program), for `station report`.
class ReportCommand : public StationTest {};

using report::test::folderEntries;

TEST_F(ReportCommand, ReportPrintsTheVerdictTheFilesAndTheTime) {
  const fs::path run_dir = work() / "20260105-101500-plate-7";
  report::test::writePlateRun(run_dir, report::test::makePlate());
  const RunResult r = run("report " + quote(run_dir), 60);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("DC04 (the default"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("wrote       report.pdf"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("verdict     failed"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("time"), std::string::npos) << r.out;
  const RunResult list = run("report --list-materials");
  EXPECT_EQ(list.exit_code, 0);
  EXPECT_NE(list.out.find("AA6016-T4"), std::string::npos) << list.out;
}

// A plant's own materials, named by the cell file, join the built-in ones (one of the same name
// replaces it); the run is recorded in the cell's results database.
TEST_F(ReportCommand, TheCellFilesMaterialsExtendTheBuiltInOnes) {
  const fs::path run_dir = work() / "runs" / "20260105-101500-plate-8";
  report::test::writePlateRun(run_dir, report::test::makePlate());
  writeFile(work() / "plant-materials.toml",
            "[[material]]\nname = \"PLANT-X\"\nfamily = \"steel\"\nthickness_mm = 0.8\nn = 0.24\n"
            "[[material]]\nname = \"DC04\"\nfamily = \"steel\"\nthickness_mm = 1.5\nn = 0.22\n");
  const fs::path db = work() / "plant-db";
  fs::create_directories(db);
  writeFile(work() / "cell.toml", "name = \"line 3\"\n[report]\nmaterials = \"plant-materials.toml\"\n[results]\n"
                                  "database = \"" + db.string() + "\"\n");
  expectCleanFailure(run("report " + quote(run_dir) + " --material PLANT-X"), "PLANT-X");
  const RunResult list = run("report --list-materials --cell " + quote(work() / "cell.toml"));
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_NE(list.out.find("PLANT-X"), std::string::npos) << list.out;
  EXPECT_NE(list.out.find("t 1.50 mm"), std::string::npos) << "the plant's DC04 replaces the built-in one:\n" << list.out;
  const RunResult r = run("report " + quote(run_dir) + " --material PLANT-X --cell " + quote(work() / "cell.toml"), 60);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("material    PLANT-X"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(db / "results.sqlite"));
  EXPECT_FALSE(fs::exists(run_dir.parent_path() / "results.sqlite"));
  const RunResult missing = run("report --list-materials --cell " + quote(work() / "no-cell.toml"));
  expectCleanFailure(missing, "no-cell.toml");
}

TEST_F(ReportCommand, ReportOnBadInputExitsOneAndWritesNothing) {
  const fs::path run_dir = work() / "run";
  report::test::writePlateRun(run_dir, report::test::makePlate());
  const auto before = folderEntries(run_dir);
  RunResult r = run("report " + quote(run_dir) + " --material unobtainium");
  expectCleanFailure(r, "unobtainium");
  EXPECT_NE(r.err.find("DC04"), std::string::npos) << "the known materials are listed: " << r.err;
  EXPECT_EQ(folderEntries(run_dir), before);

  writeFile(run_dir / "cloud4d.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n");
  r = run("report " + quote(run_dir));
  expectCleanFailure(r, "cloud4d.ply");
  EXPECT_EQ(folderEntries(run_dir), before);

  fs::remove(run_dir / "cloud4d.ply");
  r = run("report " + quote(run_dir));
  expectCleanFailure(r, "cloud4d.ply");
  EXPECT_EQ(r.exit_code, 1);

  r = run("report " + quote(work() / "no-such-run"));
  expectCleanFailure(r, "no-such-run");
}

// A simulated scan measured by `station process --fit` in a run folder of its own (no mesh: the maps
// draw the elements), reported, and the report's thinning checked against the simulator's truth.
TEST_F(ReportCommand, ReportOnASimulatedScanMatchesItsTruth) {
  const fs::path trace = work() / "scan.mcap", truth = work() / "truth.ply", run_dir = work() / "runs" / "sim";
  ASSERT_EQ(run("sim generate --quick --seed 3 -o " + quote(trace) + " --truth " + quote(truth), 120).exit_code, 0);
  fs::create_directories(run_dir);
  const RunResult p = run("process " + quote(trace) + " -o " + quote(run_dir / "cloud4d.ply") + " --fit " +
                              quote(run_dir / "fitted.ply") + " -q",
                          120);
  ASSERT_EQ(p.exit_code, 0) << p.err;
  const RunResult r = run("report " + quote(run_dir) + " --material DC05 --program OP10", 60);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("cloud4d.ply (the run has no mesh)"), std::string::npos) << r.out;

  const Cloud measured = fitting::readPly(run_dir / "cloud4d.ply"), t = fitting::readPly(truth);
  const std::string csv = readFile(run_dir / "elements.csv");
  EXPECT_EQ(static_cast<std::size_t>(countLines(csv)), measured.size() + 1);
  // Each row's thinning against the true thinning of the nearest true element.
  const fitting::KdTree tree(t.positions);
  std::vector<fitting::Neighbor> nn;
  std::istringstream rows(csv);
  std::string line;
  std::getline(rows, line);  // header
  double worst = 0, max_measured = -1e9, max_true = -1e9;
  std::size_t n = 0;
  while (std::getline(rows, line)) {
    std::vector<std::string> cells;
    std::istringstream fields(line);
    for (std::string cell; std::getline(fields, cell, ',');) cells.push_back(cell);
    ASSERT_GE(cells.size(), 14u) << line;
    const Vec3 at(std::stod(cells[1]), std::stod(cells[2]), std::stod(cells[3]));
    const double thinning = std::stod(cells[9]);
    tree.knn(at, 1, nn);
    ASSERT_LT(nn[0].distance_sq, 0.5 * 0.5) << line;
    const double true_thinning = report::thinningPercent(t.strain[nn[0].index]);
    worst = std::max(worst, std::abs(thinning - true_thinning));
    max_measured = std::max(max_measured, thinning);
    max_true = std::max(max_true, true_thinning);
    ++n;
  }
  EXPECT_EQ(n, measured.size());
  std::printf(
      "report on a simulated scan: %zu elements, max thinning %.2f%% (truth %.2f%%), worst element %.2f%% off\n", n,
      max_measured, max_true, worst);
  EXPECT_LT(worst, 2.0);  // thickness strain within 0.02 of the truth, element by element
  EXPECT_NEAR(max_measured, max_true, 1.0);
  EXPECT_NE(readFile(run_dir / "report.html").find("OP10"), std::string::npos);
}

}  // namespace
}  // namespace stampscan::station::test
