// A simulated session held in memory and decoded, for the registration tests: camera pairs by
// trigger, the CMM's position track, and clock offsets estimated from the clock-sync messages (as
// the station does; the true offsets are only in the simulator's truth).
#pragma once

#include "stampscan/acquisition/trace/trace_messages.hpp"
#include "stampscan/registration/laser_geometry.hpp"
#include "stampscan/sim/cmm_motion.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <opencv2/core.hpp>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::test_support {

namespace msg = stampscan::trace;

struct FramePair {
  msg::CameraFrame left, right;
  bool complete() const { return !left.data.empty() && !right.data.empty(); }
};

class DecodedSession final : public sim::TraceSink {
 public:
  void message(std::string_view topic, std::int64_t, std::vector<std::byte> bytes) override {
    if (topic == msg::topics::kCameraLeft || topic == msg::topics::kCameraRight) {
      msg::CameraFrame f = msg::decode<msg::CameraFrame>(bytes);
      FramePair& pair = pairs[f.trigger_id];
      (f.camera == "left" ? pair.left : pair.right) = std::move(f);
    } else if (topic == msg::topics::kCmmPosition) {
      positions.push_back(msg::decode<msg::CmmPosition>(bytes));
    } else if (topic == msg::topics::kClockSync) {
      const msg::ClockSync c = msg::decode<msg::ClockSync>(bytes);
      auto& [sum, count] = sync[c.device];
      sum += static_cast<double>(c.device_time_ns - c.station_time_ns);
      ++count;
    } else if (topic == msg::topics::kLaserProfile) {
      profiles.push_back(msg::decode<msg::LaserProfile>(bytes));
    } else if (topic == msg::topics::kCmmEvent) {
      events.push_back(msg::decode<msg::CmmEvent>(bytes));
    } else if (topic == msg::topics::kScene) {
      scenes.push_back(msg::decode<msg::SceneMarker>(bytes));
    }
  }
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override {
    metadata_records[name] = values;
  }

  // Mean device-minus-station offset of a device's clock.
  std::int64_t clockOffset(const std::string& device) const {
    const auto it = sync.find(device);
    if (it == sync.end() || it->second.second == 0) throw std::runtime_error("no clock sync for " + device);
    return static_cast<std::int64_t>(it->second.first / static_cast<double>(it->second.second));
  }

  // The head's state at a station time, linearly interpolated between position reports.
  sim::HeadState headAt(std::int64_t t) const {
    const auto it = std::lower_bound(positions.begin(), positions.end(), t,
                                     [](const msg::CmmPosition& p, std::int64_t v) { return p.station_time_ns < v; });
    if (it == positions.begin() || it == positions.end()) throw std::runtime_error("time outside the CMM track");
    const msg::CmmPosition& b = *it;
    const msg::CmmPosition& a = *(it - 1);
    const double f = static_cast<double>(t - a.station_time_ns) / static_cast<double>(b.station_time_ns - a.station_time_ns);
    sim::HeadState h;
    h.position = Eigen::Vector3d(a.x, a.y, a.z) + f * (Eigen::Vector3d(b.x, b.y, b.z) - Eigen::Vector3d(a.x, a.y, a.z));
    h.a = a.head_a + f * (b.head_a - a.head_a);
    h.b = a.head_b + f * (b.head_b - a.head_b);
    return h;
  }

  static cv::Mat image(const msg::CameraFrame& f) {
    const int type = f.encoding == "mono8" ? CV_8U : CV_16U;
    return cv::Mat(static_cast<int>(f.height), static_cast<int>(f.width), type, const_cast<std::uint8_t*>(f.data.data()),
                   f.step)
        .clone();
  }

  std::map<std::uint64_t, FramePair> pairs;
  std::vector<msg::CmmPosition> positions;
  std::vector<msg::LaserProfile> profiles;
  std::vector<msg::SceneMarker> scenes;
  std::vector<msg::CmmEvent> events;

  // Station-time windows of the sweeps whose label starts with `prefix` ("part", "reference_sphere").
  std::vector<std::pair<std::int64_t, std::int64_t>> sweepWindows(const std::string& prefix) const {
    std::vector<std::pair<std::int64_t, std::int64_t>> out;
    std::int64_t begin = -1;
    for (const msg::CmmEvent& e : events) {
      if (e.detail.rfind(prefix, 0) != 0) continue;
      if (e.kind == msg::CmmEventKind::SweepBegin) begin = e.station_time_ns;
      if (e.kind == msg::CmmEventKind::SweepEnd && begin >= 0) out.emplace_back(begin, e.station_time_ns), begin = -1;
    }
    return out;
  }
  std::map<std::string, std::pair<double, std::size_t>> sync;
  std::map<std::string, std::map<std::string, std::string>> metadata_records;
};

// A trace profile as the registration code takes it.
inline registration::Profile profileOf(const msg::LaserProfile& m) {
  registration::Profile p;
  p.device_time_ns = m.device_time_ns;
  p.angle_min = m.angle_min;
  p.angle_increment = m.angle_increment;
  p.range = m.range;
  p.intensity = m.intensity;
  p.overexposed = (m.status & msg::kProfileOverexposed) != 0;
  return p;
}

// The CMM's reports as a head track.
inline registration::HeadTrack trackOf(const DecodedSession& s) {
  std::vector<registration::HeadSample> samples;
  for (const auto& p : s.positions) samples.push_back({p.station_time_ns, Eigen::Vector3d(p.x, p.y, p.z), p.head_a, p.head_b});
  return registration::HeadTrack(std::move(samples));
}

}  // namespace stampscan::test_support
