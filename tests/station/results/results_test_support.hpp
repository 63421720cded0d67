// Helpers of the results tests: temporary folders, run records and run folders, and a PostgreSQL
// server started for the test process.
#pragma once

#include "stampscan/results/results_store.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>

namespace stampscan::results::test {

// A fresh folder under the system's temporary folder, removed with its content at the end.
class TempDir {
 public:
  TempDir() {
    std::random_device random;
    path_ = std::filesystem::temp_directory_path() / ("stampscan-results-" + std::to_string(random()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// A good run of `program` started on 2026-11-<day> at <hour>:00 UTC.
inline RunRow makeRun(const std::string& part_id, const std::string& program, int day, int hour,
                         const std::string& verdict = "good", double min_margin = 20.0) {
  char started[32], id[64];
  std::snprintf(started, sizeof started, "2026-11-%02dT%02d:00:00Z", day, hour);
  std::snprintf(id, sizeof id, "202611%02d-%02d0000-%s", day, hour, part_id.c_str());
  RunRow r;
  r.run_id = id;
  r.part_id = part_id;
  r.program = program;
  r.plan = "pan";
  r.cell = "virtual";
  r.started_utc = started;
  r.material = "DC04";
  r.verdict = verdict;
  r.max_thinning_percent = 12.5;
  r.min_margin_percent = min_margin;
  r.marginal_band_percent = 10.0;
  r.elements = 1200;
  r.run_dir = "runs/" + r.run_id;
  return r;
}

inline void writeJson(const std::filesystem::path& file, const nlohmann::json& j) {
  std::ofstream(file) << j.dump(2) << "\n";
}

// A PostgreSQL server of Debian's `postgresql` package in a temporary folder, listening on a unix
// socket only, started on first use and stopped at the end of the process. As root the server runs
// as the postgres user (it refuses to run as root).
class PostgresServer {
 public:
  // The server, or nullptr with `reason` saying why it could not start.
  static PostgresServer* get(std::string& reason);
  // A new, empty database on the server, as a postgresql:// URL.
  std::string freshDatabase();
  // The URL of an existing database.
  std::string url(const std::string& database) const;
  ~PostgresServer();

 private:
  PostgresServer() = default;
  std::filesystem::path dir_;
  std::string bin_, as_user_;
  int databases_ = 0;
  bool running_ = false;
};

}  // namespace stampscan::results::test

namespace stampscan::results::test {
// "<prefix><n>" (appended: GCC 12 warns falsely, -Wrestrict, on "literal" + std::string).
inline std::string numbered(const char* prefix, std::size_t n) { return std::string(prefix).append(std::to_string(n)); }
}  // namespace stampscan::results::test
