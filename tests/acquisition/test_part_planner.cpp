// Plans from a nominal model (acquisition/part_planner.hpp): what the generated plan is predicted
// to see, checked against geometry whose answer is known (a flat plate, a pocket deeper than the
// measuring range, walls too steep for either sensor), on a continuous and an indexing head, and on
// the simulator's own parts against their hand-made plans.
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/part_planner.hpp"
#include "stampscan/acquisition/part_program.hpp"
#include "stampscan/acquisition/plan_collisions.hpp"
#include "stampscan/acquisition/sensor_sight.hpp"
#include "stampscan/sim/part_model.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <unistd.h>

namespace stampscan::acquisition {
namespace {

namespace fs = std::filesystem;

// A quad (two triangles), counter-clockwise seen from its front.
void addQuad(NominalModel& m, std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> c,
             std::array<double, 3> d) {
  const auto base = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), {a, b, c, d});
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangles.push_back({base, base + 2, base + 3});
}

NominalModel plate(double w, double h) {
  NominalModel m;
  addQuad(m, {-w / 2, -h / 2, 0}, {w / 2, -h / 2, 0}, {w / 2, h / 2, 0}, {-w / 2, h / 2, 0});
  return m;
}

// A square pocket `depth` deep in a flange, its walls `wall_deg` from the horizontal.
NominalModel pocket(double flange, double opening, double depth, double wall_deg) {
  NominalModel m;
  const double o = opening / 2, f = flange / 2;
  const double i = o - depth / std::tan(wall_deg * std::numbers::pi / 180);  // the floor's half width
  // The flange: four quads around the opening.
  addQuad(m, {-f, -f, 0}, {f, -f, 0}, {f, -o, 0}, {-f, -o, 0});
  addQuad(m, {-f, o, 0}, {f, o, 0}, {f, f, 0}, {-f, f, 0});
  addQuad(m, {-f, -o, 0}, {-o, -o, 0}, {-o, o, 0}, {-f, o, 0});
  addQuad(m, {o, -o, 0}, {f, -o, 0}, {f, o, 0}, {o, o, 0});
  // The walls, facing inwards and up.
  addQuad(m, {-o, -o, 0}, {o, -o, 0}, {i, -i, -depth}, {-i, -i, -depth});
  addQuad(m, {o, o, 0}, {-o, o, 0}, {-i, i, -depth}, {i, i, -depth});
  addQuad(m, {-o, o, 0}, {-o, -o, 0}, {-i, -i, -depth}, {-i, i, -depth});
  addQuad(m, {o, -o, 0}, {o, o, 0}, {i, i, -depth}, {i, -i, -depth});
  addQuad(m, {-i, -i, -depth}, {i, -i, -depth}, {i, i, -depth}, {-i, i, -depth});
  return m;
}

PartSpec circles() { return PartSpec{}; }

TEST(PartPlanner, APlateIsSeenWholeByTheLaserAndTheCameras) {
  const CellConfig cell = virtualCell();
  const NominalModel model = plate(120, 80);
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
  const Coverage c = predictCoverage(model, plan, cell.geometry, cell.limits);
  EXPECT_NEAR(c.grid_area, 120 * 80, 1e-6);
  EXPECT_GE(c.share(c.laser_area), 0.995);
  EXPECT_GE(c.share(c.stereo_area), 0.995);
  // Passes no wider than the stripe, each overlapping the ground its neighbour covered by the share
  // asked for (the first one reaching as far beyond the plate's edge). Over flat ground the sensor
  // flies as high as the share of the measuring range a band may take allows, where the stripe is
  // wider than at the standoff.
  const DigitizerDrawing& d = cell.geometry.digitizer;
  const PlannerOptions defaults;
  const double flown = d.standoff_mm + 0.5 * defaults.depth_use * d.measuring_range_mm;
  const double stripe = stripeWidth(d) * flown / d.standoff_mm;
  const double overlap = defaults.strip_overlap;
  EXPECT_EQ(plan.sweepCount(Scene::Part), static_cast<std::size_t>(std::ceil(120 / ((1 - overlap) * stripe))));
  EXPECT_LT(c.overlap_area / c.laser_area, 2.5 * overlap);
  EXPECT_TRUE(checkPlan(placeOnFixture(plan, cell.geometry, cell.limits.index_step), cell.limits).empty());
  // Within the planning goal of the lower bound (the moves between passes come on top).
  const double bound = scanTimeLowerBound(c.grid_area, cell.geometry, 25);
  EXPECT_GT(bound, 0);
  EXPECT_LT(scanTimeFloor(c.grid_area, cell.geometry, 25), bound);
  EXPECT_LT(motionSeconds(plan, cell.limits), 3.0 * bound + 20);
}

