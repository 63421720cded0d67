// The unmodified UsbDigitizer driver against the virtual digitizer (a scripted USB device under
// umockdev): identify, configure, stream with the data equal to what the source supplied, and each
// fault the device can inject: a lost sequence number, a stalled endpoint, silence, an unplug.
// Runs under umockdev-wrapper (see CMakeLists.txt); skips with the reason otherwise.
#include "stampscan/drivers/digitizer/usb_digitizer.hpp"
#include "stampscan/sim/virtual_digitizer.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

namespace stampscan::drivers::digitizer {
namespace {

using namespace std::chrono_literals;
using sim::VirtualDigitizer;
using sim::VirtualDigitizerOptions;

// What the driver delivered, with bounded waits on it.
class Collector {
 public:
  void profile(Profile&& p) {
    std::lock_guard lock(mutex_);
    profiles_.push_back(std::move(p));
    changed_.notify_all();
  }
  void fault(const DeviceFault& f) {
    std::lock_guard lock(mutex_);
    faults_.push_back(f);
    changed_.notify_all();
  }
  bool waitProfiles(std::size_t n, std::chrono::milliseconds limit = 5s) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return profiles_.size() >= n; });
  }
  bool waitFault(const std::string& code, std::chrono::milliseconds limit = 5s) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] {
      for (const auto& f : faults_)
        if (f.code == code) return true;
      return false;
    });
  }
  std::size_t count() {
    std::lock_guard lock(mutex_);
    return profiles_.size();
  }
  std::vector<Profile> profiles() {
    std::lock_guard lock(mutex_);
    return profiles_;
  }
  std::vector<DeviceFault> faults() {
    std::lock_guard lock(mutex_);
    return faults_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Profile> profiles_;
  std::vector<DeviceFault> faults_;
};

class UsbDigitizerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!VirtualDigitizer::preloadActive())
      GTEST_SKIP() << "umockdev's preload library is not active: run under umockdev-wrapper "
                      "(CTest does), or set LD_PRELOAD=libumockdev-preload.so.0";
    device_ = std::make_unique<VirtualDigitizer>();
    // Record what the source supplied, per sequence, to compare with what arrives.
    device_->setProfileSource([this](std::uint32_t seq, const DigitizerConfig& c, Profile& p) {
      VirtualDigitizer::testPattern(seq, c, p);
      std::lock_guard lock(supplied_mutex_);
      supplied_[seq] = p;
    });
  }

  void connect(UsbDigitizerOptions options = {}) {
    driver_ = std::make_unique<UsbDigitizer>(options);
    driver_->setFaultCallback([this](const DeviceFault& f) { collector_.fault(f); });
    driver_->connect();
  }
  void start() { driver_->start([this](Profile&& p) { collector_.profile(std::move(p)); }); }

  // Every delivered profile equals what the source supplied for its sequence number.
  void expectDeliveredAsSupplied() {
    std::lock_guard lock(supplied_mutex_);
    for (const Profile& p : collector_.profiles()) {
      const auto it = supplied_.find(p.sequence);
      ASSERT_NE(it, supplied_.end()) << p.sequence;
      ASSERT_EQ(p.range, it->second.range) << p.sequence;
      ASSERT_EQ(p.intensity, it->second.intensity) << p.sequence;
      ASSERT_EQ(p.status, it->second.status) << p.sequence;
    }
  }
  std::vector<std::uint32_t> missingSequences() {
    std::vector<std::uint32_t> missing;
    const auto profiles = collector_.profiles();
    for (std::size_t i = 1; i < profiles.size(); ++i)
      for (std::uint32_t s = profiles[i - 1].sequence + 1; s < profiles[i].sequence; ++s) missing.push_back(s);
    return missing;
  }

  // Declared first, destroyed last: the driver must let go of the device before the testbed goes.
  std::unique_ptr<VirtualDigitizer> device_;
  std::mutex supplied_mutex_;
  std::map<std::uint32_t, Profile> supplied_;
  Collector collector_;
  std::unique_ptr<UsbDigitizer> driver_;
};

TEST_F(UsbDigitizerTest, IdentifiesAndConfigures) {
  connect();
  const DeviceIdentity id = driver_->identity();
  EXPECT_EQ(id.family, "digitizer");
  EXPECT_EQ(id.model, "SSD-1024 (virtual)");
  EXPECT_EQ(id.serial, "VD-0001");
  EXPECT_EQ(id.firmware, "1.0.0");
  EXPECT_NE(id.address.find("usb:1d50:61a5"), std::string::npos) << id.address;
  EXPECT_EQ(driver_->state(), DeviceState::Ready);
  EXPECT_EQ(device_->config(), DigitizerConfig{});

  const ConfigReply reply = driver_->configure({512, 2000, 100});
  EXPECT_EQ(device_->config(), (DigitizerConfig{512, 2000, 100}));
  EXPECT_EQ(reply.config, (DigitizerConfig{512, 2000, 100}));
  EXPECT_FLOAT_EQ(reply.angle_min, -0.21f);
  EXPECT_FLOAT_EQ(reply.angle_increment, 0.42f / 511);
  EXPECT_THROW(driver_->configure({8, 500, 100}), std::invalid_argument);
  EXPECT_EQ(driver_->readStatus().status_word & kStatusStreaming, 0u);
  EXPECT_TRUE(driver_->check());
  device_->setMirrorFault(true);
  EXPECT_FALSE(driver_->check());
}

