// Loss handling: incomplete frames are counted and never delivered; a camera that disappears
// mid-stream is reported "disconnected" and reconnected when it comes back.
#include "camera_test_support.hpp"

namespace stampscan::test {
namespace {

using drivers::camera::CameraConfig;
using drivers::camera::GigECamera;

class CameraFaults : public VirtualCamerasTest {};

TEST_F(CameraFaults, IncompleteFramesAreCountedNotDelivered) {
  auto o = options(kLeftSerial, kLeftAddress);
  o.packet_resend = false;  // the fake camera ignores resend requests: fail the frame at once
  GigECamera cam("left", o);
  cam.connect();
  CameraConfig c;
  c.roi = {0, 0, 640, 480};
  c.frame_rate_hz = 100.0;
  c.packet_size = 1400;  // ~220 packets a frame
  cam.configure(c);
  left_->setLostPacketRatio(0.003);  // about half the frames lose a packet
  FrameSink frames;
  cam.startStreaming(std::ref(frames));
  EXPECT_TRUE(waitUntil([&] { return cam.stats().incomplete >= 10 && frames.size() >= 10; },
                        std::chrono::seconds(10)));
  cam.stopStreaming();
  const auto s = cam.stats();
  EXPECT_GE(s.incomplete, 10u);
  EXPECT_GT(s.incomplete_by_reason.count("missing-packets") + s.incomplete_by_reason.count("timeout") +
                s.incomplete_by_reason.count("wrong-packet-id"),
            0u);
  std::uint64_t by_reason = 0;
  for (const auto& [reason, n] : s.incomplete_by_reason) by_reason += n;
  EXPECT_EQ(by_reason, s.incomplete);
  const auto got = frames.frames();
  EXPECT_EQ(got.size(), s.delivered);
  for (const auto& f : got) EXPECT_TRUE(imageIsIntact(1, f.info.bytes)) << "frame " << f.info.frame_id;
}

TEST_F(CameraFaults, DisappearingCameraIsReportedAndReconnected) {
  GigECamera cam("right", options(kRightSerial, kRightAddress));
  cam.connect();
  CameraConfig c;
  c.roi = {0, 0, 320, 240};
  c.frame_rate_hz = 50.0;
  cam.configure(c);
  FrameSink frames;
  cam.startStreaming(std::ref(frames));
  ASSERT_TRUE(frames.waitFor(5, std::chrono::seconds(3)));

  right_->stop();  // unplugged
  ASSERT_TRUE(waitUntil([&] { return hasFault(cam, "disconnected"); }, std::chrono::seconds(15)))
      << "no disconnected fault";
  EXPECT_EQ(cam.state(), drivers::DeviceState::Faulted);
  EXPECT_EQ(cam.stats().disconnects, 1u);

  right_->start();  // plugged back
  const std::size_t before = frames.size();
  ASSERT_TRUE(waitUntil([&] { return cam.stats().reconnects >= 1; }, std::chrono::seconds(15))) << "no reconnect";
  EXPECT_TRUE(frames.waitFor(before + 5, std::chrono::seconds(5)));
  EXPECT_EQ(cam.state(), drivers::DeviceState::Busy);
  // The configuration was written again to the new camera.
  const auto last = frames.frames().back();
  EXPECT_EQ(last.info.width, 320u);
  EXPECT_EQ(last.info.height, 240u);
  cam.stopStreaming();
}

TEST_F(CameraFaults, ExplicitReconnectRestoresTheConfiguration) {
  GigECamera cam("left", options(kLeftSerial, kLeftAddress));
  cam.connect();
  CameraConfig c;
  c.roi = {8, 8, 256, 128};
  c.exposure_us = 1234.0;
  cam.configure(c);
  left_->stop();
  left_->start();  // a fresh camera, with its default configuration
  cam.reconnect();
  const auto back = cam.readConfig();
  EXPECT_EQ(back.roi, c.roi);
  ASSERT_TRUE(back.exposure_us);
  EXPECT_DOUBLE_EQ(*back.exposure_us, 1234.0);
  EXPECT_EQ(cam.stats().reconnects, 1u);
}

}  // namespace
}  // namespace stampscan::test
