// The cell file: a second cell that differs from the default in every section is read as written,
// its listing reads back to the same cell, each kind of mistake is refused in one line naming the
// file, the section and the key, and the simulated world and its plans follow the file.
#include "stampscan/acquisition/calibration_plan.hpp"
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <unistd.h>
#include <variant>
#include <vector>

namespace stampscan::acquisition {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = std::numbers::pi / 180;

const fs::path kSecondCell = fs::path(STAMPSCAN_CELLS_DIR) / "virtual-indexing.toml";

class CellFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stampscan_cell_config_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path file = dir_ / name;
    std::ofstream(file) << text;
    return file;
  }
  fs::path dir_;
};

TEST_F(CellFileTest, ASecondCellDiffersInEverySectionAndIsReadAsWritten) {
  const CellConfig a = virtualCell();
  CellConfig b = loadCellConfig(kSecondCell);
  // Only the optional places are left out (the calibration folder, the database, the materials, the
  // panel's users and TLS front).
  EXPECT_EQ(b.defaulted, (std::vector<std::string>{"[calibration] dir", "[hmi] http_port", "[hmi] https_port",
                                                   "[hmi] tls_certificate", "[hmi] tls_key", "[hmi] users",
                                                   "[programs] library", "[report] materials", "[results] database"}));
  EXPECT_NE(b.panel.listen, a.panel.listen);
  EXPECT_EQ(b.panel.server_names, std::vector<std::string>{"cell-b.plant.example"});
  EXPECT_NE(b.name, a.name);
  EXPECT_EQ(b.cmm.port, 11294);
  EXPECT_EQ(b.plc.port, 11502);
  EXPECT_EQ(b.plc_unit_id, 3);
  EXPECT_EQ(b.calibration.plate_views, 14);
  EXPECT_NE(b.calibration.sphere_sweeps, a.calibration.sphere_sweeps);
  // Every PLC signal elsewhere than in the standard map (the built-in cell's).
  EXPECT_EQ(a.plc_registers, drivers::plc::RegisterMap::standard());
  for (std::size_t row = 0; row < drivers::plc::kSignalCount; ++row)
    EXPECT_NE(b.plc_registers.addresses[row], a.plc_registers.addresses[row]) << drivers::plc::registerTable()[row].name;
  EXPECT_EQ(b.plc_registers.address(drivers::plc::DiscreteInput::DoorClosed), 104);
  EXPECT_EQ(b.plc_registers.address(drivers::plc::Coil::LaserShutterOpenRequest), 200);
  EXPECT_EQ(b.plc_registers.address(drivers::plc::HoldingRegister::LinePartId), 520);
  EXPECT_TRUE(b.plc_line_start);
  EXPECT_TRUE(a.plc_line_start) << "the built-in virtual cell lets the line start scans too";
  EXPECT_EQ(b.left_camera.serial, "CELL-B-LEFT");
  EXPECT_EQ(b.limits.travel_max[0], 500);
  EXPECT_EQ(b.geometry.head.kind, HeadDescription::Kind::Indexing);
  EXPECT_NEAR(b.limits.index_step, 7.5 * kDeg, 1e-12);
  EXPECT_NEAR(b.limits.max_tilt, 105 * kDeg, 1e-12);
  ASSERT_EQ(b.geometry.head.body.size(), 3u);
  EXPECT_EQ(b.geometry.head.body[0].shape, BodySolid::Shape::Sphere);
  // The fixture's solids, in the part's datum frame.
  ASSERT_EQ(b.geometry.fixture.body.size(), 3u);
  EXPECT_EQ(b.geometry.fixture.body[0].name, "base plate");
  EXPECT_EQ(b.geometry.fixture.body[1].shape, BodySolid::Shape::Cylinder);
  EXPECT_EQ(b.geometry.fixture.body[1].placement.position_mm, (std::array<double, 3>{150, 0, -52}));
  EXPECT_EQ(b.geometry.cameras.width, 1600);
  EXPECT_EQ(b.geometry.cameras.bits, 16);
  EXPECT_EQ(b.geometry.digitizer.latency_ms, 5);
  EXPECT_EQ(b.geometry.digitizer.mount.position_mm, (std::array<double, 3>{8, -5, -140}));
  EXPECT_EQ(b.geometry.sphere.diameter_mm, 30);
  ASSERT_TRUE(b.geometry.ball_bar.has_value());
  EXPECT_EQ(b.geometry.ball_bar->distance_mm, 150);
  EXPECT_EQ(b.geometry.plate.columns, 11);
  EXPECT_EQ(b.geometry.fixture.name, "nest B");
  EXPECT_EQ(b.calibration.validity_days, 3);
  for (const auto& [section, same] : std::vector<std::pair<const char*, bool>>{
           {"head", a.geometry.head == b.geometry.head},
           {"digitizer", a.geometry.digitizer == b.geometry.digitizer},
           {"cameras", a.geometry.cameras == b.geometry.cameras},
           {"sphere", a.geometry.sphere == b.geometry.sphere},
           {"ball_bar", a.geometry.ball_bar == b.geometry.ball_bar},
           {"plate", a.geometry.plate == b.geometry.plate},
           {"fixture", a.geometry.fixture == b.geometry.fixture}})
    EXPECT_FALSE(same) << section;

  // What `station cell check` prints is a cell file of the same cell.
  const fs::path listed = write("listed.toml", describeCellConfig(b));
  CellConfig again = loadCellConfig(listed);
  EXPECT_TRUE(again.defaulted.empty());
  EXPECT_EQ(again.geometry, b.geometry);
  EXPECT_EQ(again.limits.index_step, b.limits.index_step);
  EXPECT_EQ(again.plc_registers, b.plc_registers);
  again.source = b.source;
  b.defaulted.clear();
  EXPECT_EQ(describeCellConfig(again), describeCellConfig(b));
}

