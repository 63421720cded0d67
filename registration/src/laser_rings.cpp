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
  const detail::Raster R = detail::buildRaster(sweep, track, calibration);
  const double r0 = params.printed_radius, w = params.line_width;
  const double inner = r0 - 0.5 * w;
  detail::InteriorSearch search = detail::commonSearch(params);
  search.nominal_area_mm2 = std::numbers::pi * inner * inner;
  search.inner_reach_mm = inner;
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
    // The ring's axes are lengths on the sheet: where it bends (a punch or die radius) the plane's
    // chords are shorter, by a sixth of (r k)^2, 0.3 % for a 2.54 mm circle over a 10 mm radius, and
    // the thickness strain came out that much high. The edge is taken onto the sheet about its centre.
    if (PlaneEllipse on_sheet; detail::fitEllipseRobust(
            detail::unrolledOutline(in, plane, e.centre), on_sheet))
      e = on_sheet;
    // 5. Centre-line axes and strains. The edge's plane is a chord: the surface at the centre
    // bulges off it, so the centre moves along the normal onto the interior's points near it.
    GridElement g;
    if (!detail::elementFromEllipse(e, r0 / inner, frame, mean, params, g)) {
      ++st.rejected_fit;
      continue;
    }
    g.position += detail::surfaceOffset(in, g.position, 0.4 * e.b) * normal;
    g.source = Source::Laser;
    g.view = sweep_id;
    g.gauge_mm2 = inner * inner / 8;  // the inner edge is what was fitted
    out.push_back(g);
    ++st.found;
  }
  return out;
}

}  // namespace stampscan::registration
