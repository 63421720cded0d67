// The panel on the plant's network, through its TLS front: Debian's nginx with the site file that
// `station hmi --front-config` writes from the cell file's [hmi] section, before `station hmi`
// listening on loopback. Tested through the front as a browser on the plant's network reaches it:
// HTTPS with the cell's certificate, HTTP redirected, HSTS, other names refused, Secure cookies,
// the Origin checked against https, bodies limited in every transfer encoding, the live events
// passed through, login floods slowed.
#include "hmi_test_support.hpp"

#include <sys/prctl.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <future>

namespace stampscan::hmi::test {
namespace {

// `count` different ports nothing listens on now (the kernel's picks, all held until each is
// known, then let go for the servers to take).
std::vector<int> freePorts(int count) {
  std::vector<int> fds, ports;
  for (int i = 0; i < count; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof a;
    if (bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
        getsockname(fd, reinterpret_cast<sockaddr*>(&a), &size) == 0)
      ports.push_back(ntohs(a.sin_port));
    fds.push_back(fd);
  }
  for (int fd : fds) close(fd);
  return ports;
}

bool accepts(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(fd);
  return ok;
}

// A TCP connection to 127.0.0.1:port; -1 when refused.
int connectTcp(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

// A process's resident memory in MB (its VmRSS), 0 when it is gone.
double residentMb(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

// Moves this process (and what it starts) into a network namespace of its own with lo up, so that
// the probes' hundreds of connections meet no other test (root only; ctest runs each test case in a
// process of its own).
bool enterPrivateNetwork() {
  if (::geteuid() != 0 || ::unshare(CLONE_NEWNET) != 0) return false;
  return std::system("ip link set lo up >/dev/null 2>&1") == 0;
}

std::string found(const char* program) {
  for (const char* dir : {"/usr/sbin", "/usr/bin", "/sbin", "/bin"})
    if (fs::exists(fs::path(dir) / program)) return (fs::path(dir) / program).string();
  return "";
}

class HmiFrontTest : public HmiTest {
 protected:
  void SetUp() override {
    HmiTest::SetUp();
    nginx_ = found("nginx");
    openssl_ = found("openssl");
    if (nginx_.empty() || openssl_.empty())
      GTEST_SKIP() << "the TLS front's test needs Debian's nginx and openssl (scripts/setup.sh installs them)";
    // A refused body ends the connection while the client still writes: an error, not a signal.
    previous_sigpipe_ = std::signal(SIGPIPE, SIG_IGN);
  }
  void TearDown() override {
    if (nginx_pid_ > 0) {
      kill(nginx_pid_, SIGTERM);
      int status = 0;
      waitpid(nginx_pid_, &status, 0);
    }
    if (previous_sigpipe_ != SIG_ERR) std::signal(SIGPIPE, previous_sigpipe_);
    HmiTest::TearDown();
  }

  // The cell's certificate (for its name and 127.0.0.1), its users, and a cell file whose devices
  // are nowhere (the panel serves without them) and whose [hmi] puts the panel behind the front.
  void writeCell() {
    fs::create_directories(root_ / "tls");
    const std::string make_certificate =
        openssl_ + " req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=cell.test"
        " -addext subjectAltName=DNS:cell.test,IP:127.0.0.1 -keyout " + (root_ / "tls/cell.key").string() +
        " -out " + (root_ / "tls/cell.crt").string() + " 2>&1";
    const std::string made = outputOf(make_certificate);
    ASSERT_TRUE(fs::exists(root_ / "tls/cell.crt")) << made;
    std::ofstream(root_ / "users.toml") << "[[user]]\nname = \"olga\"\nrole = \"operator\"\npassword_hash = \""
                                         << hashOf("op-secret") << "\"\n";
    const std::vector<int> ports = freePorts(3);
    ASSERT_EQ(ports.size(), 3u);
    panel_port_ = ports[0];
    https_port_ = ports[1];
    http_port_ = ports[2];
    std::ofstream(root_ / "cell.toml")
        << "name = \"front test cell\"\n"
        << "[cmm]\nport = 9\n[plc]\nport = 9\n[cameras]\nleft_address = \"127.0.0.3\"\nright_address = \"127.0.0.4\"\n"
        << "[hmi]\nlisten = \"127.0.0.1:" << panel_port_ << "\"\nusers = \"users.toml\"\n"
        << "server_names = [\"cell.test\"]\ntls_certificate = \"tls/cell.crt\"\ntls_key = \"tls/cell.key\"\n"
        << "https_port = " << https_port_ << "\nhttp_port = " << http_port_ << "\n";
  }

  // nginx on its own prefix, in the foreground, with the site file the station writes.
  void startFront() {
    const fs::path dir = root_ / "nginx";
    fs::create_directories(dir);
    const std::string site = outputOf(std::string(STATION_EXE) + " hmi --cell " + (root_ / "cell.toml").string() +
                                      " --front-config");
    ASSERT_NE(site.find("ssl_certificate"), std::string::npos) << site;
    std::ofstream(dir / "site.conf") << site;
    std::ofstream conf(dir / "nginx.conf");
    conf << "worker_processes 1;\npid " << (dir / "nginx.pid").string() << ";\nerror_log "
         << (dir / "error.log").string() << " warn;\nevents { worker_connections 1024; }\nhttp {\n  access_log off;\n";
    for (const char* temp : {"client_body", "proxy", "fastcgi", "uwsgi", "scgi"})
      conf << "  " << temp << "_temp_path " << (dir / temp).string() << ";\n";
    conf << "  include " << (dir / "site.conf").string() << ";\n}\n";
    conf.close();
    std::fflush(nullptr);
    nginx_pid_ = fork();
    if (nginx_pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGTERM);  // the front goes with the test, whatever ends it
      const std::string log = (dir / "stderr.log").string();
      freopen(log.c_str(), "w", stderr);
      execl(nginx_.c_str(), "nginx", "-e", (dir / "error.log").c_str(), "-p", dir.c_str(), "-c",
            (dir / "nginx.conf").c_str(), "-g", "daemon off;", static_cast<char*>(nullptr));
      _exit(127);
    }
    for (int i = 0; i < 100 && !accepts(https_port_); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_TRUE(accepts(https_port_)) << readText(dir / "stderr.log") << readText(dir / "error.log");
  }

  // A client of the front that trusts the cell's certificate and asks for the cell's name.
  std::unique_ptr<httplib::SSLClient> frontClient() {
    auto c = std::make_unique<httplib::SSLClient>("127.0.0.1", https_port_);
    c->set_ca_cert_path((root_ / "tls/cell.crt").c_str());
    c->enable_server_certificate_verification(true);
    c->set_read_timeout(10, 0);
    c->set_default_headers({{"Host", host()}});
    return c;
  }
  std::string host() const { return "cell.test:" + std::to_string(https_port_); }

  std::string nginx_, openssl_;
  pid_t nginx_pid_ = -1;
  int panel_port_ = 0, https_port_ = 0, http_port_ = 0;
  void (*previous_sigpipe_)(int) = SIG_ERR;
};

TEST_F(HmiFrontTest, ThePanelIsServedOverTlsWithItsLimitsOnlyUnderItsNames) {
  ASSERT_NO_FATAL_FAILURE(writeCell());
  ASSERT_NO_FATAL_FAILURE(startPanel({"--cell", (root_ / "cell.toml").string()}));
  EXPECT_EQ(station_->port(), panel_port_);
  EXPECT_NE(station_->log().find("served through its TLS front"), std::string::npos) << station_->log();
  ASSERT_NO_FATAL_FAILURE(startFront());
  auto front = frontClient();

  // HTTPS with the cell's certificate, HSTS on every answer.
  auto page = front->Get("/");
  ASSERT_TRUE(page) << httplib::to_string(page.error());
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->get_header_value("Strict-Transport-Security").find("max-age="), std::string::npos);
  // Plain HTTP is redirected to HTTPS on the front's port.
  httplib::Client plain("127.0.0.1", http_port_);
  auto redirected = plain.Get("/api/session", {{"Host", "cell.test:" + std::to_string(http_port_)}});
  ASSERT_TRUE(redirected);
  EXPECT_EQ(redirected->status, 301);
  EXPECT_EQ(redirected->get_header_value("Location"), "https://" + host() + "/api/session");
  // Another name gets nothing: refused by the front, and by the panel were it reached directly.
  auto other = front->Get("/api/session", {{"Host", "evil.example"}});
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 421);
  httplib::Client direct("127.0.0.1", panel_port_);
  auto direct_other = direct.Get("/api/session", {{"Host", "evil.example"}});
  ASSERT_TRUE(direct_other);
  EXPECT_EQ(direct_other->status, 421);
  // Behind the front every user logs in, on loopback too.
  EXPECT_TRUE(body(front->Get("/api/session"))["login_required"].get<bool>());
  auto direct_cell = direct.Get("/api/cell");
  ASSERT_TRUE(direct_cell);
  EXPECT_EQ(direct_cell->status, 401);
  // Without a session the health says only how the cell is and why, none of its details.
  auto health = front->Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 503) << health->body;  // its devices are nowhere
  EXPECT_FALSE(body(health)["findings"].empty());
  EXPECT_FALSE(body(health).contains("devices")) << health->body;