// Neighbouring stripes overlap by at least an element's outline: an element straddling where one
// pass's claim ends lies whole in the other's fan. Where the stated share would need a pass more
// than that least overlap, the passes are as few as the least overlap allows.
TEST(PartPlanner, EveryElementLiesWholeWithinOneStripeWithAsFewPassesAsThatAllows) {
  const CellConfig cell = virtualCell();
  const DigitizerDrawing& d = cell.geometry.digitizer;
  const PlannerOptions defaults;
  const double flown = d.standoff_mm + 0.5 * defaults.depth_use * d.measuring_range_mm;  // over flat ground
  const double half_fan = 0.5 * d.fan_angle_deg * std::numbers::pi / 180;
  const PartSpec part = circles();
  const double margin = 0.5 * 1.4 * part.pitch + defaults.placement_tolerance_mm;
  const double least_claim = 2 * (flown * std::tan(half_fan) - margin);
  const double share_claim = 2 * flown * std::tan((1 - defaults.strip_overlap) * half_fan);
  ASSERT_GT(least_claim, share_claim);  // the stated share is the larger overlap here
  // Wide enough for one pass more at the stated share than at the least overlap (a narrow strip, so
  // that the +-2 degree crossing shifts the stripes little).
  const int passes = 4;
  const double width = passes * least_claim - 1.0;
  ASSERT_GT(width, passes * share_claim);
  const NominalModel model = plate(width, 10);
  PlannerOptions laser_only;
  laser_only.stereo = false;
  const ScanPlan plan = planPart(model, part, cell.geometry, cell.limits, laser_only);
  EXPECT_EQ(plan.sweepCount(Scene::Part), static_cast<std::size_t>(passes));

  // Formed elements (the printed circle stretched by 30 %) every half pitch across the plate: each
  // lies whole within one sweep's fan.
  const LaserSight laser = laserSight(d);
  const PlanSight sight = planSight(plan, laser, stereoSight(cell.geometry.cameras, part.line_width), cell.limits.acceleration);
  const double radius = 0.5 * 1.3 * part.circle_diameter;
  int missed = 0, elements = 0;
  for (double x = -width / 2 + radius; x <= width / 2 - radius; x += 0.5 * part.pitch)
    for (double y = -5 + radius; y <= 5 - radius; y += 0.5 * part.pitch) {
      std::vector<Eigen::Vector3d> ring, normals;
      for (int k = 0; k < 16; ++k) {
        const double t = 2 * std::numbers::pi * k / 16;
        ring.emplace_back(x + radius * std::cos(t), y + radius * std::sin(t), 0);
        normals.emplace_back(Eigen::Vector3d::UnitZ());
      }
      bool whole = false;
      for (const SweepSight& sweep : sight.sweeps) whole = whole || laserSees(sweep, laser, ring, normals, nullptr);
      ++elements;
      if (!whole) ++missed;
    }
  EXPECT_EQ(missed, 0) << "of " << elements << " elements";
}

TEST(PartPlanner, APocketDeeperThanTheRangeIsFlownAtSeveralHeights) {
  CellConfig cell = virtualCell();
  cell.geometry.fixture.body.clear();  // the built-in nest's base would cut through so deep a pocket
  const double range = cell.geometry.digitizer.measuring_range_mm;
  // Walls at 60 degrees: the laser sees them (within its incidence limit) at some height.
  const NominalModel model = pocket(240, 160, 1.6 * range, 60);
  PlannerOptions laser_only;
  laser_only.stereo = false;
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits, laser_only);
  const Coverage c = predictCoverage(model, plan, cell.geometry, cell.limits);
  EXPECT_GE(c.share(c.laser_area), 0.99) << c.laser_area << " of " << c.grid_area;
  // More passes than a flat part of the same footprint gets: the pocket's passes come in bands.
  const ScanPlan flat = planPart(plate(240, 240), circles(), cell.geometry, cell.limits, laser_only);
  EXPECT_GT(plan.sweepCount(), flat.sweepCount());
}

