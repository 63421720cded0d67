// The panel server's state, shared by its route files (private to the library).
#pragma once

#include "stampscan/hmi/auth.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "stampscan/hmi/event_hub.hpp"
#include "stampscan/hmi/hmi_server.hpp"
#include "stampscan/hmi/line_handshake.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace stampscan::hmi {

struct HmiServer::Impl {
  Impl(CellSetup setup, HmiOptions o);

  HmiOptions options;
  std::string host;  // as given in the listen option
  // What host resolved to (the address bound, so a name's DNS cannot move it between the check
  // and the bind), and whether all it resolves to is loopback (no login then).
  std::string bind_address;
  bool loopback_only = false;
  int port = 0;
  EventHub hub;
  Authenticator auth;
  CellJobs jobs;
  // The line's handshake, when the cell lets the line start scans (CellSetup::line_start); started
  // by run(), stopped by stop(). After `jobs`: it goes first.
  std::unique_ptr<LineHandshake> line_handshake;
  httplib::Server server;
  std::mutex actions_mutex;
  std::mutex settings_mutex;  // one change of the cell's settings (and its file) at a time

  // Whether the request came through the TLS front (from a loopback peer, with the front's headers).
  bool viaTlsFront(const httplib::Request& req) const;
  // Who sent the request: the front's client when it came through the front.
  std::string clientAddress(const httplib::Request& req) const;
  // Whether the panel answers requests for this Host name (hmi_server.hpp, HmiOptions::server_names).
  bool servesName(const std::string& host_name) const;
  // The session of a request (its cookie), or nothing.
  std::optional<Session> sessionOf(const httplib::Request& req);
  // Appends to the actions log: who, what, the details.
  void recordAction(const Session& who, const std::string& action, const nlohmann::json& detail,
                    const httplib::Request& req);
  std::filesystem::path runsDir() const { return jobs.setup().scan.runs_dir; }
  // The cell's health, checked at most once every few seconds whoever asks (a monitoring probe,
  // the pages, the log): a check reads the disk and reaches the results database, which a probe
  // polling fast must not multiply.
  CellHealth health();
  std::mutex health_mutex;
  std::optional<CellHealth> health_cache;
  std::chrono::steady_clock::time_point health_checked{};
};

// A request whose parameters are wrong: answered 400 with the message.
class BadRequest : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A JSON body with the status; errors are {"error": "..."} (and "advice" when there is some).
void sendJson(httplib::Response& res, const nlohmann::json& body, int status = 200);
void sendError(httplib::Response& res, int status, const std::string& error, const std::string& advice = "");

// The routes under /api/ (api_routes.cpp, run_routes.cpp, ...) and the page and its scripts (hmi_server.cpp).
void addApiRoutes(HmiServer::Impl& impl);
void addRunRoutes(HmiServer::Impl& impl);
void addAnalysisRoutes(HmiServer::Impl& impl);   // analysis_routes.cpp
void addSettingsRoutes(HmiServer::Impl& impl);   // settings_routes.cpp

}  // namespace stampscan::hmi
