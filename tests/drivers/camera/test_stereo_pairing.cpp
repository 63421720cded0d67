// StereoPair: the matching rules on synthetic frames, then software-triggered pairs from the two
// virtual cameras.
#include "camera_test_support.hpp"
#include "stampscan/drivers/camera/stereo_pair.hpp"

namespace stampscan::test {
namespace {

using drivers::camera::CameraConfig;
using drivers::camera::FrameView;
using drivers::camera::GigECamera;
using drivers::camera::StereoFrame;
using drivers::camera::StereoPair;

FrameView synthetic(std::uint64_t trigger, std::int64_t t_ns) {
  FrameView f;
  f.trigger_id = trigger;
  f.frame_id = trigger;
  f.station_time_ns = t_ns;
  return f;
}

TEST(StereoMatching, ByTriggerIdWithinTolerance) {
  GigECamera a("a", {}), b("b", {});  // never connected: only the matcher is used
  std::vector<StereoFrame> pairs;
  StereoPair pair(a, b, [&](const StereoFrame& p) { pairs.push_back(p); },
                  {std::chrono::milliseconds(2), 8});
  pair.add(StereoPair::Side::Left, synthetic(1, 1'000'000));
  pair.add(StereoPair::Side::Left, synthetic(2, 11'000'000));
  pair.add(StereoPair::Side::Right, synthetic(2, 11'500'000));  // left 1 never gets a partner
  pair.add(StereoPair::Side::Right, synthetic(3, 21'000'000));
  pair.add(StereoPair::Side::Left, synthetic(3, 26'000'000));   // same trigger, 5 ms apart
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].trigger_id, 2u);
  EXPECT_EQ(pairs[0].skew_ns, 500'000);
  const auto s = pair.stats();
  EXPECT_EQ(s.pairs, 1u);
  EXPECT_EQ(s.unmatched_left, 1u);
  EXPECT_EQ(s.out_of_tolerance, 1u);
}

TEST(StereoMatching, FreeRunPairsNearestInTime) {
  GigECamera a("a", {}), b("b", {});
  std::vector<StereoFrame> pairs;
  StereoPair pair(a, b, [&](const StereoFrame& p) { pairs.push_back(p); },
                  {std::chrono::milliseconds(3), 8});
  pair.add(StereoPair::Side::Left, synthetic(0, 100'000'000));
  pair.add(StereoPair::Side::Left, synthetic(0, 110'000'000));
  pair.add(StereoPair::Side::Right, synthetic(0, 111'000'000));
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].left.info.station_time_ns, 110'000'000);
  EXPECT_EQ(pair.stats().unmatched_left, 1u);
}

class StereoCameras : public VirtualCamerasTest {};

// The fake cameras are threads of this process: when the test machine is busy (CI runs suites in
// parallel on two cores) one camera's frame can come 20-30 ms after the other's. The tolerance
// logic itself is tested above on made-up frames; here the point is that triggered frames pair.
constexpr std::chrono::nanoseconds kSkewTolerance = std::chrono::milliseconds(100);

TEST_F(StereoCameras, SoftwareTriggeredPairs) {
  GigECamera left("left", options(kLeftSerial, kLeftAddress));
  GigECamera right("right", options(kRightSerial, kRightAddress));
  left.connect();
  right.connect();
  CameraConfig c;
  c.roi = {0, 0, 640, 480};
  c.packet_size = 8192;
  c.trigger = drivers::camera::TriggerMode::Software;
  left.configure(c);
  right.configure(c);
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<StereoFrame> pairs;
  StereoPair pair(left, right, [&](const StereoFrame& p) {
    std::lock_guard lock(mutex);
    pairs.push_back(p);
    cv.notify_all();
  }, {kSkewTolerance, 8});
  pair.start();
  // Warm-up: an idle Aravis fake camera polls for work every 100 ms until it has sent its first
  // frame, so the first trigger's two frames may be up to 100 ms apart (a real camera answers in
  // microseconds). That pair may be rejected; the following ones must all pair.
  EXPECT_EQ(pair.trigger(), 1u);
  ASSERT_TRUE(waitUntil([&] { return left.stats().delivered >= 1 && right.stats().delivered >= 1; },
                        std::chrono::seconds(2)));
  {
    std::lock_guard lock(mutex);
    pairs.clear();
  }
  for (std::uint64_t k = 2; k <= 6; ++k) {
    EXPECT_EQ(pair.trigger(), k);
    std::unique_lock lock(mutex);
    ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(2), [&] { return pairs.size() >= k - 1; }))
        << "no pair for trigger " << k << "; left " << left.stats().delivered << " right "
        << right.stats().delivered << "; pairs " << pair.stats().pairs << ", out of tolerance "
        << pair.stats().out_of_tolerance << " (skew " << pair.stats().last_rejected_skew_ns << " ns)";
  }
  pair.stop();
  ASSERT_EQ(pairs.size(), 5u);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    EXPECT_EQ(pairs[i].trigger_id, i + 2);
    EXPECT_EQ(pairs[i].left.info.trigger_id, pairs[i].right.info.trigger_id);
    EXPECT_LE(std::llabs(pairs[i].skew_ns), kSkewTolerance.count());
    EXPECT_TRUE(imageIsIntact(1, pairs[i].left.info.bytes));
    EXPECT_TRUE(imageIsIntact(2, pairs[i].right.info.bytes));
  }
}

}  // namespace
}  // namespace stampscan::test
