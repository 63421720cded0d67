// The ScanRunner on the virtual cell, through the real drivers on their wire protocols: a short
// plan runs from the checks to the park position and records what the devices sent; the checks
// before motion refuse an open door; a door opened mid-scan and an operator abort end the run
// cleanly (motion stopped, shutter closed, the reason in the trace). Runs under umockdev-wrapper
// (the virtual digitizer is a USB device under umockdev); without it, it skips.
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/acquisition/trace/trace_messages.hpp"
#include "stampscan/drivers/plc/plc_register_map.hpp"
#include "stampscan/sim/virtual_cell.hpp"

#include <gtest/gtest.h>

#include <future>
#include <mutex>
#include <thread>

namespace stampscan::acquisition {
namespace {

namespace msg = stampscan::trace;
using namespace std::chrono_literals;

class MemorySink final : public trace::TraceSink {
 public:
  void message(std::string_view topic, std::int64_t, std::vector<std::byte> bytes) override {
    std::lock_guard lock(mutex_);
    if (topic == msg::topics::kLaserProfile) ++profiles_;
    if (topic == msg::topics::kCmmPosition) ++positions_;
    if (topic == msg::topics::kPlcState) ++plc_;
    if (topic == msg::topics::kCmmEvent) events_.push_back(msg::decode<msg::CmmEvent>(bytes));
    if (topic == msg::topics::kCameraLeft || topic == msg::topics::kCameraRight) {
      if (frames_++ == 0) first_frame_ = msg::decode<msg::CameraFrame>(bytes);
    }
    if (topic == msg::topics::kClockSync && msg::decode<msg::ClockSync>(bytes).device.rfind("camera", 0) == 0)
      ++camera_pairs_;
  }
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override {
    std::lock_guard lock(mutex_);
    metadata_[name] = values;
  }
  std::size_t profiles() const {
    std::lock_guard lock(mutex_);
    return profiles_;
  }
  std::size_t positions() const {
    std::lock_guard lock(mutex_);
    return positions_;
  }
  std::size_t plcStates() const {
    std::lock_guard lock(mutex_);
    return plc_;
  }
  std::size_t frames() const {
    std::lock_guard lock(mutex_);
    return frames_;
  }
  std::size_t cameraClockPairs() const {
    std::lock_guard lock(mutex_);
    return camera_pairs_;
  }
  msg::CameraFrame firstFrame() const {
    std::lock_guard lock(mutex_);
    return first_frame_;
  }
  std::vector<msg::CmmEvent> events() const {
    std::lock_guard lock(mutex_);
    return events_;
  }
  std::map<std::string, std::map<std::string, std::string>> metadata() const {
    std::lock_guard lock(mutex_);
    return metadata_;
  }

