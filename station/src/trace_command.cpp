// `station trace info TRACE.mcap`: what a scan trace holds (channels, message counts and rates, time
// span, chunks and compression, attachments, metadata) and whether it is intact. The whole file is
// scanned rather than only its summary, so damage anywhere is found and a cut trace still reports
// what it holds. Exit 0 for a healthy trace; 1 with the report for a damaged or cut one, and 1 with a
// one-line error for a file that is missing or not MCAP.
#include "stampscan/acquisition/trace/mcap_reader.hpp"
#include "stampscan/station/commands.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::station {

namespace {

struct TraceInfoOptions {
  std::string path;
};

struct Tally {
  std::uint64_t count = 0;
  std::uint64_t first = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t last = 0;
};

// Log times are integer ns (ARCHITECTURE.md: "Timestamps are int64 nanoseconds"); printed exactly.
std::string seconds(std::uint64_t ns) {
  char text[48];
  std::snprintf(text, sizeof text, "%" PRIu64 ".%09" PRIu64, ns / 1000000000u, ns % 1000000000u);
  return text;
}

std::string bytes(std::uint64_t n) {
  char text[48];
  if (n < 10 * 1024) std::snprintf(text, sizeof text, "%" PRIu64 " B", n);
  else if (n < 10 * 1024 * 1024) std::snprintf(text, sizeof text, "%.1f KiB", static_cast<double>(n) / 1024.0);
  else std::snprintf(text, sizeof text, "%.1f MiB", static_cast<double>(n) / (1024.0 * 1024.0));
  return text;
}

double spanSeconds(std::uint64_t first, std::uint64_t last) {
  return last > first ? static_cast<double>(last - first) * 1e-9 : 0.0;
}

const char* orNone(const std::string& s) { return s.empty() ? "(none)" : s.c_str(); }

int traceInfo(const TraceInfoOptions& opt) {
  trace::McapReader reader(opt.path);  // throws, naming the path, when it cannot be opened
  if (reader.fileSize() == 0) throw std::runtime_error(opt.path + ": empty file, not an MCAP trace");
  std::map<std::uint16_t, Tally> tally;
  const trace::TraceHealth h = reader.readMessages([&](const trace::TraceMessage& m) {
    Tally& t = tally[m.channel_id];
    ++t.count;
    t.first = std::min(t.first, m.log_time);
    t.last = std::max(t.last, m.log_time);
    return true;
  });
  if (h.not_mcap) throw std::runtime_error(opt.path + ": not an MCAP file (it does not start with the MCAP magic)");
  std::vector<trace::Damage> summary_problems;
  const std::optional<trace::Summary> summary = reader.summary(&summary_problems);

  // Channels and schemas: those of the data section, completed from the summary.
  std::map<std::uint16_t, trace::Channel> channels = h.channels;
  std::map<std::uint16_t, trace::Schema> schemas = h.schemas;
  if (summary) {
    channels.insert(summary->channels.begin(), summary->channels.end());
    schemas.insert(summary->schemas.begin(), summary->schemas.end());
  }
  for (const auto& [id, t] : tally) channels.try_emplace(id, trace::Channel{id, 0, "(no Channel record)", "", {}});

  std::printf("trace         %s\n", opt.path.c_str());
  std::printf("  size        %" PRIu64 " bytes", h.file_size);
  if (h.file_size >= 10 * 1024) std::printf(" (%s)", bytes(h.file_size).c_str());
  std::printf("\n");
  if (h.header) std::printf("  header      profile %s, library %s\n", orNone(h.header->profile), orNone(h.header->library));
  std::printf("  channels    %zu\n", channels.size());
  Tally all;
  for (const auto& [id, c] : channels) {
    const Tally t = tally.count(id) ? tally.at(id) : Tally{};
    const auto schema = schemas.find(c.schema_id);
    std::printf("    %5u  %-28s schema %-28s encoding %-8s %8" PRIu64 " messages", static_cast<unsigned>(id),
                c.topic.c_str(), schema == schemas.end() ? "(none)" : schema->second.name.c_str(),
                orNone(c.message_encoding), t.count);
    if (t.count) {
      const double span = spanSeconds(t.first, t.last);
      std::printf("  %s .. %s s", seconds(t.first).c_str(), seconds(t.last).c_str());
      if (span > 0) std::printf("  %.2f Hz", static_cast<double>(t.count - 1) / span);
      all.count += t.count;
      all.first = std::min(all.first, t.first);
      all.last = std::max(all.last, t.last);
    }
    std::printf("\n");
  }
  if (all.count)
    std::printf("  span        %s .. %s s (%.3f s), %" PRIu64 " messages\n", seconds(all.first).c_str(),
                seconds(all.last).c_str(), spanSeconds(all.first, all.last), all.count);
  else std::printf("  span        no messages\n");
  std::string compressions;
  for (const std::string& c : h.compressions) compressions += (compressions.empty() ? "" : ", ") + std::string(c.empty() ? "none" : c);
  std::printf("  chunks      %" PRIu64 "%s%s%s", h.chunks, compressions.empty() ? "" : " (", compressions.c_str(),
              compressions.empty() ? "" : ")");
  if (h.chunk_compressed_bytes > 0)
    std::printf(", %s -> %s, ratio %.2f", bytes(h.chunk_uncompressed_bytes).c_str(), bytes(h.chunk_compressed_bytes).c_str(),
                static_cast<double>(h.chunk_uncompressed_bytes) / static_cast<double>(h.chunk_compressed_bytes));
  std::printf("\n");
  std::printf("  attachments %zu\n", h.attachments.size());
  for (const trace::AttachmentInfo& a : h.attachments)
    std::printf("    %s (%s, %s)\n", a.name.c_str(), orNone(a.media_type), bytes(a.data_size).c_str());
  std::printf("  metadata    %zu\n", h.metadata.size());
  for (const trace::MetadataInfo& m : h.metadata) std::printf("    %s (%zu keys)\n", m.name.c_str(), m.metadata.size());

  // The summary's statistics must agree with what the scan found in an intact file.
  std::vector<std::string> inconsistencies;
  if (summary && summary->statistics && h.damage.empty() && !h.truncated) {
    const trace::Statistics& s = *summary->statistics;
    if (s.message_count != h.messages_found)
      inconsistencies.push_back("summary statistics count " + std::to_string(s.message_count) + " messages, the scan found " +
                                std::to_string(h.messages_found));
    if (s.chunk_count != h.chunks)
      inconsistencies.push_back("summary statistics count " + std::to_string(s.chunk_count) + " chunks, the scan found " +
                                std::to_string(h.chunks));
  }

  const bool healthy = h.healthy() && inconsistencies.empty();
  if (healthy) {
    std::printf("  health      ok: %s%s%s\n", h.chunks ? "every chunk CRC, " : "",
                h.data_crc_checked ? "the data section CRC, " : "",
                h.summary_crc_checked ? "the summary CRC checked" : "structure checked");
    return 0;
  }
  std::printf("  health      %s%s%s\n", h.truncated ? "TRUNCATED" : "", h.truncated && !h.damage.empty() ? ", " : "",
              !h.damage.empty() || !inconsistencies.empty() ? "DAMAGED" : (h.truncated ? "" : "INCOMPLETE"));
  if (h.truncated) {
    const trace::Truncation& t = *h.truncated;
    std::printf("  truncated   the file ends at byte %" PRIu64 ", inside the %s at byte %" PRIu64 " (%" PRIu64
                " of its %" PRIu64 " bytes present)\n",
                t.file_size, t.record.c_str(), t.record_offset, t.bytes_present, t.bytes_needed);
  }
  for (const trace::Damage& d : h.damage)
    std::printf("  damage      at byte %" PRIu64 ": %s\n", d.offset, d.what.c_str());
  for (const std::string& i : inconsistencies) std::printf("  damage      %s\n", i.c_str());
  if (!h.data_end_found && !h.truncated) std::printf("  damage      no Data End record found\n");
  if (h.footer_found && !summary)
    for (const trace::Damage& d : summary_problems)
      std::printf("  summary     not usable: %s\n", d.what.c_str());
  std::printf("  recovered   %" PRIu64 " messages (%" PRIu64 " not CRC-checked), %" PRIu64
              " lost in damaged chunks, %" PRIu64 " chunks damaged\n",
              h.messages_found, h.messages_unverified, h.messages_lost, h.chunks_damaged);
  return 1;
}

}  // namespace

CommandRunner addTraceCommand(CLI::App& app) {
  auto opt = std::make_shared<TraceInfoOptions>();
  CLI::App* cmd = app.add_subcommand("trace", "Inspect MCAP scan traces");
  cmd->require_subcommand(1);
  CLI::App* info = cmd->add_subcommand("info", "What a trace holds and whether it is intact (exit 1 if damaged or cut)");
  info->add_option("trace", opt->path, "MCAP trace file")->required();
  return [opt]() { return traceInfo(*opt); };
}

}  // namespace stampscan::station
