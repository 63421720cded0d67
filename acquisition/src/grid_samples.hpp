// The grid area of a nominal model as samples, for planning and predicting (part_planner.cpp,
// coverage_prediction.cpp): private to the planner's library.
#pragma once

#include "stampscan/acquisition/nominal_model.hpp"

#include <Eigen/Core>

#include <vector>

namespace stampscan::acquisition {

// Each facet facing the sensors' side (its normal's z at least min_normal_z) split into k x k
// sub-triangles no wider than the spacing, one sample at each one's centroid standing for its area.
struct GridSamples {
  std::vector<Eigen::Vector3d> points, normals;
  std::vector<double> area;
};
GridSamples sampleGridArea(const NominalModel& model, double spacing, double min_normal_z);

// One sample per cube of `spacing` (the one standing for the most area, carrying the cube's area): a
// finely tessellated model gives a sample per facet however small, more than planning needs.
GridSamples thinned(const GridSamples& samples, double spacing);

}  // namespace stampscan::acquisition
