#include "stampscan/fitting/cloud.hpp"

#include <limits>

namespace stampscan::fitting {

namespace {
template <class V>
void checkLength(const V& attribute, std::size_t n, const std::string& name) {
  if (!attribute.empty() && attribute.size() != n) {
    throw std::invalid_argument("cloud attribute '" + name + "' has " + std::to_string(attribute.size()) +
                                " entries for " + std::to_string(n) + " points");
  }
}
}  // namespace

void Cloud::validate() const {
  const std::size_t n = positions.size();
  checkLength(normals, n, "normals");
  checkLength(strain, n, "strain");
  checkLength(colors, n, "colors");
  for (const auto& [name, values] : scalars) checkLength(values, n, name);
}

void Cloud::appendPoint(const Cloud& other, std::size_t i) {
  positions.push_back(other.positions[i]);
  if (other.hasNormals()) normals.push_back(other.normals[i]);
  if (other.hasStrain()) strain.push_back(other.strain[i]);
  if (other.hasColors()) colors.push_back(other.colors[i]);
  for (const auto& [name, values] : other.scalars) scalars[name].push_back(values[i]);
}

Bounds boundsOf(const std::vector<Vec3>& points) {
  const double inf = std::numeric_limits<double>::infinity();
  Bounds b{Vec3::Constant(inf), Vec3::Constant(-inf)};
  for (const Vec3& p : points) {
    b.min = b.min.cwiseMin(p);
    b.max = b.max.cwiseMax(p);
  }
  return b;
}

}  // namespace stampscan::fitting
