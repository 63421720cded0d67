// The panel's API against the embedded virtual cell: the page and Debian's scripts are served, the
// cell view reads the devices and the PLC, a scan streams its events, a second start is refused
// with 409 and the reason, an abort ends the scan with the reason, and bad input gets a clear JSON
// error with a 4xx status (path traversal included).
#include "hmi_test_support.hpp"

#include <atomic>
#include <cmath>
#include <cstring>
#include <mutex>

namespace stampscan::hmi::test {
namespace {

// Collects the panel's Server-Sent Events on a thread of its own.
class EventReader {
 public:
  explicit EventReader(int port) : client_("127.0.0.1", port) {
    client_.set_read_timeout(60, 0);
    thread_ = std::thread([this] {
      client_.Get("/api/events", [this](const char* data, std::size_t length) {
        std::lock_guard lock(mutex_);
        text_.append(data, length);
        return !stop_;
      });
    });
  }
  ~EventReader() {
    stop_ = true;
    client_.stop();
    thread_.join();
  }
  std::string text() {
    std::lock_guard lock(mutex_);
    return text_;
  }
  // The data of every event of that name so far.
  std::vector<json> events(const std::string& name) {
    std::vector<json> out;
    const std::string t = text();
    const std::string marker = "event: " + name + "\ndata: ";
    for (auto pos = t.find(marker); pos != std::string::npos; pos = t.find(marker, pos + 1)) {
      const auto start = pos + marker.size();
      const auto end = t.find('\n', start);
      if (end != std::string::npos) out.push_back(json::parse(t.substr(start, end - start), nullptr, false));
    }
    return out;
  }
  bool waitFor(const std::string& name, std::chrono::seconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      if (!events(name).empty()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

 private:
  httplib::Client client_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::string text_;
  std::thread thread_;
};

TEST_F(HmiTest, ServesThePageDebiansScriptsAndTheCell) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  auto page = client_->Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("/lib/three/three.min.js"), std::string::npos);
  auto three = client_->Get("/lib/three/three.min.js");
  ASSERT_TRUE(three);
  EXPECT_EQ(three->status, 200) << "libjs-three is not installed";
  EXPECT_EQ(client_->Get("/lib/chart.js/chart.min.js")->status, 200) << "libjs-chart.js is not installed";
  EXPECT_EQ(client_->Get("/app.js")->status, 200);

  const json session = body(client_->Get("/api/session"));
  EXPECT_FALSE(session["login_required"].get<bool>()) << "loopback needs no login";
  EXPECT_FALSE(session["csrf"].get<std::string>().empty());

