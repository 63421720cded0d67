#include "results_test_support.hpp"

#include <pqxx/pqxx>

#include <pwd.h>
#include <unistd.h>

#include <cstdlib>
#include <memory>
#include <sstream>

namespace stampscan::results::test {

namespace {
namespace fs = std::filesystem;

constexpr int kPort = 55432;  // names the socket file only: no TCP port is opened

// The newest installed server's bin folder (Debian: /usr/lib/postgresql/<major>/bin).
std::string serverBinFolder() {
  std::error_code error;
  std::string best;
  for (const auto& entry : fs::directory_iterator("/usr/lib/postgresql", error)) {
    const fs::path bin = entry.path() / "bin";
    if (fs::exists(bin / "initdb") && fs::exists(bin / "pg_ctl") && bin.string() > best) best = bin.string();
  }
  return best;
}

std::string tail(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  const std::string all = text.str();
  return all.size() > 600 ? all.substr(all.size() - 600) : all;
}
}  // namespace

PostgresServer* PostgresServer::get(std::string& reason) {
  static std::unique_ptr<PostgresServer> server;
  static std::string failure;
  static bool tried = false;
  if (!tried) {
    tried = true;
    auto s = std::unique_ptr<PostgresServer>(new PostgresServer());
    s->bin_ = serverBinFolder();
    if (s->bin_.empty()) {
      failure = "no PostgreSQL server installed (Debian package postgresql: initdb and pg_ctl not found)";
    } else {
      std::string pattern = (fs::temp_directory_path() / "stampscan-pg-XXXXXX").string();
      if (!mkdtemp(pattern.data())) throw std::runtime_error("cannot create a folder for the PostgreSQL server");
      s->dir_ = pattern;  // removed with the server object, started or not
      fs::permissions(s->dir_, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                   fs::perms::others_read | fs::perms::others_exec);
      if (geteuid() == 0) {
        // The server refuses to run as root: it runs as the postgres user, which owns its folder.
        const passwd* pg = getpwnam("postgres");
        if (!pg || chown(s->dir_.c_str(), pg->pw_uid, pg->pw_gid) != 0) {
          failure = "running as root and there is no postgres user to run the server as";
        } else {
          s->as_user_ = "runuser -u postgres -- ";
        }
      }
      if (failure.empty()) {
        // Our own output files are written by this process; the server's log by the server's user.
        const fs::path init_log = s->dir_ / "initdb.out", ctl_log = s->dir_ / "pg_ctl.out";
        const fs::path server_log = s->dir_ / "server.log";
        const std::string init = s->as_user_ + s->bin_ + "/initdb -D " + (s->dir_ / "data").string() +
                                 " -A trust -U postgres --no-sync --locale=C -E UTF8 > " + init_log.string() + " 2>&1";
        const std::string start = s->as_user_ + s->bin_ + "/pg_ctl -D " + (s->dir_ / "data").string() + " -l " +
                                  server_log.string() + " -w -t 30 -o \"-k " + s->dir_.string() +
                                  " -c listen_addresses='' -p " + std::to_string(kPort) + " -c fsync=off\" start > " +
                                  ctl_log.string() + " 2>&1";
        if (std::system(init.c_str()) != 0) {
          failure = "initdb failed: " + tail(init_log);
        } else if (std::system(start.c_str()) != 0) {
          failure = "pg_ctl start failed: " + tail(ctl_log) + tail(server_log);
          s->running_ = true;  // stop whatever may have started
        } else {
          s->running_ = true;
          server = std::move(s);
        }
      }
    }
  }
  reason = failure;
  return server.get();
}

PostgresServer::~PostgresServer() {
  if (running_) {
    const std::string stop = as_user_ + bin_ + "/pg_ctl -D " + (dir_ / "data").string() + " -m immediate -w stop > /dev/null 2>&1";
    [[maybe_unused]] const int ignored = std::system(stop.c_str());
  }
  std::error_code ignored;
  if (!dir_.empty()) fs::remove_all(dir_, ignored);
}

std::string PostgresServer::url(const std::string& database) const {
  return "postgresql://postgres@/" + database + "?host=" + dir_.string() + "&port=" + std::to_string(kPort);
}

std::string PostgresServer::freshDatabase() {
  const std::string name = "results_test_" + std::to_string(++databases_);
  pqxx::connection admin(url("postgres"));
  pqxx::nontransaction n(admin);
  n.exec("CREATE DATABASE " + name);
  return url(name);
}

}  // namespace stampscan::results::test
