#include "stampscan/registration/laser_rings.hpp"

#include "laser_raster.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stampscan::registration {

using detail::median;
using detail::PlaneEllipse;

std::vector<GridElement> detectLaserRings(const std::vector<Profile>& sweep, const HeadTrack& track,
                                          const DigitizerCalibration& calibration, const RingDetectionParams& params,
                                          std::uint32_t sweep_id, RingDetectionStats* stats) {
  RingDetectionStats local;
  RingDetectionStats& st = stats ? *stats : local;
  std::vector<GridElement> out;
  if (sweep.size() < 3) return out;
  const detail::Raster R = detail::buildRaster(sweep, track, calibration);
  if (!(R.col_mm > 0) || !(R.row_mm > 0)) return out;
  const double r0 = params.printed_radius, w = params.line_width;
  const double inner = r0 - 0.5 * w;
  detail::InteriorSearch search;
  search.nominal_area_mm2 = std::numbers::pi * inner * inner;
  search.inner_reach_mm = inner;
  search.line_width = w;
  search.ink_ratio = params.ink_ratio;
  search.min_strain = params.min_strain;
  search.max_strain = params.max_strain;
  search.min_edge_share = params.min_edge_share;
  search.max_edge_gap_deg = params.max_edge_gap_deg;
  for (const detail::Interior& in : detail::findInteriors(R, search, st)) {
    const std::vector<Eigen::Vector2d>& plane = in.plane;
    const Vec3& mean = in.mean;
    const Vec3& normal = in.normal;
    const Eigen::Matrix3d& frame = in.frame;
    PlaneEllipse e;
    if (!detail::fitEllipseRobust(plane, e) || e.rms > params.max_fit_rms) {
      ++st.rejected_fit;
      continue;
    }
    // 5. Centre-line axes and strains.
    GridElement g;
    g.semi_major = e.a * r0 / inner;
    g.semi_minor = e.b * r0 / inner;
    g.major_strain = std::log(g.semi_major / r0);
    g.minor_strain = std::log(g.semi_minor / r0);
    if (g.major_strain > params.max_strain || g.minor_strain < params.min_strain) {
      ++st.rejected_fit;
      continue;
    }
    g.thickness_strain = -(g.major_strain + g.minor_strain);
    g.major_direction = (std::cos(e.angle) * frame.col(0) + std::sin(e.angle) * frame.col(1)).normalized();
    g.normal = normal;
    // The edge's plane is a chord: the surface at the centre bulges off it. Move the centre along the
    // normal onto the interior's points near it.
    const Vec3 centre = mean + e.centre.x() * frame.col(0) + e.centre.y() * frame.col(1);
    g.position = centre + detail::surfaceOffset(in, centre, 0.4 * e.b) * normal;
    g.fit_rms = e.rms;
    g.edge_points = e.used;
    g.source = Source::Laser;
    g.view = sweep_id;
    out.push_back(g);
    ++st.found;
  }
  return out;
}

}  // namespace stampscan::registration
