// ScanPlan: the plan file reads back what was written, the simulator's plans are sound, and bad plans
// are refused with the file, the line and the field.
#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/acquisition/cell_geometry.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>

#include <cmath>

namespace stampscan::acquisition {
namespace {

void expectSamePose(const HeadPose& a, const HeadPose& b) {
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(a.position[i], b.position[i], 1e-9);
  EXPECT_NEAR(a.a, b.a, 1e-12);
  EXPECT_NEAR(a.b, b.b, 1e-12);
}

TEST(ScanPlan, PlanFileRoundTrip) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.part = sim::PartKind::Dome;
  const ScanPlan plan = sim::planScan(p);
  ASSERT_GT(plan.sweepCount(Scene::Part), 0u);
  ASSERT_GT(plan.sweepCount(Scene::ReferenceSphere), 0u);
  ASSERT_GT(plan.stereoCount(Scene::CalibrationPlate), 0u);
  const ScanPlan back = parseScanPlan(toToml(plan), "round-trip");
  EXPECT_EQ(back.name, plan.name);
  EXPECT_EQ(back.part, plan.part);
  ASSERT_EQ(back.steps.size(), plan.steps.size());
  for (std::size_t k = 0; k < plan.steps.size(); ++k) {
    ASSERT_EQ(back.steps[k].index(), plan.steps[k].index());
    if (const auto* s = std::get_if<SweepStep>(&plan.steps[k])) {
      const auto& t = std::get<SweepStep>(back.steps[k]);
      EXPECT_EQ(t.scene, s->scene);
      EXPECT_EQ(t.index, s->index);
      expectSamePose(t.start, s->start);
      expectSamePose(t.end, s->end);
      EXPECT_DOUBLE_EQ(t.speed, s->speed);
      EXPECT_EQ(t.expected_elements, s->expected_elements);
    } else {
      const auto& v = std::get<StereoStep>(plan.steps[k]);
      const auto& w = std::get<StereoStep>(back.steps[k]);
      EXPECT_EQ(w.scene, v.scene);
      expectSamePose(w.pose, v.pose);
    }
  }
}

TEST(ScanPlan, ASweepsPredictedElementsRoundTripAndAreChecked) {
  ScanPlan plan;
  SweepStep w;
  w.start.position = {0, -40, 160};
  w.end.position = {0, 40, 160};
  w.expected_elements = 137;
  plan.steps.emplace_back(w);
  const std::string text = toToml(plan);
  EXPECT_NE(text.find("expected_elements = 137"), std::string::npos) << text;
  EXPECT_EQ(std::get<SweepStep>(parseScanPlan(text, "plan").steps[0]).expected_elements, 137u);
  // Without a prediction the key is left out, and a bad one names its line.
  plan.steps[0] = SweepStep{};
  EXPECT_EQ(toToml(plan).find("expected_elements"), std::string::npos);
  std::string bad = text;
  bad.replace(bad.find("137"), 3, "-2");
  try {
    parseScanPlan(bad, "bad.toml");
    FAIL() << "a negative prediction was accepted";
  } catch (const PlanError& e) {
    EXPECT_NE(std::string(e.what()).find("expected_elements"), std::string::npos) << e.what();
  }
}

TEST(ScanPlan, SimulatorPlansFitTheMachine) {
  for (const auto part : {sim::PartKind::Dome, sim::PartKind::Pan}) {
    sim::ScanParams p;
    p.part = part;
    const ScanPlan plan = sim::planScan(p);
    const auto problems = checkPlan(plan, MachineLimits{});
    EXPECT_TRUE(problems.empty()) << problems.front();
    EXPECT_GT(motionSeconds(plan, MachineLimits{}), 10.0);
  }
}

// A part plan is written in the part's datum frame; on a fixture elsewhere, the part's steps move
// with the datum so that every sensor sees the part as the plan meant, and the calibration scenes stay.
Eigen::Isometry3d isometryOf(const Placement& p) { return trace::toIsometry(toRigidPose(p)); }
Eigen::Vector3d at(const HeadPose& h) { return {h.position[0], h.position[1], h.position[2]}; }

TEST(ScanPlan, APartPlanMovesWithTheFixtureAndTheCalibrationScenesStay) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.part = sim::PartKind::Dome;
  const ScanPlan plan = sim::planScan(p);
  CellGeometry cell;
  EXPECT_EQ(placeOnFixture(plan, cell, 0), plan);  // the datum at the table's origin
  cell.fixture.datum = {{40, -25, 3}, {0, 0, 30}};
  const ScanPlan placed = placeOnFixture(plan, cell, 0);
  ASSERT_EQ(placed.steps.size(), plan.steps.size());
  const Eigen::Isometry3d machine_from_datum = isometryOf(cell.fixture.datum);
  const Eigen::Isometry3d head_from_digitizer = isometryOf(cell.digitizer.mount);
  std::size_t part_steps = 0;
  for (std::size_t k = 0; k < plan.steps.size(); ++k) {
    const auto poses = [](const PlanStep& s) {
      if (const auto* w = std::get_if<SweepStep>(&s)) return std::vector<HeadPose>{w->start, w->end};
      return std::vector<HeadPose>{std::get<StereoStep>(s).pose};
    };
    const Scene scene = std::visit([](const auto& s) { return s.scene; }, plan.steps[k]);
    const std::vector<HeadPose> before = poses(plan.steps[k]), after = poses(placed.steps[k]);
    for (std::size_t i = 0; i < before.size(); ++i) {
      if (scene != Scene::Part) {
        expectSamePose(after[i], before[i]);
        continue;
      }
      ++part_steps;
      // A turn about z is carried exactly: the digitizer stands where the datum puts it.
      const Eigen::Isometry3d want = machine_from_datum * trace::headPose(at(before[i]), before[i].a, before[i].b) * head_from_digitizer;
      const Eigen::Isometry3d got = trace::headPose(at(after[i]), after[i].a, after[i].b) * head_from_digitizer;
      EXPECT_LT((got.translation() - want.translation()).norm(), 1e-9);
      EXPECT_LT((got.linear() - want.linear()).norm(), 1e-12);
      EXPECT_NEAR(after[i].a, before[i].a, 1e-12);
    }
  }
  EXPECT_GT(part_steps, 0u);
}