TEST_F(CellFileTest, KeysLeftOutAreDefaultsAndListedAsSuch) {
  const CellConfig c = loadCellConfig(write("short.toml", "name = \"short\"\n[digitizer]\nlatency_ms = 4\n"));
  EXPECT_EQ(c.geometry.digitizer.latency_ms, 4);
  EXPECT_EQ(c.geometry.digitizer.standoff_mm, DigitizerDrawing{}.standoff_mm);
  EXPECT_NE(std::find(c.defaulted.begin(), c.defaulted.end(), "[digitizer] standoff_mm"), c.defaulted.end());
  EXPECT_EQ(std::find(c.defaulted.begin(), c.defaulted.end(), "[digitizer] latency_ms"), c.defaulted.end());
  EXPECT_FALSE(c.geometry.ball_bar.has_value());  // a file without [ball_bar]: no ball bar
  const std::string listing = describeCellConfig(c);
  EXPECT_NE(listing.find("standoff_mm = 100.0"), std::string::npos) << listing;
  EXPECT_NE(listing.find("# default"), std::string::npos);
  EXPECT_NE(listing.find("# no [ball_bar]"), std::string::npos);
}

// [plc.registers] moves a signal by its name in drivers/plc/REGISTER_MAP.md; the others keep their
// standard addresses, listed as defaults.
TEST_F(CellFileTest, PlcSignalsLeftOutKeepTheirStandardAddresses) {
  using drivers::plc::Coil;
  using drivers::plc::RegisterMap;
  const CellConfig c = loadCellConfig(write("moved.toml", "[plc]\nunit_id = 2\n[plc.registers]\nstack_light_green = 20\n"
                                                          "door_closed = 10\n"));
  RegisterMap expected;
  expected.setAddress(Coil::StackLightGreen, 20);
  expected.setAddress(drivers::plc::DiscreteInput::DoorClosed, 10);
  EXPECT_EQ(c.plc_registers, expected);
  EXPECT_EQ(c.plc_registers.address(Coil::StackLightAmber), RegisterMap::standard().address(Coil::StackLightAmber));
  EXPECT_NE(std::find(c.defaulted.begin(), c.defaulted.end(), "[plc.registers] stack_light_amber"), c.defaulted.end());
  EXPECT_EQ(std::find(c.defaulted.begin(), c.defaulted.end(), "[plc.registers] stack_light_green"), c.defaulted.end());
  const std::string listing = describeCellConfig(c);
  EXPECT_NE(listing.find("[plc.registers]\ndoor_closed = 10\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("\nstack_light_green = 20\n"), std::string::npos) << listing;
  EXPECT_NE(listing.find("\nstack_light_amber = 1"), std::string::npos) << listing;
  // A file without [plc.registers]: the standard map.
  EXPECT_EQ(loadCellConfig(write("plain.toml", "[plc]\nport = 1503\n")).plc_registers, RegisterMap::standard());
}

// [hmi]: the panel's address, its users, its names and its TLS front, paths beside the cell file.
TEST_F(CellFileTest, ThePanelsSectionIsReadWithItsPathsBesideTheFile) {
  const CellConfig defaults = loadCellConfig(write("cell.toml", "name = \"c\"\n"));
  EXPECT_EQ(defaults.panel.listen, "127.0.0.1:8080");
  EXPECT_FALSE(defaults.panel.behindTlsFront());
  const CellConfig c = loadCellConfig(write("cell.toml", "[hmi]\nlisten = \"127.0.0.1:9000\"\nusers = \"users.toml\"\n"
                                                        "server_names = [\"cell7.plant.example\", \"10.1.2.3\"]\n"
                                                        "tls_certificate = \"tls/c.crt\"\ntls_key = \"/etc/c.key\"\n"
                                                        "https_port = 8443\nhttp_port = 8081\n"));
  EXPECT_EQ(c.panel.listen, "127.0.0.1:9000");
  EXPECT_EQ(c.panel.users_file, (dir_ / "users.toml").string());
  EXPECT_EQ(c.panel.server_names, (std::vector<std::string>{"cell7.plant.example", "10.1.2.3"}));
  EXPECT_EQ(c.panel.tls_certificate, (dir_ / "tls/c.crt").string());
  EXPECT_EQ(c.panel.tls_key, "/etc/c.key");
  EXPECT_EQ(c.panel.https_port, 8443);
  EXPECT_EQ(c.panel.http_port, 8081);
  EXPECT_TRUE(c.panel.behindTlsFront());
  // The listing reads back to the same panel.
  const CellConfig again = loadCellConfig(write("again.toml", describeCellConfig(c)));
  EXPECT_EQ(again.panel.server_names, c.panel.server_names);
  EXPECT_EQ(again.panel.tls_certificate, c.panel.tls_certificate);
  EXPECT_EQ(again.panel.https_port, 8443);
}

TEST_F(CellFileTest, EveryKindOfMistakeIsRefusedInOneLineNamingWhere) {
  const std::vector<std::pair<std::string, std::string>> cases{
      {"[digitizer]\nstandoff_mm = \"100 mm\"\n", "[digitizer] standoff_mm must be a positive number"},
      {"[digitizer]\nstandof_mm = 100\n", "[digitizer] standof_mm is not a key of this section"},
      {"[digitizer]\nmount_mm = [0, -120]\n", "[digitizer] mount_mm must be a list of 3 numbers"},
      {"[digitizer]\nfan_angle_deg = 190\n", "[digitizer] fan_angle_deg must be below 170"},
      {"[digitizer]\npoints_per_profile = 8192\n", "[digitizer] points_per_profile is 8192, not 16..4096"},
      {"[digitizer]\nprofile_rate_hz = 50000\n", "[digitizer] profile_rate_hz must be within 1..20000 Hz"},
      {"[digitizer]\nmeasuring_range_mm = 400\n", "[digitizer] measuring_range_mm must be below twice standoff_mm"},
      {"[cameras]\nbits = 12\n", "[cameras] bits is 12: expected 8 (Mono8) or 16 (Mono16)"},
      {"[cameras]\nwidth = 20.5\n", "[cameras] width has the wrong type: expected an integer"},
      {"[head]\nkind = \"wobbly\"\n", "[head] kind is \"wobbly\": expected continuous or indexing"},
      {"[head]\n[[head.body]]\nname = \"ram\"\nshape = \"cylinder\"\nradius_mm = 30\n", "[head.body 1] length_mm is missing"},
      {"[head]\n[[head.body]]\nshape = \"box\"\n", "[head.body 1] name is missing"},
      {"[fixture]\n[[fixture.body]]\nname = \"clamp\"\nshape = \"cone\"\n",
       "[fixture.body 1] shape is \"cone\": expected box, cylinder or sphere"},
      {"[fixture]\nbody = 3\n", "[fixture] body must be an array of tables ([[fixture.body]] entries)"},
      {"[machine]\nmax_tilt_deg = 90\n", "[machine] max_tilt_deg has moved: write it as [head] a_max_deg"},
      {"[machine]\ntravel_min = [0, 0, 0]\ntravel_max = [0, 1, 1]\n", "[machine] travel_min must be below travel_max"},
      {"[sphere]\ncentre_mm = [250, 0, 40]\n[ball_bar]\ncentre_mm = [250, -120, 40]\ndistance_mm = 100\n",
       "[ball_bar] distance_mm is 100.000 mm, but centre_mm puts the spheres 120.000 mm apart"},
      {"[plate]\ncolumns = 8\n", "[plate] columns must be odd"},
      {"[plate]\npitch_mm = 3\ndot_diameter_mm = 3\n", "[plate] dot_diameter_mm must be below pitch_mm"},
      {"[fixture]\ndatum_rotation_deg = [0, 0]\n", "[fixture] datum_rotation_deg must be a list of 3 numbers"},
      {"[plc]\nport = 70000\n", "[plc] port 70000 is not 1-65535"},
      {"[calibration]\nplate_views = 2\n", "[calibration] plate_views is 2, not 4..200"},
      {"[plc]\nunit_id = 300\n", "[plc] unit_id is 300, not 0..255"},
      {"[plc]\nregisters = 5\n", "[plc] registers must be a table"},
      {"[plc.registers]\ndoor_closd = 10\n", "[plc.registers] door_closd is not a key of this section (known: "},
      {"[plc.registers]\ndoor_closed = -1\n", "[plc.registers] door_closed is -1, not 0..65535"},
      {"[plc.registers]\nstack_light_red = 65536\n", "[plc.registers] stack_light_red is 65536, not 0..65535"},
      {"[plc.registers]\nfault_word = 4.5\n", "[plc.registers] fault_word has the wrong type: expected an integer"},
      {"[plc.registers]\nfault_word = \"4\"\n", "[plc.registers] fault_word has the wrong type: expected an integer"},
      {"[plc.registers]\npart_clamped = 0\n", "[plc.registers] door_closed and part_clamped are both discrete-input 0"},
      {"[plc.registers]\nclamp_request = 30\nmotion_enable = 30\n",
       "[plc.registers] clamp_request and motion_enable are both coil 30"},
      {"[plc.registers]\nfault_word = 200\n",
       "[plc.registers] input-register addresses from plc_heartbeat (0) to fault_word (200) span 201, more than the 100"},
      {"[hmi]\nserver_names = \"cell7\"\n", "[hmi] server_names has the wrong type: expected a list of strings"},
      {"[hmi]\nserver_names = [\"cell7; return 200\"]\n", "[hmi] server_names 'cell7; return 200' is not a host name"},
      {"[hmi]\nserver_names = [\"cell7\"]\ntls_key = \"cell7.key\"\n", "[hmi] tls_certificate is missing"},
      {"[hmi]\ntls_certificate = \"c.crt\"\ntls_key = \"c.key\"\n", "[hmi] server_names is missing"},
      {"[hmi]\nserver_names = [\"a\"]\ntls_certificate = \"c\\\"x.crt\"\ntls_key = \"c.key\"\n",
       "[hmi] tls_certificate '"},
      {"[hmi]\nhttps_port = 8443\nhttp_port = 8443\n", "[hmi] http_port is the https_port"},
      {"[hmi]\nlistn = \"127.0.0.1:8080\"\n", "[hmi] listn is not a key of this section"},
      {"[camera]\nwidth = 10\n", "[camera] is not a section of a cell file"},
      {"name = 3\n", "name has the wrong type"},
      {"name = \"cell\\nserver { }\"\n", "name holds a line break"},
      {"[digitizer\n", "cell.toml:1:"},
  };
  for (const auto& [text, expected] : cases) {
    const fs::path file = write("cell.toml", text);
    try {
      (void)loadCellConfig(file);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file.string(), 0), 0u) << what;  // starts with the file
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;  // one line
    }
  }
}

