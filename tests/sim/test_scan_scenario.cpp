// The simulated session: deterministic by seed, in log-time order, every message decodable, scenes
// bracketed, cameras paired, and the raw data consistent with the cell's true geometry and clocks
// (profiles placed with the true hand-eye transform and latency lie on the part and the sphere).
#include "stampscan/acquisition/trace/trace_messages.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

namespace {

using namespace stampscan::sim;
namespace msg = stampscan::trace;

struct Stored {
  std::string topic;
  std::int64_t log_time;
  std::vector<std::byte> bytes;
};

class MemorySink final : public TraceSink {
 public:
  void message(std::string_view topic, std::int64_t log_time_ns, std::vector<std::byte> bytes) override {
    messages.push_back({std::string(topic), log_time_ns, std::move(bytes)});
  }
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override {
    metadata_records[name] = values;
  }
  std::vector<Stored> messages;
  std::map<std::string, std::map<std::string, std::string>> metadata_records;
};

ScanParams small(std::uint64_t seed = 5) {
  ScanParams p = ScanParams::quick();
  p.seed = seed;
  p.plate_poses = 3;
  return p;
}

struct Session {
  MemorySink sink;
  ScanSummary summary;
};

const Session& dome() {
  static const Session session = [] {
    Session s;
    s.summary = generateScan(small(), s.sink);
    return s;
  }();
  return session;
}

std::uint64_t fingerprint(const MemorySink& sink) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&](std::uint64_t v) { h = (h ^ v) * 1099511628211ull; };
  for (const Stored& m : sink.messages) {
    mix(static_cast<std::uint64_t>(m.log_time));
    for (char c : m.topic) mix(static_cast<std::uint64_t>(c));
    for (std::byte b : m.bytes) mix(static_cast<std::uint64_t>(b));
  }
  return h;
}

TEST(ScanSession, SameSeedGivesTheSameTraceAndAnotherSeedAnother) {
  MemorySink again;
  generateScan(small(), again);
  EXPECT_EQ(fingerprint(again), fingerprint(dome().sink));
  MemorySink other;
  generateScan(small(6), other);
  EXPECT_NE(fingerprint(other), fingerprint(dome().sink));
}

TEST(ScanSession, MessagesComeInLogTimeOrderAndDecode) {
  const Session& s = dome();
  ASSERT_EQ(s.sink.messages.size(), s.summary.messages);
  std::map<std::string, std::size_t> counts;
  for (std::size_t i = 0; i < s.sink.messages.size(); ++i) {
    const Stored& m = s.sink.messages[i];
    if (i > 0) {
      ASSERT_GE(m.log_time, s.sink.messages[i - 1].log_time) << "message " << i << " on " << m.topic;
    }
    ++counts[m.topic];
    if (m.topic == msg::topics::kLaserProfile) {
      const auto p = msg::decode<msg::LaserProfile>(m.bytes);
      EXPECT_EQ(p.range.size(), static_cast<std::size_t>(small().digitizer.points_per_profile));
    } else if (m.topic == msg::topics::kCameraLeft || m.topic == msg::topics::kCameraRight) {
      const auto f = msg::decode<msg::CameraFrame>(m.bytes);
      EXPECT_EQ(f.data.size(), static_cast<std::size_t>(f.step) * f.height);
    } else if (m.topic == msg::topics::kCmmPosition) {
      msg::decode<msg::CmmPosition>(m.bytes);
    } else if (m.topic == msg::topics::kPlcState) {
      msg::decode<msg::PlcState>(m.bytes);
    } else if (m.topic == msg::topics::kClockSync) {
      msg::decode<msg::ClockSync>(m.bytes);
    } else if (m.topic == msg::topics::kCmmEvent) {
      msg::decode<msg::CmmEvent>(m.bytes);
    } else if (m.topic == msg::topics::kScene) {
      msg::decode<msg::SceneMarker>(m.bytes);
    } else {
      ADD_FAILURE() << "unexpected topic " << m.topic;
    }
  }
  EXPECT_EQ(counts[std::string(msg::topics::kLaserProfile)], s.summary.profiles);
  EXPECT_EQ(counts[std::string(msg::topics::kCameraLeft)] + counts[std::string(msg::topics::kCameraRight)],
            s.summary.frames);
  EXPECT_EQ(counts[std::string(msg::topics::kCmmPosition)], s.summary.positions);
  // 3 plate poses and 2 part views, both cameras each.
  EXPECT_EQ(s.summary.frames, 10u);
  EXPECT_TRUE(s.sink.metadata_records.count("cell"));
  EXPECT_TRUE(s.sink.metadata_records.count("simulation_truth"));
}

