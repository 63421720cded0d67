// The default fit on real scanner data: the two partial scans of a hippo from CGAL's data (Debian's
// libcgal-demo), which carry the scanner's own normals. Nobody here tuned anything to them; they
// check that the method holds on data it was not built on: every projection converges, the fitted
// normals agree with the scan's, and the points move by about the scan's noise, not more.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

using namespace stampscan::fitting;

namespace {
double quantile(std::vector<double> v, double q) {
  const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}
}  // namespace

class RealScan : public ::testing::TestWithParam<const char*> {};

TEST_P(RealScan, ConvergesKeepsTheScannersNormalsAndMovesLittle) {
  const std::filesystem::path file = std::filesystem::path(STAMPSCAN_HIPPO_DIR) / GetParam();
  if (!std::filesystem::exists(file))
    GTEST_SKIP() << file << " not found (install Debian's libcgal-demo, which ships the hippo scans)";
  const Cloud scan = readPly(file);
  ASSERT_TRUE(scan.hasNormals());
  const FitResult r = fitSurface(scan);
  ASSERT_EQ(r.surface.size(), scan.size());
  std::vector<double> agreement, moved;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    agreement.push_back(std::abs(r.surface.normals[i].dot(scan.normals[i].normalized())));
    moved.push_back((r.surface.positions[i] - scan.positions[i]).norm());
  }
  const Bounds b = boundsOf(scan.positions);
  const double diagonal = (b.max - b.min).norm();
  std::printf("%s: %zu points, not converged %zu, normals |cos| median %.4f, 5th percentile %.4f; moved median %.5f, "
              "95th percentile %.5f (diagonal %.3f, median h %.4f)\n",
              GetParam(), scan.size(), r.stats.not_converged, quantile(agreement, 0.5), quantile(agreement, 0.05),
              quantile(moved, 0.5), quantile(moved, 0.95), diagonal, r.stats.bandwidth.median);
  EXPECT_LE(r.stats.not_converged, scan.size() / 1000);  // under 0.1 %
  EXPECT_GT(quantile(agreement, 0.5), 0.98);
  EXPECT_GT(quantile(agreement, 0.05), 0.8);
  // The scan's noise is a small fraction of the bandwidth; a fit that moves points by more than a
  // bandwidth is not smoothing but reshaping.
  EXPECT_LT(quantile(moved, 0.95), r.stats.bandwidth.median);
}

INSTANTIATE_TEST_SUITE_P(Hippo, RealScan, ::testing::Values("hippo1.ply", "hippo2.ply"),
                         [](const ::testing::TestParamInfo<const char*>& param) { return std::string(param.param).substr(0, 6); });
