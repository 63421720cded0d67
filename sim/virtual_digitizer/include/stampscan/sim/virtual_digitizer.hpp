// The virtual laser digitizer: a scripted USB device under umockdev. A umockdev testbed holds the
// device (sysfs attributes, USB descriptors, vendor 1d50:61a5) and an ioctl handler that answers the
// usbfs ioctls libusb sends (claim, control and bulk URBs, reap, discard, clear halt) speaking the
// protocol of drivers/digitizer/PROTOCOL.md. The unmodified UsbDigitizer driver talks to it exactly
// as to the real head. Profiles come from a profile source (the simulator, or a test pattern).
//
// umockdev's preload library must be active in the process (run under `umockdev-wrapper`, or with
// LD_PRELOAD=libumockdev-preload.so.0); preloadActive() says whether it is. The testbed redirects
// /sys and /dev for the whole process: create the VirtualDigitizer before the driver's libusb
// context (libusb enumerates at init) and only one per process at a time.
//
// Timing: the device answers a posted bulk transfer as soon as the host reaps it (as fast as the
// host can take profiles) unless `paced` is set, when it keeps the configured profile rate.
// Unpaced, device timestamps follow the configured rate (sequence / rate), a clock that stands
// still between streams. Paced, the device has a free-running clock like the real head's (ns since
// the device was made): GetStatus reports it, and profile k of a stream is exposed at
// start + k / rate, whenever the host happens to reap it, and stamped `stamp_latency_ns` later; a
// timed profile source is told that exposure time, so it renders the world as it was then. Like the
// real head's buffer, a paced device counts a profile as made when it falls due (GetStatus's
// next_sequence), and after Stop still sends every profile it made before it: a host that reaps
// late (a loaded machine, a slow profile source) gets the whole sweep, later.
//
// Threads: umockdev runs the ioctl handler on its own worker thread; the profile source runs there,
// under the device's lock, so it must not call back into the VirtualDigitizer. Every public method
// is thread-safe. The destructor removes the testbed; disconnect the driver first.
#pragma once

#include <chrono>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "stampscan/drivers/digitizer/digitizer_protocol.hpp"

namespace stampscan::sim {

struct VirtualDigitizerOptions {
  drivers::digitizer::Identity identity{drivers::digitizer::kProtocolVersion, "SSD-1024 (virtual)",
                                        "VD-0001", "1.0.0"};
  int bus = 1;  // the device is /dev/bus/usb/<bus>/001
  float half_angle = 0.21f;  // rad: the fan the GetConfig reply describes
  bool paced = false;
  std::int64_t stamp_latency_ns = 0;  // paced only: profile stamp minus its exposure
};

class VirtualDigitizer {
 public:
  // Fills range and intensity (config.points_per_profile each) and the status word of one profile;
  // sequence and timestamp are set by the device.
  using ProfileSource =
      std::function<void(std::uint32_t sequence, const drivers::digitizer::DigitizerConfig& config,
                         drivers::digitizer::Profile& profile)>;

  // Throws std::runtime_error when the testbed cannot be built.
  explicit VirtualDigitizer(VirtualDigitizerOptions options = {});
  ~VirtualDigitizer();
  VirtualDigitizer(const VirtualDigitizer&) = delete;
  VirtualDigitizer& operator=(const VirtualDigitizer&) = delete;

  static bool preloadActive();

  // The source of profile data; the default is testPattern().
  void setProfileSource(ProfileSource source);
  // A source that is also told when the profile was exposed (steady clock): a simulated world
  // renders itself as it was at that instant. Replaces the plain source. It returns how much later
  // (ns, may be negative) than `exposure` the profile it gave was really exposed, and the profile is
  // stamped so: a replay serves the recorded profile nearest to each tick, exposed between ticks.
  using TimedProfileSource =
      std::function<std::int64_t(std::uint32_t sequence, const drivers::digitizer::DigitizerConfig& config,
                                 std::chrono::steady_clock::time_point exposure, drivers::digitizer::Profile& profile)>;
  void setTimedProfileSource(TimedProfileSource source);
  // A deterministic pattern of the sequence number: ranges 80..120 mm with every 97th point a
  // dropout (0), intensities cycling.
  static void testPattern(std::uint32_t sequence, const drivers::digitizer::DigitizerConfig& config,
                          drivers::digitizer::Profile& profile);

  // Fault injection.
  void stallEndpoint();            // the next bulk transfer ends with STALL; halted until cleared
  void setSilent(bool silent);     // stop answering bulk transfers (the host sees timeouts)
  void dropSequence(int count = 1);  // the next `count` profiles are made but lost on the wire
  void unplug();                   // the device goes away: transfers end, every ioctl fails ENODEV
  void setMirrorFault(bool on);    // status bit in GetStatus and in the profiles

  // What happened, for tests.
  bool streaming() const;
  drivers::digitizer::DigitizerConfig config() const;
  std::uint32_t nextSequence() const;  // as GetStatus says (paced: one past the last profile made)
  std::uint64_t profilesSent() const;
  std::uint64_t haltsCleared() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::sim
