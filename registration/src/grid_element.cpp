#include "stampscan/registration/grid_element.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::registration {

fitting::Cloud toCloud(const std::vector<GridElement>& elements) {
  fitting::Cloud c;
  const std::size_t n = elements.size();
  c.positions.reserve(n);
  c.normals.reserve(n);
  c.strain.reserve(n);
  auto& major = c.scalars[fitting::kMajorStrain];
  auto& minor = c.scalars[fitting::kMinorStrain];
  auto& dx = c.scalars[fitting::kMajorDirection[0]];
  auto& dy = c.scalars[fitting::kMajorDirection[1]];
  auto& dz = c.scalars[fitting::kMajorDirection[2]];
  auto& source = c.scalars[fitting::kSource];
  auto& view = c.scalars[fitting::kView];
  auto& quality = c.scalars[fitting::kFitQuality];
  auto& measurements = c.scalars[fitting::kMeasurementCount];
  for (const GridElement& g : elements) {
    c.positions.push_back(g.position);
    c.normals.push_back(g.normal);
    c.strain.push_back(g.thickness_strain);
    major.push_back(g.major_strain);
    minor.push_back(g.minor_strain);
    dx.push_back(g.major_direction.x());
    dy.push_back(g.major_direction.y());
    dz.push_back(g.major_direction.z());
    source.push_back(static_cast<double>(g.source));
    view.push_back(g.view);
    quality.push_back(g.fit_rms);
    measurements.push_back(g.measurements);
  }
  // The uncertainties only when every element has them: a column of NaN would make readers skip rows.
  const auto known = [&](auto member) {
    return !elements.empty() &&
           std::all_of(elements.begin(), elements.end(), [&](const GridElement& g) { return std::isfinite(g.*member); });
  };
  if (known(&GridElement::strain_sigma) && known(&GridElement::position_sigma_mm)) {
    auto& strain_u = c.scalars[fitting::kStrainUncertainty];
    auto& position_u = c.scalars[fitting::kPositionUncertainty];
    for (const GridElement& g : elements) {
      strain_u.push_back(g.strain_sigma);
      position_u.push_back(g.position_sigma_mm);
    }
  }
  if (known(&GridElement::strain_noise)) {
    auto& noise = c.scalars[fitting::kStrainNoise];
    for (const GridElement& g : elements) noise.push_back(g.strain_noise);
  }
  return c;
}

}  // namespace stampscan::registration
