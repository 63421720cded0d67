#include "stampscan/registration/scan_trace.hpp"

#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <utility>

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

void ScanTraceBuilder::add(std::string_view topic, std::span<const std::byte> bytes) {
  try {
    if (topic == msg::topics::kCmmPosition) {
      const auto p = msg::decode<msg::CmmPosition>(bytes);
      // The runner writes positions from two threads (the CMM's move reports, and the pose it reads
      // at each stop), so one may arrive after a later one. Each goes in at its time (a repeated
      // instant once): a trace measured as it arrives then has the track a file gives, where the
      // head stood still at a stop instead of a chord across it.
      auto& head = out_.head;
      const auto at = std::upper_bound(head.begin(), head.end(), p.station_time_ns,
                                       [](std::int64_t t, const HeadSample& h) { return t < h.time_ns; });
      if (at == head.begin() || std::prev(at)->time_ns != p.station_time_ns)
        head.insert(at, {p.station_time_ns, Vec3(p.x, p.y, p.z), p.head_a, p.head_b});
    } else if (topic == msg::topics::kLaserProfile) {
      auto p = msg::decode<msg::LaserProfile>(bytes);
      Profile prof;
      prof.device_time_ns = p.device_time_ns;
      prof.angle_min = p.angle_min;
      prof.angle_increment = p.angle_increment;
      prof.range = std::move(p.range);
      prof.intensity = std::move(p.intensity);
      prof.overexposed = (p.status & msg::kProfileOverexposed) != 0;
      out_.profiles.push_back(std::move(prof));
    } else if (topic == msg::topics::kClockSync) {
      const auto c = msg::decode<msg::ClockSync>(bytes);
      out_.clock_pairs[c.device].emplace_back(c.station_time_ns, c.device_time_ns);
    } else if (topic == msg::topics::kCmmEvent) {
      const auto e = msg::decode<msg::CmmEvent>(bytes);
      if (e.kind == msg::CmmEventKind::SweepBegin) {
        sweep_begin_ = e.station_time_ns;
        sweep_label_ = e.detail;
      } else if (e.kind == msg::CmmEventKind::SweepEnd && sweep_begin_ >= 0 && e.detail == sweep_label_) {
        out_.sweeps.push_back({sweep_label_, sweep_begin_, e.station_time_ns});
        sweep_begin_ = -1;
      } else if (e.kind == msg::CmmEventKind::SweepDiscarded && !out_.sweeps.empty() && out_.sweeps.back().label == e.detail) {
        out_.sweeps.pop_back();  // it lost profiles and was run again
      }
    } else if (topic == msg::topics::kScene) {
      const auto s = msg::decode<msg::SceneMarker>(bytes);
      scene_ = s.phase == "begin" ? std::optional<msg::Scene>(s.scene) : std::nullopt;
    } else if (topic == msg::topics::kCameraLeft || topic == msg::topics::kCameraRight) {
      const bool plate = scene_ == msg::Scene::CalibrationPlate;
      if (!plate) ++out_.part_frames;
      if (!plate && !(keep_part_frames_ && scene_ == msg::Scene::Part)) return;
      auto f = msg::decode<msg::CameraFrame>(bytes);
      const std::uint64_t trigger = f.trigger_id;
      auto& pair = pending_pairs_[trigger];
      (f.camera == "left" ? pair.first : pair.second) = std::move(f);
      if (pair.first.data.empty() || pair.second.data.empty()) return;
      auto& left = plate ? out_.plate_left : out_.part_left;
      auto& right = plate ? out_.plate_right : out_.part_right;
      left.push_back({trigger, pair.first.device_time_ns, imageOf(pair.first)});
      right.push_back({trigger, pair.second.device_time_ns, imageOf(pair.second)});
      pending_pairs_.erase(trigger);
    }
  } catch (const msg::MessageError& e) {
    if (decode_errors_++ == 0) first_decode_error_ = e.what();
  }
}

void ScanTraceBuilder::metadata(const std::string& name, const std::map<std::string, std::string>& values) {
  if (name == trace::kSessionMetadataName) out_.session = trace::decodeSession(values);
}

TraceBulk ScanTraceBuilder::takeBulk() {
  TraceBulk bulk;
  bulk.profiles = std::exchange(out_.profiles, {});
  bulk.plate_left = std::exchange(out_.plate_left, {});
  bulk.plate_right = std::exchange(out_.plate_right, {});
  bulk.part_left = std::exchange(out_.part_left, {});
  bulk.part_right = std::exchange(out_.part_right, {});
  return bulk;
}

ScanTrace ScanTraceBuilder::finish(bool cut) const& {
  ScanTraceBuilder copy = *this;
  return std::move(copy).finish(cut);
}

ScanTrace ScanTraceBuilder::finish(bool cut) && {
  ScanTrace t = std::move(out_);
  out_ = {};
  if (decode_errors_ > 0)
    t.health.damage.push_back({0, trace::DamageKind::BadRecord,
                               std::to_string(decode_errors_) + " messages did not decode; the first: " + first_decode_error_});
  if (cut && sweep_begin_ >= 0 && !t.head.empty() && t.head.back().time_ns > sweep_begin_)
    t.sweeps.push_back({sweep_label_, sweep_begin_, t.head.back().time_ns});
  if (t.head.size() >= 2) t.scan_seconds = static_cast<double>(t.head.back().time_ns - t.head.front().time_ns) * 1e-9;
  return t;
}

void LiveScanTrace::message(std::string_view topic, std::int64_t, std::vector<std::byte> bytes) {
  std::lock_guard lock(mutex_);
  builder_.add(topic, bytes);
}

void LiveScanTrace::metadata(const std::string& name, const std::map<std::string, std::string>& values) {
  std::lock_guard lock(mutex_);
  builder_.metadata(name, values);
}

TraceBulk LiveScanTrace::takeBulk() {
  std::lock_guard lock(mutex_);
  return builder_.takeBulk();
}

ScanTrace loadScanTrace(const std::filesystem::path& file, const LoadProgress& progress, bool keep_part_frames) {
  trace::McapReader reader(file);
  const std::uint64_t size = std::max<std::uint64_t>(reader.fileSize(), 1);
  ScanTraceBuilder builder(keep_part_frames);
  std::uint64_t delivered = 0;
  trace::TraceHealth health = reader.readMessages([&](const trace::TraceMessage& m) {
    if (progress && (delivered++ & 1023) == 0) progress(static_cast<double>(m.record_offset) / static_cast<double>(size));
    if (m.channel) builder.add(m.channel->topic, m.data);
    return true;
  });
  if (health.not_mcap) throw std::runtime_error(file.string() + ": not an MCAP trace");
  for (const auto& md : health.metadata) {
    try {
      builder.metadata(md.name, md.metadata);
    } catch (const trace::SessionDescriptionError& e) {
      throw std::runtime_error(file.string() + ": " + e.what());
    }
  }
  ScanTrace out = std::move(builder).finish(health.truncated.has_value());
  const auto damage = std::move(out.health.damage);
  out.health = std::move(health);
  out.health.damage.insert(out.health.damage.end(), damage.begin(), damage.end());
  if (out.head.size() < 2) throw std::runtime_error(file.string() + ": the trace holds no CMM position reports");
  if (progress) progress(1.0);
  return out;
}

}  // namespace stampscan::registration
