// Internal to registration/: what the stereo paths for circle and square grids share. Pixels to
// rays, the bright interiors of printed grid elements in an image, and the matching of elements
// between the left and right image with the help of a depth prior.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/stereo_rings.hpp"
#include "sheet_arcs.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <tbb/parallel_invoke.h>

#include <utility>
#include <vector>

namespace stampscan::registration::detail {

// Pixels to undistorted normalised image coordinates (x/z, y/z).
std::vector<Eigen::Vector2d> normalised(const std::vector<Eigen::Vector2d>& px, const CameraModel& cam);

// Pixel coordinates of a point in the camera frame, distortion applied.
Eigen::Vector2d projectPoint(const Vec3& camera_point, const CameraModel& cam);

// Closest point between two rays (origin, unit direction): the triangulated point, and the gap.
Vec3 midpoint(const Vec3& o1, const Vec3& d1, const Vec3& o2, const Vec3& d2, double* gap);

// The two cameras' poses for one pair, and the prior's typical depth in front of the left camera
// (0 when the prior is empty or behind it).
struct PairPoses {
  Eigen::Isometry3d machine_from_left, machine_from_right, left_from_machine, right_from_machine;
  double prior_depth = 0;
};
PairPoses pairPoses(const StereoRig& rig, const Eigen::Isometry3d& machine_from_head, const std::vector<Vec3>& prior);

// A bright region enclosed by ink: a ring's or a square cell's interior. Found as pixels brighter
// than `ink_ratio` of the local sheet level (a grey closing wider than where two touching elements'
// lines run side by side, blurred), of an area within a
// wide window around `nominal_area` (distance and tilt change it), convex to `min_convexity` (area
// over hull area), not touching the image border.
struct ImageInterior {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  std::vector<cv::Point> hull;  // of its outline
  double area = 0;              // px
  double sheet_level = 0;       // median brightness inside
};
std::vector<ImageInterior> findImageInteriors(const cv::Mat& image_f32, double nominal_area, double line_px,
                                              double ink_ratio, double min_convexity);

// An element seen in both images: its index in each and the triangulated centre (machine frame).
struct StereoMatch {
  std::size_t left = 0, right = 0;
  Vec3 centre = Vec3::Zero();
};

// Matches elements by their image centres. The grid repeats every pitch, so the epipolar line alone
// is ambiguous; the prior (points of the part's surface) predicts where each left element lies in
// the right image, and the match is the right element nearest the prediction within `window_px`
// among those whose rays meet the left one's within 0.2 mm.
std::vector<StereoMatch> matchAcrossViews(const std::vector<Eigen::Vector2d>& left_centres,
                                          const std::vector<Eigen::Vector2d>& right_centres, const StereoRig& rig,
                                          const PairPoses& poses, const std::vector<Vec3>& prior, double window_px,
                                          StereoStats& stats);

// Both images' elements (anything with an image `centre`: rings, square cells) found by `detect`;
// the two images at once, as much of a detection runs on one thread.
template <typename Detect>
auto detectInBoth(const cv::Mat& left_image, const cv::Mat& right_image, const Detect& detect) {
  std::pair<decltype(detect(left_image)), decltype(detect(right_image))> found;
  tbb::parallel_invoke([&] { found.first = detect(left_image); }, [&] { found.second = detect(right_image); });
  return found;
}

// Both images' elements counted in `stats` and matched with matchAcrossViews.
template <typename Element>
std::vector<StereoMatch> matchFound(const std::vector<Element>& left, const std::vector<Element>& right,
                                    const StereoRig& rig, const PairPoses& poses, const std::vector<Vec3>& prior,
                                    double window_px, StereoStats& stats) {
  stats.left_rings += left.size();
  stats.right_rings += right.size();
  std::vector<Eigen::Vector2d> left_centres, right_centres;
  for (const auto& e : left) left_centres.push_back(e.centre);
  for (const auto& e : right) right_centres.push_back(e.centre);
  return matchAcrossViews(left_centres, right_centres, rig, poses, prior, window_px, stats);
}

}  // namespace stampscan::registration::detail
