// One client connection of the virtual CMM: the I++ DME server's two queues (§4, picture 11).
//
// The reader thread hands every line to onLine(). Lines with an E tag run at once on that thread
// (the fast queue: AbortE, GetErrStatusE, GetPropE, OnMoveReportE). Other commands are acknowledged
// (`&`) and queued; one executor thread runs them in order, so responses keep the order of §6.2.3,
// and moves run in real time on it while the reader thread stays free to take an AbortE.
//
// Errors follow §6.2.5 and §8: a class 2+ error aborts the queued transactions (0006) and puts the
// server into the error state, where only ClearAllErrors and a few queries are served (0511, 0514).
#pragma once

#include "cmm_machine.hpp"
#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace stampscan::sim::detail {

namespace ipp = drivers::cmm::ipp;

// Thrown by a command handler: the §8.2 number, and the particulars that GetErrorInfo explains.
class CommandFailure : public std::runtime_error {
 public:
  CommandFailure(int number, const std::string& detail, std::optional<int> severity = {})
      : std::runtime_error(detail), number_(number), severity_(severity) {}
  int number() const { return number_; }
  std::optional<int> severity() const { return severity_; }

 private:
  int number_;
  std::optional<int> severity_;
};

// Faults a test asks for, shared by the server and its sessions.
class FaultInjection {
 public:
  struct Failure {
    int number;
    std::optional<int> severity;
  };
  void failNext(int number, std::optional<int> severity);
  // The injected failure, once: the next command takes it.
  std::optional<Failure> take();

 private:
  std::mutex mutex_;
  std::optional<Failure> next_;
};

class IppSession {
 public:
  using Sink = std::function<void(const std::string& line)>;  // one response line, without CR LF

  IppSession(CmmMachine& machine, FaultInjection& faults, Sink sink);
  // The connection is gone: stops the move where it is, drops queued commands and daemons.
  ~IppSession();
  IppSession(const IppSession&) = delete;
  IppSession& operator=(const IppSession&) = delete;

  void onLine(const ipp::LineFramer::Line& line);  // reader thread only

  bool sessionActive() const;
  bool errorState() const;
  // When the last command finished (or the session began); nothing while a command is queued or
  // runs. The server's idle timeout counts from here, so a long move is never taken for idleness.
  std::optional<Clock::time_point> idleSince() const;

 private:
  struct Pending {
    ipp::Tag tag;
    std::optional<ipp::Command> command;
    // A line that did not parse, answered in queue order (§6.2.3). Plain data: an exception object
    // is not handed to another thread (its message may be a shared, reference-counted string).
    struct SyntaxError {
      int number;
      std::string message;
    };
    std::optional<SyntaxError> syntax_error;
    bool aborted = false;                            // by an error or AbortE before it started
  };
  struct MoveDaemon {  // OnMoveReportE (§6.3.2.7)
    ipp::Tag tag;
    double interval = 0;      // Time(s), 0 when not given
    double min_distance = 0;  // Dis(d), 0 when not given
    std::vector<std::string> items;  // X, Y, Z, Tool.A, Tool.B, Tool.C, SS.Time, in the order asked for
    bool reported = false;
    Clock::time_point last_time;
    MachinePose last_pose{};
  };
  class Responder;

  // Reader thread.
  void onCommand(ipp::Command command);
  void enqueue(Pending pending);  // acknowledges and queues for the executor
  void runFast(const ipp::Command& command);
  void abortE(const ipp::Command& command);
  void onMoveReportE(const ipp::Command& command, Responder& out);
  void replyToBadLine(const ipp::ProtocolError& error);
  bool tagInUse(ipp::Tag tag) const;

  // Executor thread.
  void executorLoop();
  void execute(Pending& pending);
  void dispatch(const ipp::Command& command, Responder& out);  // session_commands.cpp
  bool runMove(const MachinePose& target);                       // false when aborted
  void sendFinalReport(std::unique_lock<std::mutex>& lock);      // under mutex_, which it may release
  bool pause(Clock::time_point until);                           // false when aborted
  std::optional<std::string> dueReport(Clock::time_point now, bool at_rest);  // with mutex_ held
  // The report of the daemon's items now, whatever its schedule (a replayed move's recorded instants).
  std::optional<std::string> reportNow(Clock::time_point now);
  Clock::time_point nextReportCheck(Clock::time_point now) const;             // with mutex_ held

