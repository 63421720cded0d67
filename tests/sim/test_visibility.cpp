// Which grid elements a plan can see, from the simulator's truth (sim/visibility.hpp): the
// yardstick of the share of visible elements a scan finds.
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/visibility.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <variant>

namespace {

using namespace stampscan;

struct Counts {
  std::size_t inside = 0, inside_laser = 0, outside = 0, outside_seen = 0;
};

// Elements well inside the scan region (machine xy) and well outside it.
Counts countAround(const sim::ScanParams& p, const fitting::Cloud& truth, const sim::ElementVisibility& v,
                   const std::vector<std::uint8_t>& seen) {
  Counts c;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const auto& x = truth.positions[i];
    const bool inside = x.x() > p.scan_region.min.x() + 5 && x.x() < p.scan_region.max.x() - 5 &&
                        x.y() > p.scan_region.min.y() + 8 && x.y() < p.scan_region.max.y() - 8;
    const bool outside = std::abs(x.x()) > 60 || std::abs(x.y()) > 50;
    if (inside) {
      ++c.inside;
      c.inside_laser += v.laser[i];
    }
    if (outside) {
      ++c.outside;
      c.outside_seen += seen[i];
    }
  }
  return c;
}

TEST(Visibility, TheLaserSeesTheElementsUnderItsSweepsAndNoneFarAway) {
  sim::ScanParams p = sim::ScanParams::quick();  // a 40 x 30 mm region of the dome
  p.stereo = false;
  const acquisition::ScanPlan plan = sim::planScan(p);
  const fitting::Cloud truth = sim::groundTruth(*sim::makePart(p), p.grid);
  const sim::ElementVisibility v = sim::visibleElements(p, plan, truth);
  ASSERT_EQ(v.laser.size(), truth.size());
  const Counts c = countAround(p, truth, v, v.visibleOr());
  EXPECT_GT(c.inside, 50u);
  EXPECT_GT(c.outside, 500u);
  EXPECT_EQ(c.outside_seen, 0u);
  for (std::size_t i = 0; i < truth.size(); ++i) EXPECT_EQ(v.stereo[i], 0) << "no views in the plan";
  // The dome's top is flat enough, within range, with nothing in between: the laser sees all of it
  // but a polished spot, where the sweeps from straight above meet it near normal incidence and the
  // glare saturates the digitizer's camera. Without glare it sees everything there.
  sim::ScanParams matt = p;
  matt.digitizer.glare_incidence = 0;
  const sim::ElementVisibility without_glare = sim::visibleElements(matt, plan, truth);
  const Counts all = countAround(matt, truth, without_glare, without_glare.visibleOr());
  EXPECT_EQ(all.inside_laser, all.inside);
  EXPECT_LT(c.inside_laser, c.inside);  // this seed's region holds a polished spot
  for (std::size_t i = 0; i < truth.size(); ++i) EXPECT_LE(v.laser[i], without_glare.laser[i]);
}

// The pan's walls, seen from straight above: lit where the digitizer loses more than a few per cent
// of its points at random (well beyond DigitizerSpec::steep_from), their rings come back with too
// many holes to be measured; a
// camera that sees them obliquely sees their lines foreshortened, too thin to locate.
TEST(Visibility, SteepWallsAreNotSeenWholeWhereTheSensorsLoseThem) {
  sim::ScanParams p;
  p.part = sim::PartKind::Pan;
  p.calibration = false;
  const acquisition::ScanPlan plan = sim::planScan(p);
  const fitting::Cloud truth = sim::groundTruth(*sim::makePart(p), p.grid);
  const sim::ElementVisibility v = sim::visibleElements(p, plan, truth);
  sim::ScanParams no_dropouts = p;
  no_dropouts.digitizer.steep_from = no_dropouts.digitizer.max_incidence;
  const sim::ElementVisibility lenient = sim::visibleElements(no_dropouts, plan, truth);
  std::size_t walls_lost = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_LE(v.laser[i], lenient.laser[i]);
    if (lenient.laser[i] && !v.laser[i]) {
      ++walls_lost;
      // Only where the wall is steeper than the sensor loses what the search measures without.
      EXPECT_GT(std::acos(truth.normals[i].z()), p.digitizer.incidenceLosing(sim::VisibilityParams{}.laser_loss_measured) - 0.2) << "element " << i;
    }
  }
  EXPECT_GT(walls_lost, 20u);  // 36 on this plan
  // A camera of half the focal length sees every line half as wide: the oblique walls drop out first.
  sim::ScanParams short_lens = p;
  short_lens.camera.fx *= 0.5;
  short_lens.camera.fy *= 0.5;
  const sim::ElementVisibility coarse = sim::visibleElements(short_lens, plan, truth);
  std::size_t flat_kept = 0, flat = 0, oblique_kept = 0, oblique = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!v.stereo[i]) continue;
    const bool steep = truth.normals[i].z() < 0.7;
    (steep ? oblique : flat) += 1;
    (steep ? oblique_kept : flat_kept) += coarse.stereo[i];
  }
  ASSERT_GT(oblique, 0u);
  EXPECT_LT(static_cast<double>(oblique_kept) / static_cast<double>(oblique), static_cast<double>(flat_kept) / static_cast<double>(flat));
}

