// The r-SIG of Eq. (8), its pruning, and graph distances.
#include "stampscan/fitting/sig_graph.hpp"

#include <gtest/gtest.h>

#include <queue>
#include <random>

using namespace stampscan::fitting;

namespace {
std::size_t components(const SigGraph& g) {
  std::vector<int> seen(g.vertexCount(), 0);
  std::size_t count = 0;
  for (std::size_t s = 0; s < g.vertexCount(); ++s) {
    if (seen[s]) continue;
    ++count;
    std::queue<std::size_t> q;
    q.push(s);
    seen[s] = 1;
    while (!q.empty()) {
      const std::size_t v = q.front();
      q.pop();
      for (const auto* e = g.begin(v); e != g.end(v); ++e)
        if (!seen[e->to]) {
          seen[e->to] = 1;
          q.push(e->to);
        }
    }
  }
  return count;
}
}  // namespace

TEST(SigGraph, Eq8MatchesBruteForce) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::vector<Vec3> pts;
  for (int i = 0; i < 400; ++i) pts.emplace_back(u(rng), u(rng), 0.05 * u(rng));
  const KdTree tree(pts);
  for (int r : {1, 3, 7}) {
    SigParams params;
    params.r = r;
    params.prune_factor = 0;
    const SigGraph g = SigGraph::build(pts, tree, params);
    const auto& d = g.sphereRadii();
    std::size_t expected_edges = 0;
    for (std::size_t i = 0; i < pts.size(); ++i)
      for (std::size_t j = i + 1; j < pts.size(); ++j) {
        const bool edge = (pts[i] - pts[j]).norm() <= d[i] + d[j];
        expected_edges += edge;
        ASSERT_EQ(g.connected(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)), edge)
            << "r " << r << " pair " << i << "," << j;
      }
    EXPECT_EQ(g.edgeCount(), expected_edges) << "r " << r;
  }
}

TEST(SigGraph, RepeatsDisconnectSmallR) {
  // Paper Fig. 4: with repeated points and r = 1 only the copies connect; r above the number of
  // repeats connects the grid.
  std::vector<Vec3> pts;
  for (int i = 0; i < 15; ++i)
    for (int j = 0; j < 15; ++j)
      for (int k = 0; k < 4; ++k) pts.emplace_back(i * 2.54, j * 2.54, 0.0);
  const KdTree tree(pts);
  SigParams small;
  small.r = 1;
  EXPECT_EQ(components(SigGraph::build(pts, tree, small)), 15u * 15u);
  SigParams large;
  large.r = 7;
  EXPECT_EQ(components(SigGraph::build(pts, tree, large)), 1u);
}

TEST(SigGraph, PruningDropsOverlyLongEdges) {
  // A dense patch and a sparse far-away pair: the pair's huge spheres reach into the patch.
  std::vector<Vec3> pts;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) pts.emplace_back(i * 0.5, j * 0.5, 0.0);
  pts.emplace_back(30.0, 0.0, 0.0);
  pts.emplace_back(60.0, 0.0, 0.0);
  const KdTree tree(pts);
  SigParams params;
  params.r = 3;
  params.prune_factor = 0;
  const SigGraph unpruned = SigGraph::build(pts, tree, params);
  params.prune_factor = 2.5;
  const SigGraph pruned = SigGraph::build(pts, tree, params);
  EXPECT_GT(pruned.prunedEdgeCount(), 0u);
  EXPECT_EQ(unpruned.edgeCount() - pruned.edgeCount(), pruned.prunedEdgeCount());
  // No edge from the patch to the far points survives, and the patch stays connected.
  for (std::uint32_t i = 0; i < 100; ++i) EXPECT_FALSE(pruned.connected(i, 100)) << i;
  for (std::uint32_t i = 0; i < 99; ++i) EXPECT_GT(pruned.degree(i), 0u);
}

TEST(SigGraph, GraphDistancesFollowPaths) {
  std::vector<Vec3> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(i * 1.0, 0.0, 0.0);
  const KdTree tree(line);
  SigParams params;
  params.r = 1;
  const SigGraph g = SigGraph::build(line, tree, params);
  std::vector<SigGraph::Reached> reached;
  g.distancesFrom(5, 3.5, reached);
  ASSERT_EQ(reached.size(), 7u);  // 5 itself, 2..4 and 6..8
  for (const auto& r : reached) EXPECT_NEAR(r.distance, std::abs(static_cast<double>(r.vertex) - 5.0), 1e-6);
  EXPECT_EQ(reached.front().vertex, 5u);
}
