// The results: GET /api/runs (the results database), /api/runs/{id} (run.json and report.json),
// /api/runs/{id}/files/{name} (the report's files), /api/runs/{id}/mesh (mesh.ply for three.js).
// Every id and name from the URL goes through run_files.hpp's checks. See API.md.
#include "json_views.hpp"
#include "server_impl.hpp"
#include "stampscan/hmi/run_files.hpp"
#include "stampscan/results/results_store.hpp"
#include "stampscan/run_folder/run_record.hpp"

#include <fstream>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json readJsonFile(const fs::path& file) {
  std::ifstream in(file);
  if (!in) return nullptr;
  json j = json::parse(in, nullptr, false);
  return j.is_discarded() ? json(nullptr) : j;
}

void listRuns(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  results::RunFilter filter;
  filter.part_id = req.get_param_value("part_id");
  filter.program = req.get_param_value("program");
  filter.verdict = req.get_param_value("verdict");
  filter.limit = 200;
  if (req.has_param("last")) {
    try {
      filter.limit = std::clamp<std::size_t>(std::stoul(req.get_param_value("last")), 1, 10000);
    } catch (const std::exception&) {
      return sendError(res, 400, "'last' must be a number");
    }
  }
  const fs::path db = impl.runsDir() / results::kSqliteFileName;
  json runs = json::array();
  std::error_code ec;
  if (fs::exists(db, ec)) {
    results::StoreOptions options;
    options.read_only = true;
    std::vector<results::RunRow> records;
    try {
      records = results::openResultsStore(impl.runsDir().string(), options)->queryRuns(filter);
    } catch (const results::ResultsError& e) {
      return sendError(res, 400, e.what());
    }
    // Newest first, as the history table shows them.
    for (auto it = records.rbegin(); it != records.rend(); ++it) runs.push_back(runRowJson(*it));
  }
  sendJson(res, {{"runs", runs}, {"database", db.string()}});
}

void runDetails(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  const fs::path dir = runFolder(impl.runsDir(), req.matches[1]);
  json files = json::array();
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file() && isSafeName(entry.path().filename().string()))
      names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  for (const auto& n : names) files.push_back(n);
  // run.json through its one reader: what the panel shows is what the report and the history read.
  json run = nullptr, run_problem = nullptr;
  try {
    if (const auto record = run_folder::readRunRecord(dir)) run = run_folder::toJson(*record);
  } catch (const run_folder::RunRecordError& e) {
    run_problem = e.what();
  }
  sendJson(res, {{"run_id", dir.filename().string()},
                 {"run", run},
                 {"run_problem", run_problem},
                 {"report", readJsonFile(dir / "report.json")},
                 {"files", files}});
}

}  // namespace

void addRunRoutes(HmiServer::Impl& impl) {
  auto& s = impl.server;
  s.Get("/api/runs", [&impl](const httplib::Request& req, httplib::Response& res) { listRuns(impl, req, res); });
  // The id and name patterns take any character but '/', so that a bad one reaches the checks and
  // gets their clear answer rather than a bare 404.
  s.Get(R"(/api/runs/([^/]+))", [&impl](const httplib::Request& req, httplib::Response& res) {
    runDetails(impl, req, res);
  });
  s.Get(R"(/api/runs/([^/]+)/files/([^/]+))", [&impl](const httplib::Request& req, httplib::Response& res) {
    const fs::path file = runFile(impl.runsDir(), req.matches[1], req.matches[2]);
    res.set_header("Cache-Control", "no-cache");
    // Streamed in pieces: a whole part's trace is hundreds of megabytes.
    auto in = std::make_shared<std::ifstream>(file, std::ios::binary);
    const std::size_t size = fs::file_size(file);
    res.set_content_provider(size, contentType(file.filename().string()),
                             [in](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                               std::vector<char> buffer(std::min<std::size_t>(length, 1 << 16));
                               in->seekg(static_cast<std::streamoff>(offset));
                               in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
                               const auto got = static_cast<std::size_t>(in->gcount());
                               return got > 0 && sink.write(buffer.data(), got);
                             });
  });
  s.Get(R"(/api/runs/([^/]+)/mesh)", [&impl](const httplib::Request& req, httplib::Response& res) {
    const fs::path dir = runFolder(impl.runsDir(), req.matches[1]);
    res.set_content(meshJson(dir / "mesh.ply"), "application/json");
  });
}

}  // namespace stampscan::hmi
