// Internal to registration/: the intensity raster of one laser sweep and the search for the bright
// interiors of printed grid elements in it (ring interiors or square cells), shared by the circle
// and the square grid paths. See laser_rings.hpp for the steps.
#pragma once

#include "stampscan/fitting/median.hpp"
#include "stampscan/registration/laser_geometry.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_rings.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <limits>
#include <vector>

namespace stampscan::registration::detail {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using fitting::median;  // NaN for no values

// The sweep as images: intensity, validity, and the machine position behind every pixel.
struct Raster {
  int rows = 0, cols = 0;
  cv::Mat intensity;  // CV_32F
  cv::Mat valid;      // CV_8U, 255 where the point returned and is not saturated
  std::vector<Vec3> position;
  Vec3 viewpoint = Vec3::Zero();  // the sensor, mid-sweep: normals face it
  double col_mm = 0, row_mm = 0;  // typical pixel spacing on the part

  const Vec3& at(int r, int c) const { return position[static_cast<std::size_t>(r) * cols + c]; }
  bool ok(int r, int c) const { return r >= 0 && c >= 0 && r < rows && c < cols && valid.at<std::uint8_t>(r, c); }
  // Bilinear value at raster point (x = column, y = row); NaN where a corner is missing.
  double sample(double x, double y) const;
  // Bilinear machine position at a raster point; false where a corner is missing.
  bool lift(double x, double y, Vec3& out) const;
};

Raster buildRaster(const std::vector<Profile>& sweep, const HeadTrack& track, const DigitizerCalibration& cal);

struct InteriorSearch {
  double nominal_area_mm2 = 0;   // of an unstrained interior
  double inner_reach_mm = 0;     // an unstrained interior's largest centre-to-edge distance
  double line_width = 0.15;      // mm
  double ink_ratio = 0.6;
  double min_strain = -0.7, max_strain = 1.0;
  double min_edge_share = 0.85;
  double max_edge_gap_deg = 15;
};

// A bright region enclosed by ink, with its inner edge found along 360 rays from its centroid.
struct Interior {
  std::vector<Vec3> edge;                // machine frame, in ray order
  std::vector<Eigen::Vector2d> plane;    // the same in the plane fitted to the edge
  Vec3 mean = Vec3::Zero();              // the plane's origin
  Vec3 normal = Vec3::UnitZ();           // facing the sensor
  Eigen::Matrix3d frame;                 // columns: plane axes and normal
  std::vector<Vec3> pixels;              // the interior's own points
};

// Empty when the raster is too small to measure (fewer than three profiles, no spacing).
std::vector<Interior> findInteriors(const Raster& R, const InteriorSearch& search, RingDetectionStats& stats);

// The search settings shared by every grid kind, from its detection parameters.
template <typename Params>
InteriorSearch commonSearch(const Params& params) {
  InteriorSearch s;
  s.line_width = params.line_width;
  s.ink_ratio = params.ink_ratio;
  s.min_strain = params.min_strain;
  s.max_strain = params.max_strain;
  s.min_edge_share = params.min_edge_share;
  s.max_edge_gap_deg = params.max_edge_gap_deg;
  return s;
}

// The interior's outline (`outline`, in its plane) taken from the plane onto the sheet under it, about
// `centre`: each point at its distance along the sheet from the centre, in the direction the sheet's
// shortest path to it leaves the centre (see sheet_arcs.hpp). The sheet is a cubic height field
// through the interior's edge and its own points, so a ring that straddles the start of a radius
// has its flat side flat and its bent side bent. The outline as it is when they do not determine one.
std::vector<Eigen::Vector2d> unrolledOutline(const Interior& interior, const std::vector<Eigen::Vector2d>& outline,
                                             const Eigen::Vector2d& centre);

// The edge plane is a chord: the surface at a centre bulges off it. The distance along the normal
// to the interior's own points near `centre` (within `radius` of it, across the normal).
double surfaceOffset(const Interior& interior, const Vec3& centre, double radius);

// An ellipse in a plane (2D coordinates, mm).
struct PlaneEllipse {
  double a = 0, b = 0;  // semi-axes, a >= b
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double angle = 0;     // of the major axis from the plane's first axis
  double rms = 0;       // of the points used, about the ellipse
  std::size_t used = 0;
};

// Distance of each point from an ellipse, along the ray from its centre.
std::vector<double> ellipseResiduals(const PlaneEllipse& e, const std::vector<Eigen::Vector2d>& points);
// The direct fit (fitDirectEllipse), then points farther than 3 robust sigmas (at least 4 um) dropped and the fit
// repeated: a stray edge point (a neighbour's line, a speck) does not bend the ellipse.
bool fitEllipseRobust(const std::vector<Eigen::Vector2d>& points, PlaneEllipse& out);

// A grid element from the ellipse fitted to a printed circle in the plane `frame` (columns: plane
// axes, normal) at `origin`: `scale` turns the fitted axes into the circle's centre line (r0 over
// the inner radius for an inner edge, 1 for the line itself). False when a strain is implausible.
bool elementFromEllipse(const PlaneEllipse& e, double scale, const Eigen::Matrix3d& frame, const Vec3& origin,
                        const RingDetectionParams& params, GridElement& g);

// A square cell's strains from B = F F^T (F: the cell's deformation gradient) in the plane `frame`
// (columns: plane axes, normal): principal strains, major direction and the deformed square's half
// sides. False when B is not positive or a strain is implausible.
bool elementFromStretch(const Eigen::Matrix2d& B, const Eigen::Matrix3d& frame, const SquareDetectionParams& params,
                        GridElement& g);

}  // namespace stampscan::registration::detail