TEST_F(UsbDigitizerTest, OpensBySerial) {
  UsbDigitizerOptions options;
  options.serial = "VD-0001";
  connect(options);
  EXPECT_EQ(driver_->identity().serial, "VD-0001");
  driver_->disconnect();
  options.serial = "VD-9999";
  UsbDigitizer other(options);
  try {
    other.connect();
    FAIL() << "connected to the wrong serial";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.code(), "not-found");
    EXPECT_NE(std::string(e.what()).find("VD-9999"), std::string::npos) << e.what();
  }
}

TEST_F(UsbDigitizerTest, StreamsProfilesEqualToWhatTheSourceSupplied) {
  connect();
  start();
  EXPECT_TRUE(device_->streaming());
  EXPECT_EQ(driver_->state(), DeviceState::Busy);
  ASSERT_TRUE(collector_.waitProfiles(500));
  driver_->stop();
  EXPECT_FALSE(device_->streaming());
  EXPECT_FALSE(driver_->streaming());
  EXPECT_EQ(driver_->state(), DeviceState::Ready);
  const auto profiles = collector_.profiles();
  for (std::size_t i = 0; i < profiles.size(); ++i) {
    ASSERT_EQ(profiles[i].sequence, i);
    ASSERT_EQ(profiles[i].range.size(), 1024u);
    EXPECT_EQ(profiles[i].device_time_ns, i * 2'000'000u);  // 500 profiles/s
  }
  expectDeliveredAsSupplied();
  const DigitizerCounters c = driver_->counters();
  EXPECT_EQ(c.profiles, profiles.size());
  EXPECT_EQ(c.lost_profiles + c.bad_packets + c.timeouts + c.stalls_recovered, 0u);
  EXPECT_TRUE(collector_.faults().empty());
  // Streaming again continues the sequence without a gap being reported.
  start();
  ASSERT_TRUE(collector_.waitProfiles(profiles.size() + 10));
  driver_->stop();
  EXPECT_EQ(driver_->counters().sequence_gaps, 0u);
}

TEST_F(UsbDigitizerTest, DetectsADroppedSequenceNumber) {
  connect();
  start();
  ASSERT_TRUE(collector_.waitProfiles(20));
  device_->dropSequence(3);
  ASSERT_TRUE(collector_.waitFault("sequence-gap"));
  ASSERT_TRUE(collector_.waitProfiles(collector_.count() + 20));
  driver_->stop();
  const DigitizerCounters c = driver_->counters();
  EXPECT_EQ(c.sequence_gaps, 1u);
  EXPECT_EQ(c.lost_profiles, 3u);
  EXPECT_EQ(missingSequences().size(), 3u);
  for (const auto& f : collector_.faults()) {
    if (f.code == "sequence-gap") {
      EXPECT_NE(f.text.find("3 profile(s) lost"), std::string::npos) << f.text;
    }
  }
  expectDeliveredAsSupplied();
}

TEST_F(UsbDigitizerTest, RecoversFromAStall) {
  connect();
  start();
  ASSERT_TRUE(collector_.waitProfiles(20));
  device_->stallEndpoint();
  const std::size_t before = collector_.count();
  ASSERT_TRUE(collector_.waitProfiles(before + 200));
  driver_->stop();
  EXPECT_EQ(driver_->counters().stalls_recovered, 1u);
  EXPECT_EQ(device_->haltsCleared(), 1u);
  EXPECT_TRUE(missingSequences().empty());
  EXPECT_EQ(driver_->counters().lost_profiles, 0u);
  expectDeliveredAsSupplied();
}

TEST_F(UsbDigitizerTest, ReportsATimeoutAndResumes) {
  UsbDigitizerOptions options;
  options.transfer_timeout = 200ms;
  connect(options);
  start();
  ASSERT_TRUE(collector_.waitProfiles(10));
  device_->setSilent(true);
  const auto silent_from = std::chrono::steady_clock::now();
  ASSERT_TRUE(collector_.waitFault("timeout", 3s));
  EXPECT_GE(std::chrono::steady_clock::now() - silent_from, 150ms);
  device_->setSilent(false);
  ASSERT_TRUE(collector_.waitProfiles(collector_.count() + 50));
  driver_->stop();
  EXPECT_GE(driver_->counters().timeouts, 1u);
  EXPECT_TRUE(missingSequences().empty());  // the device held its data: nothing lost
  EXPECT_EQ(driver_->state(), DeviceState::Faulted);  // until the operator clears the fault
  driver_->clearFaults();
  EXPECT_EQ(driver_->state(), DeviceState::Ready);
}

