// A triangle mesh of the fitted surface for viewing (surface nets on a sparse grid).
//
// The signed distance to the WLS surface is evaluated only at grid corners near the data, so holes
// in the data stay holes: no corner far from every point is evaluated and no face crosses the gap.
// Each mesh vertex is projected onto the WLS surface and carries the strain there.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <optional>

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

// `projected` is the fitted cloud from FittedSurface::projectAll (it seeds the grid cells).
Mesh meshSurface(const FittedSurface& fitted, const Cloud& projected, const MeshParams& params = {},
                 MeshStats* stats = nullptr);

}  // namespace stampscan::fitting