TEST(CellPlans, AnIndexingHeadsPlanUsesOnlyItsStops) {
  MachineLimits limits;
  limits.index_step = 7.5 * kDeg;
  ScanPlan plan;
  plan.steps.emplace_back(StereoStep{Scene::Part, 0, HeadPose{{0, 0, 300}, 15 * kDeg, -7.5 * kDeg}, 0.4});
  EXPECT_TRUE(checkPlan(plan, limits).empty());
  plan.steps.emplace_back(StereoStep{Scene::Part, 1, HeadPose{{0, 0, 300}, 2 * kDeg, 0}, 0.4});
  const auto problems = checkPlan(plan, limits);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("head tilt 2 deg is not a stop of the indexing head (every 7.5 deg)"), std::string::npos)
      << problems[0];
}

// The simulated world is the cell file's: its planner uses the head's stops and the sensors as
// drawn, and a session of it is described as the file describes the cell.
TEST(CellPlans, TheSimulatedWorldAndItsPlansFollowTheCellFile) {
  const CellConfig b = loadCellConfig(kSecondCell);
  for (const sim::PartKind part : {sim::PartKind::Dome, sim::PartKind::Pan}) {
    sim::ScanParams world;
    world.part = part;
    world.second_sphere_sweeps = 4;
    world.setCell(b);
    const ScanPlan plan = sim::planScan(world);
    const auto problems = checkPlan(plan, b.limits);
    EXPECT_TRUE(problems.empty()) << problems.front();
    EXPECT_GT(plan.sweepCount(Scene::Part), 0u);
    EXPECT_GT(plan.sweepCount(Scene::SecondSphere), 0u);
    trace::SessionDescription expected = describeSession(b.geometry, plan);
    expected.plan.clear();
    EXPECT_EQ(sim::describeSession(world), expected);
  }
  // The true sensors are the drawn ones plus the seed's deviation: near the drawing, not on it.
  sim::ScanParams world;
  world.setCell(b);
  const sim::CellTruth truth = sim::drawCellTruth(world);
  const Eigen::Vector3d drawn(8, -5, -140);
  EXPECT_LT((truth.head_from_digitizer.translation() - drawn).norm(), 5.0);
  EXPECT_GT((truth.head_from_digitizer.translation() - drawn).norm(), 1e-6);
  EXPECT_NEAR(static_cast<double>(truth.digitizer_latency_ns) * 1e-6, 5.0, 1.0);
  EXPECT_EQ(truth.left.width, 1600);
  EXPECT_NEAR(truth.left.fx, 12 / 4.5e-3, 0.02 * 12 / 4.5e-3);
}

