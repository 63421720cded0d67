// End-to-end tests of the `station` program's command line: help and usage, `station sample`, the
// errors of `station fit` (bad input files, bad options, unwritable output) and `station demo`.
#include "station_test_support.hpp"

#include <sys/stat.h>

#include <gtest/gtest.h>

#include <cmath>
#include <ostream>
#include <random>
#include <regex>
#include <string>
#include <vector>

namespace stampscan::station::test {
namespace {

// --- help and usage --------------------------------------------------------------------------

TEST_F(StationTest, HelpListsSubcommands) {
  const RunResult r = run("--help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  for (const char* word : {"fit", "sample", "demo"}) EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
}

TEST_F(StationTest, FitHelpListsOptions) {
  const RunResult r = run("fit --help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  for (const char* word : {"--output", "--method", "--bandwidth", "--sig-r", "--kernel", "--scalar", "--viewpoint",
                           "--mesh", "--ascii", "--double", "--colors", "--threads", "--quiet"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
}

TEST_F(StationTest, FitHelpNamesEveryMethod) {
  const RunResult r = run("fit --help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  for (const char* method : {"auto", "apss", "euclidean", "sig", "gaussian"})
    EXPECT_NE(r.out.find(method), std::string::npos) << method << "\n" << r.out;
}

TEST_F(StationTest, SampleAndDemoHelp) {
  for (const char* sub : {"sample", "demo"}) {
    const RunResult r = run(std::string(sub) + " --help");
    EXPECT_EQ(r.exit_code, 0) << sub << ": " << r.err;
    for (const char* word : {"--output", "--points", "--seed", "--noise"})
      EXPECT_NE(r.out.find(word), std::string::npos) << sub << " " << word << "\n" << r.out;
  }
}

TEST_F(StationTest, VersionFlag) {
  const RunResult r = run("--version");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("0.1.0"), std::string::npos) << r.out;
}

TEST_F(StationTest, NoSubcommandFails) {
  const RunResult r = run("");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_LT(r.exit_code, 128) << "crashed";
  EXPECT_FALSE(r.err.empty());
}

TEST_F(StationTest, UnknownSubcommandFails) {
  const RunResult r = run("frobnicate");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_LT(r.exit_code, 128) << "crashed";
}

TEST_F(StationTest, FitWithoutOutputFails) {
  const fs::path in = sample(5000);
  const RunResult r = run("fit " + quote(in));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("output"), std::string::npos) << r.err;
}

// --- sample ----------------------------------------------------------------------------------

TEST_F(StationTest, SampleWritesTheSimulatedCloud) {
  const fs::path file = sample(20000);
  const Cloud cloud = fitting::readPly(file);
  // Exactly the sampler's cloud with the default parameters, stored as float.
  sim::SampleCloudParams params;
  params.target_points = 20000;
  const sim::SampleCloud truth = sim::makeSampleCloud(sim::PanPart{}, params);
  ASSERT_EQ(cloud.size(), truth.cloud.size());
  ASSERT_TRUE(cloud.hasStrain());
  EXPECT_FALSE(cloud.hasNormals());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_LT((cloud.positions[i] - truth.cloud.positions[i]).norm(), 1e-4) << "point " << i;
    ASSERT_NEAR(cloud.strain[i], truth.cloud.strain[i], 1e-6) << "point " << i;
  }
  EXPECT_NE(plyHeader(file).find("format binary_little_endian 1.0"), std::string::npos);
}

TEST_F(StationTest, SampleIsDeterministicPerSeed) {
  const fs::path a = sample(5000, "a.ply", "--seed 5");
  const fs::path b = sample(5000, "b.ply", "--seed 5");
  const fs::path c = sample(5000, "c.ply", "--seed 6");
  EXPECT_EQ(readFile(a), readFile(b));
  EXPECT_NE(readFile(a), readFile(c));
}

TEST_F(StationTest, SampleAsciiAndNoise) {
  const fs::path file = sample(5000, "a.ply", "--ascii --noise 0.2");
  EXPECT_EQ(readFile(file).rfind("ply\nformat ascii 1.0\n", 0), 0u) << plyHeader(file);
  const Cloud cloud = fitting::readPly(file);
  // Outliers aside, the cloud's distance to the part reflects --noise.
  std::vector<double> d;
  const sim::PanPart part;
  for (const Vec3& p : cloud.positions) d.push_back(part.distance(p));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  // Median of |N(0, 0.2)| is 0.6745 * 0.2.
  EXPECT_NEAR(d[d.size() / 2], 0.6745 * 0.2, 0.03);
}

TEST_F(StationTest, SampleRejectsBadPointCount) {
  for (const char* points : {"10", "abc", "-5"}) {
    const RunResult r = run("sample -o " + quote(work() / "s.ply") + " --points " + points);
    EXPECT_NE(r.exit_code, 0) << points;
    EXPECT_LT(r.exit_code, 128) << points;
    EXPECT_FALSE(r.err.empty()) << points;
    EXPECT_FALSE(fs::exists(work() / "s.ply")) << points;
  }
}

// --- fit: errors -----------------------------------------------------------------------------

TEST_F(StationTest, NonexistentInputFails) {
  const fs::path in_file = work() / "missing.ply", out_file = work() / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_LT(r.exit_code, 128);
  EXPECT_NE(r.err.find("missing.ply"), std::string::npos) << r.err;
  EXPECT_TRUE(workEntries().empty());
}

struct MalformedCase {
  const char* name;
  // Builds the bad file's bytes from a good binary PLY's bytes.
  std::string (*make)(const std::string& good);
};

void PrintTo(const MalformedCase& c, std::ostream* os) { *os << c.name; }

class StationMalformedTest : public StationTest, public ::testing::WithParamInterface<MalformedCase> {};

TEST_P(StationMalformedTest, FailsCleanlyWithoutOutput) {
  const std::string good = readFile(sample(5000, "good.ply"));
  const fs::path in_file = work() / "bad input.ply", out_file = work() / "fitted.ply";
  writeFile(in_file, GetParam().make(good));
  fs::remove(work() / "good.ply");
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --mesh " + quote(work() / "mesh.ply"));
  expectCleanFailure(r, in_file.string());
  EXPECT_EQ(workEntries(), std::vector<std::string>{"bad input.ply"}) << "a failed run left files behind";
}

TEST_P(StationMalformedTest, KeepsAnExistingOutputUnchanged) {
  const std::string good = readFile(sample(5000, "good.ply"));
  const fs::path in_file = work() / "bad.ply", out_file = work() / "good.ply";
  writeFile(in_file, GetParam().make(good));
  // The output name already holds a valid earlier result.
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file));
  expectCleanFailure(r, in_file.string());
  EXPECT_EQ(readFile(out_file), good) << "the existing output was modified";
  const std::vector<std::string> expected{"bad.ply", "good.ply"};
  EXPECT_EQ(workEntries(), expected) << "a failed run left files behind";
}

