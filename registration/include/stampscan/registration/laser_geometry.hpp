// The laser path's geometry: the CMM's head track, a digitizer profile, and where its points lie in
// the machine frame given the digitizer's calibration (mount on the head, clock offset, latency).
#pragma once

#include "stampscan/acquisition/trace/rigid_pose.hpp"
#include "stampscan/fitting/cloud.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace stampscan::registration {

using fitting::Vec3;

struct HeadSample {
  std::int64_t time_ns = 0;  // station clock
  Vec3 position = Vec3::Zero();
  double a = 0, b = 0;
};

// The CMM's reported positions over time, interpolated linearly. Between two reports the head moves
// on a straight line, but not always at a constant speed: a CMM's move report daemon reports at
// 10 Hz at most (I++ DME §6.3.2.7), and a move that starts or stops between two reports leaves the
// chord up to |dv| dt / 4 away from the true path (0.15 mm for a 25 mm/s sweep starting within a
// 0.1 s interval). chordError() bounds that per interval from the change of velocity at its ends,
// so the measuring path can leave out data taken where the track is not to be trusted.
class HeadTrack {
 public:
  // Samples in time order; throws std::invalid_argument otherwise or with fewer than two.
  explicit HeadTrack(std::vector<HeadSample> samples);
  bool covers(std::int64_t t) const { return t >= samples_.front().time_ns && t <= samples_.back().time_ns; }
  // Throws std::out_of_range outside the track.
  HeadSample at(std::int64_t t) const;
  Eigen::Isometry3d poseAt(std::int64_t t) const;
  // How far (mm) the interpolated position at t may be from where the head was: |dv| dt / 4 for the
  // interval holding t, dv the larger change of velocity between it and its neighbours. Throws
  // std::out_of_range outside the track.
  double chordError(std::int64_t t) const;
  const std::vector<HeadSample>& samples() const { return samples_; }

 private:
  std::size_t intervalOf(std::int64_t t) const;  // i: samples_[i - 1] .. samples_[i] holds t

  std::vector<HeadSample> samples_;
  std::vector<double> chord_error_;  // per interval, indexed by its end sample
};

// A digitizer profile as the device sent it (see the trace's LaserProfile message).
struct Profile {
  std::int64_t device_time_ns = 0;
  float angle_min = 0, angle_increment = 0;
  std::vector<float> range;               // mm, 0 = no return
  std::vector<std::uint16_t> intensity;
  bool overexposed = false;
};

struct DigitizerCalibration {
  Eigen::Isometry3d head_from_digitizer = Eigen::Isometry3d::Identity();
  std::int64_t clock_offset_ns = 0;  // digitizer clock minus station clock
  std::int64_t latency_ns = 0;       // profile stamp minus its exposure (digitizer clock)
  std::int64_t exposureTime(const Profile& p) const { return p.device_time_ns - clock_offset_ns - latency_ns; }
};

// Point i of a profile in the sensor frame: along the ray at angle_min + i * increment in the x-z
// plane, from -z towards +x.
Vec3 sensorPoint(const Profile& p, std::size_t i);

// The profile's returns in the machine frame, appended to `points` (and their intensities to
// `intensity` when given). Saturated intensities are kept; the caller decides. Returns false (and
// appends nothing) when the exposure time is outside the head track.
bool profileToMachine(const Profile& p, const HeadTrack& track, const DigitizerCalibration& calibration,
                      std::vector<Vec3>& points, std::vector<std::uint16_t>* intensity = nullptr);

// The median of device-minus-station differences of clock-sync pairs.
std::int64_t clockOffset(const std::vector<std::pair<std::int64_t, std::int64_t>>& station_and_device_times);

}  // namespace stampscan::registration
