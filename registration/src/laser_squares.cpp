#include "stampscan/registration/laser_rings.hpp"

#include "laser_raster.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <optional>
#include <vector>

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

// The cell's outline with its corners made sharp. The spot's blur rounds an interior's corners off,
// and a rounded corner takes area and, more, second moment from the cell: its in-plane strains read
// low (its thickness strain 0.0007 high on the simulated dome). Each side is a line fitted (total
// least squares) to the middle three quarters of its stretch of the outline, away from the corners;
// each corner is where consecutive sides meet; the outline becomes the corners and the sides' own
// middles between them. Nothing when the outline (in ray order about `centre`) shows no four
// corners, each the farthest point from the centre over an eighth of the outline on either side.
std::optional<std::vector<Eigen::Vector2d>> sharpCornered(const std::vector<Eigen::Vector2d>& outline,
                                                          const Eigen::Vector2d& centre) {
  const std::size_t n = outline.size();
  if (n < 40) return std::nullopt;
  std::vector<double> r(n);
  for (std::size_t i = 0; i < n; ++i) r[i] = (outline[i] - centre).norm();
  const std::size_t window = n / 8;
  std::vector<std::size_t> corners;
  for (std::size_t i = 0; i < n; ++i) {
    bool farthest = true;
    for (std::size_t d = 1; d <= window && farthest; ++d)
      farthest = r[(i + d) % n] < r[i] && r[(i + n - d) % n] <= r[i];
    if (farthest) corners.push_back(i);
  }
  if (corners.size() != 4) return std::nullopt;
  struct Line {
    Eigen::Vector2d point, direction;
  };
  std::vector<Line> sides;
  std::vector<std::vector<Eigen::Vector2d>> middles;
  for (std::size_t k = 0; k < 4; ++k) {
    const std::size_t from = corners[k], length = (corners[(k + 1) % 4] + n - from) % n;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    std::vector<Eigen::Vector2d> points;
    for (std::size_t j = length / 8; j <= length - length / 8; ++j) points.push_back(outline[(from + j) % n]);
    if (points.size() < 5) return std::nullopt;
    for (const Eigen::Vector2d& p : points) mean += p;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& p : points) cov += (p - mean) * (p - mean).transpose();
    sides.push_back({mean, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvectors().col(1)});
    middles.push_back(std::move(points));
  }
  std::vector<Eigen::Vector2d> vertices;
  for (std::size_t k = 0; k < 4; ++k) {
    const Line& a = sides[(k + 3) % 4];
    const Line& b = sides[k];
    Eigen::Matrix2d m;
    m << a.direction, -b.direction;
    if (std::abs(m.determinant()) < 0.2) return std::nullopt;  // sides within 12 degrees: no corner
    const Eigen::Vector2d t = m.colPivHouseholderQr().solve(b.point - a.point);
    vertices.push_back(a.point + t.x() * a.direction);
  }
  // The outline with its corners made sharp: each corner, then its side's measured middle.
  std::vector<Eigen::Vector2d> sharp;
  for (std::size_t k = 0; k < 4; ++k) {
    sharp.push_back(vertices[k]);
    sharp.insert(sharp.end(), middles[k].begin(), middles[k].end());
  }
  return sharp;
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
    const std::vector<Eigen::Vector2d> outline = detail::unrolledOutline(in, in.plane, momentsOf(in.plane).centroid);
    const PolygonMoments m = momentsOf(outline);
    if (m.area <= 0) {
      ++st.rejected_fit;
      continue;
    }
    // A parallelogram's area is sqrt(det(12 Cov)); anything rounder or more ragged is not a cell.
    const double shape_error = m.area / std::sqrt(std::max(144 * m.covariance.determinant(), 1e-30)) - 1;
    // The cell's stretch from its sides and sharp corners, not its rounded outline, where they show.
    const std::optional<std::vector<Eigen::Vector2d>> sharp = sharpCornered(outline, m.centroid);
    const PolygonMoments cell = sharp ? momentsOf(*sharp) : m;
    GridElement g;
    if (std::abs(shape_error) > params.max_shape_error || !(cell.area > 0) ||
        !detail::elementFromStretch(12 * cell.covariance / (side * side), in.frame, params, g)) {
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
