// `station scan` end to end on the embedded virtual cell: the plan runs through the drivers on
// loopback, the trace is recorded live, measured and fitted, and the result matches the simulated
// part's truth. And the refusals before motion: a plan that leaves the travel, a malformed plan.
#include "station_test_support.hpp"

#include "stampscan/acquisition/trace/mcap_reader.hpp"

#include <nlohmann/json.hpp>

#include <fstream>

namespace stampscan::station::test {
namespace {

fs::path onlyRunFolder(const fs::path& runs) {
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(runs)) dirs.push_back(e.path());
  EXPECT_EQ(dirs.size(), 1u);
  return dirs.empty() ? fs::path() : dirs.front();
}

TEST_F(StationTest, ScanOnTheVirtualCellMeasuresThePart) {
  const fs::path runs = work() / "runs";
  const RunResult r = run("scan -q --part-id P-17 -o " + quote(runs));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("check       interlocks healthy"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("calibrated on the reference sphere"), std::string::npos) << r.out;
  const fs::path dir = onlyRunFolder(runs);
  EXPECT_NE(dir.filename().string().find("P-17"), std::string::npos);
  for (const char* f : {"trace.mcap", "cloud4d.ply", "fitted.ply", "mesh.ply", "run.json"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;

  // The trace recorded live is whole, and holds what the devices sent.
  trace::McapReader reader(dir / "trace.mcap");
  std::size_t profiles = 0, positions = 0, plc = 0;
  const trace::TraceHealth health = reader.readMessages([&](const trace::TraceMessage& m) {
    if (!m.channel) return true;
    profiles += m.channel->topic == "/digitizer/profile";
    positions += m.channel->topic == "/cmm/position";
    plc += m.channel->topic == "/plc/state";
    return true;
  });
  EXPECT_TRUE(health.healthy());
  EXPECT_GT(profiles, 3000u);
  EXPECT_GT(positions, 50u);
  EXPECT_GT(plc, 10u);

  std::ifstream in(dir / "run.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_TRUE(j.at("completed").get<bool>());
  EXPECT_EQ(j.at("part_id"), "P-17");
  EXPECT_EQ(j.at("scan").at("lost_profiles").get<int>(), 0);
  // Every element lies on a true grid element; positions and thickness strain within the goals.
  EXPECT_GT(j.at("measurement").at("elements").get<int>(), 250);
  EXPECT_EQ(j.at("accuracy").at("matched"), j.at("measurement").at("elements"));
  EXPECT_LE(j.at("accuracy").at("position_rms_mm").get<double>(), 0.05);
  EXPECT_LE(j.at("accuracy").at("strain_rms").get<double>(), 0.005);
  // The latency found on the sphere is the virtual digitizer's own, to within 0.3 ms.
  EXPECT_NEAR(j.at("measurement").at("digitizer_latency_ms").get<double>(),
              j.at("accuracy").at("true_latency_ms").get<double>(), 0.3);
}

TEST_F(StationTest, ScanRefusesAPlanBeforeAnythingMoves) {
  const fs::path runs = work() / "runs", plan = work() / "far.toml";
  {
    std::ofstream out(plan);
    out << "name = \"too far\"\n[part]\nkind = \"pan\"\n\n[[step]]\nkind = \"sweep\"\nscene = \"part\"\n"
           "start = [0, 0, 200]\nend = [900, 0, 200]\nspeed = 25\n";
  }
  RunResult r = run("scan --dry-run --plan " + quote(plan));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("end x = 900 mm is outside the travel"), std::string::npos) << r.out;
  r = run("scan -q --plan " + quote(plan) + " -o " + quote(runs));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("outside the travel"), std::string::npos) << r.err;
  EXPECT_TRUE(!fs::exists(runs) || fs::is_empty(runs)) << "a refused plan leaves no run folder";

  // A malformed plan names the file, the line and the field.
  {
    std::ofstream out(plan);
    out << "name = \"bad\"\n\n[[step]]\nkind = \"sweep\"\nstart = [0, 0]\nend = [1, 0, 200]\n";
  }
  r = run("scan --dry-run --plan " + quote(plan));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(plan.string() + ":5: step[1].start must be a list of 3 numbers"), std::string::npos) << r.err;
}

TEST_F(StationTest, DryRunPrintsTheBuiltInPlan) {
  const RunResult r = run("scan --dry-run --part dome");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("on the reference sphere"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the plan can run on this cell"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace stampscan::station::test