TEST(PartPlanner, WallsTooSteepForEitherSensorAreNamedAsUnseen) {
  CellConfig cell = virtualCell();
  // Walls at 85 degrees, a digitizer that returns nothing beyond 70 degrees: beyond its incidence
  // limit even from the fan's edge (12 degrees off the vertical), and beyond the cameras' resolving
  // angle.
  cell.geometry.digitizer.incidence_limit_deg = 70;
  const NominalModel model = pocket(160, 100, 20, 85);
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
  const Coverage c = predictCoverage(model, plan, cell.geometry, cell.limits);
  double walls = 0, unseen = 0, unseen_on_walls = 0;
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    // The flange (z = 0) and the floor (z = -20) are level; every other sample is on a wall.
    const bool on_wall = std::abs(c.points[i][2]) > 1e-9 && std::abs(c.points[i][2] + 20) > 1e-9;
    if (on_wall) walls += c.sample_area[i];
    if (c.laser_passes[i] == 0 && c.stereo[i] == 0) {
      unseen += c.sample_area[i];
      if (on_wall) unseen_on_walls += c.sample_area[i];
    }
  }
  ASSERT_GT(walls, 0);
  EXPECT_GT(unseen_on_walls, 0.9 * walls);  // the walls are not claimed as seen
  EXPECT_LT(unseen - unseen_on_walls, 0.01 * c.grid_area);  // and the rest is
}

// A low roof over part of a plate: deep under it, the plate is seen by no sensor above (a line of
// sight out from under it would be more than 60 degrees from the plate's normal, where the cameras
// cannot resolve the grid and the laser's fan never reaches), and the prediction says so because it
// casts each line of sight against the model.
TEST(PartPlanner, WhatThePartHidesFromItselfIsNotPredictedSeen) {
  const CellConfig cell = virtualCell();
  NominalModel model = plate(120, 80);
  addQuad(model, {-30, -40, 10}, {30, -40, 10}, {30, 40, 10}, {-30, 40, 10});
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
  const auto under_roof = [](const std::array<double, 3>& p) {
    return p[2] < 1 && std::abs(p[0]) < 10 && std::abs(p[1]) < 25;
  };
  const auto unseen_under_roof = [&](const Coverage& c) {
    double area = 0, roof = 0, roof_seen = 0;
    for (std::size_t i = 0; i < c.points.size(); ++i) {
      const bool seen = c.laser_passes[i] > 0 || c.stereo[i] != 0;
      if (under_roof(c.points[i]) && !seen) area += c.sample_area[i];
      if (c.points[i][2] > 9) {
        roof += c.sample_area[i];
        if (seen) roof_seen += c.sample_area[i];
      }
    }
    EXPECT_GE(roof_seen, 0.99 * roof);
    return area;
  };
  const Coverage with = predictCoverage(model, plan, cell.geometry, cell.limits);
  EXPECT_GE(unseen_under_roof(with), 0.98 * 20 * 50);
  CoverageOptions no_occlusion;
  no_occlusion.occlusion = false;
  EXPECT_LT(unseen_under_roof(predictCoverage(model, plan, cell.geometry, cell.limits, no_occlusion)), 0.02 * 20 * 50);
}

// The fixture's solids stand in the sensors' lines of sight as the part does: a clamp bar across a
// plate, 30 mm above it, hides the strip under it from the laser (whose fan reaches a point straight
// from above, across the bar); the cameras, looking from aside, may still see under it.
TEST(PartPlanner, WhatTheFixtureHidesIsNotPredictedSeen) {
  CellConfig cell = virtualCell();
  cell.geometry.fixture.body.clear();
  const NominalModel model = plate(120, 80);
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
  const Coverage open = predictCoverage(model, plan, cell.geometry, cell.limits);
  EXPECT_GE(open.share(open.laser_area), 0.995);
  BodySolid clamp;
  clamp.name = "clamp bar";
  clamp.shape = BodySolid::Shape::Box;
  clamp.placement.position_mm = {0, 0, 30};
  clamp.size_mm = {200, 12, 6};
  cell.geometry.fixture.body.push_back(clamp);
  const Coverage clamped = predictCoverage(model, plan, cell.geometry, cell.limits);
  // At least the bar's own footprint (12 of 80 mm) is lost to the laser, and nothing far from it.
  EXPECT_LT(clamped.share(clamped.laser_area), open.share(open.laser_area) - 12.0 / 80.0 + 0.01);
  int under = 0;
  for (std::size_t i = 0; i < clamped.points.size(); ++i) {
    const auto& p = clamped.points[i];
    if (std::abs(p[1]) < 5.5) {
      ++under;
      EXPECT_EQ(clamped.laser_passes[i], 0) << p[0] << ", " << p[1];
    }
    if (std::abs(p[1]) > 35) {
      EXPECT_GT(clamped.laser_passes[i], 0) << p[0] << ", " << p[1];
    }
  }
  EXPECT_GT(under, 0);
}

