// The stereo path: printed circles in the camera images, matched between the left and right image,
// triangulated, and measured in 3D.
//
//  1. In each image, ring interiors as in the laser path (ink against a grey closing, convex bright
//     regions of the expected size) and a first ellipse from the line's half-level crossings on
//     rays from them. Then the line's centre by fitting a model of the blurred line to the pixels
//     along it (see image_line_fit.hpp): the half-level edge of a line only two or three pixels
//     wide moves with the blur, the centre of its symmetric profile does not.
//  2. Matching: the grid repeats every pitch, so the epipolar line alone is ambiguous (one pitch
//     along it is about 6 mm of depth). A depth prior resolves it: the laser's surface when the
//     trace has one, projected into the left image, with a plane through it at each ring; the
//     right ring is the one nearest where the prior puts it, within half a pitch, among those on
//     the epipolar line.
//  3. Each ring's plane from both views: the plane on which the two images' lines, cast onto it,
//     become one ellipse (its depth shows in where the two cast ellipses sit, its tilt across the
//     baseline in their different foreshortening; the tilt along the baseline barely shows and
//     stays near the plane of the triangulated neighbours). Views that disagree by more than 1 %
//     of the ring (more where a camera sees the plane obliquely) give no element, and so does a
//     ring whose sagitta on the sheet (its curvature from the neighbours' centres) exceeds 0.06 mm:
//     a ring bent over a tight radius is no plane. Then one robust ellipse through the cast points (of the better
//     view only, when the other sees the ring much more obliquely), and strains from its axes.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_rings.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <optional>
#include <vector>

namespace stampscan::registration {

// A ring's printed line as the image shows it: its fitted centre line, centre + M (cos t, sin t)
// moved along the normal by the third harmonic a cos 3t + b sin 3t (pixel coordinates, distortion
// not removed), and what the fit saw of the line. A few numbers each: a scan keeps every view's
// rings from their images' arrival to their matching.
struct ImageRing {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // of the fitted ellipse
  Eigen::Matrix2d shape = Eigen::Matrix2d::Identity();  // M, symmetric
  Eigen::Vector2d third = Eigen::Vector2d::Zero();      // (a, b), px
  double blur = 0;      // px: the line profile's Gaussian width (optics and pixel)
  double contrast = 0;  // share of the sheet's light the ink takes
  double rms = 0;       // of the fit, as a share of the sheet's level
  // `points` points on the centre line, evenly spread in t.
  std::vector<Eigen::Vector2d> edge(int points = 360) const;
};

// `expected_radius_px` is an unstrained ring's radius in pixels at the working distance.
std::vector<ImageRing> detectImageRings(const cv::Mat& image, double expected_radius_px, const RingDetectionParams& params);

struct StereoRig {
  CameraModel left, right;
  Eigen::Isometry3d head_from_left = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d right_from_left = Eigen::Isometry3d::Identity();
};

// The depth in front of the left camera (along its optical axis) where the two cameras' axes pass
// nearest each other: the pair's working distance, from its calibration alone. None when the axes
// are near parallel (no vergence) or meet behind the cameras.
std::optional<double> workingDistance(const StereoRig& rig);

struct StereoStats {
  std::size_t left_rings = 0, right_rings = 0, without_prior = 0, unmatched = 0, matched = 0, rejected_fit = 0;
};

// Where one view was taken from and what resolves its matching: the head's pose, and points of the
// part's surface (machine frame); without them nothing can be matched. Borrowed for the call.
struct StereoViewPose {
  const StereoRig& rig;
  Eigen::Isometry3d machine_from_head = Eigen::Isometry3d::Identity();
  const std::vector<Vec3>& prior;
  std::uint32_t index = 0;  // the view's number, which its elements carry (GridElement::view)
};

// The typical depth of the pose's prior points in front of the left camera (its axis): where a pair
// without a working distance looks for its elements. 0 when none lies in front.
double priorDepth(const StereoViewPose& pose);

// How many pixels of the left camera `mm` millimetres span at `depth` in front of it: the size of
// the elements stage 1 looks for.
double pixelsAtDepth(const StereoRig& rig, double mm, double depth);

// Both images' rings of one view: stage 1 above, from the images alone (most of a view's work), so
// that a scan runs it as the frames arrive and lets the images go.
struct StereoRingImages {
  std::vector<ImageRing> left, right;
};
StereoRingImages detectStereoRings(const cv::Mat& left, const cv::Mat& right, double expected_radius_px,
                                   const RingDetectionParams& params);

// Stages 2 and 3: the detected rings matched and measured.
std::vector<GridElement> measureStereoPair(const StereoRingImages& found, const StereoViewPose& pose,
                                           const RingDetectionParams& params, StereoStats* stats = nullptr);

}  // namespace stampscan::registration