std::string truncatedBinary(const std::string& good) { return good.substr(0, good.size() / 2); }
std::string truncatedHeader(const std::string& good) { return good.substr(0, good.find("end_header") / 2); }
std::string garbage(const std::string&) {
  std::mt19937 rng(3);
  std::string bytes(4096, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
  return bytes;
}
std::string textGarbage(const std::string&) { return "this is not a point cloud\n"; }
std::string emptyFile(const std::string&) { return ""; }
std::string headerWithoutX(const std::string&) {
  return "ply\nformat ascii 1.0\nelement vertex 2\nproperty float y\nproperty float z\nend_header\n1 2\n3 4\n";
}
std::string noVertices(const std::string&) {
  return "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
}
std::string asciiShortRow(const std::string&) {
  return "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
         "1 2 3\n4 5\n7 8 9\n";
}
std::string asciiNotANumber(const std::string&) {
  return "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
         "1 2 3\n4 five 6\n";
}
std::string hugeVertexCount(const std::string&) {
  return "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
         "property float z\nend_header\n" + std::string(24, '\0');
}

INSTANTIATE_TEST_SUITE_P(Inputs, StationMalformedTest,
                         ::testing::Values(MalformedCase{"TruncatedBinary", truncatedBinary},
                                           MalformedCase{"TruncatedHeader", truncatedHeader},
                                           MalformedCase{"Garbage", garbage},
                                           MalformedCase{"TextGarbage", textGarbage},
                                           MalformedCase{"Empty", emptyFile},
                                           MalformedCase{"HeaderWithoutX", headerWithoutX},
                                           MalformedCase{"NoVertices", noVertices},
                                           MalformedCase{"AsciiShortRow", asciiShortRow},
                                           MalformedCase{"AsciiNotANumber", asciiNotANumber},
                                           MalformedCase{"HugeVertexCount", hugeVertexCount}),
                         [](const ::testing::TestParamInfo<MalformedCase>& c) { return std::string(c.param.name); });

// A FIFO, a folder or a device given as input is refused at once, naming the file: opening a FIFO
// for reading would otherwise wait for a writer forever.
TEST_F(StationTest, InputsThatAreNotRegularFilesAreRefused) {
  const fs::path fifo = work() / "input.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string f = quote(fifo), out = quote(work() / "out.ply");
  for (const std::string& args : {"fit " + f + " -o " + out, "fit " + quote(work()) + " -o " + out + " --mesh " + quote(work() / "mesh.ply"),
                                  "process " + f + " -o " + out, "trace info " + f, "scan --dry-run --cell " + f,
                                  std::string("scan --dry-run --cell /dev/null"), "scan --dry-run --plan " + f,
                                  "process " + quote(work() / "missing.mcap") + " -o " + out + " --calibration " + quote(work())}) {
    // `timeout` guards the test itself: a regression would hang rather than fail.
    const RunResult r = run(args, 20);
    EXPECT_TRUE(r.exit_code != 0 && r.exit_code != 137) << args << ": exit " << r.exit_code << ": " << r.out << r.err;
    const bool named = r.err.find("not a regular file") != std::string::npos || r.err.find("FIFO") != std::string::npos ||
                       r.err.find("directory") != std::string::npos || r.err.find("folder") != std::string::npos ||
                       r.err.find("does not exist") != std::string::npos || r.err.find("cannot open") != std::string::npos;
    EXPECT_TRUE(named) << args << ": " << r.err;
  }
  EXPECT_FALSE(fs::exists(work() / "out.ply"));
}

TEST_F(StationTest, BadBandwidthFails) {
  const fs::path in_file = sample(5000);
  const fs::path out_file = work() / "fitted.ply";
  for (const char* h : {"-1", "abc", "0", "1.5mm", "nan", "inf"}) {
    const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --bandwidth " + quote(std::string(h)));
    EXPECT_NE(r.exit_code, 0) << h;
    EXPECT_LT(r.exit_code, 128) << h;
    EXPECT_NE(r.err.find("bandwidth"), std::string::npos) << h << ": " << r.err;
    if (std::string(h) != "inf") {
      EXPECT_NE(r.err.find(h), std::string::npos) << h << ": " << r.err;
    }
    EXPECT_FALSE(fs::exists(out_file)) << h;
  }
}

TEST_F(StationTest, UnknownOptionValuesFail) {
  const fs::path in_file = sample(5000);
  const fs::path out_file = work() / "fitted.ply";
  for (const char* args : {"--method simplex", "--kernel box", "--scalar magic", "--sig-r 0", "--threads 0",
                           "--viewpoint 1 2", "--no-such-option"}) {
    const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " " + args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_LT(r.exit_code, 128) << args;
    EXPECT_FALSE(r.err.empty()) << args;
    EXPECT_FALSE(fs::exists(out_file)) << args;
  }
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " --method simplex");
  EXPECT_NE(r.err.find("simplex"), std::string::npos) << r.err;
}

