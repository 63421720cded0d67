// Where a scan's messages go as they are made: the recorder (an MCAP file), or a consumer in memory
// (tests). The simulator and the ScanRunner both write to one, so that a simulated session and a
// scan on the cell produce the same trace.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::trace {

class TraceSink {
 public:
  virtual ~TraceSink() = default;
  // One message on a standard topic (trace_messages.hpp), `log_time_ns` on the station clock.
  virtual void message(std::string_view topic, std::int64_t log_time_ns, std::vector<std::byte> bytes) = 0;
  virtual void metadata(const std::string& name, const std::map<std::string, std::string>& values) = 0;
};

}  // namespace stampscan::trace
