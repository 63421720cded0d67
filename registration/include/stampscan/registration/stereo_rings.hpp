// The stereo path: printed circles in the camera images, matched between the left and right image,
// triangulated, and measured in 3D.
//
//  1. In each image, ring interiors as in the laser path (ink against a grey closing, convex bright
//     regions of the expected size), and the printed line's centre to sub-pixel precision along
//     rays from them (the darkest point of the dip: the optics' blur leaves it in place, where it
//     moves the half-level edge of a line only two or three pixels wide).
//  2. Matching: the grid repeats every pitch, so the epipolar line alone is ambiguous (one pitch
//     along it is a few millimetres of depth). A depth prior resolves it: the laser's surface when
//     the trace has one, projected into the left image; the right ring must then lie where the
//     prior puts it, within a fraction of the pitch, and on the epipolar line.
//  3. The ring's centre triangulated (midpoint of the two rays); the surface around it from the
//     triangulated neighbours (a quadric height field); both images' line points cast onto that
//     surface, taken into its tangent plane, and one robust ellipse fitted to them; strains from
//     its axes.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_rings.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <vector>

namespace stampscan::registration {

// A ring's printed line as the image shows it: the line's centre along 360 rays from the ring's
// interior (pixel coordinates, distortion not removed).
struct ImageRing {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // of the line points
  std::vector<Eigen::Vector2d> edge;
};

// `expected_radius_px` is an unstrained ring's radius in pixels at the working distance.
std::vector<ImageRing> detectImageRings(const cv::Mat& image, double expected_radius_px, const RingDetectionParams& params);

struct StereoRig {
  CameraModel left, right;
  Eigen::Isometry3d head_from_left = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d right_from_left = Eigen::Isometry3d::Identity();
};

struct StereoStats {
  std::size_t left_rings = 0, right_rings = 0, without_prior = 0, unmatched = 0, matched = 0, rejected_fit = 0;
};

// One stereo pair taken with the head at `machine_from_head`. `prior` holds points of the part's
// surface (machine frame) to resolve the matching; without it nothing can be matched.
std::vector<GridElement> measureStereoPair(const cv::Mat& left, const cv::Mat& right, const StereoRig& rig,
                                           const Eigen::Isometry3d& machine_from_head, const std::vector<Vec3>& prior,
                                           const RingDetectionParams& params, std::uint32_t view,
                                           StereoStats* stats = nullptr);

}  // namespace stampscan::registration
