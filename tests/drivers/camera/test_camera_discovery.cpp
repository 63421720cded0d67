// Discovery: both virtual cameras are found by serial (GVCP discovery) and by address.
#include <cstdio>
#include <cstdlib>

#include "camera_test_support.hpp"

namespace stampscan::test {
namespace {

using drivers::camera::GigECamera;

class CameraDiscovery : public VirtualCamerasTest {};

TEST_F(CameraDiscovery, FindsBothBySerial) {
  for (const char* serial : {kLeftSerial, kRightSerial}) {
    GigECamera cam(serial, options(serial));
    cam.connect();
    EXPECT_EQ(cam.state(), drivers::DeviceState::Ready);
    const auto id = cam.identity();
    EXPECT_EQ(id.family, "camera");
    EXPECT_EQ(id.serial, serial);
    EXPECT_EQ(id.vendor, "Aravis");
    EXPECT_EQ(id.address, std::string(serial) == kLeftSerial ? kLeftAddress : kRightAddress);
    EXPECT_TRUE(cam.check());
  }
}

TEST_F(CameraDiscovery, FindsBothByAddress) {
  for (const char* address : {kLeftAddress, kRightAddress}) {
    GigECamera cam(address, options("", address));
    cam.connect();
    EXPECT_EQ(cam.identity().serial, std::string(address) == kLeftAddress ? kLeftSerial : kRightSerial);
  }
}

TEST_F(CameraDiscovery, UnknownSerialIsAClearError) {
  GigECamera cam("nobody", options("NO-SUCH-CAMERA"));
  try {
    cam.connect();
    FAIL() << "connected to a camera that does not exist";
  } catch (const drivers::DeviceError& e) {
    EXPECT_EQ(e.code(), "disconnected");
    EXPECT_NE(std::string(e.what()).find("NO-SUCH-CAMERA"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cam.state(), drivers::DeviceState::Faulted);
}

TEST_F(CameraDiscovery, ArvToolListsBothCameras) {
  if (std::system("command -v arv-tool-0.8 >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "arv-tool-0.8 is not installed (apt-get install aravis-tools-cli)";
  }
  std::FILE* pipe = popen("arv-tool-0.8 2>&1", "r");
  ASSERT_NE(pipe, nullptr);
  std::string out;
  char line[512];
  while (std::fgets(line, sizeof line, pipe) != nullptr) out += line;
  pclose(pipe);
  EXPECT_NE(out.find(kLeftSerial), std::string::npos) << out;
  EXPECT_NE(out.find(kRightSerial), std::string::npos) << out;
}

}  // namespace
}  // namespace stampscan::test
