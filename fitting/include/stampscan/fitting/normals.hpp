// Normals at the data points: the paper's weighted covariance (Eqs. (6), (7)) evaluated at each
// P_i, and a consistent orientation, either towards the sensor side or propagated over a neighbour
// graph (Hoppe et al.: a minimum spanning tree on 1 - |n_i . n_j|, so the sign travels along the
// flattest paths first and crosses creases last).
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace stampscan::fitting {

using Vec3f = Eigen::Vector3f;

// Up to this many graph neighbours per point are kept for propagating orientation.
inline constexpr int kOrientationNeighbors = 6;

struct PointNormals {
  std::vector<Vec3f> normals;  // unit, one per point
  // Orientation graph: for point i, entries [i*K, i*K+K) hold neighbour indices, unused ones = i.
  std::vector<std::uint32_t> graph;
};

// Weighted-covariance normals with a Gaussian of per-point bandwidth h[i] around each P_i. The graph
// links each point to nearby points that are not near-duplicates of it (farther than h/4 where
// possible), so clusters of repeated stereo observations stay connected to the rest of the part.
PointNormals estimateNormals(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>& h);

enum class OrientationMode {
  Propagate,         // spanning tree over the graph; each connected piece faces `direction` on average
  TowardsViewpoint,  // n . (viewpoint - p) > 0
  TowardsDirection,  // n . direction > 0
};

struct OrientationParams {
  OrientationMode mode = OrientationMode::Propagate;
  Vec3 viewpoint = Vec3::Zero();
  Vec3 direction = Vec3::UnitZ();  // the scanners look at the part from +z in the machine frame
};

struct OrientationReport {
  std::size_t components = 0;  // connected pieces of the graph (Propagate only)
  std::size_t flipped = 0;     // normals whose sign was changed
};

OrientationReport orientNormals(const std::vector<Vec3>& points, PointNormals& normals, const OrientationParams& params);

}  // namespace stampscan::fitting
