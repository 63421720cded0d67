// Automatic bandwidths: r-th neighbour distances (Eqs. (8)-(9)), Eq. (12), Shepard's interpolant
// (Eqs. (9), (13), (14)) and the density-robust scale.
#include "stampscan/fitting/bandwidth.hpp"
#include "stampscan/fitting/kernels.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace stampscan::fitting;

namespace {
// Regular grid of pitch p in the z = 0 plane, each site repeated `copies` times (exactly).
std::vector<Vec3> grid(int n, double pitch, int copies) {
  std::vector<Vec3> pts;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < copies; ++k) pts.emplace_back(i * pitch, j * pitch, 0.0);
  return pts;
}
}  // namespace

TEST(Bandwidth, RthNeighbourDistanceSeesDuplicates) {
  const auto single = grid(10, 2.54, 1);
  const KdTree t1(single);
  const auto d1 = rthNeighborDistances(single, t1, 1);
  EXPECT_NEAR(d1[55], 2.54, 1e-12);
  // With three coincident copies, r = 1 and r = 2 stop at a copy; r = 3 reaches the next site.
  const auto triple = grid(10, 2.54, 3);
  const KdTree t3(triple);
  EXPECT_NEAR(rthNeighborDistances(triple, t3, 2)[165], 0.0, 1e-12);
  EXPECT_NEAR(rthNeighborDistances(triple, t3, 3)[165], 2.54, 1e-12);
}

TEST(Bandwidth, GaussianDataBandwidthEq12MatchesDirectSum) {
  const auto pts = grid(12, 1.0, 1);
  const KdTree tree(pts);
  const double h0 = 1.7;
  const auto h = gaussianDataBandwidths(pts, tree, h0);
  for (std::size_t i : {0u, 30u, 77u}) {
    double sw = 0, swd = 0;
    for (std::size_t j = 0; j < pts.size(); ++j) {
      if (j == i) continue;
      const double d = (pts[i] - pts[j]).norm();
      if (d > kGaussianCutoff * h0) continue;
      const double w = std::exp(-d * d / (h0 * h0));
      sw += w;
      swd += w * d;
    }
    EXPECT_NEAR(h[i], swd / sw, 1e-12) << "point " << i;
  }
}

TEST(Bandwidth, ShepardFieldIsSmoothAndBounded) {
  // Two regions with h = 1 and h = 3: the interpolant stays within [1, 3], keeps each region's value
  // well inside it, and crosses the boundary without jumps.
  std::vector<Vec3> pts;
  std::vector<double> values;
  for (int i = -20; i <= 20; ++i)
    for (int j = -5; j <= 5; ++j) {
      pts.emplace_back(i * 0.5, j * 0.5, 0.0);
      values.push_back(i < 0 ? 1.0 : 3.0);
    }
  const KdTree tree(pts);
  const BandwidthField field(pts, tree, values);
  EXPECT_NEAR(field.at(Vec3(-8, 0, 0)), 1.0, 1e-9);
  EXPECT_NEAR(field.at(Vec3(8, 0, 0)), 3.0, 1e-9);
  double previous = field.at(Vec3(-3.05, 0.1, 0));
  for (double x = -3; x <= 3; x += 0.05) {
    const double h = field.at(Vec3(x, 0.1, 0));
    EXPECT_GE(h, 1.0 - 1e-12);
    EXPECT_LE(h, 3.0 + 1e-12);
    EXPECT_LT(std::abs(h - previous), 0.25) << "x " << x;
    previous = h;
  }
  EXPECT_LT(field.at(Vec3(-2, 0, 0)), field.at(Vec3(0, 0, 0)));
  EXPECT_LT(field.at(Vec3(0, 0, 0)), field.at(Vec3(2, 0, 0)));
}

TEST(Bandwidth, RobustScaleIgnoresStereoRepeats) {
  // Stereo data repeat a grid element up to 12 times; the default scale must not shrink for it.
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<int> copies(1, 12);
  std::vector<Vec3> repeated;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      const int m = copies(rng);
      for (int k = 0; k < m; ++k) repeated.emplace_back(i * 2.54, j * 2.54, 0.001 * k);
    }
  const KdTree tr(repeated);
  const auto hr = summarize(robustScales(repeated, tr, {})).min;
  // The nearest-neighbour distance collapses onto the repeats; the robust scale stays wider than
  // a grid pitch everywhere, so every fit spans several distinct elements.
  EXPECT_LT(summarize(rthNeighborDistances(repeated, tr, 1)).median, 0.01);
  EXPECT_GT(hr, 1.2 * 2.54);
}
