// Shared by the end-to-end tests of the `station` program: running the built executable with its
// output captured, a scratch directory per test, file helpers, and checks of the fit contract
// (ARCHITECTURE.md: one output point per input point, same order) against the sample part's truth.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/sim/sample_cloud.hpp"
#include "stampscan/sim/sample_part.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#ifndef STATION_EXE
#error "STATION_EXE must name the station executable"
#endif

namespace stampscan::station::test {

namespace fs = std::filesystem;
using fitting::Cloud;
using fitting::Vec3;

struct RunResult {
  int exit_code = -1;  // the process's exit status; 128 + signal when it was killed by one
  std::string out, err;
};

inline std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void writeFile(const fs::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Single-quoted for /bin/sh.
inline std::string quote(const std::string& word) {
  std::string q = "'";
  for (const char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
inline std::string quote(const fs::path& path) { return quote(path.string()); }

inline int countLines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

// The PLY header, up to and including end_header.
inline std::string plyHeader(const fs::path& file) {
  const std::string bytes = readFile(file);
  const auto end = bytes.find("end_header\n");
  return end == std::string::npos ? std::string() : bytes.substr(0, end + 11);
}

class StationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    root_ = fs::temp_directory_path() /
            ("stampscan_station_test_" + std::to_string(device()) + "_" + std::to_string(device()));
    fs::create_directories(root_ / "work");
    work_ = root_ / "work";
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(root_, ignored);
  }

  // Runs `station ARGS` (ARGS already quoted as needed) with stdout and stderr captured outside work().
  // With `timeout_seconds`, the run is killed after that long (exit code 137), so that a hang fails.
  RunResult run(const std::string& args, int timeout_seconds = 0) const {
    const fs::path out = root_ / "stdout.txt", err = root_ / "stderr.txt";
    const std::string limit = timeout_seconds > 0 ? "timeout -s KILL " + std::to_string(timeout_seconds) + " " : "";
    const std::string command =
        limit + quote(std::string(STATION_EXE)) + " " + args + " >" + quote(out) + " 2>" + quote(err) + " </dev/null";
    const int status = std::system(command.c_str());
    RunResult r;
    if (status != -1 && WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
    else if (status != -1 && WIFSIGNALED(status)) r.exit_code = 128 + WTERMSIG(status);
    r.out = readFile(out);
    r.err = readFile(err);
    return r;
  }

  // Writes the sample pan cloud with `station sample`; fails the test when that fails.
  fs::path sample(std::size_t points, const std::string& name = "scan.ply", const std::string& extra = "") const {
    const fs::path file = work_ / name;
    const RunResult r = run("sample -o " + quote(file) + " --points " + std::to_string(points) + " " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(file));
    return file;
  }

  std::vector<std::string> workEntries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(work_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  const fs::path& work() const { return work_; }

 private:
  fs::path root_, work_;
};

// The fit contract: one output point per input point, in input order, with unit normals. Order is
// judged by how far points move: a reordered output would move nearly every point by many mm.
inline void expectOnePointPerInput(const Cloud& in, const Cloud& out) {
  ASSERT_EQ(out.size(), in.size());
  ASSERT_TRUE(out.hasNormals());
  EXPECT_NO_THROW(out.validate());
  std::size_t near = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    ASSERT_TRUE(out.positions[i].allFinite()) << "point " << i;
    ASSERT_NEAR(out.normals[i].norm(), 1.0, 1e-4) << "normal " << i;
    near += (out.positions[i] - in.positions[i]).norm() < 1.0;
  }
  EXPECT_GT(static_cast<double>(near), 0.95 * static_cast<double>(in.size()))
      << "only " << near << " of " << in.size() << " output points are within 1 mm of their input point";
}

// Every output point is within `slack` mm of its input point, beyond the input's own distance from the
// true surface: a good point stays within `slack`, an outlier may travel back onto the surface.
inline void expectProjectionMovesBounded(const Cloud& in, const Cloud& out, double slack) {
  ASSERT_EQ(out.size(), in.size());
  const sim::PanPart part;
  std::size_t far = 0;
  double worst = 0;
  std::size_t worst_i = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const double excess = (out.positions[i] - in.positions[i]).norm() - part.distance(in.positions[i]);
    if (excess >= slack) ++far;
    if (excess > worst) {
      worst = excess;
      worst_i = i;
    }
  }
  EXPECT_EQ(far, 0u) << far << " of " << in.size() << " points moved more than " << slack
                     << " mm beyond their distance to the true surface; worst: point " << worst_i << " at ("
                     << in.positions[worst_i].transpose() << ") moved " << (out.positions[worst_i] - in.positions[worst_i]).norm()
                     << " mm to (" << out.positions[worst_i].transpose() << "), " << part.distance(out.positions[worst_i])
                     << " mm off the true surface";
}

// Fitting must not push points off the surface: each output point is within `tolerance` mm of the true
// surface, or at least no farther from it than its input point was.
inline void expectNoPointPushedOffTheSurface(const Cloud& in, const Cloud& out, double tolerance) {
  ASSERT_EQ(out.size(), in.size());
  const sim::PanPart part;
  std::size_t pushed = 0;
  double worst = 0;
  std::size_t worst_i = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const double d_in = part.distance(in.positions[i]), d_out = part.distance(out.positions[i]);
    if (d_out > std::max(tolerance, d_in)) ++pushed;
    if (d_out - d_in > worst) {
      worst = d_out - d_in;
      worst_i = i;
    }
  }
  EXPECT_EQ(pushed, 0u) << pushed << " of " << in.size() << " output points are more than " << tolerance
                        << " mm off the true surface and farther than their input point; worst: point " << worst_i
                        << " at (" << in.positions[worst_i].transpose() << "), "
                        << part.distance(in.positions[worst_i]) << " mm off, fitted to ("
                        << out.positions[worst_i].transpose() << "), " << part.distance(out.positions[worst_i])
                        << " mm off";
}

// A failed run: non-zero exit without a crash, and a one-line message on stderr naming `name`.
inline void expectCleanFailure(const RunResult& r, const std::string& name) {
  EXPECT_NE(r.exit_code, 0);
  EXPECT_LT(r.exit_code, 128) << "crashed (signal " << r.exit_code - 128 << ")";
  EXPECT_EQ(countLines(r.err), 1) << "stderr:\n" << r.err;
  EXPECT_NE(r.err.find(name), std::string::npos) << "message does not name " << name << ":\n" << r.err;
}

}  // namespace stampscan::station::test
