#include "stampscan/hmi/hmi_server.hpp"

#include "json_views.hpp"
#include "server_impl.hpp"
#include "stampscan/hmi/run_files.hpp"
#include "stampscan/registration/calibration_store.hpp"
#include "web_assets.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <fstream>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kSessionCookie = "stampscan_session";

std::pair<std::string, int> parseListen(const std::string& listen) {
  const auto colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0)
    throw std::runtime_error("--listen '" + listen + "': expected HOST:PORT, e.g. 127.0.0.1:8080");
  std::string host = listen.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  int port = -1;
  try {
    std::size_t used = 0;
    port = std::stoi(listen.substr(colon + 1), &used);
    if (used != listen.size() - colon - 1) port = -1;
  } catch (const std::exception&) {
  }
  if (port < 0 || port > 65535) throw std::runtime_error("--listen '" + listen + "': the port is not a number 0-65535");
  return {host, port};
}

std::string cookieValue(const httplib::Request& req, const std::string& name) {
  const std::string cookies = req.get_header_value("Cookie");
  std::size_t pos = 0;
  while (pos < cookies.size()) {
    const std::size_t end = std::min(cookies.find(';', pos), cookies.size());
    std::string item = cookies.substr(pos, end - pos);
    item.erase(0, item.find_first_not_of(' '));
    if (item.rfind(name + "=", 0) == 0) return item.substr(name.size() + 1);
    pos = end + 1;
  }
  return "";
}

// What a route needs of the caller: nothing (the page, the login), a session, or the maintenance role.
std::optional<Role> neededRole(const httplib::Request& req) {
  const std::string& p = req.path;
  if (p == "/api/verify" || p == "/api/calibrate" || p == "/api/actions" || p == "/api/settings")
    return Role::Maintenance;
  // Planning a part program changes it: the engineers' work.
  if (p.rfind("/api/programs/", 0) == 0 && p.size() > 5 && p.compare(p.size() - 5, 5, "/plan") == 0) return Role::Maintenance;
  return Role::Operator;
}

bool isStateChanging(const httplib::Request& req) { return req.method != "GET" && req.method != "HEAD"; }

// No login only when every address the listen name resolves to is a loopback one: a name such as
// "127.example" may resolve to an address of the plant's network.
bool listensOnLoopbackOnly(const std::vector<std::string>& addresses) {
  return std::all_of(addresses.begin(), addresses.end(), [](const std::string& a) { return isLoopbackHost(a); });
}

// Behind the TLS front the panel listens on loopback only (the front is the way in) and every user
// logs in; anywhere but loopback, too.
bool loginRequiredFor(const HmiOptions& o, bool loopback_only) {
  if (o.behind_tls_front && !loopback_only)
    throw std::runtime_error("behind its TLS front the panel listens on a loopback address, not " + o.listen +
                             " (the cell file's [hmi] listen)");
  return o.behind_tls_front || !loopback_only;
}

std::vector<User> usersFor(const HmiOptions& o, bool login_required) {
  if (!login_required) return {};
  if (!o.behind_tls_front && !o.allow_plain_http)
    throw std::runtime_error("listening on " + o.listen + " (not loopback) would send passwords and session cookies in "
                             "clear text: on the plant's network the panel is served through its TLS front ([hmi] "
                             "tls_certificate and tls_key in the cell file, `station hmi --front-config`); "
                             "--allow-plain-http serves it so anyway (a closed test bench)");
  if (o.users_file.empty())
    throw std::runtime_error(std::string(o.behind_tls_front ? "behind its TLS front" : "listening on " + o.listen + " (not loopback)") +
                             " the panel needs a login: give a users file with --users or as [hmi] users in the cell "
                             "file (see `station hmi --help`)");
  return loadUsers(o.users_file);
}

// The name of a Host header, without its port; lower case (names are compared so). An IPv6
// literal keeps its brackets; anything after them but a port makes no name ("").
std::string hostName(const std::string& host) {
  std::string name;
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    if (close == std::string::npos || (close + 1 < host.size() && host[close + 1] != ':')) return "";
    name = host.substr(0, close + 1);
  } else {
    name = host.substr(0, std::min(host.rfind(':'), host.size()));
  }
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return std::tolower(ch); });
  return name;
}

bool isAddressLiteral(const std::string& name) {
  in_addr v4{};
  in6_addr v6{};
  const std::string bare = name.size() > 2 && name.front() == '[' ? name.substr(1, name.size() - 2) : name;
  return inet_pton(AF_INET, bare.c_str(), &v4) == 1 || inet_pton(AF_INET6, bare.c_str(), &v6) == 1;
}

}  // namespace

