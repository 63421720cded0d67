// One measured grid element: where it is and the strain its printed shape shows. The rows of the
// Cloud4D the station writes.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <cstdint>
#include <limits>
#include <vector>

namespace stampscan::registration {

using fitting::Vec3;

enum class Source : std::uint8_t { Laser = 0, Stereo = 1 };

struct GridElement {
  Vec3 position = Vec3::Zero();  // on the surface, machine frame (mm)
  Vec3 normal = Vec3::UnitZ();   // unit, facing the sensor
  double major_strain = 0, minor_strain = 0, thickness_strain = 0;  // true strains
  Vec3 major_direction = Vec3::UnitX();  // unit, in the surface
  double semi_major = 0, semi_minor = 0;  // mm, of the printed circle's centre line
  double fit_rms = 0;     // mm, of the edge points about the fitted ellipse: the quality measure
  std::size_t edge_points = 0;
  Source source = Source::Laser;
  std::uint32_t view = 0;  // sweep or stereo pose
  // Standard (k = 1) uncertainties of the thickness strain and of the position along each axis
  // (element_merge.hpp: from the scan's own repeated measurements); NaN while not known.
  double strain_sigma = std::numeric_limits<double>::quiet_NaN();
  double position_sigma_mm = std::numeric_limits<double>::quiet_NaN();
  // Of strain_sigma, the measurements' noise alone (element_merge.hpp, addFieldUncertainty).
  double strain_noise = std::numeric_limits<double>::quiet_NaN();
  std::uint32_t measurements = 1;  // how many measurements this element merges (element_merge.hpp)
  // A printed element shows the mean of the sheet's strain over its outline, not the strain at its
  // centre: to second order a measured strain is the centre's plus gauge_mm2 times the strain's
  // Laplacian over the printed (unformed) grid. It depends on how the path reads the outline: a ring
  // fitted at radius r averages as r^2 / 8, a cell's interior of side s as about s^2 / 30, a cell
  // from its four corners a pitch apart as about pitch^2 / 12. 0 where not known.
  double gauge_mm2 = 0;
};

// As a Cloud4D: x y z, nx ny nz, strain (thickness), major_strain, minor_strain, major_dir_x/y/z,
// source, view, quality (fit_rms), measurements (how many it merges: 1 for a single measurement);
// and strain_uncertainty, position_uncertainty, strain_noise (standard, k = 1) when every element's is known. A
// merged element's source and view are those of its most certain measurement.
fitting::Cloud toCloud(const std::vector<GridElement>& elements);

}  // namespace stampscan::registration
