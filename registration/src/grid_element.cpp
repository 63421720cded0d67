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
  auto& major = c.scalars["major_strain"];
  auto& minor = c.scalars["minor_strain"];
  auto& dx = c.scalars["major_dir_x"];
  auto& dy = c.scalars["major_dir_y"];
  auto& dz = c.scalars["major_dir_z"];
  auto& source = c.scalars["source"];
  auto& view = c.scalars["view"];
  auto& quality = c.scalars["quality"];
  auto& measurements = c.scalars["measurements"];
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
  return c;
}

}  // namespace stampscan::registration
