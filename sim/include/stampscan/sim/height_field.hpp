// Helpers for surfaces given as a height field z = h(x, y) over the machine's xy plane: the gradient
// by central differences and the closest surface point to any point in space.
#pragma once

#include <Eigen/Core>

#include <functional>

namespace stampscan::sim {

using HeightFunction = std::function<double(double, double)>;

// Central-difference gradient; the step keeps the truncation error near 1e-10 for smooth fields.
Eigen::Vector2d heightGradient(const HeightFunction& height, double x, double y);

// The point (u, v, h(u, v)) closest to p, by Levenberg-Marquardt from the point below p.
Eigen::Vector3d closestPointOnHeightField(const HeightFunction& height, const Eigen::Vector3d& p);

}  // namespace stampscan::sim
