// Shared set-up for the camera tests: the two virtual cameras of the cell on loopback, skipped with
// a reason when the machine cannot host them, and bounded waits on conditions.
#pragma once

#include <cstdlib>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "stampscan/drivers/camera/gige_camera.hpp"
#include "stampscan/sim/virtual_camera.hpp"

namespace stampscan::test {

inline constexpr const char* kLeftSerial = "STAMPSCAN-L";
inline constexpr const char* kRightSerial = "STAMPSCAN-R";
inline constexpr const char* kLeftAddress = "127.0.0.1";
inline constexpr const char* kRightAddress = "127.0.0.2";

// Waits (polling every 5 ms) until pred() holds or the timeout passes; returns pred().
inline bool waitUntil(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return pred();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

// The image the tests' frame source draws: the frame index in the first 8 bytes, then a ramp that
// depends on the camera tag and the index, so a delivered frame can be checked on its own.
inline void drawTestImage(std::uint8_t tag, std::uint64_t index, std::span<std::uint8_t> out) {
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<std::uint8_t>(i * 7 + index * 13 + tag);
  std::memcpy(out.data(), &index, std::min<std::size_t>(8, out.size()));
}

inline bool imageIsIntact(std::uint8_t tag, std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 8) return false;
  std::uint64_t index = 0;
  std::memcpy(&index, bytes.data(), 8);
  std::vector<std::uint8_t> expected(bytes.size());
  drawTestImage(tag, index, expected);
  const auto mismatch = std::mismatch(expected.begin(), expected.end(), bytes.begin());
  if (mismatch.first != expected.end()) {
    std::fprintf(stderr, "image of frame index %llu (%zu bytes) differs at byte %td: got %d, want %d\n",
                 static_cast<unsigned long long>(index), bytes.size(), mismatch.first - expected.begin(),
                 int(*mismatch.second), int(*mismatch.first));
  }
  return mismatch.first == expected.end();
}

class VirtualCamerasTest : public ::testing::Test {
 protected:
  // Set in the environment of a test run by another test's process, whose cameras it then uses
  // (test_camera_stream.cpp: the stream of a process without privileges).
  static constexpr const char* kCamerasServedElsewhere = "STAMPSCAN_TEST_CAMERAS_SERVED_ELSEWHERE";

  void SetUp() override {
    if (std::getenv(kCamerasServedElsewhere) != nullptr) return;
    const sim::LoopbackStatus status = sim::VirtualCamera::ensureLoopbackAddress(kRightAddress);
    if (!status.ok) GTEST_SKIP() << "virtual right camera unavailable: " << status.reason;
    // The left camera has GigE Vision's timestamp latch, as most machine-vision cameras; the right
    // one has none (as Aravis' own fake camera), so that both ways of reading a camera's clock run.
    sim::VirtualCameraOptions left{kLeftAddress, kLeftSerial, "", 0.0}, right{kRightAddress, kRightSerial, "", 0.0};
    right.timestamp_latch = false;
    left_ = std::make_unique<sim::VirtualCamera>(left);
    right_ = std::make_unique<sim::VirtualCamera>(right);
    left_->setFrameSource([](const sim::FrameRequest& r, std::span<std::uint8_t> out) {
      drawTestImage(1, r.index, out);
      return true;
    });
    right_->setFrameSource([](const sim::FrameRequest& r, std::span<std::uint8_t> out) {
      drawTestImage(2, r.index, out);
      return true;
    });
    try {
      left_->start();
      right_->start();
    } catch (const std::exception& e) {
      GTEST_SKIP() << "cannot start the virtual cameras: " << e.what();
    }
  }

  static drivers::camera::GigECameraOptions options(const std::string& serial, const std::string& address = "") {
    drivers::camera::GigECameraOptions o;
    o.serial = serial;
    o.address = address;
    o.silence_limit = std::chrono::milliseconds(400);
    o.reconnect_period = std::chrono::milliseconds(100);
    return o;
  }

  std::unique_ptr<sim::VirtualCamera> left_, right_;
};

// Collects delivered frames (copied) and wakes a waiter.
class FrameSink {
 public:
  void operator()(const drivers::camera::FrameView& f) {
    std::lock_guard lock(mutex_);
    frames_.push_back(drivers::camera::Frame::copyOf(f));
    cv_.notify_all();
  }
  bool waitFor(std::size_t n, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return frames_.size() >= n; });
  }
  std::vector<drivers::camera::Frame> frames() const {
    std::lock_guard lock(mutex_);
    return frames_;
  }
  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return frames_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<drivers::camera::Frame> frames_;
};

inline bool hasFault(const drivers::Device& d, const std::string& code) {
  for (const auto& f : d.faults()) {
    if (f.code == code) return true;
  }
  return false;
}

}  // namespace stampscan::test