  // The devices connect in the background: wait for the PLC.
  json cell;
  for (int i = 0; i < 100; ++i) {
    cell = body(client_->Get("/api/cell"));
    if (cell["plc"]["connected"].get<bool>()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(cell["devices"].size(), 5u) << cell.dump(2);
  for (const auto& d : cell["devices"]) EXPECT_FALSE(d["name"].get<std::string>().empty());
  ASSERT_TRUE(cell["plc"]["connected"].get<bool>()) << cell.dump(2);
  EXPECT_TRUE(cell["plc"]["interlocks"]["door_closed"].get<bool>());
  EXPECT_TRUE(cell["plc"]["interlocks"]["e_stop_ok"].get<bool>());
  EXPECT_TRUE(cell["plc"]["stack_light"].is_object());
  EXPECT_EQ(cell["calibration"]["verdict"], "not verified");
  // Each sensor's calibration in use, as a scan would judge it: none stored yet.
  ASSERT_EQ(cell["calibration"]["sensors"].size(), 2u);
  EXPECT_EQ(cell["calibration"]["sensors"][0]["sensor"], "digitizer");
  EXPECT_FALSE(cell["calibration"]["sensors"][0]["in_use"].get<bool>());
  EXPECT_FALSE(cell["calibration"]["sensors"][1]["usable"].get<bool>());
  // The health the plant's monitoring reads: the virtual cell can scan once every device has
  // connected (the cameras come after the PLC); nothing to mend but, on a full machine, the disk.
  json h;
  int status = 0;
  for (int i = 0; i < 100; ++i) {
    auto health = client_->Get("/api/health");
    ASSERT_TRUE(health);
    status = health->status;
    h = body(health);
    if (status == 200) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(status, 200) << h.dump(2);
  for (const auto& f : h["findings"]) EXPECT_EQ(f["what"], "disk") << h.dump(2);
  EXPECT_EQ(h["devices"].size(), 5u);
  EXPECT_GT(h["disk"]["available_bytes"].get<double>(), 0);
  EXPECT_TRUE(h["database"]["reachable"].get<bool>());
  EXPECT_FALSE(cell["job"]["busy"].get<bool>());
}

// The panel stopped as its service is (SIGTERM) in the middle of a scan: the scan is aborted with
// the reason, its trace ended and readable, and the panel exits cleanly within seconds.
TEST_F(HmiTest, AStopSignalDuringAScanAbortsItAndEndsItsTrace) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  EventReader events(station_->port());
  ASSERT_TRUE(events.waitFor("hello", std::chrono::seconds(10)));
  auto started = post("/api/scan/start", R"({"part_id": "sig-1"})", csrf());
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;
  ASSERT_TRUE(events.waitFor("progress", std::chrono::seconds(60))) << events.text();
  const auto start = std::chrono::steady_clock::now();
  station_->stop();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(station_->exit_code, 0) << station_->log();
  EXPECT_LT(seconds, 10.0);
  EXPECT_NE(station_->log().find("station hmi: stopped"), std::string::npos) << station_->log();
  fs::path run;
  for (const auto& entry : fs::directory_iterator(root_ / "runs"))
    if (entry.path().filename().string().find("sig-1") != std::string::npos) run = entry.path();
  ASSERT_FALSE(run.empty());
  const json record = json::parse(readText(run / "run.json"));
  EXPECT_FALSE(record["completed"].get<bool>()) << record.dump(2);
  EXPECT_EQ(record["abort_reason"], "the panel is shutting down") << record.dump(2);
  // The trace is whole: its summary at the end, as `station trace info` checks.
  const std::string info = outputOf(std::string(STATION_EXE) + " trace info " + (run / "trace.mcap").string() +
                                    " 2>&1; echo exit=$?");
  EXPECT_NE(info.find("/plc/state"), std::string::npos) << info;
  EXPECT_EQ(info.find("TRUNCATED"), std::string::npos) << info;
  EXPECT_NE(info.find("exit=0"), std::string::npos) << info;
}

TEST_F(HmiTest, AScanStreamsEventsRefusesASecondStartAndAborts) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  EventReader events(station_->port());
  ASSERT_TRUE(events.waitFor("hello", std::chrono::seconds(10)));
  const std::string token = csrf();
  auto started = post("/api/scan/start", R"({"part_id": "p-17", "program": "OP20"})", token);
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;

  // The scan reports as it goes: its run folder, the checks, then progress with counts and devices.
  ASSERT_TRUE(events.waitFor("progress", std::chrono::seconds(60))) << events.text();
  const json progress = events.events("progress").front();
  EXPECT_GT(progress["steps"].get<int>(), 0);
  EXPECT_TRUE(progress.contains("remaining_s"));
  EXPECT_TRUE(progress.contains("profiles"));
  EXPECT_EQ(progress["devices"].size(), 5u);
  EXPECT_TRUE(progress["t_ms"].is_number());
  ASSERT_FALSE(events.events("run").empty());
  const std::string run_id = events.events("run").front()["run_id"];
  EXPECT_NE(run_id.find("p-17"), std::string::npos);
  EXPECT_FALSE(events.events("check").empty());

  // One scan at a time: the second start is refused, with the reason.
  auto second = post("/api/scan/start", R"({"part_id": "p-18"})", token);
  ASSERT_TRUE(second);
  EXPECT_EQ(second->status, 409);
  EXPECT_NE(body(second)["error"].get<std::string>().find("a scan is running"), std::string::npos) << second->body;
  EXPECT_TRUE(body(client_->Get("/api/status"))["busy"].get<bool>());

  // The live cloud grows as the part's sweeps are measured: the elements arrive as `cloud` events,
  // and a page opened now gets them all at once.
  ASSERT_TRUE(events.waitFor("cloud", std::chrono::seconds(120))) << events.text();
  const json cloud = events.events("cloud").front();
  ASSERT_GT(cloud["thickness"].size(), 0u) << cloud.dump();
  EXPECT_EQ(cloud["xyz"].size(), 3 * cloud["thickness"].size());
  EXPECT_GE(cloud["measured"].get<std::size_t>(), cloud["shown"].get<std::size_t>());
  EXPECT_EQ(cloud["run_id"], run_id);
  const json so_far = body(client_->Get("/api/scan/cloud"));
  EXPECT_EQ(so_far["run_id"], run_id);
  EXPECT_GE(so_far["shown"].get<std::size_t>(), cloud["thickness"].size());
  EXPECT_EQ(so_far["xyz"].size(), 3 * so_far["shown"].get<std::size_t>());

  auto aborted = post("/api/scan/abort", "{}", token);
  ASSERT_TRUE(aborted);
  EXPECT_EQ(aborted->status, 202);
  ASSERT_TRUE(events.waitFor("finished", std::chrono::seconds(60))) << events.text();
  const json finished = events.events("finished").front();
  EXPECT_FALSE(finished["ok"].get<bool>());
  EXPECT_NE(finished["error"].get<std::string>().find("operator abort"), std::string::npos) << finished.dump();
  EXPECT_FALSE(finished["advice"].get<std::string>().empty());
  EXPECT_FALSE(body(client_->Get("/api/status"))["busy"].get<bool>());

  // The aborted run is in the results database, with its reason, and its folder is served.
  const json runs = body(client_->Get("/api/runs"));
  ASSERT_EQ(runs["runs"].size(), 1u) << runs.dump(2);
  EXPECT_EQ(runs["runs"][0]["run_id"], run_id);
  EXPECT_EQ(runs["runs"][0]["status"], "aborted");
  const json details = body(client_->Get(("/api/runs/" + run_id).c_str()));
  EXPECT_EQ(details["run"]["part_id"], "p-17") << details.dump(2);
  auto trace = client_->Get(("/api/runs/" + run_id + "/files/trace.mcap").c_str());
  ASSERT_TRUE(trace);
  EXPECT_EQ(trace->status, 200);
  // Nothing to abort now.
  EXPECT_EQ(post("/api/scan/abort", "{}", token)->status, 409);
  // Who did what.
  const std::string actions = readText(root_ / "runs" / "hmi-actions.jsonl");
  EXPECT_NE(actions.find("\"scan start\""), std::string::npos);
  EXPECT_NE(actions.find("\"scan refused\""), std::string::npos);
  EXPECT_NE(actions.find("\"abort\""), std::string::npos);
}

// The cell's part programs on the panel: listed (the virtual cell's own parts among them), a
// program's nominal model served as binary STL for the 3D view, and a scan of a program started with
// its plan; a name that is not a program's is refused.
TEST_F(HmiTest, ThePanelListsThePartProgramsShowsAModelAndScansOne) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  const json list = body(client_->Get("/api/programs"));
  std::vector<std::string> names;
  for (const json& p : list["programs"]) names.push_back(p["name"]);
  for (const char* name : {"sim-dome-circle", "sim-dome-square", "sim-pan-circle", "sim-pan-square"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << list.dump(2);

  auto model = client_->Get("/api/programs/sim-pan-square/model.stl");
  ASSERT_TRUE(model);
  ASSERT_EQ(model->status, 200) << model->body;
  ASSERT_GT(model->body.size(), 84u);
  std::uint32_t triangles = 0;
  std::memcpy(&triangles, model->body.data() + 80, 4);
  EXPECT_GT(triangles, 1000u);
  EXPECT_EQ(model->body.size(), 84u + 50u * triangles);  // a whole binary STL
  EXPECT_EQ(client_->Get("/api/programs/no-such/model.stl")->status, 404);
  // What its plan is predicted to see, sample by sample, where the model is drawn.
  const json coverage = body(client_->Get("/api/programs/sim-pan-square/coverage"));
  EXPECT_GE(coverage["either"].get<double>(), 0.99) << coverage.dump().substr(0, 300);
  EXPECT_GE(coverage["laser"].get<double>(), 0.99);
  EXPECT_GT(coverage["sweeps"].get<int>(), 0);
  const std::size_t samples = coverage["seen"].size();
  EXPECT_GT(static_cast<double>(samples) * coverage["spacing_mm"].get<double>() * coverage["spacing_mm"].get<double>(),
            0.5 * coverage["grid_area_mm2"].get<double>());
  EXPECT_EQ(coverage["xyz"].size(), 3 * samples);
  std::size_t seen = 0;
  for (const json& s : coverage["seen"]) seen += s.get<int>() != 0 ? 1 : 0;
  EXPECT_GE(seen, samples * 99 / 100);
  EXPECT_EQ(client_->Get("/api/programs/no-such/coverage")->status, 404);
  // Written into the library on first use, and listed as such from then on.
  EXPECT_TRUE(fs::exists(root_ / "runs" / "programs" / "sim-pan-square" / "program.toml"));

  // A program not planned yet (a copy of it without its plan): listed as such, no prediction, and
  // planned on request from its model; its program file names the new plan from then on.
  const fs::path library = root_ / "runs" / "programs";
  fs::copy(library / "sim-pan-square", library / "bracket-17", fs::copy_options::recursive);
  fs::remove(library / "bracket-17" / "plan.toml");
  {
    std::istringstream in(readText(library / "bracket-17" / "program.toml"));
    std::string text, line;
    bool named = false;
    while (std::getline(in, line)) {
      if (line.rfind("plan = ", 0) == 0) continue;
      if (!named && line.rfind("name = ", 0) == 0) line = "name = \"bracket-17\"", named = true;
      text += line + "\n";
    }
    std::ofstream(library / "bracket-17" / "program.toml") << text;
  }
  const auto hasPlan = [&](const std::string& name) {
    const json listed = body(client_->Get("/api/programs"));
    for (const json& p : listed["programs"])
      if (p["name"] == name) return p["has_plan"].get<bool>();
    ADD_FAILURE() << name << " is not listed";
    return false;
  };
  EXPECT_FALSE(hasPlan("bracket-17"));
  EXPECT_TRUE(hasPlan("sim-pan-square"));
  EXPECT_EQ(client_->Get("/api/programs/bracket-17/coverage")->status, 404);
  const std::string planning_token = csrf();
  auto planned = post("/api/programs/bracket-17/plan", "{}", planning_token);
  ASSERT_TRUE(planned);
  ASSERT_EQ(planned->status, 200) << planned->body;
  const json plan_coverage = json::parse(planned->body);
  EXPECT_GE(plan_coverage["either"].get<double>(), 0.99) << planned->body.substr(0, 300);
  EXPECT_GT(plan_coverage["sweeps"].get<int>(), 0);
  EXPECT_TRUE(fs::exists(library / "bracket-17" / "plan.toml"));
  EXPECT_TRUE(hasPlan("bracket-17"));
  EXPECT_EQ(client_->Get("/api/programs/bracket-17/coverage")->status, 200);
  EXPECT_EQ(post("/api/programs/no-such/plan", "{}", planning_token)->status, 404);
  // A plan written beside the panel (from the command line, by hand) is what the panel predicts from
  // then on: here the plan cut to its first sweep.
  {
    const std::string plan = readText(library / "bracket-17" / "plan.toml");
    const std::size_t first = plan.find("[[step]]"), second = plan.find("[[step]]", first + 1);
    ASSERT_NE(second, std::string::npos);
    std::ofstream(library / "bracket-17" / "plan.toml") << plan.substr(0, second);
  }
  EXPECT_EQ(body(client_->Get("/api/programs/bracket-17/coverage"))["sweeps"].get<int>(), 1);

  EventReader events(station_->port());
  ASSERT_TRUE(events.waitFor("hello", std::chrono::seconds(10)));
  const std::string token = csrf();
  EXPECT_EQ(post("/api/scan/start", R"({"part_id": "p-1", "part_program": "../etc"})", token)->status, 400);
  auto started = post("/api/scan/start", R"({"part_id": "p-2", "part_program": "sim-pan-square"})", token);
  ASSERT_TRUE(started);
  ASSERT_EQ(started->status, 202) << started->body;
  ASSERT_TRUE(events.waitFor("progress", std::chrono::seconds(60))) << events.text();
  EXPECT_EQ(events.events("started").front()["part_program"], "sim-pan-square");
  // The program's whole-part plan: many more steps than the sample region's.
  EXPECT_GT(events.events("progress").front()["steps"].get<int>(), 20) << events.events("progress").front().dump();
  EXPECT_EQ(post("/api/scan/abort", "{}", token)->status, 202);
  ASSERT_TRUE(events.waitFor("finished", std::chrono::seconds(60))) << events.text();
  const std::string actions = readText(root_ / "runs" / "hmi-actions.jsonl");
  EXPECT_NE(actions.find("\"part_program\":\"sim-pan-square\""), std::string::npos) << actions;
}

TEST_F(HmiTest, BadInputGetsAClearJsonErrorNeverAFile) {
  // A run folder with a report file, and a symlink in it that points out of the runs folder.
  const fs::path run = root_ / "runs" / "20261125-010203-part";
  fs::create_directories(run);
  std::ofstream(run / "run.json") << R"({"part_id": "part"})";
  std::ofstream(run / "fld.png") << "not really a png";
  fs::create_symlink("/etc/passwd", run / "evil.png");
  std::ofstream(root_ / "secret.txt") << "TOP-SECRET-CONTENT";
  ASSERT_NO_FATAL_FAILURE(startPanel());
  const std::string token = csrf();

  const auto expectError = [&](const httplib::Result& r, int status, const std::string& what) {
    ASSERT_TRUE(r) << what;
    EXPECT_EQ(r->status, status) << what << ": " << r->body;
    const json j = body(r);
    EXPECT_TRUE(j.is_object() && j.contains("error")) << what << ": " << r->body;
    EXPECT_EQ(r->body.find("root:"), std::string::npos) << what;
    EXPECT_EQ(r->body.find("TOP-SECRET-CONTENT"), std::string::npos) << what;
  };
  expectError(post("/api/scan/start", "{not json", token), 400, "malformed JSON");
  expectError(post("/api/scan/start", "[1, 2]", token), 400, "not an object");
  expectError(post("/api/scan/start", R"({"program": "OP20"})", token), 400, "no part id");
  expectError(post("/api/scan/start", R"({"part_id": "../up"})", token), 400, "a part id that climbs");
  expectError(post("/api/scan/start", R"({"part_id": 7})", token), 400, "a part id that is a number");
  expectError(post("/api/scan/start", R"({"part_id": "a", "material": "cheese"})", token), 400, "unknown material");
  expectError(client_->Get("/api/runs/no-such-run"), 404, "unknown run id");
  expectError(client_->Get("/api/runs/no-such-run/mesh"), 404, "unknown run's mesh");
  expectError(client_->Get("/api/runs/20261125-010203-part/mesh"), 404, "a run without a mesh");
  expectError(client_->Get("/api/runs/20261125-010203-part/files/report.pdf"), 404, "a file the run lacks");
  expectError(client_->Get("/api/runs/20261125-010203-part/files/evil.png"), 404, "a symlink out of the run");
  expectError(client_->Get("/api/runs/..%2Fsecret.txt"), 404, "an encoded ../ as run id");
  expectError(client_->Get("/api/runs/20261125-010203-part/files/..%2F..%2Fsecret.txt"), 404, "an encoded ../ as file");
  expectError(client_->Get("/api/runs/20261125-010203-part/files/%2E%2E"), 400, "an encoded .. as file");
  expectError(client_->Get("/api/runs/%2E%2E/files/secret.txt"), 400, "an encoded .. as run id");
  expectError(client_->Get("/api/runs/20261125-010203-part/files/.hidden"), 400, "a hidden file");
  expectError(client_->Get("/api/runs/../secret.txt"), 404, "a raw ../");
  expectError(client_->Get("/lib/../../../../etc/passwd"), 404, "a raw ../ under the scripts");
  expectError(client_->Get("/lib/%2E%2E/%2E%2E/%2E%2E/etc/passwd"), 404, "an encoded ../ under the scripts");
  expectError(client_->Get("/api/nothing-here"), 404, "an unknown API path");
  expectError(client_->Get("/api/runs?last=many"), 400, "a count that is no number");

  // DNS rebinding: a name other than loopback's is refused by the loopback panel.
  expectError(client_->Get("/api/cell", {{"Host", "evil.example:8080"}}), 421, "a Host that is not loopback");
  expectError(client_->Get("/api/session", {{"Host", "127.0.0.1.evil.example:8080"}}), 421,
              "a name that only starts like a loopback address");
  expectError(client_->Get("/", {{"Host", "evil.example"}}), 421, "the page under another name");
  EXPECT_EQ(client_->Get("/api/session", {{"Host", "LOCALHOST:8080"}})->status, 200) << "names are not case-sensitive";
  // A body without a declared length (chunked: as much as the sender likes) is refused unread. Sent
  // whole in one write on a socket of its own: a client writing its last chunk after the refusal
  // would find the connection closed (and, without SIGPIPE ignored, die of it).
  const std::string chunked = rawExchange(station_->port(),
                                          "POST /api/scan/abort HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Type: "
                                          "application/json\r\nTransfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n");
  EXPECT_EQ(chunked.rfind("HTTP/1.1 411", 0), 0u) << chunked;
  auto fld = client_->Get("/api/runs/20261125-010203-part/files/fld.png");
  ASSERT_TRUE(fld);
  EXPECT_EQ(fld->status, 200);
  EXPECT_EQ(fld->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(fld->body, "not really a png");
  // And the server is still there.
  EXPECT_EQ(client_->Get("/api/session")->status, 200);
}

TEST_F(HmiTest, TheAnalysisViewsOfTwoRunsOfOneProgram) {
  // Run B is thinner by a known amount and its grid lies 0.3 mm off A's; run C is of another program.
  writeSyntheticRun(root_ / "runs" / "20261125-080000-a", "a", "OP20", -0.05, 0);
  writeSyntheticRun(root_ / "runs" / "20261125-090000-b", "b", "OP20", -0.08, 0.3);
  writeSyntheticRun(root_ / "runs" / "20261125-100000-c", "c", "OP30", -0.05, 0);
  ASSERT_NO_FATAL_FAILURE(startPanel());

  // The elements, with the measurement's major direction for the arrows.
  const json e = body(client_->Get("/api/runs/20261125-080000-a/elements"));
  ASSERT_EQ(e["elements"], 80) << e.dump();
  EXPECT_EQ(e["xyz"].size(), 240u);
  EXPECT_EQ(e["major"].size(), 80u);
  EXPECT_TRUE(e["has_directions"].get<bool>());
  ASSERT_EQ(e["major_direction"].size(), 240u);
  EXPECT_NEAR(e["major_direction"][0].get<double>(), 1.0, 1e-6);

  // A section through the fourth column of elements: eight of them, in order, 7 pitches long.
  const json cut = body(client_->Get("/api/runs/20261125-080000-a/section?axis=x&at=7.62"));
  ASSERT_EQ(cut["points"].size(), 8u) << cut.dump();
  EXPECT_NEAR(cut["points"][7]["along_mm"].get<double>(), 17.78, 1e-3);
  EXPECT_NEAR(cut["points"][0]["thinning_percent"].get<double>(), (1 - std::exp(-0.05)) * 100, 1e-3);
  EXPECT_NEAR(cut["points"][0]["major_percent"].get<double>(), (std::exp(0.04) - 1) * 100, 1e-3);
  EXPECT_NEAR(cut["range_mm"][1].get<double>(), 22.86, 1e-3);
  EXPECT_EQ(body(client_->Get("/api/runs/20261125-080000-a/section?axis=y&at=0&width=1"))["points"].size(), 10u);

  // B minus A on A's surface: every element matched, the known difference everywhere.
  const json diff = body(client_->Get("/api/compare?a=20261125-080000-a&b=20261125-090000-b"));
  const double expected = (1 - std::exp(-0.08)) * 100 - (1 - std::exp(-0.05)) * 100;
  ASSERT_EQ(diff["matched"], 80) << diff.dump();
  EXPECT_EQ(diff["strain"], "thinning");
  EXPECT_NEAR(diff["mean"].get<double>(), expected, 2e-3);
  EXPECT_NEAR(diff["max"].get<double>(), expected, 2e-3);
  EXPECT_EQ(diff["elements"]["difference"].size(), 80u);
  ASSERT_TRUE(diff["mesh"].is_object());
  ASSERT_EQ(diff["mesh"]["difference"].size(), 4u) << "one value per vertex of A's mesh";
  EXPECT_NEAR(diff["mesh"]["difference"][2].get<double>(), expected, 2e-3);
  EXPECT_EQ(diff["a"]["part_id"], "a");
  EXPECT_EQ(diff["b"]["part_id"], "b");
  const json major = body(client_->Get("/api/compare?a=20261125-080000-a&b=20261125-090000-b&strain=major"));
  EXPECT_NEAR(major["rms"].get<double>(), 0, 1e-3) << "the same major strain in both";

  const auto expectError = [&](const char* path, int status, const std::string& says) {
    auto r = client_->Get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, status) << path << ": " << r->body;
    EXPECT_NE(body(r)["error"].get<std::string>().find(says), std::string::npos) << path << ": " << r->body;
  };
  expectError("/api/compare?a=20261125-080000-a&b=20261125-100000-c", 400, "one program");
  expectError("/api/compare?a=20261125-080000-a", 400, "two runs");
  expectError("/api/compare?a=20261125-080000-a&b=20261125-090000-b&strain=stress", 400, "stress");
  expectError("/api/compare?a=20261125-080000-a&b=20261125-090000-b&max_distance=-1", 400, "max_distance");
  expectError("/api/compare?a=20261125-080000-a&b=..%2Fsecret", 400, "not a run id");
  expectError("/api/runs/20261125-080000-a/section?axis=w&at=1", 400, "axis");
  expectError("/api/runs/20261125-080000-a/section?axis=x&at=left", 400, "'at' must be a number");
  expectError("/api/runs/20261125-080000-a/section?axis=x", 400, "'at' is required");
  expectError("/api/runs/20261125-080000-a/section?axis=x&at=1&width=0", 400, "width");
  expectError("/api/runs/no-such-run/elements", 404, "no run");
  // A run folder without grid elements (an aborted scan) says so.
  fs::remove(root_ / "runs" / "20261125-100000-c" / "cloud4d.ply");
  expectError("/api/runs/20261125-100000-c/elements", 404, "no grid elements");

  // No scan yet: the live cloud is empty.
  const json live = body(client_->Get("/api/scan/cloud"));
  EXPECT_EQ(live["shown"], 0) << live.dump();
  EXPECT_EQ(live["xyz"].size(), 0u);
}

TEST_F(HmiTest, MaintenanceSettingsAreCheckedAppliedAndLogged) {
  ASSERT_NO_FATAL_FAILURE(startPanel());
  const std::string token = csrf();
  // On loopback the local user has the maintenance role.
  const json before = body(client_->Get("/api/settings"));
  EXPECT_EQ(before["settings"]["validity_days"], 7) << before.dump();
  EXPECT_FALSE(before["persisted"].get<bool>()) << "the built-in virtual cell has no cell file";
  EXPECT_EQ(before["ranges"].size(), 4u);

  auto changed = post("/api/settings", R"({"validity_days": 2.5, "form_mpe_mm": 0.08})", token);
  ASSERT_TRUE(changed);
  ASSERT_EQ(changed->status, 200) << changed->body;
  EXPECT_EQ(body(changed)["settings"]["validity_days"], 2.5);
  EXPECT_EQ(body(client_->Get("/api/settings"))["settings"]["form_mpe_mm"], 0.08);
  // Applied: the calibration status judges the calibration in use by the new validity.
  const json calibration = body(client_->Get("/api/calibration"));
  EXPECT_EQ(calibration["sensors"][0]["valid_days"], 2.5) << calibration.dump();

  const auto refused = [&](const std::string& payload, int status, const std::string& says, httplib::Headers h = {},
                           const std::string& t = "") {
    auto r = post("/api/settings", payload, t.empty() ? token : t, std::move(h));
    ASSERT_TRUE(r) << payload;
    EXPECT_EQ(r->status, status) << payload << ": " << r->body;
    EXPECT_NE(body(r)["error"].get<std::string>().find(says), std::string::npos) << payload << ": " << r->body;
  };
  refused(R"({"validity_days": 7000})", 400, "validity_days");
  refused(R"({"validity_days": "7"})", 400, "must be a number");
  refused(R"({"results_database": 1})", 400, "no setting 'results_database'");
  refused("{}", 400, "settings to change");
  refused("not json", 400, "settings to change");
  refused(R"({"validity_days": 3})", 403, "CSRF", {}, "forged");
  refused(R"({"validity_days": 3})", 403, "another site", {{"Origin", "http://evil.example"}});
  EXPECT_EQ(body(client_->Get("/api/settings"))["settings"]["validity_days"], 2.5) << "nothing refused was applied";

  // Who changed what, from what to what; and the refusals.
  const std::string log = readText(root_ / "runs" / "hmi-actions.jsonl");
  EXPECT_NE(log.find(R"("action":"settings change")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("validity_days":{"from":7.0,"to":2.5})"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("action":"settings refused")"), std::string::npos) << log;
}

// A cell whose devices are nowhere and whose results database is damaged: the health says so (503,
// each finding named; 200 with the same findings for the panel's banner), and `station hmi` writes the findings into its log once.
TEST_F(HmiTest, TheHealthNamesWhatKeepsTheCellFromScanning) {
  const fs::path cell = root_ / "cell.toml";
  std::ofstream(cell) << "name = \"press line 5\"\n[cmm]\nport = 9\n[plc]\nport = 9\n[cameras]\nleft_address = \"127.0.0.3\"\n"
                         "right_address = \"127.0.0.4\"\n";
  std::ofstream(root_ / "runs" / "results.sqlite") << "not a database";
  ASSERT_NO_FATAL_FAILURE(startPanel({"--listen", "127.0.0.1:0", "--cell", cell.string()}));
  auto health = client_->Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 503) << health->body;
  const json h = body(health);
  EXPECT_EQ(h["status"], "fault");
  std::string findings;
  for (const auto& f : h["findings"]) findings += f["what"].get<std::string>() + ": " + f["text"].get<std::string>() + "\n";
  EXPECT_NE(findings.find("database: the results database cannot be read"), std::string::npos) << findings;
  EXPECT_NE(findings.find(" is disconnected"), std::string::npos) << findings;
  EXPECT_FALSE(h["database"]["reachable"].get<bool>());
  // The panel's banner reads the same findings answered 200: a fault is shown, not a failed request.
  auto banner = client_->Get("/api/cell/health");
  ASSERT_TRUE(banner);
  EXPECT_EQ(banner->status, 200) << banner->body;
  EXPECT_EQ(body(banner)["status"], "fault");
  EXPECT_EQ(body(banner)["findings"].size(), h["findings"].size());
  // Into the log after the devices' first ten seconds, once.
  std::string log;
  for (int i = 0; i < 150 && log.find("station hmi: fault: the results database") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    log = station_->log();
  }
  EXPECT_NE(log.find("station hmi: fault: the results database cannot be read"), std::string::npos) << log;
}

TEST_F(HmiTest, SettingsGoIntoTheCellFileWhenThereIsOne) {
  // A cell of its own file, whose devices are nowhere (the panel serves all the same; they show as
  // faulted): a change of its settings is written into that file, comments kept.
  const fs::path cell = root_ / "cell.toml";
  std::ofstream(cell) << "name = \"press line 4\"\n[cmm]\nport = 9\n[plc]\nport = 9\n[cameras]\nleft_address = \"127.0.0.3\"\n"
                         "right_address = \"127.0.0.4\"\n\n[calibration]  # the rules\nvalidity_days = 7   # a week\n";
  ASSERT_NO_FATAL_FAILURE(startPanel({"--listen", "127.0.0.1:0", "--cell", cell.string()}));
  const json before = body(client_->Get("/api/settings"));
  EXPECT_TRUE(before["persisted"].get<bool>()) << before.dump();
  EXPECT_EQ(before["cell_file"], cell.string());
  auto changed = post("/api/settings", R"({"validity_days": 3, "size_mpe_mm": 0.02})", csrf());
  ASSERT_TRUE(changed);
  ASSERT_EQ(changed->status, 200) << changed->body;
  const std::string text = readText(cell);
  EXPECT_NE(text.find("validity_days = 3.0   # a week"), std::string::npos) << text;
  EXPECT_NE(text.find("size_mpe_mm = 0.02"), std::string::npos) << text;
  EXPECT_NE(text.find("name = \"press line 4\""), std::string::npos) << text;
  EXPECT_NE(readText(root_ / "runs" / "hmi-actions.jsonl").find(cell.string()), std::string::npos)
      << "the actions log names the file changed";
  // A panel started again on that file starts with the new rules.
  station_->stop();
  ASSERT_NO_FATAL_FAILURE(startPanel({"--listen", "127.0.0.1:0", "--cell", cell.string()}));
  EXPECT_EQ(body(client_->Get("/api/settings"))["settings"]["validity_days"], 3);
}

}  // namespace
}  // namespace stampscan::hmi::test
