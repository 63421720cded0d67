// End-to-end tests of `station fit`: the output contract (one projected point per input point, same
// order, unit normals, strain carried), its formats and options, every fitting method, and the
// default method's accuracy against the sample part's ground truth.
#include "station_test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

namespace stampscan::station::test {
namespace {

// --- the contract and the default method ------------------------------------------------------

TEST_F(StationTest, FitWritesOneProjectedPointPerInputPoint) {
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud in = fitting::readPly(in_file);
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(in, out);
  expectProjectionMovesBounded(in, out, 1.0);
  ASSERT_TRUE(out.hasStrain());
  for (const double e : out.strain) ASSERT_TRUE(std::isfinite(e));
  EXPECT_FALSE(out.hasColors());
  const std::string header = plyHeader(out_file);
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos) << header;
  EXPECT_NE(header.find("property float x\nproperty float y\nproperty float z\n"
                        "property float nx\nproperty float ny\nproperty float nz\nproperty float strain\n"),
            std::string::npos)
      << header;
  // The summary counts the points, names the method and the output.
  EXPECT_NE(r.out.find(std::to_string(in.size()) + " read"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("auto"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(out_file.string()), std::string::npos) << r.out;
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST_F(StationTest, FitMovesPointsOntoTheTrueSurface) {
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud in = fitting::readPly(in_file);
  const Cloud out = fitting::readPly(out_file);
  ASSERT_EQ(out.size(), in.size());
  const sim::PanPart part;
  const sim::SurfaceError before = sim::surfaceError(part, in.positions);
  const sim::SurfaceError after = sim::surfaceError(part, out.positions);
  EXPECT_LT(after.rms, 0.6 * before.rms) << "RMS " << before.rms << " -> " << after.rms;
  // Normals face +z like the part's and agree with its true normals.
  std::size_t good = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Vec3& p = out.positions[i];
    good += out.normals[i].dot(part.normal(p.x(), p.y())) > 0.95;
  }
  EXPECT_GT(static_cast<double>(good), 0.97 * static_cast<double>(out.size()));
}

TEST_F(StationTest, FitPushesNoPointOffTheSurface) {
  // Input noise is 0.05 mm; a fitted point more than 0.25 mm off the true surface (and farther than
  // its input) was made worse by the fit.
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expectNoPointPushedOffTheSurface(fitting::readPly(in_file), fitting::readPly(out_file), 0.25);
}

TEST_F(StationTest, FitOfASparserScanStaysAccurate) {
  // `--points 10000` gives about 1.7 mm laser spacing: the default, tuning-free method must still
  // improve on the raw scan and keep every point near the surface. (At 5000 points the spacing,
  // about 2.5 mm, is coarser than the part's tightest radii, 2.3 mm; there the fit cuts those
  // corners by up to 2 mm. Such scans cannot resolve the part.)
  const fs::path in_file = sample(10000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud in = fitting::readPly(in_file);
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(in, out);
  const sim::PanPart part;
  const sim::SurfaceError before = sim::surfaceError(part, in.positions);
  const sim::SurfaceError after = sim::surfaceError(part, out.positions);
  EXPECT_LT(after.rms, before.rms) << "RMS distance to the true surface " << before.rms << " -> " << after.rms;
  EXPECT_LT(after.max, 1.0) << "max distance to the true surface " << before.max << " -> " << after.max;
  expectProjectionMovesBounded(in, out, 1.0);
}

TEST_F(StationTest, FitImprovesTheStrainField) {
  // The measured strain carries noise of about 0.005; the fitted strain at the fitted points should be
  // closer to the true strain than the measurement was (the demo reports exactly this).
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud in = fitting::readPly(in_file);
  const Cloud out = fitting::readPly(out_file);
  sim::SampleCloudParams params;
  params.target_points = 20000;
  const sim::SampleCloud truth = sim::makeSampleCloud(sim::PanPart{}, params);
  ASSERT_EQ(truth.cloud.size(), out.size());
  ASSERT_TRUE(out.hasStrain());
  double in_sq = 0, out_sq = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    in_sq += std::pow(in.strain[i] - truth.true_strain[i], 2);
    out_sq += std::pow(out.strain[i] - truth.true_strain[i], 2);
  }
  const double n = static_cast<double>(out.size());
  EXPECT_LT(out_sq, in_sq) << "strain RMS error " << std::sqrt(in_sq / n) << " -> " << std::sqrt(out_sq / n);
}

TEST_F(StationTest, FitScalarOptionTakesEffect) {
  // --scalar selects the strain field (smooth or Shepard's, Eqs. 15-16); with the default method it
  // must change the fitted strain, not be silently ignored.
  const fs::path in_file = sample(5000);
  const fs::path smooth = work() / "smooth.ply", shepard = work() / "shepard.ply";
  ASSERT_EQ(run("fit " + quote(in_file) + " -o " + quote(smooth) + " -q --scalar smooth").exit_code, 0);
  ASSERT_EQ(run("fit " + quote(in_file) + " -o " + quote(shepard) + " -q --scalar shepard").exit_code, 0);
  const Cloud a = fitting::readPly(smooth), b = fitting::readPly(shepard);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_TRUE(a.hasStrain() && b.hasStrain());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differing += a.strain[i] != b.strain[i];
  EXPECT_GT(differing, 0u) << "--scalar shepard gave the same strain as --scalar smooth at all " << a.size()
                           << " points";
}

TEST_F(StationTest, FitAsciiOutput) {
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --ascii -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(readFile(out_file).rfind("ply\nformat ascii 1.0\n", 0), 0u) << plyHeader(out_file);
  expectOnePointPerInput(fitting::readPly(in_file), fitting::readPly(out_file));
  EXPECT_TRUE(r.out.empty()) << "--quiet printed: " << r.out;
}

TEST_F(StationTest, FitDoublePrecisionAndColours) {
  const fs::path in_file = sample(5000);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --double --colors -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string header = plyHeader(out_file);
  EXPECT_NE(header.find("property double x\n"), std::string::npos) << header;
  EXPECT_NE(header.find("property uchar red\n"), std::string::npos) << header;
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(fitting::readPly(in_file), out);
  ASSERT_TRUE(out.hasColors());
  // The temperature map: most thinning red, least blue.
  const auto most = std::min_element(out.strain.begin(), out.strain.end()) - out.strain.begin();
  const auto least = std::max_element(out.strain.begin(), out.strain.end()) - out.strain.begin();
  EXPECT_EQ(out.colors[static_cast<std::size_t>(most)][0], 255);
  EXPECT_EQ(out.colors[static_cast<std::size_t>(least)][2], 255);
}

TEST_F(StationTest, FitMesh) {
  const fs::path in_file = sample(20000);
  const fs::path out_file = work() / "fitted.ply", mesh_file = work() / "mesh.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --mesh " + quote(mesh_file));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(fitting::readPly(out_file).size(), fitting::readPly(in_file).size());
  fitting::ReadReport report;
  const fitting::Mesh mesh = fitting::readPlyMesh(mesh_file, &report);
  ASSERT_GT(mesh.vertices.size(), 0u);
  ASSERT_GT(mesh.triangles.size(), 0u);
  EXPECT_EQ(report.faces_read, mesh.triangles.size());
  EXPECT_TRUE(mesh.vertices.hasStrain());
  EXPECT_TRUE(mesh.vertices.hasColors());
  for (const fitting::Triangle& t : mesh.triangles)
    for (const std::uint32_t v : t.v) ASSERT_LT(v, mesh.vertices.size());
  // The mesh lies on the part and covers it (its area is close to the blank's, less the hole).
  const sim::PanPart part;
  EXPECT_LT(sim::surfaceError(part, mesh.vertices.positions).rms, 0.1);
  double area = 0;
  for (const fitting::Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.vertices.positions[t.v[0]];
    area += 0.5 * (mesh.vertices.positions[t.v[1]] - a).cross(mesh.vertices.positions[t.v[2]] - a).norm();
  }
  EXPECT_GT(area, 0.8 * 160 * 120) << "mesh area " << area;
  EXPECT_NE(r.out.find("triangles"), std::string::npos) << r.out;
}

TEST_F(StationTest, FitIsIndependentOfThreadCount) {
  const fs::path in_file = sample(5000);
  const fs::path one = work() / "one.ply", two = work() / "two.ply";
  ASSERT_EQ(run("fit " + quote(in_file) + " -o " + quote(one) + " --threads 1 -q").exit_code, 0);
  ASSERT_EQ(run("fit " + quote(in_file) + " -o " + quote(two) + " --threads 2 -q").exit_code, 0);
  EXPECT_EQ(readFile(one), readFile(two));
}

TEST_F(StationTest, FitViewpointOrientsNormals) {
  const fs::path in_file = sample(5000);
  const fs::path up = work() / "up.ply", down = work() / "down.ply";
  ASSERT_EQ(run("fit " + quote(in_file) + " -o " + quote(up) + " -q").exit_code, 0);
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(down) + " --viewpoint 0 0 -1000 -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud a = fitting::readPly(up), b = fitting::readPly(down);
  ASSERT_EQ(a.size(), b.size());
  std::size_t facing_up = 0, facing_down = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    facing_up += a.normals[i].z() > 0;
    facing_down += b.normals[i].z() < 0;
  }
  EXPECT_GT(facing_up, a.size() * 99 / 100);
  EXPECT_GT(facing_down, b.size() * 99 / 100);
}

TEST_F(StationTest, FitTextInputAndNoStrain) {
  // An x y z text cloud: no strain in, none out.
  const Cloud in = fitting::readPly(sample(5000));
  std::string text = "# x y z\n";
  for (const Vec3& p : in.positions)
    text += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
  const fs::path in_file = work() / "scan.xyz", out_file = work() / "fitted.ply";
  writeFile(in_file, text);
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(in, out);
  EXPECT_FALSE(out.hasStrain());
  EXPECT_EQ(plyHeader(out_file).find("strain"), std::string::npos);
}

TEST_F(StationTest, FitCsvInputWithStrainColumn) {
  // A CSV cloud with a header naming its columns (strain first, to check columns go by name).
  const Cloud in = fitting::readPly(sample(5000));
  std::string text = "strain,x,y,z\n";
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Vec3& p = in.positions[i];
    text += std::to_string(in.strain[i]) + "," + std::to_string(p.x()) + "," + std::to_string(p.y()) + "," +
            std::to_string(p.z()) + "\n";
  }
  const fs::path in_file = work() / "scan.csv", out_file = work() / "fitted.ply";
  writeFile(in_file, text);
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(in, out);
  ASSERT_TRUE(out.hasStrain());
  // The fitted strain is a smoothed version of the input's, in the same range.
  const auto [lo, hi] = std::minmax_element(out.strain.begin(), out.strain.end());
  EXPECT_LT(*lo, -0.2);
  EXPECT_GT(*hi, -0.05);
  EXPECT_LT(*hi, 0.05);
}

