// The operator's panel: `station hmi` serves the page (station/hmi/web/, built into the program),
// Debian's packaged JavaScript (three.js, Chart.js from /usr/share/javascript: no CDN) and the JSON
// API of API.md, with live updates as Server-Sent Events. It is a client of the CLI's own jobs
// (cell_jobs.hpp), results database and calibration store: no workflow lives here.
//
// Security (auth.hpp): on a loopback address there is no login; on any other, or behind the TLS
// front, a users file is required and every API call but the login needs a session. Only the
// names it is served under are answered (HmiOptions::server_names). Every state-changing request must
// carry the session's CSRF token and, when the browser sends an Origin, come from this server's
// own origin. Every action is appended to the actions log with who did it.
//
// Thread safety: construct and run() on one thread; stop() from any thread.
#pragma once

#include "stampscan/hmi/cell_health.hpp"
#include "stampscan/hmi/cell_jobs.hpp"

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace stampscan::hmi {

struct HmiOptions {
  std::string listen = "127.0.0.1:8080";  // host:port; port 0 picks a free one
  // Required when the host is not loopback.
  std::filesystem::path users_file;
  std::chrono::seconds session_idle_timeout{15 * 60};
  // Who did what, one JSON object a line; empty: hmi-actions.jsonl in the runs folder.
  std::filesystem::path actions_log;
  // The page's files; empty: the copy built into the program.
  std::filesystem::path web_dir;
  // Debian's packaged JavaScript, served under /lib/.
  std::filesystem::path javascript_dir = "/usr/share/javascript";
  // The names the plant's network reaches the panel under, besides loopback ones. A request for any
  // other Host is refused (421) before anything is handed out: a page of another site cannot drive
  // the panel through a name of its own that resolves here (DNS rebinding). Without a login only
  // loopback names are served; with one, also any IP address literal.
  std::vector<std::string> server_names;
  // Served through its TLS front (tls_front.hpp): the panel listens on loopback, every user logs in,
  // its cookies are Secure, and the front's X-Forwarded-Proto and X-Forwarded-For are believed
  // from a loopback peer.
  bool behind_tls_front = false;
  // Off loopback without the front, passwords and cookies would travel in clear text: refused
  // unless asked for (a closed test bench).
  bool allow_plain_http = false;
};

class HmiServer {
 public:
  // Throws std::runtime_error for a listen address that cannot be parsed, or that is not loopback
  // without a users file, or a users file that cannot be read.
  HmiServer(CellSetup setup, HmiOptions options);
  // The same checks of the options alone (listen address, users file), so that a caller can refuse
  // bad options before it starts anything (the embedded virtual cell takes its ports).
  static void checkOptions(const HmiOptions& options);
  ~HmiServer();
  HmiServer(const HmiServer&) = delete;
  HmiServer& operator=(const HmiServer&) = delete;

  // Binds the listening socket; returns the port. Throws std::runtime_error naming the address when
  // it cannot bind.
  int bind();
  // Connects the cell's devices in the background and serves until stop(). Call bind() first.
  void run();
  void stop();
  // http://host:port/ once bound.
  std::string url() const;
  bool loginRequired() const;
  // The cell's health now (cell_health.hpp): what GET /api/health answers.
  CellHealth health() const;

 // The server's state, defined in the library's sources (its route files share it).
  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace stampscan::hmi
