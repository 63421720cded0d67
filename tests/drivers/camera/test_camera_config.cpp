// Configuration through GenICam features, written and read back over GVCP.
#include "camera_test_support.hpp"

namespace stampscan::test {
namespace {

using drivers::camera::CameraConfig;
using drivers::camera::GigECamera;
using drivers::camera::TriggerMode;

class CameraConfigTest : public VirtualCamerasTest {};

TEST_F(CameraConfigTest, RoundTrip) {
  GigECamera cam("left", options(kLeftSerial, kLeftAddress));
  cam.connect();
  const auto formats = cam.pixelFormats();
  EXPECT_NE(std::find(formats.begin(), formats.end(), "Mono8"), formats.end());
  EXPECT_NE(std::find(formats.begin(), formats.end(), "Mono16"), formats.end());
  const auto [sw, sh] = cam.sensorSize();
  EXPECT_GE(sw, 2048);
  EXPECT_GE(sh, 1536);

  CameraConfig c;
  c.pixel_format = "Mono16";
  c.exposure_us = 2500.0;
  c.gain = 3.0;
  c.roi = {16, 8, 640, 480};
  c.packet_size = 4000;
  c.trigger = TriggerMode::Software;
  cam.configure(c);
  const CameraConfig back = cam.readConfig();
  EXPECT_EQ(back.pixel_format, "Mono16");
  ASSERT_TRUE(back.exposure_us && back.gain && back.packet_size);
  EXPECT_DOUBLE_EQ(*back.exposure_us, 2500.0);
  EXPECT_DOUBLE_EQ(*back.gain, 3.0);
  EXPECT_EQ(back.roi, c.roi);
  EXPECT_EQ(*back.packet_size, 4000u);
  EXPECT_EQ(back.trigger, TriggerMode::Software);

  c.pixel_format = "Mono8";
  c.trigger = TriggerMode::FreeRun;
  c.frame_rate_hz = 50.0;
  c.roi = {};
  cam.configure(c);
  const CameraConfig full = cam.readConfig();
  EXPECT_EQ(full.pixel_format, "Mono8");
  EXPECT_EQ(full.trigger, TriggerMode::FreeRun);
  EXPECT_EQ(full.roi, (drivers::camera::Roi{0, 0, sw, sh}));
  ASSERT_TRUE(full.frame_rate_hz);
  EXPECT_NEAR(*full.frame_rate_hz, 50.0, 0.5);
}

TEST_F(CameraConfigTest, RefusedValueNamesTheFeature) {
  GigECamera cam("left", options(kLeftSerial, kLeftAddress));
  cam.connect();
  CameraConfig c;
  c.pixel_format = "YUV422_Packed_NotHere";
  try {
    cam.configure(c);
    FAIL() << "an unknown pixel format was accepted";
  } catch (const drivers::DeviceError& e) {
    EXPECT_EQ(e.code(), "config");
    EXPECT_NE(std::string(e.what()).find("PixelFormat"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stampscan::test