TEST(ScanPlan, OnATiltedFixtureTheDigitizerAimsAsPlannedAndAnIndexingHeadKeepsItsAngles) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.part = sim::PartKind::Pan;
  const ScanPlan plan = sim::planScan(p);
  CellGeometry cell;
  cell.fixture.datum = {{-30, 20, 8}, {2, -1.5, -100}};
  const Eigen::Isometry3d machine_from_datum = isometryOf(cell.fixture.datum);
  const Eigen::Isometry3d head_from_digitizer = isometryOf(cell.digitizer.mount);
  const double step = 7.5 * std::numbers::pi / 180;
  for (const double index_step : {0.0, step}) {
    const ScanPlan placed = placeOnFixture(plan, cell, index_step);
    for (std::size_t k = 0; k < plan.steps.size(); ++k) {
      const auto* w = std::get_if<SweepStep>(&plan.steps[k]);
      if (w == nullptr || w->scene != Scene::Part) continue;
      const auto& moved = std::get<SweepStep>(placed.steps[k]);
      const Eigen::Isometry3d want = machine_from_datum * trace::headPose(at(w->start), w->start.a, w->start.b) * head_from_digitizer;
      const Eigen::Isometry3d got = trace::headPose(at(moved.start), moved.start.a, moved.start.b) * head_from_digitizer;
      // The mirror where the datum puts it; the beam and the fan within the tilt (2.5 degrees) of
      // the plan's, and within half a step more of each angle on the indexing head.
      EXPECT_LT((got.translation() - want.translation()).norm(), 1e-9);
      const auto degreesBetween = [](const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
        return std::acos(std::clamp(u.dot(v), -1.0, 1.0)) * 180 / std::numbers::pi;
      };
      const double bound = 2.51 + (index_step > 0 ? 7.5 : 0.0);
      EXPECT_LT(degreesBetween(got.linear().col(2), want.linear().col(2)), bound);
      EXPECT_LT(degreesBetween(got.linear().col(0), want.linear().col(0)), bound);
      EXPECT_EQ(moved.start.a, moved.end.a);
      EXPECT_EQ(moved.start.b, moved.end.b);
      if (index_step > 0) {
        for (const double angle : {moved.start.a, moved.start.b})
          EXPECT_NEAR(std::remainder(angle, step), 0.0, 1e-9) << "an angle the indexing head cannot take: " << angle;
      }
    }
  }
}

// Poses a planner may write: level or tilted either way, turned anywhere, near the turn's limits.
TEST(ScanPlan, EveryHeadPoseTurnsExactlyWithTheDatum) {
  CellGeometry cell;
  cell.fixture.datum = {{-12, 7, 0}, {0, 0, 170}};
  const Eigen::Isometry3d machine_from_datum = isometryOf(cell.fixture.datum);
  for (const double a_deg : {-90.0, -20.0, 0.0, 0.001, 35.0, 105.0})
    for (const double b_deg : {-179.9, -90.0, 0.0, 12.5, 179.9}) {
      ScanPlan plan;
      StereoStep view;
      view.pose = {{10, -20, 300}, a_deg * std::numbers::pi / 180, b_deg * std::numbers::pi / 180};
      plan.steps.emplace_back(view);
      const HeadPose got = std::get<StereoStep>(placeOnFixture(plan, cell, 0).steps[0]).pose;
      const Eigen::Isometry3d want = machine_from_datum * trace::headPose(at(view.pose), view.pose.a, view.pose.b);
      const Eigen::Isometry3d placed = trace::headPose(at(got), got.a, got.b);
      EXPECT_LT((placed.linear() - want.linear()).norm(), 1e-9) << a_deg << ", " << b_deg;
      EXPECT_LT((placed.translation() - want.translation()).norm(), 1e-9) << a_deg << ", " << b_deg;
      EXPECT_NEAR(got.a, view.pose.a, 1e-12);
      EXPECT_LE(std::abs(got.b), std::numbers::pi);
    }
}