void sendJson(httplib::Response& res, const json& body, int status) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(), "application/json");
}

void sendError(httplib::Response& res, int status, const std::string& error, const std::string& advice) {
  json body = {{"error", error}};
  if (!advice.empty()) body["advice"] = advice;
  sendJson(res, body, status);
}

HmiServer::Impl::Impl(CellSetup setup, HmiOptions o)
    : options(std::move(o)),
      host(parseListen(options.listen).first),
      bind_address(resolveListenAddress(host).front()),
      loopback_only(listensOnLoopbackOnly(resolveListenAddress(host))),
      port(parseListen(options.listen).second),
      auth(loginRequiredFor(options, loopback_only), usersFor(options, loginRequiredFor(options, loopback_only)),
           options.session_idle_timeout),
      jobs(std::move(setup), hub) {
  if (options.actions_log.empty()) options.actions_log = runsDir() / "hmi-actions.jsonl";
  if (jobs.setup().line_start) line_handshake = std::make_unique<LineHandshake>(jobs, hub);
}

void HmiServer::checkOptions(const HmiOptions& options) {
  const std::string host = parseListen(options.listen).first;
  usersFor(options, loginRequiredFor(options, listensOnLoopbackOnly(resolveListenAddress(host))));
}

std::optional<Session> HmiServer::Impl::sessionOf(const httplib::Request& req) {
  return auth.session(cookieValue(req, kSessionCookie));
}

bool HmiServer::Impl::viaTlsFront(const httplib::Request& req) const {
  return options.behind_tls_front && isLoopbackHost(req.remote_addr) && req.has_header("X-Forwarded-For");
}

std::string HmiServer::Impl::clientAddress(const httplib::Request& req) const {
  return viaTlsFront(req) ? req.get_header_value("X-Forwarded-For") : req.remote_addr;
}

bool HmiServer::Impl::servesName(const std::string& name) const {
  if (isLoopbackHost(name)) return true;
  if (!auth.loginRequired()) return false;
  return isAddressLiteral(name) || std::any_of(options.server_names.begin(), options.server_names.end(), [&](std::string n) {
           std::transform(n.begin(), n.end(), n.begin(), [](unsigned char ch) { return std::tolower(ch); });
           return n == name;
         });
}

void HmiServer::Impl::recordAction(const Session& who, const std::string& action, const json& detail,
                                   const httplib::Request& req) {
  const json line = {{"time", registration::utcNow()}, {"user", who.user}, {"role", toString(who.role)},
                     {"action", action}, {"from", clientAddress(req)}, {"detail", detail}};
  std::lock_guard lock(actions_mutex);
  std::error_code ec;
  fs::create_directories(options.actions_log.parent_path().empty() ? fs::path(".") : options.actions_log.parent_path(), ec);
  std::ofstream out(options.actions_log, std::ios::app);
  out << line.dump() << '\n';
}

