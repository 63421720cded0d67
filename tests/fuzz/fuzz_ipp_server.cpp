// Fuzz target for I++ DME lines at the server: a client's bytes, framed and handed to the virtual
// CMM's session, which parses and runs them on a machine whose moves take milliseconds. Every line
// it answers must be a well-formed response within the line limit of §6.2.
#include "fuzz_targets.hpp"

#include "cmm_machine.hpp"
#include "ipp_session.hpp"
#include "stampscan/drivers/cmm/ipp_protocol.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace stampscan::fuzz {

namespace {
namespace ipp = drivers::cmm::ipp;

// Throwing (rather than returning) makes libFuzzer report the input as a crash.
void require(bool condition, const char* what) {
  if (!condition) throw std::logic_error(what);
}

// A machine whose every move and tool change takes a few milliseconds at most, whatever speed a
// mutated SetProp asks for, so that a case runs its commands rather than waiting for them.
sim::VirtualCmmConfig quickMachine() {
  sim::VirtualCmmConfig c;
  c.min_speed = 1e5;
  c.max_speed = c.default_speed = 1e6;
  c.min_accel = 1e9;
  c.max_accel = c.default_accel = 1e10;
  c.head_max_rate_deg_s = 1e6;
  c.head_accel_deg_s2 = 1e10;
  c.tool_change_seconds = 0;
  return c;
}
}  // namespace

int fuzzIppServer(const std::uint8_t* data, std::size_t size) {
  sim::detail::CmmMachine machine(quickMachine());
  sim::detail::FaultInjection faults;
  std::mutex mutex;
  std::vector<std::string> sent;
  {
    sim::detail::IppSession session(machine, faults, [&](const std::string& line) {
      std::lock_guard lock(mutex);
      sent.push_back(line);
    });
    ipp::LineFramer framer;
    framer.append(std::string_view(reinterpret_cast<const char*>(data), size));
    while (std::optional<ipp::LineFramer::Line> line = framer.next()) {
      session.onLine(*line);
      // One command at a time, as a client waiting for each answer: bounded, since a daemon's last
      // report may hold a move's end for up to 0.1 s.
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
      while (!session.idleSince() && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    }
  }  // the connection closes: the session stops what still runs
  std::lock_guard lock(mutex);
  for (const std::string& line : sent) {
    require(line.size() <= ipp::kMaxLineLength, "a response line is longer than the limit of 6.2");
    const ipp::Reply reply = ipp::parseReply(line);  // a ProtocolError here is a server bug
    require(ipp::formatReply(reply) == line || ipp::parseReply(ipp::formatReply(reply)) == reply,
            "a response does not survive parse and format");
  }
  return 0;
}

}  // namespace stampscan::fuzz

#ifndef STAMPSCAN_FUZZ_REPLAY
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return stampscan::fuzz::fuzzIppServer(data, size);
}
#endif
