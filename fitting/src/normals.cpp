#include "stampscan/fitting/normals.hpp"

#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/local_fit.hpp"

#include "spanning_orientation.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace stampscan::fitting {

PointNormals estimateNormals(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>& h) {
  const std::size_t n = points.size();
  constexpr std::size_t K = kOrientationNeighbors;
  PointNormals result;
  result.normals.assign(n, Vec3f::UnitZ());
  result.graph.assign(n * K, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512), [&](const tbb::blocked_range<std::size_t>& range) {
    std::vector<Neighbor> near;
    std::vector<Neighbor> candidates;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const double hi = h[i];
      tree.radius(points[i], kGaussianCutoff * hi, near);
      WeightedSums sums(points[i], hi);
      const double h_sq = hi * hi;
      for (const Neighbor& nb : near) sums.add(points[nb.index], gaussianWeightSq(nb.distance_sq, h_sq));  // Eq. (6)
      const auto plane = LocalSurface::fitPlane(sums);                                               // Eq. (7)
      if (plane) result.normals[i] = plane->normal(points[i]).cast<float>();

      // Graph neighbours: nearest points beyond a quarter bandwidth, else the nearest ones at all.
      candidates.clear();
      const double min_sq = 0.0625 * h_sq;
      for (const Neighbor& nb : near)
        if (nb.index != i && nb.distance_sq >= min_sq) candidates.push_back(nb);
      if (candidates.size() < K)
        for (const Neighbor& nb : near)
          if (nb.index != i && nb.distance_sq < min_sq) candidates.push_back(nb);
      const auto by_distance = [](const Neighbor& a, const Neighbor& b) {
        return a.distance_sq < b.distance_sq || (a.distance_sq == b.distance_sq && a.index < b.index);
      };
      const std::size_t take = std::min(K, candidates.size());
      std::partial_sort(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(take), candidates.end(),
                        by_distance);
      for (std::size_t k = 0; k < K; ++k)
        result.graph[i * K + k] = k < take ? candidates[k].index : static_cast<std::uint32_t>(i);
    }
  });
  return result;
}

namespace {
OrientationReport propagate(const std::vector<Vec3>& points, PointNormals& pn, const Vec3& direction) {
  constexpr std::size_t K = kOrientationNeighbors;
  const std::size_t n = points.size();
  OrientationReport report;
  // Symmetric adjacency: the stored graph is directed (i lists its neighbours), so add reverse edges.
  std::vector<std::uint32_t> degree(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < K; ++k) {
      const std::uint32_t j = pn.graph[i * K + k];
      if (j != i) {
        ++degree[i + 1];
        ++degree[j + 1];
      }
    }
  std::vector<std::size_t> offset(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) offset[i + 1] = offset[i] + degree[i + 1];
  std::vector<std::uint32_t> adjacency(offset[n]);
  std::vector<std::size_t> fill(offset.begin(), offset.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < K; ++k) {
      const std::uint32_t j = pn.graph[i * K + k];
      if (j != i) {
        adjacency[fill[i]++] = j;
        adjacency[fill[j]++] = static_cast<std::uint32_t>(i);
      }
    }
  std::vector<std::uint32_t>().swap(pn.graph);

  const Vec3 dir = direction.normalized();
  report.components = detail::orientOverGraph(
      pn.normals, offset, adjacency, adjacency.size(), nullptr, [&](std::uint32_t) { return dir; },
      [&](std::uint32_t) { ++report.flipped; });
  return report;
}
}  // namespace

OrientationReport orientNormals(const std::vector<Vec3>& points, PointNormals& pn, const OrientationParams& params) {
  if (params.mode == OrientationMode::Propagate) return propagate(points, pn, params.direction);
  OrientationReport report;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 towards = params.mode == OrientationMode::TowardsViewpoint ? Vec3(params.viewpoint - points[i])
                                                                          : params.direction;
    if (pn.normals[i].cast<double>().dot(towards) < 0) {
      pn.normals[i] = -pn.normals[i];
      ++report.flipped;
    }
  }
  return report;
}

}  // namespace stampscan::fitting
