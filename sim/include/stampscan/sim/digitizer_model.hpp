// The laser digitizer: a laser beam swept by internal rotating mirrors through a planar fan (the
// sensor's x-z plane), measuring range and returned intensity at N angles per profile. The printed
// grid shows in the intensity; steep or polished spots drop out; noise grows at grazing incidence.
#pragma once

#include "stampscan/sim/scene.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <random>
#include <vector>

namespace stampscan::sim {

struct DigitizerSpec {
  int points_per_profile = 1024;
  double half_angle = 0.21;      // rad: the fan spans +-12 degrees
  double standoff = 100;         // mm from the mirror to the middle of the measuring range
  double measuring_range = 60;   // mm deep, centred on the standoff
  double profile_rate = 500;     // profiles per second
  double range_noise = 0.006;    // mm, one sigma at normal incidence
  double max_incidence = 1.31;   // rad (75 degrees): beyond it the triangulation camera sees nothing
  double steep_from = 0.96;      // rad (55 degrees): dropouts start here, rising to certain at max
  double glare_incidence = 0.35; // rad (20 degrees): on a polished spot, nearer normal saturates the camera
  double glare_dropout = 0.7;    // chance of losing a point on a polished spot near normal incidence
  // The incidence beyond which the digitizer loses more than `share` of the points (rad).
  double incidenceLosing(double share) const;
  double angle(int i) const { return -half_angle + 2 * half_angle * i / (points_per_profile - 1); }
  double angleIncrement() const { return 2 * half_angle / (points_per_profile - 1); }
};

struct ProfileMeasurement {
  std::vector<float> range;              // mm along each ray; 0 = no return
  std::vector<std::uint16_t> intensity;  // 0..65535
  bool glare = false;                    // some point saturated
};

// The ray of point i in the sensor frame: from the mirror, at angle(i) from -z towards +x.
Vec3 digitizerRay(const DigitizerSpec& spec, int i);

// Measures one profile with the sensor at `machine_from_sensor`.
ProfileMeasurement measureProfile(const Scene& scene, const DigitizerSpec& spec,
                                  const Eigen::Isometry3d& machine_from_sensor, std::mt19937_64& rng);

}  // namespace stampscan::sim