 private:
  mutable std::mutex mutex_;
  std::size_t profiles_ = 0, positions_ = 0, plc_ = 0, frames_ = 0, camera_pairs_ = 0;
  msg::CameraFrame first_frame_;
  std::vector<msg::CmmEvent> events_;
  std::map<std::string, std::map<std::string, std::string>> metadata_;
};

class ScanRunnerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!sim::VirtualDigitizer::preloadActive())
      GTEST_SKIP() << "umockdev's preload library is not active: run under umockdev-wrapper (apt-get install umockdev)";
    sim::VirtualCellOptions o;
    o.world = sim::ScanParams::quick();
    o.cmm_port = 0;
    o.plc_port = 0;
    o.cameras = withCameras();
    cell_ = std::make_unique<sim::VirtualCell>(o);
    digitizer_device_ = std::make_unique<sim::VirtualDigitizer>(cell_->digitizerOptions());
    digitizer_device_->setTimedProfileSource(cell_->profileSource());
    cell_->start();
    drivers::cmm::IppCmmOptions c;
    c.port = cell_->cmm().port();
    c.device_time_in_reports = true;
    cmm_ = std::make_unique<drivers::cmm::IppCmm>(c);
    drivers::plc::ModbusPlcOptions p;
    p.port = cell_->plc().port();
    plc_ = std::make_unique<drivers::plc::ModbusPlc>(p);
    digitizer_ = std::make_unique<drivers::digitizer::UsbDigitizer>();
    if (withCameras()) {
      for (auto [camera, serial] : {std::pair{&left_, "STAMPSCAN-LEFT"}, std::pair{&right_, "STAMPSCAN-RIGHT"}}) {
        drivers::camera::GigECameraOptions options;
        options.serial = serial;
        *camera = std::make_unique<drivers::camera::GigECamera>(serial, options);
      }
    }
  }
  virtual bool withCameras() const { return false; }
  void TearDown() override {
    if (left_) left_->disconnect();
    if (right_) right_->disconnect();
    if (digitizer_) digitizer_->disconnect();
    if (plc_) plc_->disconnect();
    if (cmm_) cmm_->disconnect();
  }

  // One sweep over the middle of the part, 40 mm at 25 mm/s (1.6 s).
  static ScanPlan shortPlan() {
    ScanPlan plan;
    plan.name = "one sweep";
    plan.park = {{0, 0, 300}, 0, 0};
    SweepStep s;
    s.start = {{0, -20, 200}, 0, 0};
    s.end = {{0, 20, 200}, 0, 0};
    s.speed = 25;
    plan.steps.emplace_back(s);
    return plan;
  }
  static ScanRunParams params() {
    ScanRunParams p;
    p.session.digitizer_standoff_mm = 100;
    p.session.digitizer_measuring_range_mm = 60;
    return p;
  }
  CellDevices devices() { return {*cmm_, *plc_, *digitizer_, left_.get(), right_.get()}; }
  bool shutterOpen() { return cell_->plc().coil(drivers::plc::Coil::LaserShutterOpenRequest); }
  static bool hasEvent(const std::vector<msg::CmmEvent>& events, msg::CmmEventKind kind) {
    return std::any_of(events.begin(), events.end(), [&](const msg::CmmEvent& e) { return e.kind == kind; });
  }

  std::unique_ptr<sim::VirtualCell> cell_;
  std::unique_ptr<sim::VirtualDigitizer> digitizer_device_;
  std::unique_ptr<drivers::cmm::IppCmm> cmm_;
  std::unique_ptr<drivers::plc::ModbusPlc> plc_;
  std::unique_ptr<drivers::digitizer::UsbDigitizer> digitizer_;
  std::unique_ptr<drivers::camera::GigECamera> left_, right_;
  StationClock clock_;
  MemorySink sink_;
};

TEST_F(ScanRunnerTest, RunsAShortPlanAndRecordsWhatTheDevicesSent) {
  ScanRunner runner(devices(), sink_, clock_);
  const ScanRunResult r = runner.run(shortPlan(), params());
  ASSERT_TRUE(r.completed) << r.abort_reason;
  EXPECT_EQ(r.sweeps_done, 1u);
  // 1.6 s at 500 profiles a second; a loaded machine renders fewer in time, none are lost.
  EXPECT_GT(sink_.profiles(), 400u);
  EXPECT_EQ(r.lost_profiles, 0u);
  EXPECT_GT(sink_.positions(), 10u);
  EXPECT_GT(sink_.plcStates(), 5u);
  const auto events = sink_.events();
  EXPECT_TRUE(hasEvent(events, msg::CmmEventKind::SweepBegin));
  EXPECT_TRUE(hasEvent(events, msg::CmmEventKind::SweepEnd));
  EXPECT_FALSE(hasEvent(events, msg::CmmEventKind::Abort));
  const auto md = sink_.metadata();
  ASSERT_TRUE(md.count("cell"));
  EXPECT_EQ(md.at("cell").at("plan"), "one sweep");
  EXPECT_EQ(md.at("cell").at("digitizer_points_per_profile"), "1024");
  // Parked, the laser off, the part released.
  const sim::VirtualCmmStatus st = cell_->cmm().status();
  EXPECT_NEAR(st.position[2], 300, 1e-6);
  EXPECT_FALSE(shutterOpen());
  EXPECT_FALSE(cell_->plc().coil(drivers::plc::Coil::ClampRequest));
  // The plan's motion is the floor; the run may take longer, not shorter.
  EXPECT_GE(r.wall_seconds, 0.9 * r.motion_seconds);
}

