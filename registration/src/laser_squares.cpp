#include "stampscan/registration/laser_rings.hpp"

#include "laser_raster.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace stampscan::registration {

namespace {

// Area, centroid and central second moments of a closed polygon (Green's theorem).
struct PolygonMoments {
  double area = 0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // of the region, per unit area
};

PolygonMoments momentsOf(const std::vector<Eigen::Vector2d>& poly) {
  PolygonMoments m;
  double a = 0, cx = 0, cy = 0, ixx = 0, iyy = 0, ixy = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d& p = poly[i];
    const Eigen::Vector2d& q = poly[(i + 1) % poly.size()];
    const double cross = p.x() * q.y() - q.x() * p.y();
    a += cross;
    cx += (p.x() + q.x()) * cross;
    cy += (p.y() + q.y()) * cross;
    ixx += (p.x() * p.x() + p.x() * q.x() + q.x() * q.x()) * cross;
    iyy += (p.y() * p.y() + p.y() * q.y() + q.y() * q.y()) * cross;
    ixy += (p.x() * q.y() + 2 * p.x() * p.y() + 2 * q.x() * q.y() + q.x() * p.y()) * cross;
  }
  a *= 0.5;
  if (std::abs(a) < 1e-12) return m;
  m.area = std::abs(a);
  m.centroid = Eigen::Vector2d(cx, cy) / (6 * a);
  const double xx = ixx / (12 * a), yy = iyy / (12 * a), xy = ixy / (24 * a);
  m.covariance << xx - m.centroid.x() * m.centroid.x(), xy - m.centroid.x() * m.centroid.y(),
      xy - m.centroid.x() * m.centroid.y(), yy - m.centroid.y() * m.centroid.y();
  return m;
}

}  // namespace

std::vector<GridElement> detectLaserSquares(const std::vector<Profile>& sweep, const HeadTrack& track,
                                            const DigitizerCalibration& calibration, const SquareDetectionParams& params,
                                            std::uint32_t sweep_id, RingDetectionStats* stats) {
  RingDetectionStats local;
  RingDetectionStats& st = stats ? *stats : local;
  std::vector<GridElement> out;
  const detail::Raster R = detail::buildRaster(sweep, track, calibration);
  const double side = params.pitch - params.line_width;  // the interior's side before forming
  detail::InteriorSearch search = detail::commonSearch(params);
  search.nominal_area_mm2 = side * side;
  search.inner_reach_mm = side / std::sqrt(2.0);  // to a corner
  for (const detail::Interior& in : detail::findInteriors(R, search, st)) {
    // The cell's sides are lengths on the sheet: where it bends the outline is taken onto the sheet
    // about the cell's centre, not left in the plane's shorter chords (see laser_rings.cpp).
    const PolygonMoments m =
        momentsOf(detail::unrolledOutline(in, in.plane, momentsOf(in.plane).centroid));
    if (m.area <= 0) {
      ++st.rejected_fit;
      continue;
    }
    // A parallelogram's area is sqrt(det(12 Cov)); anything rounder or more ragged is not a cell.
    const double shape_error = m.area / std::sqrt(std::max(144 * m.covariance.determinant(), 1e-30)) - 1;
    GridElement g;
    if (std::abs(shape_error) > params.max_shape_error ||
        !detail::elementFromStretch(12 * m.covariance / (side * side), in.frame, params, g)) {
      ++st.rejected_fit;
      continue;
    }
    g.normal = in.normal;
    const Vec3 centre = in.mean + m.centroid.x() * in.frame.col(0) + m.centroid.y() * in.frame.col(1);
    g.position = centre + detail::surfaceOffset(in, centre, 0.3 * side) * in.normal;
    g.fit_rms = std::abs(shape_error);
    g.edge_points = in.plane.size();
    g.source = Source::Laser;
    g.view = sweep_id;
    // The interior's second moments: a quadratic strain along a side of half-length a enters as
    // a^2 / 10, across it as a^2 / 6; their mean, (2 / 15) a^2, for a cell however it is turned.
    g.gauge_mm2 = side * side / 30;
    out.push_back(g);
    ++st.found;
  }
  return out;
}

}  // namespace stampscan::registration
