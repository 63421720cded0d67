// A triangle mesh of the fitted surface for viewing (surface nets on a sparse grid).
//
// The signed distance to the WLS surface is evaluated only at grid corners near the data, so holes
// in the data stay holes: no corner far from every point is evaluated and no face crosses the gap.
// Each mesh vertex is projected onto the WLS surface and carries the strain there.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <optional>
#include <utility>

namespace stampscan::fitting {

struct MeshParams {
  std::optional<double> cell_size;  // mm; default: half the median bandwidth
  // A corner is evaluated only when a data point lies within max(gap_factor * h, 2.5 cells) of it
  // (a cell through the surface has corners up to 1.7 cells from it);
  // a vertex is kept only within max(h / 2, 1 cell, half the local point spacing) of a data point.
  double gap_factor = 1.0;
  std::function<void(const std::string& stage, double fraction)> progress;
};

struct MeshStats {
  double cell_size = 0;
  std::size_t corners_evaluated = 0;
  std::size_t vertices = 0;
  std::size_t triangles = 0;
};

// Where the data behind a surface are: the mesh keeps to them (no face across a hole or past an edge).
class DataLocator {
 public:
  virtual ~DataLocator() = default;
  // The data point nearest to x and its squared distance; nullopt when there are no data.
  virtual std::optional<std::pair<Vec3, double>> nearest(const Vec3& x) const = 0;
  // The data's spacing at one of its points: the distance to its 16th neighbour.
  virtual double spacingAt(const Vec3& data_point) const = 0;
};

// `projected` seeds the grid cells: the surface's points where there are data (FittedSurface::projectAll,
// or the output points of a shape). `cell` > 0 in mm.
Mesh meshSurface(const ImplicitSurface& surface, const DataLocator& data, const Cloud& projected, double cell,
                 const MeshParams& params = {}, MeshStats* stats = nullptr);

// The same on one fitted cloud: its kd-tree says where the data are; the cell defaults to half the
// median data bandwidth.
Mesh meshSurface(const FittedSurface& fitted, const Cloud& projected, const MeshParams& params = {},
                 MeshStats* stats = nullptr);

// A fitted cloud's data, by its kd-tree.
class TreeLocator : public DataLocator {
 public:
  TreeLocator(const KdTree& tree, const std::vector<Vec3>& data_points) : tree_(tree), points_(data_points) {}
  std::optional<std::pair<Vec3, double>> nearest(const Vec3& x) const override;
  double spacingAt(const Vec3& data_point) const override;

 private:
  const KdTree& tree_;
  const std::vector<Vec3>& points_;
};

}  // namespace stampscan::fitting
