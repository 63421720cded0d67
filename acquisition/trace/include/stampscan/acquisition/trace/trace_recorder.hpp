// Records the station's standard topics into an MCAP trace: the first message on a topic registers
// its ros2msg schema and its CDR channel, so every trace of the cell carries the same layout.
// Not thread-safe: one writer at a time (the ScanRunner serialises its device threads).
#pragma once

#include "stampscan/acquisition/trace/mcap_writer.hpp"
#include "stampscan/acquisition/trace/trace_sink.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>

namespace stampscan::trace {

class TraceRecorder final : public TraceSink {
 public:
  explicit TraceRecorder(McapWriter& writer) : writer_(writer) {}
  // Writes one message on a standard topic (see trace_messages.hpp); publish time = log time.
  // Throws std::invalid_argument for a topic without a schema.
  void write(std::string_view topic, std::int64_t log_time_ns, std::span<const std::byte> bytes);
  // TraceSink
  void message(std::string_view topic, std::int64_t log_time_ns, std::vector<std::byte> bytes) override {
    write(topic, log_time_ns, bytes);
  }
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override {
    writer_.addMetadata(name, values);
  }
  McapWriter& writer() { return writer_; }

 private:
  McapWriter& writer_;
  std::map<std::string, std::uint16_t, std::less<>> channels_;
  std::map<std::string, std::uint16_t, std::less<>> schemas_;
};

}  // namespace stampscan::trace
