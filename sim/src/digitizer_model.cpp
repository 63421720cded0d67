#include "stampscan/sim/digitizer_model.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::sim {

double DigitizerSpec::incidenceLosing(double share) const {
  return steep_from + std::sqrt(std::clamp(share, 0.0, 1.0)) * (max_incidence - steep_from);
}

Vec3 digitizerRay(const DigitizerSpec& spec, int i) {
  const double a = spec.angle(i);
  return {std::sin(a), 0.0, -std::cos(a)};
}

ProfileMeasurement measureProfile(const Scene& scene, const DigitizerSpec& spec,
                                  const Eigen::Isometry3d& machine_from_sensor, std::mt19937_64& rng) {
  const int n = spec.points_per_profile;
  ProfileMeasurement out;
  out.range.assign(n, 0.0f);
  out.intensity.assign(n, 0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Vec3 origin = machine_from_sensor.translation();
  // The laser spot is about as wide as the spacing of the points at the standoff.
  const double spot_per_mm = spec.angleIncrement();
  const double near = spec.standoff - 0.5 * spec.measuring_range, far = spec.standoff + 0.5 * spec.measuring_range;
  double t_hint = -1;
  for (int i = 0; i < n; ++i) {
    const Ray ray{origin, machine_from_sensor.linear() * digitizerRay(spec, i)};
    // Draw every random number whatever happens, so that one point's fate does not shift the noise
    // of the others (the same seed gives the same scan after a change of one dropout rule).
    const double u_drop = unit(rng), noise = gauss(rng), speckle = gauss(rng);
    const auto hit = scene.cast(ray, spot_per_mm, t_hint);
    if (!hit) continue;
    t_hint = hit->t;
    if (hit->t < near || hit->t > far) continue;  // outside the measuring range
    const double cos_inc = std::clamp(-hit->normal.dot(ray.direction), 0.0, 1.0);
    const double incidence = std::acos(cos_inc);
    if (incidence >= spec.max_incidence) continue;
    if (incidence > spec.steep_from) {
      // The chance of losing the point rises with the square of the way from steep_from to the
      // limit (incidenceLosing inverts it).
      const double way = (incidence - spec.steep_from) / (spec.max_incidence - spec.steep_from);
      if (u_drop < way * way) continue;
    }
    if (hit->shiny && incidence < spec.glare_incidence) {
      // Specular glare saturates the triangulation camera: the point is lost or badly placed.
      out.glare = true;
      out.intensity[i] = 65535;
      if (u_drop < spec.glare_dropout) continue;
    }
    const double sigma = spec.range_noise / std::max(cos_inc, 0.25);
    out.range[i] = static_cast<float>(hit->t + sigma * noise);
    if (out.intensity[i] == 0) {
      const double level = 0.9 * hit->albedo / PartScene::kSheetAlbedo * (0.3 + 0.7 * cos_inc);
      const double counts = std::clamp(level * 60000.0 * (1 + 0.03 * speckle), 1.0, 65535.0);
      out.intensity[i] = static_cast<std::uint16_t>(counts);
    }
  }
  return out;
}

}  // namespace stampscan::sim