  // The login's cookie is Secure; a small chunked body reaches the panel (the front gives it a length).
  auto login = front->Post("/api/login", {}, [](std::size_t, httplib::DataSink& sink) {
    const std::string credentials = R"({"user": "olga", "password": "op-secret"})";
    sink.write(credentials.data(), credentials.size());
    sink.done();
    return true;
  }, "application/json");
  ASSERT_TRUE(login);
  ASSERT_EQ(login->status, 200) << login->body;
  const std::string cookie = login->get_header_value("Set-Cookie");
  EXPECT_NE(cookie.find("; Secure"), std::string::npos) << cookie;
  EXPECT_NE(cookie.find("HttpOnly"), std::string::npos) << cookie;
  const std::string session = cookie.substr(0, cookie.find(';'));
  const std::string csrf = body(login)["csrf"].get<std::string>();
  const httplib::Headers as_olga = {{"Host", host()}, {"Cookie", session}, {"X-CSRF-Token", csrf}};
  auto cell = front->Get("/api/cell", as_olga);
  ASSERT_TRUE(cell);
  EXPECT_EQ(cell->status, 200);
  auto detailed = front->Get("/api/health", as_olga);
  ASSERT_TRUE(detailed);
  EXPECT_TRUE(body(detailed).contains("devices")) << detailed->body;
  // The Origin of a page served by the front is https: the plain one is another site's.
  httplib::Headers from_page = as_olga, from_plain = as_olga;
  from_page.emplace("Origin", "https://" + host());
  from_plain.emplace("Origin", "http://" + host());
  // (A forged X-Forwarded-For is replaced by the front with the client's address.)
  from_page.emplace("X-Forwarded-For", "203.0.113.9");
  auto aborted = front->Post("/api/scan/abort", from_page, "{}", "application/json");
  ASSERT_TRUE(aborted);
  EXPECT_EQ(aborted->status, 409);  // nothing runs, but not refused
  auto foreign = front->Post("/api/scan/abort", from_plain, "{}", "application/json");
  ASSERT_TRUE(foreign);
  EXPECT_EQ(foreign->status, 403);

