// TraceReplayer with an injected clock: the schedule at speed 1, 4 and 0 (as fast as possible),
// lateness when the consumer is slow, stopping, and filters.
#include "mcap_test_support.hpp"
#include "stampscan/acquisition/trace/trace_replay.hpp"

#include <thread>

namespace stampscan::trace::test {
namespace {

// A fake clock: sleeping jumps to the requested time; the consumer can add work time.
struct FakeClock {
  std::int64_t now = 5'000'000'000;  // any start
  std::vector<std::int64_t> sleeps;
  ReplayClock clock() {
    return {[this] { return now; }, [this](std::int64_t t) {
              sleeps.push_back(t);
              now = std::max(now, t);
            }};
  }
};

// Messages at log times 0, 0.1, 0.25, 0.25, 1.0, 1.5 s after 100 s (two channels).
fs::path writeTimedTrace(const fs::path& file, std::vector<std::uint64_t>& times) {
  times = {100'000'000'000, 100'100'000'000, 100'250'000'000, 100'250'000'000, 101'000'000'000, 101'500'000'000};
  McapWriter writer(file);
  const std::uint16_t a = writer.addChannel(0, "/a", "json"), b = writer.addChannel(0, "/b", "json");
  for (std::size_t i = 0; i < times.size(); ++i) writer.write(i % 2 ? b : a, times[i], times[i], payload(i, 10));
  return file;
}

std::vector<std::int64_t> playedAt(const fs::path& file, double speed, FakeClock& fake, ReplayStats& stats,
                                   std::int64_t work_ns = 0) {
  ReplayOptions options;
  options.speed = speed;
  TraceReplayer replayer(file, options, fake.clock());
  std::vector<std::int64_t> at;
  stats = replayer.run([&](const TraceMessage&) {
    at.push_back(fake.now);
    fake.now += work_ns;
    return true;
  });
  return at;
}

TEST_F(TraceTest, ReplayKeepsTheOriginalTimingAtSpeedOne) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  FakeClock fake;
  const std::int64_t start = fake.now;
  ReplayStats stats;
  const std::vector<std::int64_t> at = playedAt(file, 1.0, fake, stats);
  ASSERT_EQ(at.size(), times.size());
  for (std::size_t i = 0; i < at.size(); ++i)
    EXPECT_EQ(at[i] - start, static_cast<std::int64_t>(times[i] - times[0])) << "message " << i;
  EXPECT_EQ(stats.messages, times.size());
  EXPECT_EQ(stats.spanNs(), 1'500'000'000u);
  EXPECT_EQ(stats.wall_ns, 1'500'000'000);
  EXPECT_EQ(stats.max_lateness_ns, 0);
  EXPECT_FALSE(stats.stopped);
  EXPECT_TRUE(stats.health.healthy());
  EXPECT_EQ(fake.sleeps.size(), 4u);  // not for the first message, nor for the second at 0.25 s
}

TEST_F(TraceTest, ReplayAtSpeedFourIsFourTimesFaster) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  FakeClock fake;
  const std::int64_t start = fake.now;
  ReplayStats stats;
  const std::vector<std::int64_t> at = playedAt(file, 4.0, fake, stats);
  ASSERT_EQ(at.size(), times.size());
  for (std::size_t i = 0; i < at.size(); ++i)
    EXPECT_EQ(at[i] - start, static_cast<std::int64_t>(times[i] - times[0]) / 4) << "message " << i;
  EXPECT_EQ(stats.wall_ns, 375'000'000);
}

TEST_F(TraceTest, ReplayAtSpeedZeroNeverWaits) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  FakeClock fake;
  ReplayStats stats;
  const std::vector<std::int64_t> at = playedAt(file, 0.0, fake, stats);
  EXPECT_EQ(at.size(), times.size());
  EXPECT_TRUE(fake.sleeps.empty());
  EXPECT_EQ(stats.wall_ns, 0);
  EXPECT_EQ(stats.spanNs(), 1'500'000'000u);
}

TEST_F(TraceTest, ReplayReportsLatenessOfASlowConsumer) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  FakeClock fake;
  const std::int64_t start = fake.now;
  ReplayStats stats;
  // 200 ms of work per message: the messages at 0.1 and 0.25 s go out late, then it catches up.
  const std::vector<std::int64_t> at = playedAt(file, 1.0, fake, stats, 200'000'000);
  ASSERT_EQ(at.size(), times.size());
  EXPECT_EQ(at[1] - start, 200'000'000);
  EXPECT_EQ(at[2] - start, 400'000'000);
  EXPECT_EQ(at[3] - start, 600'000'000);
  EXPECT_EQ(at[4] - start, 1'000'000'000);
  EXPECT_EQ(stats.max_lateness_ns, 350'000'000);
  EXPECT_GT(stats.mean_lateness_ns, 0.0);
}

TEST_F(TraceTest, ReplayStopsFromTheConsumerOrAnotherThread) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  {
    FakeClock fake;
    TraceReplayer replayer(file, {}, fake.clock());
    int n = 0;
    const ReplayStats stats = replayer.run([&](const TraceMessage&) {
      if (++n == 3) replayer.stop();
      return true;
    });
    EXPECT_EQ(stats.messages, 3u);
    EXPECT_TRUE(stats.stopped);
  }
  {
    // Real clock, speed 1: the replay waits 1.5 s unless stop() wakes it.
    TraceReplayer replayer(file);
    std::thread stopper([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      replayer.stop();
    });
    const auto t0 = std::chrono::steady_clock::now();
    const ReplayStats stats = replayer.run([](const TraceMessage&) { return true; });
    stopper.join();
    EXPECT_TRUE(stats.stopped);
    EXPECT_LT(stats.messages, times.size());
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(1000));
  }
}

TEST_F(TraceTest, ReplayFiltersAndRejectsBadSpeeds) {
  std::vector<std::uint64_t> times;
  const fs::path file = writeTimedTrace(dir() / "t.mcap", times);
  FakeClock fake;
  ReplayOptions options;
  options.read.topics = {"/b"};
  TraceReplayer replayer(file, options, fake.clock());
  const ReplayStats stats = replayer.run([](const TraceMessage& m) { return m.channel && m.channel->topic == "/b"; });
  EXPECT_EQ(stats.messages, 3u);
  EXPECT_FALSE(stats.stopped);
  ReplayOptions bad;
  bad.speed = -1;
  EXPECT_THROW(TraceReplayer(file, bad), std::invalid_argument);
  EXPECT_THROW(TraceReplayer(dir() / "missing.mcap"), std::runtime_error);
}

}  // namespace
}  // namespace stampscan::trace::test
