// Consistent orientation of normals over a neighbour graph (a private part of fitting/), shared by
// the point normals and the anchors of the default fit. After Hoppe et al.: Prim's spanning tree on
// 1 - |n_i . n_j|, so that the sign travels along the flattest paths first and crosses creases last;
// each connected piece then faces the sensor side on average.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <cstdint>
#include <queue>
#include <utility>
#include <vector>

namespace stampscan::fitting::detail {

// `normals[v]` for each vertex (any Eigen 3-vector type); the graph in compressed rows: the
// neighbours of v are targets[offsets[v] .. offsets[v + 1]), of which at most `max_degree` are used.
// Vertices with usable[v] == 0 (when given) are left out. `towards(v)` is the direction vertex v
// should face. Returns the number of connected pieces; `flip(v)` is called for every vertex whose
// sign must change (normals are updated in place too).
template <class Normal, class Towards, class Flip>
std::size_t orientOverGraph(std::vector<Normal>& normals, const std::vector<std::size_t>& offsets,
                            const std::vector<std::uint32_t>& targets, std::size_t max_degree,
                            const std::vector<std::uint8_t>* usable, Towards&& towards, Flip&& flip) {
  const std::size_t n = normals.size();
  std::vector<std::uint8_t> done(n, 0);
  std::vector<std::uint32_t> members;
  using Item = std::pair<double, std::uint32_t>;  // (alignment, vertex): best aligned first
  std::priority_queue<Item> queue;
  std::size_t components = 0;
  const auto ok = [&](std::size_t v) { return !usable || (*usable)[v]; };
  const auto turn = [&](std::uint32_t v) {
    normals[v] = -normals[v];
    flip(v);
  };
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (done[seed] || !ok(seed)) continue;
    ++components;
    members.clear();
    queue.push({2.0, static_cast<std::uint32_t>(seed)});
    while (!queue.empty()) {
      const std::uint32_t v = queue.top().second;
      queue.pop();
      if (done[v]) continue;
      done[v] = 1;
      members.push_back(v);
      const std::size_t last = std::min(offsets[v + 1], offsets[v] + max_degree);
      for (std::size_t e = offsets[v]; e < last; ++e) {
        const std::uint32_t w = targets[e];
        if (w == v || done[w] || !ok(w)) continue;
        // w takes the sign of the settled neighbour that reaches it; settled neighbours agree
        // with each other away from creases.
        double dot = static_cast<double>(normals[v].dot(normals[w]));
        if (dot < 0) {
          turn(w);
          dot = -dot;
        }
        queue.push({dot, w});
      }
    }
    // The tree fixes signs relative to the seed; make the piece face the sensor side on average.
    double facing = 0;
    for (std::uint32_t v : members) facing += normals[v].template cast<double>().dot(towards(v));
    if (facing < 0)
      for (std::uint32_t v : members) turn(v);
  }
  return components;
}

}  // namespace stampscan::fitting::detail
