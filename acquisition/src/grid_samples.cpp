#include "grid_samples.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace stampscan::acquisition {

namespace {
using Vec3 = Eigen::Vector3d;
Vec3 vec(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }
}  // namespace

GridSamples sampleGridArea(const NominalModel& model, double spacing, double min_normal_z) {
  GridSamples s;
  for (const auto& t : model.triangles) {
    const Vec3 p0 = vec(model.vertices[t[0]]), p1 = vec(model.vertices[t[1]]), p2 = vec(model.vertices[t[2]]);
    const Vec3 cross = (p1 - p0).cross(p2 - p0);
    const double twice_area = cross.norm();
    if (!(twice_area > 0)) continue;
    const Vec3 n = cross / twice_area;
    if (n.z() < min_normal_z) continue;
    const double longest = std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
    const int k = std::max(1, static_cast<int>(std::ceil(longest / spacing)));
    const double sub_area = 0.5 * twice_area / (k * k);
    const Vec3 e1 = (p1 - p0) / k, e2 = (p2 - p0) / k;
    for (int i = 0; i < k; ++i)
      for (int j = 0; i + j < k; ++j) {
        const Vec3 corner = p0 + i * e1 + j * e2;
        s.points.push_back(corner + (e1 + e2) / 3.0);  // the upright sub-triangle
        s.normals.push_back(n);
        s.area.push_back(sub_area);
        if (i + j + 1 < k) {  // and the inverted one beside it
          s.points.push_back(corner + (2.0 * e1 + 2.0 * e2) / 3.0);
          s.normals.push_back(n);
          s.area.push_back(sub_area);
        }
      }
  }
  return s;
}

GridSamples thinned(const GridSamples& s, double spacing) {
  std::unordered_map<std::uint64_t, std::size_t> kept;  // cube -> index into out
  GridSamples out;
  const auto cell = [&](double v) { return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / spacing)) & 0x1FFFFF); };
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const Vec3& p = s.points[i];
    const std::uint64_t key = cell(p.x()) << 42 | cell(p.y()) << 21 | cell(p.z());
    const auto [at, fresh] = kept.try_emplace(key, out.points.size());
    if (fresh) {
      out.points.push_back(p);
      out.normals.push_back(s.normals[i]);
      out.area.push_back(s.area[i]);
      continue;
    }
    const std::size_t j = at->second;
    if (s.area[i] > out.area[j]) out.points[j] = p, out.normals[j] = s.normals[i];
    out.area[j] += s.area[i];
  }
  return out;
}

}  // namespace stampscan::acquisition