  // The live events come through as they are sent.
  std::string events;
  auto stream = front->Get("/api/events", as_olga, [&](const char* data, std::size_t size) {
    events.append(data, size);
    return events.find("\n\n") == std::string::npos;  // the first event whole: enough
  });
  EXPECT_NE(events.find("event: hello"), std::string::npos) << events;

  // A chunked body over the limit is refused by the front, which never holds more than the limit of it
  // (the panel alone refuses chunked bodies).
  std::size_t sent = 0;
  auto flood = front->Post("/api/login", as_olga, [&](std::size_t, httplib::DataSink& sink) {
    const std::string block(64 * 1024, 'a');
    if (sent >= (8u << 20)) {
      sink.done();
      return true;
    }
    sent += block.size();
    return sink.write(block.data(), block.size());
  }, "application/json");
  // (nginx reads the rest away, into nothing, and answers when the sender is done.)
  ASSERT_TRUE(flood) << httplib::to_string(flood.error());
  EXPECT_EQ(flood->status, 413);

  // Repeated logins from one client are slowed down (429) before the panel spends a hash on each.
  int slowed = 0;
  for (int i = 0; i < 12; ++i) {
    auto wrong = front->Post("/api/login", R"({"user": "x", "password": "y"})", "application/json");
    ASSERT_TRUE(wrong);
    slowed += wrong->status == 429;
  }
  EXPECT_GE(slowed, 4);
  // And the panel answers its page all along.
  auto page_again = front->Get("/");
  ASSERT_TRUE(page_again);
  EXPECT_EQ(page_again->status, 200);
  // The actions are recorded with the client's address as the front saw it, not as a client claimed.
  const std::string actions = readText(root_ / "runs" / "hmi-actions.jsonl");
  EXPECT_NE(actions.find(R"("action":"abort")"), std::string::npos) << actions;
  EXPECT_NE(actions.find(R"("from":"127.0.0.1")"), std::string::npos) << actions;
  EXPECT_EQ(actions.find("203.0.113.9"), std::string::npos) << actions;
}

// The panel probed through its front as an attacker on the plant's network would: names that are
// not the panel's, slow and idle connections by the hundred, chunked floods and login floods. All
// the while a normal client is answered within a second, and the panel's memory stays bounded.
TEST_F(HmiFrontTest, UnderHostileClientsTheFrontKeepsAnsweringAndThePanelStaysSmall) {
  const bool private_network = enterPrivateNetwork();
  std::printf("[ probe    ] %s\n", private_network ? "in a private network namespace"
                                                   : "on this machine's loopback (no private network namespace)");
  ASSERT_NO_FATAL_FAILURE(writeCell());
  ASSERT_NO_FATAL_FAILURE(startPanel({"--cell", (root_ / "cell.toml").string()}));
  ASSERT_NO_FATAL_FAILURE(startFront());
  auto normal = frontClient();
  ASSERT_TRUE(normal->Get("/api/session"));
  const double panel_mb_before = residentMb(station_->pid());
  double slowest = 0, panel_mb_peak = panel_mb_before;
  // A normal client's request through the front, timed; the panel's memory sampled with it.
  const auto normalRequest = [&](const std::string& during) {
    const auto start = std::chrono::steady_clock::now();
    auto r = normal->Get("/api/session");
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(r && r->status == 200) << "during " << during;
    slowest = std::max(slowest, seconds);
    panel_mb_peak = std::max(panel_mb_peak, residentMb(station_->pid()));
    EXPECT_LT(seconds, 1.0) << "during " << during;
  };

  // Names that are not the panel's: refused by the front, and by the panel.
  for (const std::string name : {"evil.example", "127.0.0.1.evil.example", "cell.test.evil.example", "localhost"}) {
    auto r = frontClient()->Get("/api/session", {{"Host", name}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 421) << name;
  }
  normalRequest("names");

  // 200 idle connections (no TLS hello) and 60 slow ones (a header line a second on plain HTTP).
  std::vector<int> held;
  for (int i = 0; i < 200; ++i) held.push_back(connectTcp(https_port_));
  std::vector<int> slow;
  for (int i = 0; i < 60; ++i) {
    const int fd = connectTcp(http_port_);
    const std::string head = "GET / HTTP/1.1\r\nHost: cell.test\r\n";
    if (fd >= 0) (void)!::write(fd, head.data(), head.size());
    slow.push_back(fd);
  }
  EXPECT_EQ(std::count(held.begin(), held.end(), -1) + std::count(slow.begin(), slow.end(), -1), 0);
  for (int second = 0; second < 4; ++second) {
    for (int fd : slow) (void)!::send(fd, "X-a: b\r\n", 8, MSG_NOSIGNAL);
    normalRequest("260 idle and slow connections");
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }

  // Chunked floods: three senders of 32 MiB each at once.
  std::vector<std::future<int>> floods;
  for (int i = 0; i < 3; ++i)
    floods.push_back(std::async(std::launch::async, [this] {
      auto c = frontClient();
      std::size_t sent = 0;
      auto r = c->Post("/api/login", {{"Host", host()}}, [&](std::size_t, httplib::DataSink& sink) {
        static const std::string block(64 * 1024, 'a');
        if (sent >= (32u << 20)) {
          sink.done();
          return true;
        }
        sent += block.size();
        return sink.write(block.data(), block.size());
      }, "application/json");
      return r ? r->status : 0;
    }));
  for (int i = 0; i < 4; ++i) {
    normalRequest("chunked floods");
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  for (auto& f : floods) {
    const int status = f.get();
    EXPECT_TRUE(status == 413 || status == 0) << status;  // refused, or cut off while sending
  }

  // 48 parallel wrong logins: slowed by the front (429), at most two hashes at once in the panel.
  std::vector<std::future<int>> logins;
  for (int i = 0; i < 48; ++i)
    logins.push_back(std::async(std::launch::async, [this, i] {
      auto r = frontClient()->Post("/api/login", json{{"user", "olga"}, {"password", "guess" + std::to_string(i)}}.dump(),
                                   "application/json");
      return r ? r->status : 0;
    }));
  normalRequest("a login flood");
  int slowed = 0, refused = 0;
  for (auto& f : logins) {
    const int status = f.get();
    slowed += status == 429;
    refused += status == 401;
  }
  EXPECT_EQ(slowed + refused, 48);
  EXPECT_GE(slowed, 40);
  normalRequest("after the login flood");
  for (int fd : held)
    if (fd >= 0) close(fd);
  for (int fd : slow)
    if (fd >= 0) close(fd);

  std::printf("[ probe    ] the normal client's slowest answer %.3f s; the panel's memory %.0f MB before, %.0f MB at "
              "most\n", slowest, panel_mb_before, panel_mb_peak);
  EXPECT_LT(panel_mb_peak, panel_mb_before + 200) << "the panel grew under the probes";
  EXPECT_GT(residentMb(station_->pid()), 0) << "the panel is gone";
}

TEST_F(HmiFrontTest, TheFrontConfigurationNeedsTheCellsCertificateAndNames) {
  ASSERT_NO_FATAL_FAILURE(writeCell());
  // Without the [hmi] TLS keys there is no front to configure.
  std::ofstream(root_ / "plain.toml") << "[hmi]\nlisten = \"127.0.0.1:8080\"\n";
  const std::string plain =
      outputOf(std::string(STATION_EXE) + " hmi --cell " + (root_ / "plain.toml").string() + " --front-config 2>&1; echo exit=$?");
  EXPECT_NE(plain.find("no tls_certificate"), std::string::npos) << plain;
  EXPECT_NE(plain.find("exit=1"), std::string::npos) << plain;
  // A key without its certificate, and a name that is no name, are refused naming the key.
  std::ofstream(root_ / "half.toml") << "[hmi]\nserver_names = [\"cell.test\"]\ntls_key = \"tls/cell.key\"\n";
  const std::string half = outputOf(std::string(STATION_EXE) + " hmi --cell " + (root_ / "half.toml").string() + " --front-config 2>&1");
  EXPECT_NE(half.find("[hmi] tls_certificate is missing"), std::string::npos) << half;
  std::ofstream(root_ / "bad.toml") << "[hmi]\nserver_names = [\"cell.test; return 200\"]\n";
  const std::string bad = outputOf(std::string(STATION_EXE) + " hmi --cell " + (root_ / "bad.toml").string() + " --front-config 2>&1");
  EXPECT_NE(bad.find("[hmi] server_names"), std::string::npos) << bad;
  // Behind the front the panel listens on loopback only.
  std::string cell = readText(root_ / "cell.toml");
  cell.replace(cell.find("listen = \"127.0.0.1:"), 20, "listen = \"0.0.0.0:");
  std::ofstream(root_ / "open.toml") << cell;
  const std::string open = outputOf("timeout 20 " STATION_EXE " hmi --cell " + (root_ / "open.toml").string() + " 2>&1");
  EXPECT_NE(open.find("behind its TLS front the panel listens on a loopback address"), std::string::npos) << open;
}

}  // namespace
}  // namespace stampscan::hmi::test