// The calibration scenes come from the cell file alone: on the second cell its plate views look at
// its plate, its sphere sweeps pass its sphere at its digitizer's standoff, all at the head's stops.
TEST(CellPlans, CalibrationScenesArePlannedFromTheCellFile) {
  const CellConfig b = loadCellConfig(kSecondCell);
  const ScanPlan plan = calibrationPlan(b, {12, 8, 4, 3});
  EXPECT_EQ(plan.stereoCount(Scene::CalibrationPlate), 12u);
  EXPECT_EQ(plan.sweepCount(Scene::ReferenceSphere), 8u);
  EXPECT_EQ(plan.sweepCount(Scene::SecondSphere), 4u);
  const auto problems = checkPlan(plan, b.limits);
  EXPECT_TRUE(problems.empty()) << problems.front();
  const Eigen::Vector3d mount(8, -5, -140);
  for (const PlanStep& step : plan.steps) {
    const auto* sweep = std::get_if<SweepStep>(&step);
    if (sweep == nullptr) continue;
    const auto& p = sweep->start;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(p.b, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(p.a, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(2 * kDeg, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
    const Eigen::Vector3d mirror = Eigen::Vector3d(p.position[0], p.position[1], p.position[2]) +
                                   (Eigen::AngleAxisd(p.b, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(p.a, Eigen::Vector3d::UnitX())) * mount;
    const auto& c = sweep->scene == Scene::ReferenceSphere ? b.geometry.sphere.centre_mm : b.geometry.ball_bar->centre_mm;
    // Along the sensor's view (its z), the ball lies within the measuring range of the standoff.
    const double depth = (mirror - Eigen::Vector3d(c[0], c[1], c[2])).dot(R.col(2));
    EXPECT_NEAR(depth, 110, 0.5 * 70) << sweep->scene << " " << sweep->index;
  }
  // The plan parks within this cell's travel, whatever its size.
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_GT(plan.park.position[static_cast<std::size_t>(axis)], b.limits.travel_min[static_cast<std::size_t>(axis)]);
    EXPECT_LT(plan.park.position[static_cast<std::size_t>(axis)], b.limits.travel_max[static_cast<std::size_t>(axis)]);
  }
}

// The counts of calibration scenes come from the cell's [calibration] section; a quick session runs
// a share of them, never fewer than calibrate the sensors.
TEST(CellPlans, TheCellFileSetsHowManyCalibrationScenes) {
  const CellConfig b = loadCellConfig(kSecondCell);
  const CalibrationScenes all = calibrationScenes(b.calibration);
  EXPECT_EQ(all.plate_views, 14);
  EXPECT_EQ(all.sphere_sweeps, 10);
  const CalibrationScenes half = calibrationScenes(b.calibration, 0.5, 7);
  EXPECT_EQ(half.plate_views, 7);
  EXPECT_EQ(half.sphere_sweeps, 5);
  EXPECT_EQ(half.seed, 7u);
  CalibrationPolicy few;
  few.plate_views = 5;
  few.sphere_sweeps = 4;
  EXPECT_EQ(calibrationScenes(few, 0.1).plate_views, 4);
  EXPECT_EQ(calibrationScenes(few, 0.1).sphere_sweeps, 4);
  EXPECT_THROW(calibrationScenes(few, 0.0), std::invalid_argument);
  const ScanPlan plan = calibrationPlan(b, all);
  EXPECT_EQ(plan.stereoCount(Scene::CalibrationPlate), 14u);
  EXPECT_EQ(plan.sweepCount(Scene::ReferenceSphere), 10u);
}

// A scan that calibrates itself runs the sphere's sweeps, the part's sweeps, the plate's views, then
// the part's views; the part's steps keep their order, whatever order its plan gave them in.
TEST(CellPlans, ASelfCalibratingScanPutsTheScenesWhereTheirWorkOverlapsThePartsWork) {
  const CellConfig b = loadCellConfig(kSecondCell);
  ScanPlan part;
  part.name = "part";
  for (std::uint32_t k = 0; k < 3; ++k) {
    part.steps.emplace_back(StereoStep{Scene::Part, k, {}, 0.4});
    part.steps.emplace_back(SweepStep{Scene::Part, k, {}, {}, 25, 0});
  }
  const ScanPlan plan = withCalibrationScenes(part, b.geometry, b.limits, {5, 4, 0, 1});
  EXPECT_EQ(plan.name, "part");
  std::vector<std::string> order;
  for (const PlanStep& step : plan.steps) {
    const bool sweep = std::holds_alternative<SweepStep>(step);
    const Scene scene = std::visit([](const auto& s) { return s.scene; }, step);
    const std::uint32_t index = std::visit([](const auto& s) { return s.index; }, step);
    const std::string kind = std::string(toString(scene)) + (sweep ? " sweep" : " view");
    if (order.empty() || order.back().rfind(kind, 0) != 0) order.push_back(kind);
    if (scene == Scene::Part) order.back() += " " + std::to_string(index);
  }
  EXPECT_EQ(order, (std::vector<std::string>{"reference_sphere sweep", "part sweep 0 1 2", "calibration_plate view",
                                             "part view 0 1 2"}));
  EXPECT_EQ(plan.sweepCount(Scene::ReferenceSphere), 4u);
  EXPECT_EQ(plan.stereoCount(Scene::CalibrationPlate), 5u);
}

}  // namespace
}  // namespace stampscan::acquisition
