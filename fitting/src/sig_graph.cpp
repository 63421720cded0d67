#include "stampscan/fitting/sig_graph.hpp"

#include "stampscan/fitting/bandwidth.hpp"
#include "stampscan/fitting/median.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

namespace stampscan::fitting {

namespace {
}  // namespace

SigGraph SigGraph::build(const std::vector<Vec3>& points, const KdTree& tree, const SigParams& params) {
  SigGraph g;
  const std::size_t n = points.size();
  g.radii_ = rthNeighborDistances(points, tree, params.r);

  // Eq. (8): i and j are adjacent when |Pi - Pj| <= d_i + d_j. Since d_i + d_j <= 2 max(d_i, d_j),
  // the end with the larger sphere finds the edge by searching 2 d within its own radius; each point
  // records the edges it finds towards points with a smaller (or equal, higher-index) sphere.
  std::vector<std::vector<Edge>> found(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512), [&](const tbb::blocked_range<std::size_t>& range) {
    std::vector<Neighbor> near;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const double di = g.radii_[i];
      tree.radius(points[i], 2.0 * di, near, /*sorted=*/true);
      for (const Neighbor& nb : near) {
        const std::size_t j = nb.index;
        if (j == i) continue;
        const double dj = g.radii_[j];
        const bool owner = dj < di || (dj == di && j > i);
        if (!owner) continue;
        const double len = std::sqrt(nb.distance_sq);
        if (len <= di + dj) found[i].push_back({static_cast<std::uint32_t>(j), static_cast<float>(len)});
      }
    }
  });

  // Median incident edge length per vertex, for pruning.
  std::vector<std::vector<Edge>> adjacency(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (const Edge& e : found[i]) {
      adjacency[i].push_back(e);
      adjacency[e.to].push_back({static_cast<std::uint32_t>(i), e.length});
    }
    std::vector<Edge>().swap(found[i]);
  }
  std::vector<double> med(n, 0.0);
  if (params.prune_factor > 0) {
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      std::vector<float> lengths;
      lengths.reserve(adjacency[i].size());
      for (const Edge& e : adjacency[i]) lengths.push_back(e.length);
      med[i] = lengths.empty() ? 0.0 : medianInPlace(lengths);
    });
  }

  g.offsets_.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    auto& edges = adjacency[i];
    if (params.prune_factor > 0) {
      const auto keep_end = std::remove_if(edges.begin(), edges.end(), [&](const Edge& e) {
        return e.length > params.prune_factor * std::min(med[i], med[e.to]);
      });
      g.pruned_ += static_cast<std::size_t>(edges.end() - keep_end);
      edges.erase(keep_end, edges.end());
    }
    std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) { return a.to < b.to; });
    g.offsets_[i + 1] = g.offsets_[i] + edges.size();
  }
  g.pruned_ /= 2;  // each pruned edge was seen from both ends
  g.targets_.reserve(g.offsets_[n]);
  for (auto& edges : adjacency) g.targets_.insert(g.targets_.end(), edges.begin(), edges.end());
  return g;
}

bool SigGraph::connected(std::uint32_t a, std::uint32_t b) const {
  return std::binary_search(begin(a), end(a), Edge{b, 0.f}, [](const Edge& x, const Edge& y) { return x.to < y.to; });
}

void SigGraph::distancesFrom(std::uint32_t source, double max_distance, std::vector<Reached>& out) const {
  out.clear();
  struct State {
    double distance;
    bool settled;
  };
  std::unordered_map<std::uint32_t, State> best;
  using Item = std::pair<double, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  best[source] = {0.0, false};
  queue.push({0.0, source});
  while (!queue.empty()) {
    const auto [dist, v] = queue.top();
    queue.pop();
    State& state = best[v];
    if (state.settled || dist > state.distance) continue;
    state.settled = true;
    out.push_back({v, dist});
    for (const Edge* e = begin(v); e != end(v); ++e) {
      const double nd = dist + e->length;
      if (nd > max_distance) continue;
      auto [it, inserted] = best.try_emplace(e->to, State{nd, false});
      if (inserted || (!it->second.settled && nd < it->second.distance)) {
        it->second.distance = nd;
        queue.push({nd, e->to});
      }
    }
  }
}

}  // namespace stampscan::fitting