TEST(ScanSession, ScenesAreBracketedAndCamerasPaired) {
  const Session& s = dome();
  std::map<msg::Scene, std::vector<std::string>> phases;
  std::map<std::uint64_t, std::vector<msg::CameraFrame>> by_trigger;
  for (const Stored& m : s.sink.messages) {
    if (m.topic == msg::topics::kScene) {
      const auto marker = msg::decode<msg::SceneMarker>(m.bytes);
      phases[marker.scene].push_back(marker.phase);
    } else if (m.topic == msg::topics::kCameraLeft || m.topic == msg::topics::kCameraRight) {
      auto f = msg::decode<msg::CameraFrame>(m.bytes);
      f.data.clear();
      by_trigger[f.trigger_id].push_back(f);
    }
  }
  // Each run of a scene's steps is bracketed. The part's sweeps and its views are two runs, with the
  // plate's views between them (acquisition::withCalibrationScenes).
  const std::vector<std::string> one_run{"begin", "end"}, two_runs{"begin", "end", "begin", "end"};
  EXPECT_EQ(phases[msg::Scene::ReferenceSphere], one_run);
  EXPECT_EQ(phases[msg::Scene::CalibrationPlate], one_run);
  EXPECT_EQ(phases[msg::Scene::Part], two_runs);
  ASSERT_EQ(by_trigger.size(), 5u);
  const CellTruth& truth = s.summary.truth;
  for (const auto& [trigger, frames] : by_trigger) {
    ASSERT_EQ(frames.size(), 2u) << "trigger " << trigger;
    EXPECT_NE(frames[0].camera, frames[1].camera);
    // Both exposures started together: equal once each camera's clock offset is removed.
    const auto station_time = [&](const msg::CameraFrame& f) {
      return f.device_time_ns - truth.camera_clock_offset_ns[f.camera == "left" ? 0 : 1];
    };
    EXPECT_EQ(station_time(frames[0]), station_time(frames[1]));
  }
}

// Linear interpolation of the CMM's reported head state at a station time.
struct PositionTrack {
  std::vector<msg::CmmPosition> reports;
  HeadState at(std::int64_t t) const {
    const auto it = std::lower_bound(reports.begin(), reports.end(), t,
                                     [](const msg::CmmPosition& p, std::int64_t v) { return p.station_time_ns < v; });
    if (it == reports.begin() || it == reports.end()) throw std::runtime_error("time outside the CMM track");
    const msg::CmmPosition& b = *it;
    const msg::CmmPosition& a = *(it - 1);
    const double f = static_cast<double>(t - a.station_time_ns) / static_cast<double>(b.station_time_ns - a.station_time_ns);
    HeadState h;
    h.position = Vec3(a.x, a.y, a.z) + f * (Vec3(b.x, b.y, b.z) - Vec3(a.x, a.y, a.z));
    h.a = a.head_a + f * (b.head_a - a.head_a);
    h.b = a.head_b + f * (b.head_b - a.head_b);
    return h;
  }
};

