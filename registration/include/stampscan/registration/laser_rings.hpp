// Printed circles in the laser digitizer's intensity. The profiles of one sweep, side by side, form
// an intensity raster (rows: profiles, columns: points along the fan) with a machine-frame position
// behind every pixel. In it each printed ring is a dark closed line around a bright interior:
//  1. ink: pixels darker than a share of the local sheet level (a grey closing of the raster);
//  2. ring interiors: connected bright regions of the expected size, not at the raster's edge and
//     mostly away from gaps in the data (a return lost between two that returned is filled from
//     them first: a steep wall loses 1-2 % of its points so);
//  3. the interior's edge to sub-pixel precision: along the ray from the interior's centre, where
//     the intensity crosses the middle between sheet and ink (a ray marches over a hole of up to
//     two and a half pixels, never reads the crossing across one);
//  4. the edge lifted to 3D through the raster's positions, a plane fitted to it, and a robust
//     ellipse fit in that plane (OpenCV's direct fit, then points far from it dropped and the fit
//     repeated; fits with a large residual or implausible axes are rejected);
//  5. the inner edge is the image of radius r0 - w/2, so the centre line's axes are the edge's times
//     r0 / (r0 - w/2); strains from the axes.
#pragma once

#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_geometry.hpp"

#include <vector>

namespace stampscan::registration {

struct RingDetectionParams {
  double printed_radius = 1.27;  // mm, of the circles' centre line
  double line_width = 0.15;      // mm
  double ink_ratio = 0.6;        // ink is darker than this share of the local sheet level
  double max_fit_rms = 0.02;     // mm: worse fits are rejected
  double min_edge_share = 0.85;  // of 360 rays from the centre that must find the edge
  double max_edge_gap_deg = 15;  // largest run of rays without an edge
  double min_strain = -0.7, max_strain = 1.0;  // plausible range of either principal strain
};

struct RingDetectionStats {
  std::size_t candidates = 0, rejected_size = 0, rejected_gap = 0, rejected_fit = 0, found = 0;
};

// The rings of one sweep. All profiles must have the same number of points.
std::vector<GridElement> detectLaserRings(const std::vector<Profile>& sweep, const HeadTrack& track,
                                          const DigitizerCalibration& calibration, const RingDetectionParams& params,
                                          std::uint32_t sweep_id, RingDetectionStats* stats = nullptr);

// Square grids. The interior of a printed square cell (side p - w between the lines' inner edges)
// becomes, under the local deformation gradient F, a parallelogram whose second moments are
// F (p - w)^2 / 12 F^T. So B = F F^T = 12 Cov / (p - w)^2, from the area moments of the cell's
// sub-pixel inner edge (a polygon of 360 points), gives the principal stretches and the major
// direction: the deformation gradient of the cell's corners, without locating the corners one by one.
struct SquareDetectionParams {
  double pitch = 2.54;       // mm between grid lines
  double line_width = 0.15;  // mm
  double ink_ratio = 0.6;
  double max_shape_error = 0.02;  // relative: a parallelogram's area is sqrt(det(12 Cov)); an ellipse's 1.047x
  double min_strain = -0.7, max_strain = 1.0;
  double min_edge_share = 0.85;
  double max_edge_gap_deg = 15;
};

// The square cells of one sweep; each element is a cell's centre. fit_rms holds the relative shape
// error. All profiles must have the same number of points.
std::vector<GridElement> detectLaserSquares(const std::vector<Profile>& sweep, const HeadTrack& track,
                                            const DigitizerCalibration& calibration, const SquareDetectionParams& params,
                                            std::uint32_t sweep_id, RingDetectionStats* stats = nullptr);

}  // namespace stampscan::registration
