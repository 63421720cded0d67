// The line's PLC starts scans: the handshake of drivers/plc/REGISTER_MAP.md ("Started by the line"),
// watched while the panel serves (the cell file's [plc] line_start).
//
// The line writes line_program_number and line_part_id, then raises line_start_request and holds it.
// The cell takes the request as a person pressing Start takes a scan (CellJobs::startScan, the
// program found by its line number): cell_busy 1 while it runs; then cell_verdict and
// cell_error_code, and cell_done 1. The line reads the answer and drops its request; the cell then
// drops cell_done. A request the cell cannot take (unknown program, bad part id, another job
// running) is answered at once: cell_verdict 4 (error), its code, cell_done 1. A request dropped
// while its scan runs aborts the scan. cell_ready is 1 while a request would be taken: no job runs,
// no answer waits for its request to drop, the interlock is clear.
//
// Restarts: the answer registers are the PLC's and outlive the panel. At start the handshake reads
// them back: an answer still waiting for its request to drop keeps waiting; a cell_busy left by a
// panel that stopped during the line's scan is answered "scan_failed".
//
// Thread safety: every method may be called from any thread. The watch runs on a thread
// of its own, polling the PLC through the cell's driver (its API connection).
#pragma once

#include "stampscan/drivers/plc/modbus_plc.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "stampscan/hmi/event_hub.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace stampscan::hmi {

struct LineHandshakeOptions {
  // How often the line's request is read. The time from the request to cell_busy is about this.
  std::chrono::milliseconds poll_period{100};
  // The answer is written again at least this often, though unchanged: a PLC that restarted (and
  // lost its registers) has it back within this.
  std::chrono::milliseconds rewrite_period{1000};
};

// What the panel shows of the line (and GET /api/cell's "line").
struct LineState {
  bool connected = false;  // the last poll reached the PLC
  drivers::plc::LineRequest request;
  drivers::plc::CellAnswer answer;
  std::optional<std::uint64_t> job;  // the line's scan under way
  std::string last;                  // the last thing the handshake did, in words
  std::string error;                 // why the last poll failed, when it did
};

class LineHandshake {
 public:
  LineHandshake(CellJobs& jobs, EventHub& hub, LineHandshakeOptions options = {});
  ~LineHandshake();
  LineHandshake(const LineHandshake&) = delete;
  LineHandshake& operator=(const LineHandshake&) = delete;

  void start();
  // Stops watching. A line's scan under way is aborted and answered "aborted"; cell_ready drops.
  void stop();
  LineState state() const;

 private:
  void loop();
  // One poll: read the request, act on it, write the answer when it changed.
  void poll(drivers::plc::ModbusPlc& plc);
  void takeRequest(const drivers::plc::LineRequest& request);
  void refuse(drivers::plc::LineError error, const std::string& why);
  void note(const std::string& what);  // into state().last and an event for the pages

  CellJobs& jobs_;
  EventHub& hub_;
  LineHandshakeOptions options_;
  std::mutex control_mutex_;  // start() and stop(): the thread's life
  mutable std::mutex mutex_;  // the state below
  std::condition_variable wake_;
  bool stopping_ = false;
  LineState state_;
  bool read_back_ = false;  // the PLC's answer registers were read at the first poll
  bool withdrawn_ = false;  // the line dropped its request during its scan: the abort was asked
  std::optional<drivers::plc::CellAnswer> written_;
  std::chrono::steady_clock::time_point last_write_{};
  std::thread thread_;
};

}  // namespace stampscan::hmi