  // Command handlers (session_commands.cpp).
  void startSession(const ipp::Command& c, Responder& out);
  void endSession(const ipp::Command& c, Responder& out);
  void stopDaemon(const ipp::Command& c, Responder& out);
  void stopAllDaemons(const ipp::Command& c, Responder& out);
  void clearAllErrors(const ipp::Command& c, Responder& out);
  void getErrorInfo(const ipp::Command& c, Responder& out);
  void getXtdErrStatus(const ipp::Command& c, Responder& out);
  void home(const ipp::Command& c, Responder& out);
  void goTo(const ipp::Command& c, Responder& out);
  void get(const ipp::Command& c, Responder& out);
  void getProp(const ipp::Command& c, Responder& out);
  void setProp(const ipp::Command& c, Responder& out);
  void changeTool(const ipp::Command& c, Responder& out);
  void setTool(const ipp::Command& c, Responder& out);
  void findTool(const ipp::Command& c, Responder& out);
  void enumTools(const ipp::Command& c, Responder& out);
  void userCommand(const ipp::Command& c, Responder& out);  // EnableUser, DisableUser, IsUserEnabled
  void simpleQuery(const ipp::Command& c, Responder& out);  // IsHomed, GetMachineClass, GetDMEVersion
  ipp::Argument propertyValue(const ipp::Argument& property) const;

  // Either thread.
  void send(const ipp::Reply& reply);
  // Records an error response; class 2+ enters the error state and aborts what is queued. mutex_ held.
  void recordError(const ipp::ErrorReport& report, const std::string& detail);
  bool commandAllowed(const std::string& name, bool fast, Responder& out);

  CmmMachine& machine_;
  FaultInjection& faults_;
  Sink sink_;

  mutable std::mutex mutex_;
  std::condition_variable work_;    // queue_ changed, or closing_
  std::condition_variable idle_;    // the executor finished a command
  std::condition_variable motion_;  // abort_requested_ or closing_ changed: a running move stops
  std::deque<Pending> queue_;
  std::set<ipp::Tag> in_flight_;    // queued or executing (§6.2.1: unique while processed)
  bool executing_ = false;
  Clock::time_point last_done_ = Clock::now();  // idleSince()
  bool abort_requested_ = false;
  bool closing_ = false;

  bool session_active_ = false;
  Clock::time_point session_start_;
  bool error_state_ = false;
  std::vector<ipp::ErrorReport> errors_;  // since the last ClearAllErrors, for GetXtdErrStatus
  std::map<int, std::string> error_info_;  // number -> particulars of its last occurrence
  bool user_enabled_ = false;
  std::string found_tool_ = "UnDefTool";  // FindTool's pointer (§6.3.2.17)
  std::optional<MoveDaemon> daemon_;
  // When the report at a move's target, held back by the rate limit, is due (the executor sends it).
  std::optional<Clock::time_point> final_report_due_;

  std::thread executor_;
};

// The responses of one transaction, in order: data lines, errors and warnings, then `%`.
class IppSession::Responder {
 public:
  Responder(IppSession& session, ipp::Tag tag, std::string method)
      : session_(session), tag_(tag), method_(std::move(method)) {}

  ipp::Tag tag() const { return tag_; }
  void data(std::vector<ipp::Argument> items);
  // An error or warning of §8.2 with its default class unless `severity` is given; `detail` is what
  // GetErrorInfo will tell.
  void error(int number, const std::string& detail, std::optional<int> severity = {});
  void fail(const CommandFailure& failure) { error(failure.number(), failure.what(), failure.severity()); }
  void complete();

 private:
  IppSession& session_;
  ipp::Tag tag_;
  std::string method_;
};

}  // namespace stampscan::sim::detail