TEST(ScanPlan, MotionTimeOfOneSweep) {
  ScanPlan plan;
  plan.park = {{0, 0, 100}, 0, 0};
  plan.travel_speed = 100;
  SweepStep s;
  s.start = {{0, 0, 100}, 0, 0};
  s.end = {{0, 100, 100}, 0, 0};
  s.speed = 25;
  plan.steps.emplace_back(s);
  MachineLimits limits;
  limits.acceleration = 1000;
  // 100 mm at 25 mm/s with 1000 mm/s^2: 4 s + 0.025 s; back 100 mm at 100 mm/s: 1 s + 0.1 s.
  EXPECT_NEAR(motionSeconds(plan, limits), 4.025 + 1.1, 1e-9);
}

// A move that turns the head takes as long as the turn needs: all axes start and finish together.
TEST(ScanPlan, MotionTimeOfAViewThatTurnsTheHead) {
  ScanPlan plan;
  plan.park = {{0, 0, 100}, 0, 0};
  plan.travel_speed = 100;
  StereoStep v;
  v.pose = {{10, 0, 100}, 0, std::numbers::pi / 2};  // 10 mm, and a quarter turn of B
  v.settle_s = 0.5;
  plan.steps.emplace_back(v);
  MachineLimits limits;
  limits.acceleration = 1000;
  limits.head_rate = std::numbers::pi / 2;         // 90 degrees/s
  limits.head_acceleration = 2 * std::numbers::pi;  // 360 degrees/s^2
  // 90 degrees at 90 degrees/s with 360 degrees/s^2: 1 s + 0.25 s each way (the 10 mm alone would
  // take 0.2 s), plus the settling.
  EXPECT_NEAR(motionSeconds(plan, limits), 2 * 1.25 + 0.5, 1e-9);
  // Without a turn, the ram's trapezoid alone: 10 mm at 1000 mm/s^2 is a triangle of 0.2 s.
  limits.head_rate = 1e9;
  limits.head_acceleration = 1e12;
  EXPECT_NEAR(motionSeconds(plan, limits), 2 * 0.2 + 0.5, 1e-6);
}

TEST(ScanPlan, LimitsAreCheckedStepByStep) {
  ScanPlan plan;
  SweepStep s;
  s.start = {{0, 0, 100}, 0.0, 0.0};
  s.end = {{0, 500, 100}, 0.0, 0.0};
  s.speed = 900;
  plan.steps.emplace_back(s);
  StereoStep v;
  v.pose = {{0, 0, 100}, 2.5, 0};
  plan.steps.emplace_back(v);
  const auto problems = checkPlan(plan, MachineLimits{});
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_NE(problems[0].find("step 1 (sweep part 0): end y = 500 mm is outside the travel -300..300"), std::string::npos)
      << problems[0];
  EXPECT_NE(problems[1].find("speed 900 mm/s"), std::string::npos) << problems[1];
  EXPECT_NE(problems[2].find("step 2 (stereo part 0): pose head tilt"), std::string::npos) << problems[2];
}

TEST(ScanPlan, BadFilesNameTheLineAndField) {
  const auto error = [](const std::string& text) {
    try {
      parseScanPlan(text, "plan.toml");
    } catch (const PlanError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error("name = \"x\"\n"), "plan.toml:1: step is missing: a plan needs at least one [[step]]");
  EXPECT_EQ(error("[[step]]\nkind = \"sweep\"\nstart = [0, 0, 1]\nend = [0, 1, 1]\nspeed = \"fast\"\n"),
            "plan.toml:5: step[1].speed must be a number");
  EXPECT_EQ(error("[[step]]\nkind = \"hover\"\n"), "plan.toml:2: step[1].kind must be \"sweep\" or \"stereo\", is \"hover\"");
  EXPECT_EQ(error("[[step]]\nkind = \"stereo\"\npose = [0, 0, 1]\nspeeed = 3\n"), "plan.toml:4: step[1].speeed is not a known field");
  EXPECT_EQ(error("[part]\ngrid = \"hex\"\n[[step]]\nkind = \"stereo\"\npose = [0, 0, 1]\n"),
            "plan.toml:2: part.grid must be \"circle\" or \"square\"");
  EXPECT_NE(error("name = [\n").find("plan.toml:"), std::string::npos);
}

}  // namespace
}  // namespace stampscan::acquisition