// --- fit: every method -----------------------------------------------------------------------

struct MethodCase {
  const char* name;
  const char* args;
  std::size_t points;
};

void PrintTo(const MethodCase& c, std::ostream* os) { *os << "fit " << c.args << " (" << c.points << " points)"; }

class StationMethodTest : public StationTest, public ::testing::WithParamInterface<MethodCase> {};

TEST_P(StationMethodTest, FitsAndKeepsTheContract) {
  const MethodCase& c = GetParam();
  const fs::path in_file = sample(c.points);
  const fs::path out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " " + c.args);
  ASSERT_EQ(r.exit_code, 0) << c.args << "\n" << r.err;
  const Cloud in = fitting::readPly(in_file);
  const Cloud out = fitting::readPly(out_file);
  expectOnePointPerInput(in, out);
  EXPECT_TRUE(out.hasStrain());
  // The paper's plane-fit methods are references, not the most accurate choice on this strongly
  // curved part (their bias grows with kappa * h^2), so only sanity is asked of them here.
  expectProjectionMovesBounded(in, out, 5.0);
  EXPECT_LT(sim::surfaceError(sim::PanPart{}, out.positions).rms, 0.5) << c.args;
}

INSTANTIATE_TEST_SUITE_P(Methods, StationMethodTest,
                         ::testing::Values(MethodCase{"Euclidean", "--method euclidean", 10000},
                                           MethodCase{"EuclideanCubic", "--method euclidean --kernel cubic", 10000},
                                           MethodCase{"Sig", "--method sig --sig-r 7", 5000},
                                           MethodCase{"Gaussian", "--method gaussian", 5000},
                                           MethodCase{"Apss", "--method apss", 10000},
                                           MethodCase{"AutoExplicit", "--method auto --scalar shepard", 10000},
                                           MethodCase{"FixedBandwidth", "--bandwidth 1.5", 10000},
                                           MethodCase{"EuclideanFixedBandwidth", "--method euclidean --bandwidth 2.5",
                                                      10000}),
                         [](const ::testing::TestParamInfo<MethodCase>& c) { return std::string(c.param.name); });

}  // namespace
}  // namespace stampscan::station::test