TEST(PartPlanner, AnIndexingHeadGetsOnlyItsStops) {
  const CellConfig cell = loadCellConfig(fs::path(STAMPSCAN_CELLS_DIR) / "virtual-indexing.toml");
  ASSERT_GT(cell.limits.index_step, 0);
  const NominalModel model = pocket(160, 100, 20, 45);
  const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
  const auto on_stop = [&](double angle) {
    const double k = angle / cell.limits.index_step;
    return std::abs(k - std::round(k)) < 1e-9;
  };
  for (const PlanStep& step : plan.steps) {
    if (const auto* s = std::get_if<SweepStep>(&step)) {
      EXPECT_TRUE(on_stop(s->start.a) && on_stop(s->start.b) && on_stop(s->end.a) && on_stop(s->end.b));
    } else {
      const auto& v = std::get<StereoStep>(step);
      EXPECT_TRUE(on_stop(v.pose.a) && on_stop(v.pose.b));
    }
  }
  const Coverage c = predictCoverage(model, plan, cell.geometry, cell.limits);
  EXPECT_GE(c.share(c.either_area), 0.99);
}

// The sweeps lay the digitizer's profiles as densely on every cell: a digitizer drawn slower or
// faster than the default one is swept slower or faster, not at one fixed speed.
TEST(PartPlanner, TheSweepSpeedFollowsTheDigitizersProfileRate) {
  const NominalModel model = plate(60, 40);
  const PlannerOptions defaults;
  for (const double rate : {200.0, 500.0, 1000.0, 4000.0}) {
    CellConfig cell = virtualCell();
    cell.geometry.digitizer.profile_rate_hz = rate;
    const double expected = std::min(defaults.profile_spacing_mm * rate, cell.limits.max_speed);
    const ScanPlan plan = planPart(model, circles(), cell.geometry, cell.limits);
    ASSERT_GT(plan.sweepCount(Scene::Part), 0u);
    for (const PlanStep& step : plan.steps)
      if (const auto* s = std::get_if<SweepStep>(&step)) {
        EXPECT_DOUBLE_EQ(s->speed, expected) << rate << " Hz";
        // The profiles along the sweep as far apart as asked (the machine's top speed permitting).
        if (expected < cell.limits.max_speed) {
          EXPECT_NEAR(s->speed / rate, defaults.profile_spacing_mm, 1e-12);
        }
      }
  }
  // A speed asked for is taken as it is.
  CellConfig cell = virtualCell();
  PlannerOptions fixed;
  fixed.sweep_speed = 12;
  for (const PlanStep& step : planPart(model, circles(), cell.geometry, cell.limits, fixed).steps)
    if (const auto* s = std::get_if<SweepStep>(&step)) {
      EXPECT_DOUBLE_EQ(s->speed, 12);
    }
  PlannerOptions bad;
  bad.profile_spacing_mm = 0;
  EXPECT_THROW(planPart(model, circles(), cell.geometry, cell.limits, bad), std::invalid_argument);
}

TEST(PartPlanner, AModelWithNothingFacingTheSensorsIsRefusedNamingIt) {
  const CellConfig cell = virtualCell();
  NominalModel upside_down = plate(50, 50);
  for (auto& t : upside_down.triangles) std::swap(t[1], t[2]);
  upside_down.source = "parts/bracket/model.stl";
  try {
    (void)planPart(upside_down, circles(), cell.geometry, cell.limits);
    FAIL() << "planned a model with no grid area";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("parts/bracket/model.stl"), std::string::npos) << e.what();
  }
  PlannerOptions bad;
  bad.strip_overlap = 0.95;
  EXPECT_THROW((void)planPart(plate(50, 50), circles(), cell.geometry, cell.limits, bad), std::invalid_argument);
}

