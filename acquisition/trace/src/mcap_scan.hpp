// The linear, recovering scan behind McapReader::readMessages: one pass over the file from the
// start, record by record, that delivers messages and fills a TraceHealth.
//
// How it stays safe on damaged input:
//  - A chunk's messages are delivered only after its CRC matched (or, if it has none, it decoded to
//    exactly its declared size). Messages outside chunks are unverifiable and are delivered only on
//    channels a Channel record defined, flagged unverified.
//  - A record that cannot be right (opcode 0 or unknown and not followed by a plausible record, a
//    length past the end of the file or into the summary) means the framing is lost: the scan
//    resynchronises by searching forward, from just after the start of the last record it could not
//    vouch for, for a record that validates on its own: a chunk or attachment whose CRC matches, or
//    the Data End / Footer at the offsets a valid footer gives.
//  - A record running past the end of a file without a valid footer is a cut: the chunk it belongs to
//    yields the complete records decodable from its bytes, and the scan stops with a Truncation.
#pragma once

#include "byte_source.hpp"
#include "mcap_codec.hpp"
#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace stampscan::trace::detail {

class Scanner {
 public:
  // `summary_channels` (may be null) name channels whose Channel record the scan has not met.
  Scanner(ByteSource& source, const MessageCallback& callback, const ReadOptions& options,
          const std::map<std::uint16_t, Channel>* summary_channels, TraceHealth& health);
  void run();

 private:
  void detectTrailer();
  bool readStart();
  void scanData();
  bool handleRecord(std::uint8_t opcode, std::uint64_t length);
  void handleChunk(std::uint64_t length);
  void recoverCutChunk(std::uint64_t length, std::uint64_t available);
  void handleMessage(std::uint64_t length);
  void handleMessageIndex(std::uint64_t length);
  void handleAttachment(std::uint64_t length);
  void handleDataEnd(std::uint64_t length);
  void walkSummary(std::uint64_t start);
  void handleFooter(std::uint64_t at, std::uint64_t length, std::optional<std::uint64_t> summary_crc_start);

  void deliverRecords(Bytes records, bool verified, bool cut);
  bool deliver(const MessageView& m, std::uint64_t record_offset, bool verified);
  const Channel* channel(std::uint16_t id) const;
  void storeSchema(Bytes content, std::uint64_t offset);
  void storeChannel(Bytes content, std::uint64_t offset);

  bool plausibleRecordAt(std::uint64_t at);
  void lostFraming(std::uint64_t bad, const std::string& what, DamageKind kind);
  void resync(std::uint64_t from);
  std::optional<std::uint64_t> findAnchor(std::uint64_t from);
  bool validAnchor(std::uint64_t at);
  bool chunkValidates(std::uint64_t at, std::uint64_t length);
  enum class AttachmentCheck { kMalformed, kNoCrc, kMismatch, kOk };
  AttachmentCheck checkAttachment(std::uint64_t at, std::uint64_t length, AttachmentInfo* info);

  void damage(std::uint64_t offset, DamageKind kind, std::string what);
  void truncate(std::string record, std::uint64_t at, std::uint64_t needed, std::uint64_t present);
  void crcTo(std::uint64_t to);
  std::uint32_t crcOver(std::uint64_t from, std::uint64_t to);

  ByteSource& src_;
  const MessageCallback& callback_;
  const ReadOptions& options_;
  const std::map<std::uint16_t, Channel>* summary_channels_;
  TraceHealth& h_;
  std::uint64_t size_;

  std::uint64_t pos_ = 0;
  std::uint64_t record_start_ = 0;    // start of the last record taken on its stated length
  bool record_vouched_ = true;        // that record's content was confirmed by a CRC ...
  std::uint64_t vouched_end_ = std::numeric_limits<std::uint64_t>::max();  // ... up to here
  std::uint64_t crc_pos_ = 0;         // data section CRC computed over [0, crc_pos_)
  std::uint32_t crc_ = 0;
  bool trailer_valid_ = false;        // the file ends with a Footer record and the magic
  Footer footer_;
  std::uint64_t footer_offset_ = 0;
  std::optional<std::uint64_t> data_end_offset_;  // where the footer says Data End is
  bool last_chunk_damaged_ = false;   // Message Index records that follow count lost messages
  std::set<std::uint16_t> unknown_channels_;
  std::vector<std::byte> buffer_;     // decoded chunk records
};

}  // namespace stampscan::trace::detail
