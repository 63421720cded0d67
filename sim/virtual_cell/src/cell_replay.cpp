#include "stampscan/sim/cell_replay.hpp"

#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string_view>

namespace stampscan::sim {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
// How close a recorded pose must be to a commanded one to be taken for it: the reports' resolution
// (a micrometre) with room for the client's degree rounding.
constexpr double kMatchMm = 0.02, kMatchDeg = 0.01;

std::int64_t steadyNs(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

// device minus station: the median over the pairs, as the measurement takes it.
std::int64_t medianOffset(std::vector<std::int64_t> d) {
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

std::array<double, 6> axes(const RecordedPose& p) {
  return {p.xyz[0], p.xyz[1], p.xyz[2], p.head_a * kDegPerRad, p.head_b * kDegPerRad, 0.0};
}

bool near(const std::array<double, 6>& a, const std::array<double, 6>& b) {
  for (std::size_t i = 0; i < 3; ++i)
    if (std::abs(a[i] - b[i]) > kMatchMm) return false;
  for (std::size_t i = 3; i < 6; ++i)
    if (std::abs(a[i] - b[i]) > kMatchDeg) return false;
  return true;
}

template <typename T>
std::size_t nearestIndex(const std::vector<T>& items, std::int64_t t) {
  const auto it = std::lower_bound(items.begin(), items.end(), t,
                                   [](const T& item, std::int64_t value) { return item.station_time_ns < value; });
  std::size_t k = static_cast<std::size_t>(it - items.begin());
  if (k == items.size() || (k > 0 && t - items[k - 1].station_time_ns < items[k].station_time_ns - t)) --k;
  return k;
}

}  // namespace

RecordedSession loadRecordedSession(const std::filesystem::path& file) {
  RecordedSession out;
  struct CameraFrame {
    int camera;
    RecordedFrame frame;
    std::int64_t device_time_ns;  // its exposure, on the camera's clock
  };
  std::vector<std::pair<std::int64_t, RecordedProfile>> profiles;  // device time
  std::vector<CameraFrame> frames;
  std::map<std::string, std::vector<std::int64_t>> device_minus_station;
  trace::McapReader reader(file);
  out.health = reader.readMessages([&](const trace::TraceMessage& m) {
    if (!m.channel) return true;
    const std::string& topic = m.channel->topic;
    try {
      if (topic == trace::topics::kCmmPosition) {
        const auto p = trace::decode<trace::CmmPosition>(m.data);
        out.head.push_back({p.station_time_ns, {p.x, p.y, p.z}, p.head_a, p.head_b});
      } else if (topic == trace::topics::kLaserProfile) {
        auto p = trace::decode<trace::LaserProfile>(m.data);
        profiles.push_back({p.device_time_ns, RecordedProfile{0, p.status, std::move(p.range), std::move(p.intensity)}});
      } else if (topic == trace::topics::kClockSync) {
        const auto c = trace::decode<trace::ClockSync>(m.data);
        device_minus_station[c.device].push_back(c.device_time_ns - c.station_time_ns);
      } else if (topic == trace::topics::kCameraLeft || topic == trace::topics::kCameraRight) {
        auto f = trace::decode<trace::CameraFrame>(m.data);
        RecordedFrame frame;
        frame.width = f.width;
        frame.height = f.height;
        frame.bytes_per_pixel = f.encoding == "mono16" ? 2 : 1;
        const std::size_t row = std::size_t{f.width} * frame.bytes_per_pixel;
        if (f.step < row || f.data.size() < std::size_t{f.step} * f.height) return true;  // malformed: not served
        frame.data.resize(row * f.height);
        for (std::uint32_t y = 0; y < f.height; ++y)
          std::copy_n(f.data.begin() + static_cast<std::ptrdiff_t>(std::size_t{y} * f.step), row,
                      frame.data.begin() + static_cast<std::ptrdiff_t>(std::size_t{y} * row));
        // When it reached the station, until its exposure on the station clock is known (below):
        // the head may have left the view long before its frame arrived.
        frame.station_time_ns = static_cast<std::int64_t>(m.log_time);
        frames.push_back({f.camera == "right" ? 1 : 0, std::move(frame), f.device_time_ns});
      }
    } catch (const trace::MessageError&) {
      // A message that does not decode is left out, as the measurement leaves it out.
    }
    return true;
  });
  const std::string name = file.string();
  if (out.health.not_mcap) throw std::runtime_error(name + ": not an MCAP trace");
  bool described = false;
  for (const auto& md : out.health.metadata) {
    if (md.name != trace::kSessionMetadataName) continue;
    try {
      out.session = trace::decodeSession(md.metadata);
    } catch (const trace::SessionDescriptionError& e) {
      throw std::runtime_error(name + ": " + e.what());
    }
    described = true;
  }
  if (!described) throw std::runtime_error(name + ": the trace has no session description (metadata 'cell')");
  if (out.head.size() < 2) throw std::runtime_error(name + ": the trace holds no CMM position reports");
  std::stable_sort(out.head.begin(), out.head.end(),
                   [](const RecordedPose& a, const RecordedPose& b) { return a.station_time_ns < b.station_time_ns; });

  if (!profiles.empty()) {
    const auto pairs = device_minus_station.find("digitizer");
    if (pairs == device_minus_station.end())
      throw std::runtime_error(name + ": the trace has profiles but no clock-sync pairs for the digitizer");
    const std::int64_t offset = medianOffset(pairs->second);
    for (auto& [device_time, profile] : profiles) {
      profile.station_time_ns = device_time - offset;
      out.profiles.push_back(std::move(profile));
    }
    std::stable_sort(out.profiles.begin(), out.profiles.end(), [](const RecordedProfile& a, const RecordedProfile& b) {
      return a.station_time_ns < b.station_time_ns;
    });
  }
  // A frame's exposure on the station clock, through its camera's clock pairs (the station's own
  // reading of that camera's clock, which the recording's measurement used too).
  for (const char* camera : {"camera_left", "camera_right"}) {
    const auto pairs = device_minus_station.find(camera);
    if (pairs == device_minus_station.end() || pairs->second.empty()) continue;
    const std::int64_t offset = medianOffset(pairs->second);
    const int index = std::string_view(camera) == "camera_right" ? 1 : 0;
    for (auto& f : frames)
      if (f.camera == index) f.frame.station_time_ns = f.device_time_ns - offset;
  }
  for (auto& f : frames) out.frames[f.camera].push_back(std::move(f.frame));
  for (auto& list : out.frames)
    std::stable_sort(list.begin(), list.end(), [](const RecordedFrame& a, const RecordedFrame& b) {
      return a.station_time_ns < b.station_time_ns;
    });
  return out;
}

CellReplay::CellReplay(RecordedSession session) : recording_(std::move(session)) {
  // The usual spacing of reports while the head moves: the median of the short gaps.
  std::vector<std::int64_t> gaps;
  for (std::size_t i = 1; i < recording_.head.size(); ++i) {
    const std::int64_t gap = recording_.head[i].station_time_ns - recording_.head[i - 1].station_time_ns;
    if (gap > 0 && gap < 200'000'000) gaps.push_back(gap);
  }
  if (!gaps.empty()) report_interval_s_ = static_cast<double>(medianOffset(gaps)) * 1e-9;
}

std::optional<FollowedMove> CellReplay::followMove(const std::array<double, 6>& from, const std::array<double, 6>& to,
                                                   std::chrono::steady_clock::time_point now) {
  std::lock_guard lock(mutex_);
  const std::vector<RecordedPose>& head = recording_.head;
  // The arrival: the first sample from the cursor on at the target (a straight move reaches its
  // target only at its end).
  std::optional<std::size_t> arrival;
  for (std::size_t i = cursor_; i < head.size() && !arrival; ++i)
    if (near(axes(head[i]), to)) arrival = i;
  // The departure: the last sample before the arrival still where the machine stands.
  std::optional<std::size_t> departure;
  if (arrival) {
    for (std::size_t j = *arrival + 1; j-- > cursor_;) {
      if (near(axes(head[j]), from)) {
        departure = j;
        break;
      }
    }
  }
  if (!arrival || !departure) {
    ++stats_.moves_not_recorded;
    return std::nullopt;
  }
  // Reports come while the head moves, the first as it starts. A departure sample within one report
  // interval (and some slack) of the first moving one is that first report: the move began there.
  // Otherwise it ended a rest long before, and the motion began about one interval before the first
  // moving sample.
  std::int64_t start_ns = head[*departure].station_time_ns;
  bool reported_at_start = true;
  if (*departure < *arrival) {
    const std::int64_t first_moving = head[*departure + 1].station_time_ns;
    const auto interval_ns = static_cast<std::int64_t>(report_interval_s_ * 1e9);
    if (first_moving - start_ns > interval_ns + interval_ns / 2) {
      start_ns = first_moving - interval_ns;
      reported_at_start = false;
    }
  }
  std::vector<std::pair<double, std::array<double, 6>>> track;
  track.push_back({0.0, from});
  for (std::size_t k = *departure + 1; k <= *arrival; ++k)
    track.push_back({static_cast<double>(head[k].station_time_ns - start_ns) * 1e-9, axes(head[k])});
  cursor_ = *arrival;
  offset_ns_ = start_ns - steadyNs(now);
  offset_known_ = true;
  if (shared_offset_ns_ != nullptr) {
    shared_offset_ns_->store(offset_ns_);
    shared_known_->store(true);
  }
  ++stats_.moves_followed;

  FollowedMove move;
  move.seconds = std::max(0.0, track.back().first);
  // The recorded CMM reported as the move began (the head still at rest) when the departure sample
  // is the move's start; without that report the track would run straight from the last rest
  // report, long before, to the first moving one, and put the head on its way too early.
  if (reported_at_start) move.report_at.push_back(0.0);
  for (std::size_t k = 1; k < track.size(); ++k) move.report_at.push_back(track[k].first);
  move.pose_at = [track = std::move(track)](double t) {
    const auto after = std::upper_bound(track.begin(), track.end(), t,
                                        [](double value, const auto& sample) { return value < sample.first; });
    if (after == track.begin()) return track.front().second;
    if (after == track.end()) return track.back().second;
    const auto& [t0, p0] = *(after - 1);
    const auto& [t1, p1] = *after;
    const double f = t1 > t0 ? (t - t0) / (t1 - t0) : 1.0;
    std::array<double, 6> p{};
    for (std::size_t i = 0; i < 6; ++i) p[i] = p0[i] + (p1[i] - p0[i]) * f;
    return p;
  };
  return move;
}

std::int64_t CellReplay::recordedTime(std::chrono::steady_clock::time_point t) const {
  std::lock_guard lock(mutex_);
  const bool known = shared_known_ != nullptr ? shared_known_->load() : offset_known_;
  const std::int64_t offset = shared_offset_ns_ != nullptr ? shared_offset_ns_->load() : offset_ns_;
  // Before the first followed move the recording's first report stands for the replay's start.
  if (!known) return recording_.head.front().station_time_ns;
  return steadyNs(t) + offset;
}

void CellReplay::shareTimeMap(std::atomic<std::int64_t>* offset_ns, std::atomic<bool>* known) {
  std::lock_guard lock(mutex_);
  shared_offset_ns_ = offset_ns;
  shared_known_ = known;
}

const RecordedProfile* CellReplay::profileNear(std::int64_t recorded_ns, std::int64_t tolerance_ns) {
  std::lock_guard lock(mutex_);
  if (recording_.profiles.empty()) return nullptr;
  const RecordedProfile& p = recording_.profiles[nearestIndex(recording_.profiles, recorded_ns)];
  if (std::abs(p.station_time_ns - recorded_ns) > tolerance_ns) {
    ++stats_.profiles_missing;
    return nullptr;
  }
  ++stats_.profiles_served;
  return &p;
}

const RecordedFrame* CellReplay::frameNear(int camera, std::int64_t recorded_ns, std::int64_t tolerance_ns) {
  std::lock_guard lock(mutex_);
  const std::vector<RecordedFrame>& frames = recording_.frames[camera == 1 ? 1 : 0];
  if (frames.empty()) return nullptr;
  const RecordedFrame& f = frames[nearestIndex(frames, recorded_ns)];
  if (std::abs(f.station_time_ns - recorded_ns) > tolerance_ns) return nullptr;
  ++stats_.frames_served;
  return &f;
}

ReplayStats CellReplay::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

PreparedReplay prepareReplay(const std::filesystem::path& trace_file, bool accept_damaged,
                             const std::filesystem::path& plan_file) {
  const std::string name = trace_file.string();
  RecordedSession recorded = loadRecordedSession(trace_file);
  if (const auto loss = trace::describeDataLoss(recorded.health); loss && !accept_damaged)
    throw std::runtime_error(name + " is damaged: " + *loss + "; pass --accept-damaged to replay what remains");
  if (recorded.session.plan_toml.empty() && plan_file.empty())
    throw std::runtime_error(name + " does not carry its scan plan (recorded before traces kept it): pass --plan with "
                                    "the plan it was recorded with");
  PreparedReplay out;
  out.plan = plan_file.empty() ? acquisition::parseScanPlan(recorded.session.plan_toml, name + " (its plan)")
                               : acquisition::loadScanPlan(plan_file);
  out.session = recorded.session;
  out.replay = std::make_shared<CellReplay>(std::move(recorded));
  return out;
}

}  // namespace stampscan::sim
