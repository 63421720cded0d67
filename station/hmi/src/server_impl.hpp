// The panel server's state, shared by its route files (private to the library).
#pragma once

#include "stampscan/hmi/auth.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "stampscan/hmi/event_hub.hpp"
#include "stampscan/hmi/hmi_server.hpp"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <mutex>
#include <optional>
#include <string>

namespace stampscan::hmi {

struct HmiServer::Impl {
  Impl(CellSetup setup, HmiOptions o);

  HmiOptions options;
  std::string host;
  int port = 0;
  EventHub hub;
  Authenticator auth;
  CellJobs jobs;
  httplib::Server server;
  std::mutex actions_mutex;

  // The session of a request (its cookie), or nothing.
  std::optional<Session> sessionOf(const httplib::Request& req);
  // Appends to the actions log: who, what, the details.
  void recordAction(const Session& who, const std::string& action, const nlohmann::json& detail,
                    const httplib::Request& req);
  std::filesystem::path runsDir() const { return jobs.setup().scan.runs_dir; }
};

// A JSON body with the status; errors are {"error": "..."} (and "advice" when there is some).
void sendJson(httplib::Response& res, const nlohmann::json& body, int status = 200);
void sendError(httplib::Response& res, int status, const std::string& error, const std::string& advice = "");

// The routes under /api/ (api_routes.cpp) and the page and its scripts (hmi_server.cpp).
void addApiRoutes(HmiServer::Impl& impl);
void addRunRoutes(HmiServer::Impl& impl);

}  // namespace stampscan::hmi