TEST(ScanSession, ProfilesPlacedWithTheTrueCalibrationLieOnPartAndSphere) {
  const Session& s = dome();
  const CellTruth& truth = s.summary.truth;
  PositionTrack track;
  bool in_scene = false;
  msg::Scene scene = msg::Scene::Part;
  for (const Stored& m : s.sink.messages)
    if (m.topic == msg::topics::kCmmPosition) track.reports.push_back(msg::decode<msg::CmmPosition>(m.bytes));
  const DomePart part;
  double part_sq = 0, sphere_sq = 0, shifted_sq = 0;
  std::size_t part_n = 0, sphere_n = 0;
  for (const Stored& m : s.sink.messages) {
    if (m.topic == msg::topics::kScene) {
      const auto marker = msg::decode<msg::SceneMarker>(m.bytes);
      in_scene = marker.phase == "begin";
      scene = marker.scene;
    }
    if (m.topic != msg::topics::kLaserProfile || !in_scene || scene == msg::Scene::CalibrationPlate) continue;
    const auto p = msg::decode<msg::LaserProfile>(m.bytes);
    const std::int64_t exposure = p.device_time_ns - truth.digitizer_clock_offset_ns - truth.digitizer_latency_ns;
    const Eigen::Isometry3d sensor = track.at(exposure).pose() * truth.head_from_digitizer;
    // The same profile placed as if there were no latency: the head has moved on by then.
    const Eigen::Isometry3d late = track.at(exposure + truth.digitizer_latency_ns).pose() * truth.head_from_digitizer;
    for (std::size_t i = 0; i < p.range.size(); ++i) {
      if (p.range[i] <= 0) continue;
      const double angle = p.angle_min + static_cast<double>(i) * p.angle_increment;
      const Vec3 ray(std::sin(angle), 0, -std::cos(angle));
      const Vec3 x = sensor * (static_cast<double>(p.range[i]) * ray);
      if (scene == msg::Scene::Part) {
        part_sq += std::pow(part.distance(x), 2);
        ++part_n;
      } else {
        const auto residual = [&](const Vec3& q) { return (q - truth.sphere.centre).norm() - truth.sphere.radius; };
        if (std::abs(residual(x)) > 5) continue;  // the table, not the ball
        sphere_sq += std::pow(residual(x), 2);
        shifted_sq += std::pow(residual(late * (static_cast<double>(p.range[i]) * ray)), 2);
        ++sphere_n;
      }
    }
  }
  ASSERT_GT(part_n, 10000u);
  ASSERT_GT(sphere_n, 1000u);
  const double part_rms = std::sqrt(part_sq / static_cast<double>(part_n));
  const double sphere_rms = std::sqrt(sphere_sq / static_cast<double>(sphere_n));
  const double shifted_rms = std::sqrt(shifted_sq / static_cast<double>(sphere_n));
  // The range noise is 6 um at normal incidence, more on slopes; glare adds a few bad points.
  EXPECT_LT(part_rms, 0.02);
  EXPECT_LT(sphere_rms, 0.02);
  // Ignoring the latency misplaces the sphere's points measurably: calibration must find it.
  EXPECT_GT(shifted_rms, 1.5 * sphere_rms);
}

TEST(ScanSession, PlcTimelineAndTheShutterOpenOnlyForSweeps) {
  const Session& s = dome();
  std::uint32_t expected = 0;
  bool in_sweep = false, moving = false, door_was_open = false, door_closed_later = false;
  std::size_t open = 0;
  msg::PlcState last;
  for (const Stored& m : s.sink.messages) {
    if (m.topic == msg::topics::kCmmEvent) {
      const auto e = msg::decode<msg::CmmEvent>(m.bytes);
      if (e.kind == msg::CmmEventKind::SweepBegin) in_sweep = true;
      if (e.kind == msg::CmmEventKind::SweepEnd) in_sweep = false;
      if (e.kind == msg::CmmEventKind::MoveBegin && e.detail != "load part" && e.detail != "unload part") {
        moving = true;
        // The CMM moves only with the door closed and the part clamped.
        EXPECT_TRUE(last.door_closed && last.part_clamped) << "motion at " << e.station_time_ns;
      }
    }
    if (m.topic != msg::topics::kPlcState) continue;
    const auto st = msg::decode<msg::PlcState>(m.bytes);
    EXPECT_EQ(st.heartbeat, expected++);
    EXPECT_TRUE(st.estop_ok);
    if (!st.door_closed && !moving) door_was_open = true;
    if (door_was_open && st.door_closed) door_closed_later = true;
    EXPECT_EQ(st.laser_shutter_open, in_sweep);
    EXPECT_FALSE(st.laser_shutter_open && !st.door_closed);
    open += st.laser_shutter_open;
    last = st;
  }
  EXPECT_TRUE(door_was_open && door_closed_later);
  EXPECT_FALSE(last.door_closed);  // opened again to unload
  EXPECT_GT(open, 10u);
}

TEST(ScanSession, PanWithSquareGridAndOnlyTheLaser) {
  ScanParams p = small();
  p.part = PartKind::Pan;
  p.grid.kind = GridKind::Square;
  p.stereo = p.calibration = false;
  MemorySink sink;
  const ScanSummary summary = generateScan(p, sink);
  EXPECT_EQ(summary.frames, 0u);
  EXPECT_GT(summary.profiles, 100u);
  EXPECT_GT(summary.laser_points, summary.profiles * 100);
  EXPECT_EQ(sink.metadata_records.at("cell").at("part"), "pan");
  EXPECT_EQ(sink.metadata_records.at("cell").at("grid"), "square");
}

}  // namespace
