#include "stampscan/fitting/kdtree.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace stampscan::fitting {

namespace {
// nanoflann's dataset adaptor: answers point count and coordinates straight from our storage.
struct PositionsAdaptor {
  const std::vector<Vec3>& points;
  std::size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(std::size_t i, std::size_t dim) const { return points[i][static_cast<Eigen::Index>(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PositionsAdaptor>,
                                                 PositionsAdaptor, 3, std::uint32_t>;

// Result set that appends every point within the radius straight into our Neighbor vector.
class RadiusCollector {
 public:
  RadiusCollector(double radius_sq, std::vector<Neighbor>& out)
      : radius_sq_(radius_sq), worst_(std::nextafter(radius_sq, std::numeric_limits<double>::infinity())), out_(out) {}
  void init() { out_.clear(); }
  void clear() { out_.clear(); }
  std::size_t size() const { return out_.size(); }
  bool full() const { return true; }
  bool addPoint(double dist_sq, std::uint32_t index) {
    if (dist_sq <= radius_sq_) out_.push_back({index, dist_sq});
    return true;
  }
  // nanoflann keeps a point only if it is strictly closer than worstDist(); report a hair more so
  // that points exactly on the radius (coincident points at radius 0) are kept.
  double worstDist() const { return worst_; }

 private:
  double radius_sq_;
  double worst_;  // asked for at every node of the search
  std::vector<Neighbor>& out_;
};
}  // namespace

struct KdTree::Impl {
  explicit Impl(const std::vector<Vec3>& points)
      : adaptor{points}, tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {
    tree.buildIndex();
  }
  PositionsAdaptor adaptor;
  Tree tree;
};

KdTree::KdTree(const std::vector<Vec3>& points) : impl_(std::make_unique<Impl>(points)) {}
KdTree::~KdTree() = default;

std::size_t KdTree::size() const { return impl_->adaptor.points.size(); }

void KdTree::knn(const Vec3& query, std::size_t k, std::vector<Neighbor>& out) const {
  out.clear();
  const std::size_t n = std::min(k, size());
  if (n == 0) return;
  thread_local std::vector<std::uint32_t> indices;
  thread_local std::vector<double> dist_sq;
  indices.resize(n);
  dist_sq.resize(n);
  nanoflann::KNNResultSet<double, std::uint32_t> result(n);
  result.init(indices.data(), dist_sq.data());
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  const std::size_t found = result.size();
  out.resize(found);
  for (std::size_t i = 0; i < found; ++i) out[i] = {indices[i], dist_sq[i]};
}

void KdTree::radius(const Vec3& query, double radius, std::vector<Neighbor>& out, bool sorted) const {
  RadiusCollector collector(radius * radius, out);
  collector.init();
  if (size() == 0) return;
  impl_->tree.findNeighbors(collector, query.data(), nanoflann::SearchParams());
  if (sorted) {
    std::sort(out.begin(), out.end(), [](const Neighbor& a, const Neighbor& b) {
      return a.distance_sq < b.distance_sq || (a.distance_sq == b.distance_sq && a.index < b.index);
    });
  }
}

std::vector<std::uint32_t> KdTree::spatialOrder() const {
  // nanoflann keeps its permutation of point indices in leaf order.
  return std::vector<std::uint32_t>(impl_->tree.vAcc.begin(), impl_->tree.vAcc.end());
}

}  // namespace stampscan::fitting