namespace {

void addPageRoutes(HmiServer::Impl& impl) {
  auto serveAsset = [&impl](const std::string& name, httplib::Response& res) {
    if (!impl.options.web_dir.empty()) {
      std::ifstream in(impl.options.web_dir / name, std::ios::binary);
      if (!in) return sendError(res, 404, "no page file '" + name + "'");
      res.set_content(std::string(std::istreambuf_iterator<char>(in), {}), contentType(name));
      return;
    }
    for (const WebAsset& a : webAssets())
      if (a.name == name) {
        res.set_header("Cache-Control", "no-cache");
        return res.set_content(std::string(a.bytes), contentType(name));
      }
    sendError(res, 404, "no page file '" + name + "'");
  };
  impl.server.Get("/", [serveAsset](const httplib::Request&, httplib::Response& res) { serveAsset("index.html", res); });
  impl.server.Get(R"(/([A-Za-z0-9_-]+\.(html|js|css|svg)))", [serveAsset](const httplib::Request& req, httplib::Response& res) {
    serveAsset(req.matches[1], res);
  });
  // Debian's packaged JavaScript (libjs-three, libjs-chart.js); httplib refuses paths that climb out.
  if (!impl.server.set_mount_point("/lib", impl.options.javascript_dir.string()))
    std::fprintf(stderr, "station hmi: warning: %s is missing: the page's 3D view and plots will not load (install "
                         "libjs-three and libjs-chart.js)\n", impl.options.javascript_dir.c_str());
  impl.server.set_file_extension_and_mimetype_mapping("js", "text/javascript");
}

// Sessions, roles, Origin and CSRF, before any /api/ route runs.
httplib::Server::HandlerResponse gate(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  using R = httplib::Server::HandlerResponse;
  // A body is read into memory only with a declared length, which the payload limit bounds (this
  // library's limit does not apply to chunked bodies, and a body without a length runs until the
  // client closes): anything else is refused before it is read.
  if (req.has_header("Transfer-Encoding") ||
      (isStateChanging(req) && !req.has_header("Content-Length") && req.method != "DELETE")) {
    res.set_header("Connection", "close");
    sendError(res, 411, "refused: a request body needs a Content-Length (chunked bodies are not taken)");
    return R::Handled;
  }
  // A page of another site could reach the panel through a DNS name of its own that resolves here
  // (DNS rebinding) and then be "same origin": only the names the panel is served under are answered.
  if (const std::string host = hostName(req.get_header_value("Host")); !impl.servesName(host)) {
    sendError(res, 421,
              "refused: this panel is not served under the name '" + host + "'" +
                  (impl.auth.loginRequired() ? " (the cell file's [hmi] server_names lists its names)"
                                             : " (without a login it answers on its loopback address only)"));
    return R::Handled;
  }
  if (req.path.rfind("/api/", 0) != 0) return R::Unhandled;
  if (isStateChanging(req)) {
    const std::string origin = req.get_header_value("Origin");
    const std::string scheme = impl.viaTlsFront(req) && req.get_header_value("X-Forwarded-Proto") == "https" ? "https://" : "http://";
    if (!origin.empty() && origin != scheme + req.get_header_value("Host")) {
      sendError(res, 403, "refused: the request comes from another site (" + origin + ")");
      return R::Handled;
    }
  }
  // The session and the login, and the health the plant's monitoring reads, need no session.
  if (req.path == "/api/session" || req.path == "/api/login" || req.path == "/api/health") return R::Unhandled;
  const auto session = impl.sessionOf(req);
  if (!session) {
    sendError(res, 401, "log in first (or the session has expired)");
    return R::Handled;
  }
  if (isStateChanging(req) && req.get_header_value("X-CSRF-Token") != session->csrf) {
    sendError(res, 403, "refused: the request lacks this session's CSRF token (reload the page)");
    return R::Handled;
  }
  if (const auto needed = neededRole(req); needed && !allows(session->role, *needed)) {
    sendError(res, 403, std::string("refused: this needs the ") + toString(*needed) + " role; " + session->user +
                            " is " + toString(session->role));
    impl.recordAction(*session, "refused", {{"path", req.path}}, req);
    return R::Handled;
  }
  return R::Unhandled;
}

void addSessionRoutes(HmiServer::Impl& impl) {
  impl.server.Get("/api/session", [&impl](const httplib::Request& req, httplib::Response& res) {
    const auto s = impl.sessionOf(req);
    json j = {{"login_required", impl.auth.loginRequired()}, {"logged_in", s.has_value()}};
    if (s) j.update({{"user", s->user}, {"role", toString(s->role)}, {"csrf", s->csrf}});
    sendJson(res, j);
  });
  impl.server.Post("/api/login", [&impl](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    if (!body.is_object() || !body.contains("user") || !body["user"].is_string() || !body.contains("password") ||
        !body["password"].is_string())
      return sendError(res, 400, "expected {\"user\": ..., \"password\": ...}");
    const auto s = impl.auth.login(body["user"].get<std::string>(), body["password"].get<std::string>());
    if (!s) {
      Session unknown;
      unknown.user = body["user"].get<std::string>();
      const bool locked = impl.auth.locked(unknown.user);
      impl.recordAction(unknown, locked ? "login refused, account locked" : "login refused",
                        locked ? json{{"locked_minutes", Authenticator::kLockout.count()}} : json::object(), req);
      // The same answer either way: a locked name is not told apart from a wrong password.
      return sendError(res, 401, "wrong user name or password",
                       "after " + std::to_string(Authenticator::kMostFailures) + " wrong passwords a name is locked for " +
                           std::to_string(Authenticator::kLockout.count()) + " minutes");
    }
    impl.recordAction(*s, "login", json::object(), req);
    res.set_header("Set-Cookie", std::string(kSessionCookie) + "=" + s->token + "; Path=/; HttpOnly; SameSite=Strict" +
                                     (impl.options.behind_tls_front ? "; Secure" : ""));
    sendJson(res, {{"user", s->user}, {"role", toString(s->role)}, {"csrf", s->csrf}});
  });
  impl.server.Post("/api/logout", [&impl](const httplib::Request& req, httplib::Response& res) {
    if (const auto s = impl.sessionOf(req)) {
      impl.recordAction(*s, "logout", json::object(), req);
      impl.auth.logout(s->token);
    }
    res.set_header("Set-Cookie", std::string(kSessionCookie) + "=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict" +
                                     (impl.options.behind_tls_front ? "; Secure" : ""));
    sendJson(res, {{"logged_out", true}});
  });
}

void addEventRoute(HmiServer::Impl& impl) {
  impl.server.Get("/api/events", [&impl](const httplib::Request&, httplib::Response& res) {
    auto sub = impl.hub.subscribe();
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    // The first event says where things stand, so a page opened mid-scan knows at once.
    const std::string hello = "event: hello\ndata: " + json{{"job", statusJson(impl.jobs.status())}}.dump() + "\n\n";
    auto sent_hello = std::make_shared<bool>(false);
    res.set_chunked_content_provider(
        "text/event-stream",
        [sub, hello, sent_hello](std::size_t, httplib::DataSink& sink) {
          if (!*sent_hello) {
            *sent_hello = true;
            return sink.write(hello.data(), hello.size());
          }
          if (sub->closed()) return false;
          const auto e = sub->next(std::chrono::milliseconds(10000));
          // A comment line as keep-alive: it also finds a browser that has gone away.
          const std::string text = e ? formatServerSentEvent(*e) : std::string(": keep-alive\n\n");
          return sink.write(text.data(), text.size());
        },
        [&impl, sub](bool) { impl.hub.unsubscribe(sub); });
  });
}

}  // namespace

