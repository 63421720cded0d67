// The kd-tree against a brute-force oracle on seeded random clouds (with duplicates).
#include "stampscan/fitting/kdtree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace stampscan::fitting;

namespace {
std::vector<Vec3> randomCloud(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::vector<Vec3> pts;
  for (std::size_t i = 0; i < n; ++i) {
    pts.emplace_back(u(rng), u(rng), 0.1 * u(rng));
    if (i % 7 == 0) pts.push_back(pts.back());  // exact duplicates, as stereo data have
  }
  return pts;
}
}  // namespace

TEST(KdTree, KnnMatchesBruteForce) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const auto pts = randomCloud(3000, seed);
    const KdTree tree(pts);
    std::mt19937_64 rng(seed + 100);
    std::uniform_real_distribution<double> u(-12.0, 12.0);
    std::vector<Neighbor> found;
    for (int q = 0; q < 50; ++q) {
      const Vec3 x(u(rng), u(rng), 0.0);
      tree.knn(x, 16, found);
      std::vector<double> d;
      for (const Vec3& p : pts) d.push_back((p - x).squaredNorm());
      std::sort(d.begin(), d.end());
      ASSERT_EQ(found.size(), 16u) << "seed " << seed;
      for (std::size_t k = 0; k < 16; ++k) EXPECT_DOUBLE_EQ(found[k].distance_sq, d[k]) << "seed " << seed << " k " << k;
    }
  }
}

TEST(KdTree, RadiusMatchesBruteForce) {
  const auto pts = randomCloud(4000, 7);
  const KdTree tree(pts);
  std::vector<Neighbor> found;
  for (std::size_t q = 0; q < pts.size(); q += 97) {
    tree.radius(pts[q], 1.3, found, /*sorted=*/true);
    std::vector<std::uint32_t> expected;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if ((pts[i] - pts[q]).norm() <= 1.3) expected.push_back(static_cast<std::uint32_t>(i));
    std::vector<std::uint32_t> got;
    for (const Neighbor& nb : found) got.push_back(nb.index);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expected) << "query point " << q;
    EXPECT_TRUE(std::is_sorted(found.begin(), found.end(),
                               [](const Neighbor& a, const Neighbor& b) { return a.distance_sq < b.distance_sq; }));
  }
}

TEST(KdTree, SpatialOrderIsAPermutation) {
  const auto pts = randomCloud(1000, 9);
  const KdTree tree(pts);
  auto order = tree.spatialOrder();
  ASSERT_EQ(order.size(), pts.size());
  std::sort(order.begin(), order.end());
  for (std::size_t i = 0; i < order.size(); ++i) EXPECT_EQ(order[i], i);
}

TEST(KdTree, SmallAndEmptyClouds) {
  const std::vector<Vec3> empty;
  const KdTree none(empty);
  std::vector<Neighbor> found{{1, 1.0}};
  none.knn(Vec3::Zero(), 3, found);
  EXPECT_TRUE(found.empty());
  none.radius(Vec3::Zero(), 1.0, found);
  EXPECT_TRUE(found.empty());
  const std::vector<Vec3> two{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const KdTree tree(two);
  tree.knn(Vec3(0.9, 0, 0), 5, found);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].index, 1u);
}
