#include "stampscan/registration/laser_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace stampscan::registration {

HeadTrack::HeadTrack(std::vector<HeadSample> samples) : samples_(std::move(samples)) {
  if (samples_.size() < 2) throw std::invalid_argument("head track: needs at least two CMM position reports");
  for (std::size_t i = 1; i < samples_.size(); ++i)
    if (samples_[i].time_ns <= samples_[i - 1].time_ns)
      throw std::invalid_argument("head track: position report " + std::to_string(i) + " is not later than the one before");
  // Velocity of each interval (index i: samples i-1 .. i), then the chord error bound from the
  // change of velocity to the intervals before and after.
  const std::size_t n = samples_.size();
  std::vector<Vec3> velocity(n, Vec3::Zero());
  std::vector<double> dt(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    dt[i] = static_cast<double>(samples_[i].time_ns - samples_[i - 1].time_ns) * 1e-9;
    velocity[i] = (samples_[i].position - samples_[i - 1].position) / dt[i];
  }
  chord_error_.assign(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    double dv = 0;
    if (i > 1) dv = std::max(dv, (velocity[i] - velocity[i - 1]).norm());
    if (i + 1 < n) dv = std::max(dv, (velocity[i + 1] - velocity[i]).norm());
    chord_error_[i] = dv * dt[i] / 4;
  }
}

std::size_t HeadTrack::intervalOf(std::int64_t t) const {
  const auto it = std::lower_bound(samples_.begin(), samples_.end(), t,
                                   [](const HeadSample& s, std::int64_t v) { return s.time_ns < v; });
  return std::max<std::size_t>(1, static_cast<std::size_t>(it - samples_.begin()));
}

double HeadTrack::chordError(std::int64_t t) const {
  if (!covers(t)) throw std::out_of_range("head track: time " + std::to_string(t) + " ns is outside the CMM's reports");
  return chord_error_[intervalOf(t)];
}

HeadSample HeadTrack::at(std::int64_t t) const {
  if (!covers(t)) throw std::out_of_range("head track: time " + std::to_string(t) + " ns is outside the CMM's reports");
  const auto it = std::lower_bound(samples_.begin(), samples_.end(), t,
                                   [](const HeadSample& s, std::int64_t v) { return s.time_ns < v; });
  if (it == samples_.begin()) return *it;
  const HeadSample& b = *it;
  const HeadSample& a = *(it - 1);
  const double f = static_cast<double>(t - a.time_ns) / static_cast<double>(b.time_ns - a.time_ns);
  HeadSample s;
  s.time_ns = t;
  s.position = a.position + f * (b.position - a.position);
  s.a = a.a + f * (b.a - a.a);
  s.b = a.b + f * (b.b - a.b);
  return s;
}

Eigen::Isometry3d HeadTrack::poseAt(std::int64_t t) const {
  const HeadSample s = at(t);
  return trace::headPose(s.position, s.a, s.b);
}

Vec3 sensorPoint(const Profile& p, std::size_t i) {
  const double angle = static_cast<double>(p.angle_min) + static_cast<double>(i) * static_cast<double>(p.angle_increment);
  const double r = p.range[i];
  return {r * std::sin(angle), 0.0, -r * std::cos(angle)};
}

bool profileToMachine(const Profile& p, const HeadTrack& track, const DigitizerCalibration& calibration,
                      std::vector<Vec3>& points, std::vector<std::uint16_t>* intensity) {
  const std::int64_t t = calibration.exposureTime(p);
  if (!track.covers(t)) return false;
  const Eigen::Isometry3d machine_from_sensor = track.poseAt(t) * calibration.head_from_digitizer;
  for (std::size_t i = 0; i < p.range.size(); ++i) {
    if (!(p.range[i] > 0)) continue;
    points.push_back(machine_from_sensor * sensorPoint(p, i));
    if (intensity) intensity->push_back(i < p.intensity.size() ? p.intensity[i] : 0);
  }
  return true;
}

std::int64_t clockOffset(const std::vector<std::pair<std::int64_t, std::int64_t>>& pairs) {
  if (pairs.empty()) throw std::invalid_argument("clock offset: no clock-sync pairs");
  std::vector<std::int64_t> d;
  for (const auto& [station, device] : pairs) d.push_back(device - station);
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

}  // namespace stampscan::registration
