// ScanTraceBuilder: the decoding that both the file reader and a live scan use. Sweep windows from
// the CMM's events (a discarded run dropped, an open one kept at a cut), frames paired by trigger
// into the scene they were taken in.
#include "stampscan/registration/scan_trace.hpp"

#include <gtest/gtest.h>

namespace stampscan::registration {
namespace {

namespace msg = stampscan::trace;

void event(ScanTraceBuilder& b, std::int64_t t, const std::string& kind, const std::string& detail) {
  msg::CmmEvent e;
  e.station_time_ns = t;
  e.kind = msg::cmmEventKindFromString(kind);
  e.detail = detail;
  b.add(msg::topics::kCmmEvent, msg::encode(e));
}

void position(ScanTraceBuilder& b, std::int64_t t) {
  msg::CmmPosition p;
  p.station_time_ns = t;
  b.add(msg::topics::kCmmPosition, msg::encode(p));
}

void frame(ScanTraceBuilder& b, const std::string& camera, std::uint64_t trigger) {
  msg::CameraFrame f;
  f.camera = camera;
  f.trigger_id = trigger;
  f.width = 4;
  f.height = 2;
  f.encoding = "mono8";
  f.step = 4;
  f.data.assign(8, 100);
  b.add(camera == "left" ? msg::topics::kCameraLeft : msg::topics::kCameraRight, msg::encode(f));
}

void marker(ScanTraceBuilder& b, msg::Scene scene, const std::string& phase) {
  msg::SceneMarker m;
  m.scene = scene;
  m.phase = phase;
  b.add(msg::topics::kScene, msg::encode(m));
}

TEST(ScanTraceBuilder, ADiscardedSweepIsLeftOutAndItsRepeatKept) {
  ScanTraceBuilder b;
  position(b, 0);
  event(b, 10, "sweep_begin", "part sweep 0");
  event(b, 20, "sweep_end", "part sweep 0");
  event(b, 21, "sweep_discarded", "part sweep 0");
  event(b, 30, "sweep_begin", "part sweep 0");
  event(b, 40, "sweep_end", "part sweep 0");
  position(b, 50);
  const ScanTrace t = b.finish(false);
  ASSERT_EQ(t.sweeps.size(), 1u);
  EXPECT_EQ(t.sweeps[0].begin_ns, 30);
  EXPECT_EQ(t.sweeps[0].end_ns, 40);
}

// The runner writes positions from two threads, so a report can arrive after a later one: it goes
// in at its time (as a trace file's reader, which sorts by log time, has it), a repeated one once.
TEST(ScanTraceBuilder, ALatePositionGoesInAtItsTime) {
  ScanTraceBuilder b;
  position(b, 10);
  position(b, 30);
  position(b, 20);
  position(b, 30);
  position(b, 5);
  position(b, 40);
  const ScanTrace t = b.finish(false);
  ASSERT_EQ(t.head.size(), 5u);
  const std::int64_t expected[] = {5, 10, 20, 30, 40};
  for (std::size_t i = 0; i < t.head.size(); ++i) EXPECT_EQ(t.head[i].time_ns, expected[i]);
}

TEST(ScanTraceBuilder, ASweepOpenAtACutEndsWithTheLastPosition) {
  ScanTraceBuilder b;
  position(b, 0);
  event(b, 10, "sweep_begin", "part sweep 1");
  position(b, 15);
  position(b, 17);
  EXPECT_TRUE(b.finish(false).sweeps.empty());  // an open sweep of a whole trace is not a sweep
  const ScanTrace cut = b.finish(true);
  ASSERT_EQ(cut.sweeps.size(), 1u);
  EXPECT_EQ(cut.sweeps[0].label, "part sweep 1");
  EXPECT_EQ(cut.sweeps[0].end_ns, 17);
}

TEST(ScanTraceBuilder, FramesArePairedIntoTheirScene) {
  ScanTraceBuilder b(true);
  marker(b, msg::Scene::CalibrationPlate, "begin");
  frame(b, "left", 1);
  frame(b, "right", 1);
  frame(b, "left", 2);  // its partner never comes
  marker(b, msg::Scene::CalibrationPlate, "end");
  marker(b, msg::Scene::Part, "begin");
  frame(b, "right", 3);
  frame(b, "left", 3);
  const ScanTrace& t = b.trace();
  ASSERT_EQ(t.plate_left.size(), 1u);
  EXPECT_EQ(t.plate_left[0].trigger_id, 1u);
  EXPECT_EQ(t.plate_left[0].image.cols, 4);
  ASSERT_EQ(t.part_left.size(), 1u);
  EXPECT_EQ(t.part_right[0].trigger_id, 3u);
  EXPECT_EQ(t.part_frames, 2u);
}

TEST(ScanTraceBuilder, BadMessagesAreCountedNotFatal) {
  ScanTraceBuilder b;
  const std::vector<std::byte> junk(3, std::byte{0xff});
  b.add(msg::topics::kLaserProfile, junk);
  b.add(msg::topics::kCmmEvent, junk);
  EXPECT_EQ(b.decodeErrors(), 2u);
  EXPECT_FALSE(b.firstDecodeError().empty());
  const ScanTrace t = b.finish(false);
  ASSERT_EQ(t.health.damage.size(), 1u);
  EXPECT_NE(t.health.damage[0].what.find("2 messages did not decode"), std::string::npos);
}

}  // namespace
}  // namespace stampscan::registration