// The head's body along the plan (FCL): clear of a plate, named where it would dive into a pocket
// narrower than itself or where a hand-made sweep runs through the part.
TEST(PlanCollisions, TheHeadsBodyIsCheckedAlongEverySweepAndMove) {
  CellConfig cell = virtualCell();
  cell.geometry.fixture.body.clear();  // the built-in nest's base would cut through the deep pocket below
  ASSERT_FALSE(cell.geometry.head.body.empty());
  const NominalModel flat = plate(120, 80);
  const ScanPlan over_plate = planPart(flat, circles(), cell.geometry, cell.limits);
  EXPECT_TRUE(checkCollisions(flat, over_plate, cell.geometry.head).empty());

  // A pocket 160 mm deep: its lowest passes bring the sensor carrier (170 mm wide) below the
  // flange, into a 160 mm opening: reported, and only those.
  const NominalModel deep = pocket(300, 160, 160, 75);
  PlannerOptions laser_only;
  laser_only.stereo = false;
  laser_only.leave_out_colliding_sweeps = false;  // as laid, to see the check find them
  const ScanPlan into_pocket = planPart(deep, circles(), cell.geometry, cell.limits, laser_only);
  const std::vector<PlanCollision> hits = checkCollisions(deep, into_pocket, cell.geometry.head);
  ASSERT_FALSE(hits.empty());
  double top = -1e9;  // the highest passes' head height: the flange's band, clear of everything
  for (const PlanStep& step : into_pocket.steps) top = std::max(top, std::get<SweepStep>(step).start.position[2]);
  bool low_sweep_hit = false;
  for (const PlanCollision& c : hits) {
    EXPECT_LT(c.clearance_mm, 5.0);
    EXPECT_FALSE(c.solid.empty());
    if (!c.during_move) {
      EXPECT_LT(c.head_mm[2], top - 10) << describe(c, into_pocket, 5);
      low_sweep_hit = true;
    }
  }
  EXPECT_TRUE(low_sweep_hit);
  // As the planner gives it, those sweeps are left out: none of its sweeps comes too near, and the
  // pocket's floor they would have scanned is predicted unseen.
  laser_only.leave_out_colliding_sweeps = true;
  const ScanPlan clear = planPart(deep, circles(), cell.geometry, cell.limits, laser_only);
  EXPECT_LT(clear.sweepCount(), into_pocket.sweepCount());
  for (const PlanCollision& c : checkCollisions(deep, clear, cell.geometry.head)) {
    EXPECT_TRUE(c.during_move) << describe(c, clear, 5);
  }
  const Coverage all = predictCoverage(deep, into_pocket, cell.geometry, cell.limits);
  const Coverage planned = predictCoverage(deep, clear, cell.geometry, cell.limits);
  EXPECT_LT(planned.laser_area, all.laser_area);
  EXPECT_GT(planned.laser_area, 0.3 * all.laser_area);  // the flange and the walls' upper bands stay

  // A sweep through the plate itself: the step, the solid and a clearance of 0.
  ScanPlan through;
  through.park = {{0, 0, 400}, 0, 0};
  SweepStep s;
  s.start = {{-50, 0, 200}, 0, 0};  // the carrier's bottom 130 mm below the head: 70 mm above the plate
  s.end = {{-50, 0, 120}, 0, 0};    // ... and then 10 mm into it
  through.steps.emplace_back(s);
  CollisionOptions options;
  options.from_park = false;
  const std::vector<PlanCollision> through_hits = checkCollisions(flat, through, cell.geometry.head, options);
  ASSERT_EQ(through_hits.size(), 1u);
  EXPECT_EQ(through_hits[0].step, 0u);
  EXPECT_FALSE(through_hits[0].during_move);
  EXPECT_EQ(through_hits[0].clearance_mm, 0.0);
  const std::string text = describe(through_hits[0], through, 5);
  EXPECT_NE(text.find("step 1 (sweep part 0)"), std::string::npos) << text;

  HeadDescription bodiless = cell.geometry.head;
  bodiless.body.clear();
  EXPECT_TRUE(checkCollisions(flat, through, bodiless, options).empty());
}

