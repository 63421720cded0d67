// The stereo path for square grids: the grid's nodes in both images, matched, triangulated, and the
// strain of each cell from the deformation gradient of its four corners.
//
//  1. In each image, cell interiors as for rings (bright convex regions of the expected size), each
//     taken to a quadrilateral. Each side's printed line is located by fitting the blurred line
//     model (image_line_fit.hpp) to the pixels along its middle, away from the crossing lines at
//     the nodes; adjacent sides' centre lines meet at the nodes. Like the ring's centre line, a
//     node found this way does not move with the blur.
//  2. Cells matched between the images by their centres, with the depth prior (stereo_rings.hpp).
//  3. The four nodes triangulated, in the order that makes the rays meet best; the cell's plane
//     through them. The printed square (side p, corners at +-p/2) maps to the four corners by an
//     affine map q = t + F s fitted in that plane: F is the deformation gradient, B = F F^T gives
//     the principal stretches and the major direction.
#pragma once

#include "stampscan/registration/laser_rings.hpp"
#include "stampscan/registration/stereo_rings.hpp"

#include <array>

namespace stampscan::registration {

// A square cell as the image shows it: its four nodes (the centre lines' crossings, pixel
// coordinates, distortion not removed) in order around the cell, and their mean.
struct ImageCell {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  std::array<Eigen::Vector2d, 4> nodes;
  double blur = 0;  // px, mean over the four sides' fits
};

// `expected_pitch_px` is the unstrained pitch in pixels at the working distance.
std::vector<ImageCell> detectImageCells(const cv::Mat& image, double expected_pitch_px, const SquareDetectionParams& params);

// Both images' cells of one view: stage 1 above, from the images alone (as detectStereoRings).
struct StereoCellImages {
  std::vector<ImageCell> left, right;
};
StereoCellImages detectStereoCells(const cv::Mat& left, const cv::Mat& right, double expected_pitch_px,
                                   const SquareDetectionParams& params);

// Stages 2 and 3: the detected cells matched and measured. Each element is a cell's centre; fit_rms
// holds the corners' misfit to a parallelogram (mm).
std::vector<GridElement> measureStereoSquares(const StereoCellImages& found, const StereoViewPose& pose,
                                              const SquareDetectionParams& params, StereoStats* stats = nullptr);

}  // namespace stampscan::registration
