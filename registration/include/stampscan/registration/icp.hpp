// Point-to-plane ICP: aligns a source cloud to a target cloud with normals, from an initial pose.
// Used to refine the stereo views' known poses against each other and against the laser data.
//
// Each iteration pairs every source point with its nearest target point (kd-tree from fitting/),
// keeps pairs closer than the correspondence distance, weights them with Tukey's biweight on the
// point-to-plane residual (scale from the median absolute residual), and solves the linearised
// 6-DoF least-squares problem for a small rotation and translation (Chen & Medioni's error; the
// linearisation of Low, 2004). Parameters in, a value result out, as in Open3D.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <vector>

namespace stampscan::registration {

using fitting::Vec3;

struct IcpParams {
  int max_iterations = 80;
  // Pairs farther apart than this are ignored (mm). 0: 5 % of the target's bounding-box diagonal.
  double max_correspondence_distance = 0;
  // Stop when an iteration moves the source by less than this (rotation in rad, translation in the
  // units of the clouds relative to the target's diagonal).
  double rotation_tolerance = 1e-8;
  double translation_tolerance = 1e-8;
  bool robust = true;            // Tukey weights; plain least squares otherwise
  double tukey_constant = 4.685; // in units of the robust residual scale
  int normal_neighbours = 12;    // for target normals when none are given
  // Drop pairs whose target point lies more than this many target spacings to the side of the
  // source point (the source runs past the target's edge there).
  bool reject_boundary = true;
  double boundary_spacings = 3.0;
  // Weight of the pairs' offset along the target's surface, against the offset across it: 0 is
  // point-to-plane (dense surface samples, where the nearest target point is not the source point's
  // own), 1 is point-to-point. Sparse features that both clouds measured, such as grid elements,
  // pair one-to-one, and their offset along the surface is information as good as across it.
  double tangential_weight = 0;
};

struct IcpResult {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // target_from_source
  double rmse = 0;             // point-to-plane RMS of the inlier pairs at the end
  double fitness = 0;          // share of source points with a pair within the distance
  std::size_t pairs = 0;
  int iterations = 0;
  bool converged = false;
};

class PointToPlaneIcp {
 public:
  // The target is indexed once; its normals are estimated (local PCA) when `normals` is empty.
  // The target vectors must outlive this object.
  PointToPlaneIcp(const std::vector<Vec3>& target, std::vector<Vec3> normals = {});
  ~PointToPlaneIcp();

  IcpResult align(const std::vector<Vec3>& source, const Eigen::Isometry3d& initial,
                  const IcpParams& params = {}) const;
  double diagonal() const { return diagonal_; }
  double spacing() const { return spacing_; }  // median nearest-neighbour distance of the target
  const std::vector<Vec3>& normals() const { return normals_; }

 private:
  const std::vector<Vec3>& target_;
  std::vector<Vec3> normals_;
  std::unique_ptr<fitting::KdTree> tree_;
  double diagonal_ = 0;
  double spacing_ = 0;
};

}  // namespace stampscan::registration
