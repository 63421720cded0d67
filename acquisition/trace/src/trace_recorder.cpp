#include "stampscan/acquisition/trace/trace_recorder.hpp"

#include "stampscan/acquisition/trace/trace_messages.hpp"

#include <stdexcept>

namespace stampscan::trace {

void TraceRecorder::write(std::string_view topic, std::int64_t log_time_ns, std::span<const std::byte> bytes) {
  auto channel = channels_.find(topic);
  if (channel == channels_.end()) {
    const MessageSchema schema = topics::schemaOfTopic(topic);
    auto known = schemas_.find(schema.name);
    if (known == schemas_.end())
      known = schemas_.emplace(std::string(schema.name), writer_.addSchema(schema.name, "ros2msg", schema.definition)).first;
    channel = channels_.emplace(std::string(topic), writer_.addChannel(known->second, topic, "cdr")).first;
  }
  if (log_time_ns < 0) throw std::invalid_argument("TraceRecorder: negative log time on " + std::string(topic));
  const auto t = static_cast<std::uint64_t>(log_time_ns);
  writer_.write(channel->second, t, t, bytes);
}

}  // namespace stampscan::trace