TEST_F(UsbDigitizerTest, ReportsAnUnplugAsDisconnectedWithoutACrash) {
  connect();
  start();
  ASSERT_TRUE(collector_.waitProfiles(20));
  device_->unplug();
  ASSERT_TRUE(collector_.waitFault("disconnected"));
  driver_->stop();  // joins the event thread; every transfer has ended
  EXPECT_FALSE(driver_->streaming());
  EXPECT_EQ(driver_->state(), DeviceState::Faulted);
  try {
    driver_->readStatus();
    FAIL() << "a vanished device answered";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.code(), "disconnected");
  }
  EXPECT_FALSE(driver_->check());
  driver_->disconnect();
  EXPECT_EQ(driver_->state(), DeviceState::Disconnected);
}

// Profiles of 1024 points get through the driver with nothing lost while the device answers as fast
// as the host reaps. The rate is printed for the record, not asserted: on a quiet machine it is
// 4-6 times the head's 500 profiles/s, but a test machine running other suites beside this one can
// fall below that without anything being wrong in the driver.
TEST_F(UsbDigitizerTest, SustainsTheProfileRateWithoutLoss) {
  UsbDigitizerOptions options;
  options.transfers_in_flight = 8;
  connect(options);
  const auto t0 = std::chrono::steady_clock::now();
  start();
  ASSERT_TRUE(collector_.waitProfiles(3000, 20s));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  driver_->stop();
  const double rate = static_cast<double>(collector_.count()) / seconds;
  std::printf("[ rate     ] %zu profiles of 1024 points in %.2f s: %.0f profiles/s, %.1f MB/s\n",
              collector_.count(), seconds, rate, rate * static_cast<double>(profilePacketSize(1024)) / 1e6);
  EXPECT_TRUE(missingSequences().empty());
  EXPECT_EQ(driver_->counters().lost_profiles, 0u);
}


// A real head exposes at its rate into a buffer. A paced device whose profiles are reaped slower than
// they are made (here a source that takes 4 ms a profile against the 2 ms period, as a loaded host
// running the simulator) still sends, after Stop, every profile it made before Stop: the whole sweep
// arrives, later, and nothing is lost or silently cut off.
TEST_F(UsbDigitizerTest, AHeadReapedLateSendsEveryProfileItMadeBeforeStop) {
  device_.reset();
  VirtualDigitizerOptions paced;
  paced.paced = true;
  device_ = std::make_unique<VirtualDigitizer>(paced);
  device_->setProfileSource([](std::uint32_t seq, const DigitizerConfig& c, Profile& p) {
    std::this_thread::sleep_for(4ms);
    VirtualDigitizer::testPattern(seq, c, p);
  });
  connect();
  start();
  const auto t0 = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(600ms);
  const std::size_t before_stop = collector_.count();
  driver_->stop();
  const double streamed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto profiles = collector_.profiles();
  ASSERT_FALSE(profiles.empty());
  EXPECT_EQ(profiles.back().sequence + 1, device_->nextSequence());
  EXPECT_EQ(profiles.size(), device_->nextSequence() - profiles.front().sequence);
  EXPECT_TRUE(missingSequences().empty());
  EXPECT_EQ(driver_->counters().lost_profiles, 0u);
  // 600 ms at 500 profiles/s: about 300 made; the host had taken at most about half at Stop.
  EXPECT_GE(profiles.size(), 290u);
  EXPECT_LT(before_stop, profiles.size());
  EXPECT_GE(streamed, 1.0);
}

// Profiles the head made before Stop that never arrive (the head falls silent) are counted lost once
// none has come for the drain timeout: a sweep that lost its end says so.
TEST_F(UsbDigitizerTest, MadeProfilesThatNeverArriveAreCountedLost) {
  device_.reset();
  VirtualDigitizerOptions paced;
  paced.paced = true;
  device_ = std::make_unique<VirtualDigitizer>(paced);
  UsbDigitizerOptions options;
  options.drain_timeout = 300ms;
  connect(options);
  start();
  ASSERT_TRUE(collector_.waitProfiles(50));
  device_->setSilent(true);
  std::this_thread::sleep_for(200ms);
  driver_->stop();
  const auto profiles = collector_.profiles();
  const std::uint32_t made = device_->nextSequence() - profiles.front().sequence;
  EXPECT_GE(made, profiles.size() + 50);
  EXPECT_EQ(driver_->counters().lost_profiles, made - profiles.size());
  bool named = false;
  for (const DeviceFault& f : collector_.faults()) named |= f.code == "sequence-gap";
  EXPECT_TRUE(named);
}

}  // namespace
}  // namespace stampscan::drivers::digitizer