TEST(Visibility, ASweepMeasuresNothingInItsRunUps) {
  // The same sweeps, each shortened at both ends by its run-up: what the shorter sweeps' middles
  // cannot reach, the longer ones' run-ups do not count either.
  sim::ScanParams p = sim::ScanParams::quick();
  p.stereo = false;
  p.digitizer.glare_incidence = 0;
  const acquisition::ScanPlan plan = sim::planScan(p);
  const fitting::Cloud truth = sim::groundTruth(*sim::makePart(p), p.grid);
  sim::VisibilityParams trusted_everywhere;
  trusted_everywhere.report_interval_s = 0;
  trusted_everywhere.acceleration = std::numeric_limits<double>::infinity();  // no run-up at all
  const sim::ElementVisibility whole = sim::visibleElements(p, plan, truth, trusted_everywhere);
  const sim::ElementVisibility measured = sim::visibleElements(p, plan, truth);
  EXPECT_LT(measured.visibleCount(), whole.visibleCount());
  acquisition::ScanPlan shortened = plan;
  for (auto& step : shortened.steps)
    if (auto* sweep = std::get_if<acquisition::SweepStep>(&step); sweep && sweep->scene == acquisition::Scene::Part) {
      Eigen::Vector3d a(sweep->start.position[0], sweep->start.position[1], sweep->start.position[2]);
      Eigen::Vector3d b(sweep->end.position[0], sweep->end.position[1], sweep->end.position[2]);
      const double run_up = acquisition::sweepRunUp(sweep->speed, acquisition::MachineLimits{}.acceleration);
      const Eigen::Vector3d along = (b - a).normalized() * run_up;
      for (int k = 0; k < 3; ++k) {
        sweep->start.position[static_cast<std::size_t>(k)] = (a + along)(k);
        sweep->end.position[static_cast<std::size_t>(k)] = (b - along)(k);
      }
    }
  const sim::ElementVisibility middles = sim::visibleElements(p, shortened, truth, trusted_everywhere);
  EXPECT_EQ(measured.visibleCount(), middles.visibleCount());
}

TEST(Visibility, NothingIsVisibleToAPlanWithoutPartStepsOrOutOfTheDigitizersRange) {
  sim::ScanParams p = sim::ScanParams::quick();
  const fitting::Cloud truth = sim::groundTruth(*sim::makePart(p), p.grid);
  acquisition::ScanPlan plan = sim::planScan(p);
  std::erase_if(plan.steps, [](const acquisition::PlanStep& s) {
    return std::visit([](const auto& step) { return step.scene == acquisition::Scene::Part; }, s);
  });
  EXPECT_EQ(sim::visibleElements(p, plan, truth).visibleCount(), 0u);
  // The same sweeps 200 mm higher: the part is beyond the measuring range.
  plan = sim::planScan(p);
  std::erase_if(plan.steps, [](const acquisition::PlanStep& s) { return std::holds_alternative<acquisition::StereoStep>(s); });
  for (auto& s : plan.steps)
    if (auto* sweep = std::get_if<acquisition::SweepStep>(&s)) {
      sweep->start.position[2] += 200;
      sweep->end.position[2] += 200;
    }
  EXPECT_EQ(sim::visibleElements(p, plan, truth).visibleCount(), 0u);
}

TEST(Visibility, TheStereoPairSeesTheElementsInBothImages) {
  sim::ScanParams p = sim::ScanParams::quick();
  p.laser = false;
  p.image_scale = 1.0;  // the quick session's quarter-resolution images resolve no printed line (below)
  const acquisition::ScanPlan plan = sim::planScan(p);
  const fitting::Cloud truth = sim::groundTruth(*sim::makePart(p), p.grid);
  const sim::ElementVisibility v = sim::visibleElements(p, plan, truth);
  std::size_t stereo = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_EQ(v.laser[i], 0);
    stereo += v.stereo[i];
  }
  // Two views 300 mm above the middle of the dome see much of it, but not its far corners.
  EXPECT_GT(stereo, 500u);
  EXPECT_LT(stereo, truth.size());

  // At a quarter of the resolution the 0.15 mm lines are under half a pixel wide: nothing is seen.
  p.image_scale = 0.25;
  EXPECT_EQ(sim::visibleElements(p, plan, truth).visibleCount(), 0u);
}

}  // namespace
