// A 3D kd-tree over a cloud's positions, built with nanoflann on our own storage (no copy).
//
// Thread safety: queries are const and may run concurrently from many threads; building is not.
// The indexed vector must outlive the tree and must not change while the tree exists.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace stampscan::fitting {

struct Neighbor {
  std::uint32_t index;
  double distance_sq;
};

class KdTree {
 public:
  explicit KdTree(const std::vector<Vec3>& points);
  ~KdTree();
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  std::size_t size() const;

  // The k nearest points to `query`, nearest first (fewer when the cloud is smaller). `out` is
  // cleared first; its capacity is reused, so one vector can serve many queries.
  void knn(const Vec3& query, std::size_t k, std::vector<Neighbor>& out) const;

  // Every point within `radius` of `query` (inclusive), in no particular order unless `sorted`.
  void radius(const Vec3& query, double radius, std::vector<Neighbor>& out, bool sorted = false) const;

  // The index order of the tree's leaves: consecutive entries are spatially close. Processing points
  // in this order keeps caches warm.
  std::vector<std::uint32_t> spatialOrder() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::fitting