TEST_F(StationTest, OutputIntoMissingDirectoryFails) {
  const fs::path in_file = sample(5000);
  const fs::path out_file = work() / "no such dir" / "fitted.ply";
  const RunResult r = run("fit " + quote(in_file) + " -o " + quote(out_file) + " -q");
  expectCleanFailure(r, out_file.string());
  EXPECT_FALSE(fs::exists(out_file.parent_path()));
}

TEST_F(StationTest, SampleIntoMissingDirectoryFails) {
  const fs::path out_file = work() / "no such dir" / "scan.ply";
  const RunResult r = run("sample -o " + quote(out_file) + " --points 5000");
  expectCleanFailure(r, out_file.string());
}

// --- demo ------------------------------------------------------------------------------------

TEST_F(StationTest, DemoWritesSampleFitAndMesh) {
  const fs::path dir = work() / "demo";
  const RunResult r = run("demo -o " + quote(dir) + " --points 20000");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* name : {"sample.ply", "fitted.ply", "mesh.ply"}) ASSERT_TRUE(fs::exists(dir / name)) << name;
  const Cloud sample_cloud = fitting::readPly(dir / "sample.ply");
  const Cloud fitted = fitting::readPly(dir / "fitted.ply");
  expectOnePointPerInput(sample_cloud, fitted);
  expectProjectionMovesBounded(sample_cloud, fitted, 1.0);
  EXPECT_TRUE(fitted.hasStrain());
  EXPECT_TRUE(fitted.hasColors());
  const std::string header = plyHeader(dir / "fitted.ply");
  for (const char* property : {"red", "green", "blue", "strain"})
    EXPECT_NE(header.find(std::string(" ") + property + "\n"), std::string::npos) << property << "\n" << header;
  const fitting::Mesh mesh = fitting::readPlyMesh(dir / "mesh.ply");
  EXPECT_GT(mesh.triangles.size(), 0u);
  EXPECT_TRUE(mesh.vertices.hasStrain());
  EXPECT_TRUE(mesh.vertices.hasColors());
  // The report: RMS distance to the true surface before -> after, and the fit improves it.
  std::smatch m;
  const std::regex rms(R"(RMS ([0-9.]+) mm -> ([0-9.]+) mm)");
  ASSERT_TRUE(std::regex_search(r.out, m, rms)) << r.out;
  const double before = std::stod(m[1].str()), after = std::stod(m[2].str());
  EXPECT_LT(after, before) << r.out;
  // And the numbers agree with the files.
  const sim::PanPart part;
  EXPECT_NEAR(after, sim::surfaceError(part, fitted.positions).rms, 1e-3 + 0.01 * after);
  EXPECT_NEAR(before, sim::surfaceError(part, sample_cloud.positions).rms, 1e-3 + 0.01 * before);
}

TEST_F(StationTest, DemoIntoAFileFails) {
  const fs::path file = work() / "occupied";
  writeFile(file, "not a directory\n");
  const RunResult r = run("demo -o " + quote(file) + " --points 5000");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_LT(r.exit_code, 128);
  EXPECT_NE(r.err.find(file.string()), std::string::npos) << r.err;
  EXPECT_EQ(readFile(file), "not a directory\n");
}

}  // namespace
}  // namespace stampscan::station::test
