#pragma once

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace stampscan::registration {

// An ellipse as its centre and shape matrix M: the curve c + M (cos t, sin t), M symmetric and
// positive definite (its eigenvalues are the semi-axes, its eigenvectors their directions).
struct CentredEllipse {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Matrix2d shape = Eigen::Matrix2d::Identity();
};

// The direct least-squares ellipse through the points: Fitzgibbon, Pilu & Fisher's fit (the
// algebraic distance under the constraint 4ac - b^2 = 1), in Halir & Flusser's numerically stable
// form, in double precision. It is the fit cv::fitEllipseDirect makes; that one takes the points
// as floats and its matrices through the heap and LAPACK, some ten times the time, and the
// elements' measurement fits tens of thousands of ellipses a view. Empty for fewer than six
// points or points that no ellipse fits (a line, a hyperbola).
std::optional<CentredEllipse> fitDirectEllipse(const std::vector<Eigen::Vector2d>& points);

}  // namespace stampscan::registration
