// The r-th order sphere-of-influence graph (r-SIG) of Klein, Eq. (8), with deterministic pruning of
// overly long edges, and graph distances for the graph-distance kernel (paper Sec. 3.3).
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <cstdint>
#include <vector>

namespace stampscan::fitting {

struct SigParams {
  int r = 7;  // the r-th nearest neighbour; the paper finds 3..7 common, 7 needed for stereo duplicates
  // Deterministic stand-in for Klein's stochastic pruning: an edge is dropped when it is longer
  // than prune_factor times the median edge length at either of its ends (so a point far from the
  // rest, whose own edges are all long, loses them). 0 disables pruning.
  double prune_factor = 2.5;
};

// Undirected graph in compressed sparse row form.
class SigGraph {
 public:
  static SigGraph build(const std::vector<Vec3>& points, const KdTree& tree, const SigParams& params = {});

  std::size_t vertexCount() const { return offsets_.empty() ? 0 : offsets_.size() - 1; }
  std::size_t edgeCount() const { return targets_.size() / 2; }
  std::size_t prunedEdgeCount() const { return pruned_; }
  // Neighbours of vertex i and the lengths of the edges to them.
  struct Edge {
    std::uint32_t to;
    float length;
  };
  const Edge* begin(std::size_t i) const { return targets_.data() + offsets_[i]; }
  const Edge* end(std::size_t i) const { return targets_.data() + offsets_[i + 1]; }
  std::size_t degree(std::size_t i) const { return offsets_[i + 1] - offsets_[i]; }
  bool connected(std::uint32_t a, std::uint32_t b) const;

  // d_i of Eq. (8): the r-th nearest neighbour distance of each point.
  const std::vector<double>& sphereRadii() const { return radii_; }

  // Shortest-path distances from `source` to every vertex reachable within `max_distance`
  // (Dijkstra, bounded). Returns pairs (vertex, distance), source first.
  struct Reached {
    std::uint32_t vertex;
    double distance;
  };
  void distancesFrom(std::uint32_t source, double max_distance, std::vector<Reached>& out) const;

 private:
  std::vector<std::size_t> offsets_;
  std::vector<Edge> targets_;
  std::vector<double> radii_;
  std::size_t pruned_ = 0;
};

}  // namespace stampscan::fitting
