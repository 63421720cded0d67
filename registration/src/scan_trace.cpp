#include "stampscan/registration/scan_trace.hpp"

#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <algorithm>
#include <stdexcept>

namespace stampscan::registration {

namespace msg = stampscan::trace;

namespace {
cv::Mat imageOf(const msg::CameraFrame& f) {
  const int type = f.encoding == "mono8" ? CV_8U : CV_16U;
  return cv::Mat(static_cast<int>(f.height), static_cast<int>(f.width), type, const_cast<std::uint8_t*>(f.data.data()),
                 f.step)
      .clone();
}
}  // namespace

ScanTrace loadScanTrace(const std::filesystem::path& file, const LoadProgress& progress, bool keep_part_frames) {
  ScanTrace out;
  trace::McapReader reader(file);
  const std::uint64_t size = std::max<std::uint64_t>(reader.fileSize(), 1);
  std::string scene;  // the scene the plate frames belong to, from the scene markers
  std::map<std::uint64_t, std::pair<msg::CameraFrame, msg::CameraFrame>> plate_pairs, part_pairs;
  std::int64_t sweep_begin = -1;
  std::string sweep_label;
  std::size_t decode_errors = 0;
  std::string first_decode_error;
  out.health = reader.readMessages([&](const trace::TraceMessage& m) {
    if (progress && (out.health.messages_delivered & 1023) == 0)
      progress(static_cast<double>(m.record_offset) / static_cast<double>(size));
    if (!m.channel) return true;
    const std::string& topic = m.channel->topic;
    try {
      if (topic == msg::topics::kCmmPosition) {
        const auto p = msg::decode<msg::CmmPosition>(m.data);
        if (out.head.empty() || p.station_time_ns > out.head.back().time_ns)
          out.head.push_back({p.station_time_ns, Vec3(p.x, p.y, p.z), p.head_a, p.head_b});
      } else if (topic == msg::topics::kLaserProfile) {
        const auto p = msg::decode<msg::LaserProfile>(m.data);
        Profile prof;
        prof.device_time_ns = p.device_time_ns;
        prof.angle_min = p.angle_min;
        prof.angle_increment = p.angle_increment;
        prof.range = p.range;
        prof.intensity = p.intensity;
        prof.overexposed = (p.status & msg::kProfileOverexposed) != 0;
        out.profiles.push_back(std::move(prof));
      } else if (topic == msg::topics::kClockSync) {
        const auto c = msg::decode<msg::ClockSync>(m.data);
        out.clock_pairs[c.device].emplace_back(c.station_time_ns, c.device_time_ns);
      } else if (topic == msg::topics::kCmmEvent) {
        const auto e = msg::decode<msg::CmmEvent>(m.data);
        if (e.kind == "sweep_begin") {
          sweep_begin = e.station_time_ns;
          sweep_label = e.detail;
        } else if (e.kind == "sweep_end" && sweep_begin >= 0 && e.detail == sweep_label) {
          out.sweeps.push_back({sweep_label, sweep_begin, e.station_time_ns});
          sweep_begin = -1;
        }
      } else if (topic == msg::topics::kScene) {
        const auto s = msg::decode<msg::SceneMarker>(m.data);
        scene = s.phase == "begin" ? s.scene : "";
      } else if (topic == msg::topics::kCameraLeft || topic == msg::topics::kCameraRight) {
        if (scene == "calibration_plate") {
          auto f = msg::decode<msg::CameraFrame>(m.data);
          auto& pair = plate_pairs[f.trigger_id];
          (f.camera == "left" ? pair.first : pair.second) = std::move(f);
        } else {
          ++out.part_frames;
          if (keep_part_frames && scene == "part") {
            auto f = msg::decode<msg::CameraFrame>(m.data);
            auto& pair = part_pairs[f.trigger_id];
            (f.camera == "left" ? pair.first : pair.second) = std::move(f);
          }
        }
      }
    } catch (const msg::MessageError& e) {
      if (decode_errors++ == 0) first_decode_error = e.what();
    }
    return true;
  });
  if (out.health.not_mcap) throw std::runtime_error(file.string() + ": not an MCAP trace");
  if (decode_errors > 0)
    out.health.damage.push_back({0, trace::DamageKind::BadRecord,
                                 std::to_string(decode_errors) + " messages did not decode; the first: " + first_decode_error});
  for (const auto& md : out.health.metadata)
    if (md.name == trace::kSessionMetadataName) {
      try {
        out.session = trace::decodeSession(md.metadata);
      } catch (const trace::SessionDescriptionError& e) {
        throw std::runtime_error(file.string() + ": " + e.what());
      }
    }
  for (auto& [trigger, pair] : plate_pairs) {
    if (pair.first.data.empty() || pair.second.data.empty()) continue;
    out.plate_left.push_back({trigger, pair.first.device_time_ns, imageOf(pair.first)});
    out.plate_right.push_back({trigger, pair.second.device_time_ns, imageOf(pair.second)});
  }
  for (auto& [trigger, pair] : part_pairs) {
    if (pair.first.data.empty() || pair.second.data.empty()) continue;
    out.part_left.push_back({trigger, pair.first.device_time_ns, imageOf(pair.first)});
    out.part_right.push_back({trigger, pair.second.device_time_ns, imageOf(pair.second)});
  }
  if (out.head.size() < 2) throw std::runtime_error(file.string() + ": the trace holds no CMM position reports");
  // A trace cut during a sweep (a crash, a power cut) keeps the sweep up to the cut: its window ends
  // with the last position the CMM reported.
  if (sweep_begin >= 0 && out.health.truncated && out.head.back().time_ns > sweep_begin)
    out.sweeps.push_back({sweep_label, sweep_begin, out.head.back().time_ns});
  out.scan_seconds = static_cast<double>(out.head.back().time_ns - out.head.front().time_ns) * 1e-9;
  if (progress) progress(1.0);
  return out;
}

}  // namespace stampscan::registration