HmiServer::HmiServer(CellSetup setup, HmiOptions options)
    : impl_(std::make_unique<Impl>(std::move(setup), std::move(options))) {
  Impl& impl = *impl_;
  // Each live page holds one connection for its events; leave room for the page's other requests.
  impl.server.new_task_queue = [] { return new httplib::ThreadPool(24); };
  impl.server.set_payload_max_length(1 << 20);
  impl.server.set_pre_routing_handler([&impl](const httplib::Request& req, httplib::Response& res) {
    return gate(impl, req, res);
  });
  impl.server.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    try {
      std::rethrow_exception(ep);
    } catch (const RunFileError& e) {
      sendError(res, e.status(), e.what());
    } catch (const BadRequest& e) {
      sendError(res, 400, e.what());
    } catch (const std::exception& e) {
      sendError(res, 500, e.what());
    }
  });
  impl.server.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (res.body.empty()) sendError(res, res.status, res.status == 404 ? "no such resource: " + req.path : "request failed");
  });
  addPageRoutes(impl);
  addSessionRoutes(impl);
  addEventRoute(impl);
  addApiRoutes(impl);
  addRunRoutes(impl);
  addAnalysisRoutes(impl);
  addSettingsRoutes(impl);
}

HmiServer::~HmiServer() { stop(); }

int HmiServer::bind() {
  Impl& impl = *impl_;
  if (impl.port == 0) {
    impl.port = impl.server.bind_to_any_port(impl.bind_address);
    if (impl.port < 0) throw std::runtime_error("cannot listen on " + impl.options.listen);
  } else if (!impl.server.bind_to_port(impl.bind_address, impl.port)) {
    throw std::runtime_error("cannot listen on " + impl.options.listen + " (in use, or not an address of this machine)");
  }
  return impl.port;
}

void HmiServer::run() {
  impl_->jobs.connectDevices();
  if (impl_->line_handshake) impl_->line_handshake->start();
  impl_->server.listen_after_bind();
}

void HmiServer::stop() {
  if (impl_->line_handshake) impl_->line_handshake->stop();
  impl_->hub.close();
  impl_->server.stop();
}

std::string HmiServer::url() const {
  const bool v6 = impl_->host.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + impl_->host + "]" : impl_->host) + ":" + std::to_string(impl_->port) + "/";
}

bool HmiServer::loginRequired() const { return impl_->auth.loginRequired(); }

CellHealth HmiServer::health() const { return impl_->health(); }

CellHealth HmiServer::Impl::health() {
  // One check at a time: callers that arrive during one wait for it and share its answer.
  std::lock_guard lock(health_mutex);
  const auto now = std::chrono::steady_clock::now();
  if (!health_cache || now - health_checked > std::chrono::seconds(5)) {
    health_cache = cellHealth(jobs);
    health_checked = std::chrono::steady_clock::now();
  }
  return *health_cache;
}

}  // namespace stampscan::hmi