TEST_F(ScanRunnerTest, AnOpenDoorIsRefusedBeforeAnythingMoves) {
  cell_->plc().openDoor();
  ScanRunner runner(devices(), sink_, clock_);
  try {
    runner.run(shortPlan(), params());
    FAIL() << "ran with the door open";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("door is open"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cell_->cmm().status().moves_completed, 0u);
  EXPECT_EQ(sink_.profiles(), 0u);
}

TEST_F(ScanRunnerTest, ADoorOpenedMidSweepStopsTheScanCleanly) {
  ScanRunner runner(devices(), sink_, clock_);
  auto running = std::async(std::launch::async, [&] { return runner.run(shortPlan(), params()); });
  // Open the door once the sweep has begun.
  for (int i = 0; i < 1000 && sink_.profiles() < 100; ++i) std::this_thread::sleep_for(10ms);
  ASSERT_GE(sink_.profiles(), 100u) << "the sweep never started";
  cell_->plc().openDoor();
  ASSERT_EQ(running.wait_for(10s), std::future_status::ready) << "the run did not end after the door opened";
  const ScanRunResult r = running.get();
  EXPECT_FALSE(r.completed);
  EXPECT_NE(r.abort_reason.find("door"), std::string::npos) << r.abort_reason;
  EXPECT_EQ(r.sweeps_done, 0u);
  EXPECT_FALSE(cell_->cmm().status().moving);
  EXPECT_FALSE(shutterOpen());
  EXPECT_TRUE(hasEvent(sink_.events(), msg::CmmEventKind::Abort));
  EXPECT_FALSE(r.safety_events.empty());
}

TEST_F(ScanRunnerTest, AnOperatorAbortStopsTheScan) {
  ScanRunner runner(devices(), sink_, clock_);
  auto running = std::async(std::launch::async, [&] { return runner.run(shortPlan(), params()); });
  for (int i = 0; i < 1000 && sink_.profiles() < 50; ++i) std::this_thread::sleep_for(10ms);
  runner.abort("operator abort");
  ASSERT_EQ(running.wait_for(10s), std::future_status::ready);
  const ScanRunResult r = running.get();
  EXPECT_FALSE(r.completed);
  EXPECT_EQ(r.abort_reason, "operator abort");
  EXPECT_FALSE(cell_->cmm().status().moving);
  EXPECT_FALSE(shutterOpen());
}

// An abort that arrives before the run starts (Abort pressed as the job starts) is not lost.
TEST_F(ScanRunnerTest, AnAbortBeforeTheRunStartsEndsItAtItsFirstStep) {
  ScanRunner runner(devices(), sink_, clock_);
  runner.abort("operator abort, early");
  auto running = std::async(std::launch::async, [&] { return runner.run(shortPlan(), params()); });
  ASSERT_EQ(running.wait_for(10s), std::future_status::ready);
  const ScanRunResult r = running.get();
  EXPECT_FALSE(r.completed);
  EXPECT_EQ(r.abort_reason, "operator abort, early");
  EXPECT_EQ(sink_.profiles(), 0u);
  EXPECT_FALSE(shutterOpen());
}

TEST_F(ScanRunnerTest, ASweepThatLostProfilesIsRunAgain) {
  ScanRunner runner(devices(), sink_, clock_);
  auto running = std::async(std::launch::async, [&] { return runner.run(shortPlan(), params()); });
  // Lose 50 profiles on the wire in the middle of the sweep (the digitizer's sequence numbers jump).
  for (int i = 0; i < 1000 && sink_.profiles() < 200; ++i) std::this_thread::sleep_for(10ms);
  digitizer_device_->dropSequence(50);
  ASSERT_EQ(running.wait_for(30s), std::future_status::ready);
  const ScanRunResult r = running.get();
  ASSERT_TRUE(r.completed) << r.abort_reason;
  EXPECT_EQ(r.sweeps_done, 1u);
  EXPECT_EQ(r.sweeps_repeated, 1u);
  EXPECT_GE(r.lost_profiles, 50u);
  const auto events = sink_.events();
  EXPECT_TRUE(hasEvent(events, msg::CmmEventKind::SweepDiscarded));
  EXPECT_EQ(std::count_if(events.begin(), events.end(), [](const msg::CmmEvent& e) { return e.kind == msg::CmmEventKind::SweepEnd; }), 2);
}

TEST_F(ScanRunnerTest, StereoViewsNeedTheCameras) {
  ScanPlan plan = shortPlan();
  StereoStep v;
  v.pose = {{0, 0, 400}, 0, 0};
  plan.steps.emplace_back(v);
  ScanRunner runner(devices(), sink_, clock_);
  try {
    runner.run(plan, params());
    FAIL() << "ran stereo views without cameras";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("1 stereo views, but the cell has no cameras"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cell_->cmm().status().moves_completed, 0u);
}

// With the virtual cameras (Aravis fake cameras on 127.0.0.1 and 127.0.0.2: one suite at a time).
class ScanRunnerStereoTest : public ScanRunnerTest {
 protected:
  bool withCameras() const override { return true; }
  static ScanPlan stereoPlan() {
    ScanPlan plan;
    plan.name = "two views and a sweep";
    plan.park = {{0, 0, 450}, 0, 0};
    // The first view in a scene of its own: the head leaves a view when its exposure ends, but not a
    // scene before its frames are in, so the second view comes after the first one's frames.
    for (std::uint32_t k = 0; k < 2; ++k) {
      StereoStep v;
      v.index = k;
      v.scene = k == 0 ? Scene::CalibrationPlate : Scene::Part;
      v.pose = {{k == 0 ? -10.0 : 10.0, 0, 360}, 0, 0};
      v.settle_s = 0.1;
      plan.steps.emplace_back(v);
    }
    SweepStep s;
    s.start = {{0, -10, 200}, 0, 0};
    s.end = {{0, 10, 200}, 0, 0};
    plan.steps.emplace_back(s);
    return plan;
  }
  ScanRunParams stereoParams() const {
    ScanRunParams p = params();
    p.session = sim::describeSession(cell_->options().world);
    p.frame_timeout = std::chrono::milliseconds(10000);  // rendering is slow under the sanitizers
    return p;
  }
  std::size_t frames() { return sink_.frames(); }
};

TEST_F(ScanRunnerStereoTest, EachViewIsAPairOfFramesOfTheWorld) {
  ScanRunner runner(devices(), sink_, clock_);
  const ScanRunResult r = runner.run(stereoPlan(), stereoParams());
  ASSERT_TRUE(r.completed) << r.abort_reason;
  EXPECT_EQ(r.views_done, 2u);
  EXPECT_EQ(r.views_missing, 0u);
  EXPECT_EQ(r.sweeps_done, 1u);
  ASSERT_EQ(sink_.frames(), 4u);
  EXPECT_EQ(sink_.cameraClockPairs(), 4u);
  // The frames are the world's, rendered at the camera's size, not the fake camera's test pattern:
  // the part under a ring light is bright in the middle of the image.
  const msg::CameraFrame f = sink_.firstFrame();
  const auto nominal = sim::describeSession(cell_->options().world).camera_nominal;
  ASSERT_TRUE(nominal.has_value());
  EXPECT_EQ(static_cast<int>(f.width), nominal->width);
  EXPECT_EQ(static_cast<int>(f.height), nominal->height);
  const std::size_t centre = (f.height / 2) * f.step + f.width / 2;
  EXPECT_GT(f.data.at(centre), 60) << "the centre of the view is dark";
}

TEST_F(ScanRunnerStereoTest, ALostCameraMarksItsViewsMissingAndTheScanGoesOn) {
  ScanRunner runner(devices(), sink_, clock_);
  auto running = std::async(std::launch::async, [&] { return runner.run(stereoPlan(), stereoParams()); });
  // Unplug the right camera once the first pair is in.
  for (int i = 0; i < 1000 && sink_.frames() < 2; ++i) std::this_thread::sleep_for(10ms);
  cell_->stopRightCamera();
  ASSERT_EQ(running.wait_for(60s), std::future_status::ready);
  const ScanRunResult r = running.get();
  EXPECT_TRUE(r.completed) << r.abort_reason;
  EXPECT_EQ(r.views_done + r.views_missing, 2u);
  EXPECT_GE(r.views_missing, 1u);
  EXPECT_EQ(r.sweeps_done, 1u);
  EXPECT_TRUE(hasEvent(sink_.events(), msg::CmmEventKind::ViewMissing));
}

}  // namespace
}  // namespace stampscan::acquisition