// The fixture's solids stand in the head's way too: the cell file's nest is clear of a plan over a
// plate; a clamp standing up into the passes is named, with the pass; carried with the datum, the
// same clamp is checked where the fixture puts it.
TEST(PlanCollisions, TheFixturesSolidsAreCheckedWhereTheFixtureHoldsThem) {
  const CellConfig cell = virtualCell();
  ASSERT_FALSE(cell.geometry.fixture.body.empty());
  const NominalModel flat = plate(120, 80);
  const ScanPlan plan = planPart(flat, circles(), cell.geometry, cell.limits);
  EXPECT_TRUE(checkCollisions(flat, cell.geometry.fixture.body, trace::RigidPose{}, plan, cell.geometry.head).empty());

  BodySolid clamp;
  clamp.name = "clamp 1";
  clamp.shape = BodySolid::Shape::Box;
  clamp.placement.position_mm = {0, 0, 60};  // 20 x 20 mm, standing 120 mm tall in the plate's middle
  clamp.size_mm = {20, 20, 120};
  const std::vector<PlanCollision> hits = checkCollisions(flat, {clamp}, trace::RigidPose{}, plan, cell.geometry.head);
  ASSERT_FALSE(hits.empty());
  for (const PlanCollision& c : hits) EXPECT_EQ(c.obstacle, "the fixture's clamp 1") << describe(c, plan, 5);
  EXPECT_NE(describe(hits[0], plan, 5).find("of the fixture's clamp 1"), std::string::npos) << describe(hits[0], plan, 5);
  // The same clamp, the plan and the plate placed 400 mm along x: the clamp goes with the datum.
  CellGeometry moved = cell.geometry;
  moved.fixture.datum.position_mm = {400, 0, 0};
  const ScanPlan placed = placeOnFixture(plan, moved, cell.limits.index_step);
  EXPECT_FALSE(checkCollisions(placeOnFixture(flat, moved), {clamp}, toRigidPose(moved.fixture.datum), placed,
                               cell.geometry.head).empty());
  // Left in the machine frame's origin while the part moved away, it is no longer in the way.
  EXPECT_TRUE(checkCollisions(placeOnFixture(flat, moved), {clamp}, trace::RigidPose{}, placed, cell.geometry.head).empty());
}

// The simulator's whole parts, as their programs describe them, at their own size and at other
// scales and depths: the generated plan sees as much of the grid area as the hand-made one, in about
// as much motion or less, keeps to the machine and clear of the part.
TEST(PartPlanner, TheSimulatedPartsAreCoveredAsWellAsByTheirHandMadePlansInLessTime) {
  const CellConfig cell = virtualCell();
  const fs::path dir = fs::temp_directory_path() / ("stampscan_planner_" + std::to_string(::getpid()));
  struct Case {
    sim::PartKind kind;
    SimulationParameters simulation;
  };
  const Case cases[] = {{sim::PartKind::Dome, {}},
                        {sim::PartKind::Pan, {}},
                        {sim::PartKind::Dome, {0.7, 20, 0}},
                        {sim::PartKind::Pan, {0.7, 20, 0}},
                        {sim::PartKind::Pan, {1.2, 45, 0}}};
  int n = 0;
  for (const Case& c : cases) {
    const fs::path folder = dir / std::to_string(n++);
    sim::SimulatedProgramOptions options;
    options.simulation = c.simulation;
    sim::writeSimulatedProgram(c.kind, sim::GridKind::Circle, folder, options);
    const PartProgram program = loadPartProgram(folder);
    SCOPED_TRACE(program.description);
    const ScanPlan plan = planPart(program.model, program.plan.part, cell.geometry, cell.limits);
    const Coverage generated = predictCoverage(program.model, plan, cell.geometry, cell.limits);
    // The simulator's hand-laid plan of the same part.
    sim::ScanParams world = sim::worldForProgram(sim::ScanParams{}, program);
    world.calibration = false;
    const ScanPlan hand_plan = sim::planScan(world);
    const Coverage hand = predictCoverage(program.model, hand_plan, cell.geometry, cell.limits);
    EXPECT_GE(generated.share(generated.either_area), std::min(0.995, hand.share(hand.either_area) - 0.002));
    EXPECT_GE(generated.share(generated.laser_area), std::min(0.995, hand.share(hand.laser_area) - 0.002));
    const ScanPlan placed = placeOnFixture(plan, cell.geometry, cell.limits.index_step);
    EXPECT_TRUE(checkPlan(placed, cell.limits).empty());
    // The generated plans take 78 % (the dome) to 90 % (the pan) of the hand-laid ones' motion at the
    // parts' own size, about 89 % at scale 0.7, and as much for the 45 mm deep pan at scale 1.2.
    EXPECT_LE(motionSeconds(placed, cell.limits),
              1.03 * motionSeconds(placeOnFixture(hand_plan, cell.geometry, cell.limits.index_step), cell.limits));
    for (const PlanCollision& collision : checkCollisions(program.model, plan, cell.geometry.head))
      ADD_FAILURE() << describe(collision, plan, 5);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stampscan::acquisition
