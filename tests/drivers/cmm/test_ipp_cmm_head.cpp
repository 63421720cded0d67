// The CMM driver with the articulating probe head of the virtual CMM: GoTo with angles, pose(), move
// reports with the head's angles, angles the head cannot take (out of range, off an indexing head's
// grid), and axes that a GoTo does not name.
#include "ipp_test_support.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <numbers>

namespace stampscan::drivers::cmm {
namespace {

using namespace std::chrono_literals;

constexpr double kRad = std::numbers::pi / 180;  // one degree
// The wire carries degrees (§6.1.2): radians -> degrees -> radians may cost an ulp or two.
constexpr double kAngleTolerance = 1e-12;

using test::ReportLog;

void expectOrientation(const ToolOrientation& actual, const ToolOrientation& expected, const std::string& what) {
  EXPECT_NEAR(actual.a, expected.a, kAngleTolerance) << what;
  EXPECT_NEAR(actual.b, expected.b, kAngleTolerance) << what;
  EXPECT_NEAR(actual.c, expected.c, kAngleTolerance) << what;
}

class CmmHead : public ::testing::Test {
 protected:
  void start(sim::VirtualCmmConfig config = test::quickCmmConfig(), IppCmmOptions options = {}) {
    server_ = std::make_unique<sim::VirtualCmm>(std::move(config));
    server_->start();
    options.port = server_->port();
    options.reply_timeout = 2000ms;
    options.motion_timeout = 10000ms;
    options.device_time_in_reports = true;
    cmm_ = std::make_unique<IppCmm>(options);
    cmm_->connect();
    ASSERT_EQ(cmm_->home(), MoveOutcome::Reached);
  }

  // Runs `call`, expects it to throw IppError, and returns that error.
  template <typename Call>
  IppError expectIppError(Call call) {
    try {
      call();
    } catch (const IppError& e) {
      return e;
    }
    ADD_FAILURE() << "no IppError";
    return IppError(cmm_->name(), {}, {});
  }

  std::unique_ptr<sim::VirtualCmm> server_;
  std::unique_ptr<IppCmm> cmm_;  // destroyed before the server
};

TEST_F(CmmHead, GoToWithAnglesReachesThemAndGetReturnsThem) {
  start();
  const CmmPose before = cmm_->pose();
  expectOrientation(before.orientation, {}, "the head starts at 0, 0");

  const CmmPosition target{10, -20, 400};
  const ToolOrientation turned = ToolOrientation::fromDegrees(2, -30);  // the virtual cell's small tilts
  EXPECT_NEAR(turned.a, 2 * kRad, 1e-15);
  EXPECT_EQ(cmm_->goTo(target, turned), MoveOutcome::Reached);

  const CmmPose after = cmm_->pose();
  EXPECT_EQ(after.position.x, target.x);
  EXPECT_EQ(after.position.y, target.y);
  EXPECT_EQ(after.position.z, target.z);
  expectOrientation(after.orientation, turned, "pose() after the move");
  EXPECT_NEAR(after.orientation.aDegrees(), 2, 1e-12);
  EXPECT_NEAR(after.orientation.bDegrees(), -30, 1e-12);

  // The server's own view, in radians, for a simulated world to render from.
  const sim::VirtualCmmStatus status = server_->status();
  EXPECT_NEAR(status.head_a, turned.a, kAngleTolerance);
  EXPECT_NEAR(status.head_b, turned.b, kAngleTolerance);
  EXPECT_EQ(status.head_c, 0);
  EXPECT_EQ(status.position[2], target.z);

  // Back to level: negative and zero angles go over the wire as well.
  EXPECT_EQ(cmm_->goTo(target, ToolOrientation{}), MoveOutcome::Reached);
  expectOrientation(cmm_->pose().orientation, {}, "level again");
}

TEST_F(CmmHead, AnAxisNotNamedKeepsItsValue) {
  start();
  const ToolOrientation turned = ToolOrientation::fromDegrees(30, 45);
  ASSERT_EQ(cmm_->goTo({0, 0, 450}, turned), MoveOutcome::Reached);

  // §6.3.2.12: a GoTo of X, Y, Z alone leaves Tool.A and Tool.B as they were, during the move too.
  ReportLog log;
  cmm_->startMoveReports(0.1, log.callback(), MoveReportContent::PositionAndOrientation);
  const CmmPosition target{150, -100, 300};
  ASSERT_EQ(cmm_->goTo(target), MoveOutcome::Reached);
  const CmmPose after = cmm_->pose();
  EXPECT_EQ(after.position.x, target.x);
  EXPECT_EQ(after.position.z, target.z);
  expectOrientation(after.orientation, turned, "after an X, Y, Z move");

  const std::vector<MoveReport> reports = log.reports();
  ASSERT_GE(reports.size(), 3u);
  for (const MoveReport& r : reports) {
    ASSERT_TRUE(r.orientation.has_value());
    expectOrientation(*r.orientation, turned, "during an X, Y, Z move");
  }
  EXPECT_GT(std::abs(reports[reports.size() / 2].position.x - target.x), 1) << "the reports span the move";
}

TEST_F(CmmHead, MoveReportsShowTheAnglesProgressingWithThePosition) {
  start();
  ReportLog log;
  cmm_->startMoveReports(0.1, log.callback(), MoveReportContent::PositionAndOrientation);
  const CmmPosition from = cmm_->position();
  const CmmPosition target{100, 50, 300};
  const ToolOrientation turned = ToolOrientation::fromDegrees(60, -90);
  const auto began = std::chrono::steady_clock::now();
  ASSERT_EQ(cmm_->goTo(target, turned), MoveOutcome::Reached);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
  // 229 mm would take the ram 0.58 s; turning B by 90 degrees at the head's rate limits
  // (quickCmmConfig: 180 deg/s, 720 deg/s^2) takes 0.75 s, and the whole move is as slow as its
  // slowest axis.
  const sim::VirtualCmmConfig& k = server_->config();
  EXPECT_GE(took, test::trapezoidSeconds(90, k.head_max_rate_deg_s, k.head_accel_deg_s2) - 0.01);

  const std::vector<MoveReport> reports = log.reportsEndingWith([&](const MoveReport& r) {
    return r.orientation && std::abs(r.orientation->b - turned.b) <= kAngleTolerance;
  });
  ASSERT_GE(reports.size(), 8u);
  // The first report as the move starts (a moment after: the head has barely begun to turn).
  EXPECT_LT(std::abs(reports.front().orientation->a), 1e-3 * turned.a);
  EXPECT_LT(std::abs(reports.front().orientation->b), 1e-3 * std::abs(turned.b));
  expectOrientation(*reports.back().orientation, turned, "the last report, at the target");
  const double dz = target.z - from.z;
  std::size_t between = 0;
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const MoveReport& r = reports[i];
    ASSERT_TRUE(r.orientation.has_value()) << i;
    if (i > 0) {
      // Monotone: A rises towards 60, B falls towards -90, never back.
      EXPECT_GE(r.orientation->a, reports[i - 1].orientation->a) << i;
      EXPECT_LE(r.orientation->b, reports[i - 1].orientation->b) << i;
    }
    // One progress for all axes (§6.3.2.12): the ram and each angle are the same fraction along.
    const double progress = (r.position.z - from.z) / dz;
    EXPECT_NEAR(r.orientation->a / turned.a, progress, 1e-9) << i;
    EXPECT_NEAR(r.orientation->b / turned.b, progress, 1e-9) << i;
    EXPECT_NEAR(r.position.x, from.x + progress * (target.x - from.x), 1e-9) << i;
    if (progress > 0.05 && progress < 0.95) ++between;
  }
  EXPECT_GE(between, 4u) << "reports from inside the move, not only its ends";

  // Without PositionAndOrientation the reports carry no angles.
  ReportLog plain;
  cmm_->startMoveReports(0.1, plain.callback());
  ASSERT_EQ(cmm_->goTo(from, ToolOrientation{}), MoveOutcome::Reached);
  ASSERT_FALSE(plain.reports().empty());
  EXPECT_FALSE(plain.reports().front().orientation.has_value());
}

TEST_F(CmmHead, AnAngleOutOfRangeIsRefusedWith2505AndNothingMoves) {
  start();
  const CmmPose before = cmm_->pose();
  const IppError e = expectIppError([&] { cmm_->goTo({50, 50, 400}, ToolOrientation::fromDegrees(120, 0)); });
  EXPECT_EQ(e.report().number, ipp::error::kAngleOutOfRange);
  EXPECT_EQ(e.report().severity, 2);  // the class of §8.2
  EXPECT_EQ(e.report().method, "GoTo");
  EXPECT_EQ(e.report().text, "Specified angle out of range");
  EXPECT_NE(e.info().find("outside the head's range [-115, 115]"), std::string::npos) << e.info();

  const CmmPose after = cmm_->pose();
  EXPECT_EQ(after.position.z, before.position.z) << "no axis moves when one angle is refused";
  expectOrientation(after.orientation, before.orientation, "no axis moves");
  EXPECT_EQ(server_->status().moves_completed, 1u) << "Home only";

  cmm_->clearAllErrors();
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_FALSE(server_->status().error_state);
  const ToolOrientation limit = ToolOrientation::fromDegrees(-115, 180);  // the range's ends are allowed
  EXPECT_EQ(cmm_->goTo({50, 50, 400}, limit), MoveOutcome::Reached);
  expectOrientation(cmm_->pose().orientation, limit, "usable after ClearAllErrors");

  // B too has its range, and C is fixed on this head: c != 0 does not even leave the driver.
  EXPECT_EQ(expectIppError([&] { cmm_->goTo({0, 0, 400}, ToolOrientation::fromDegrees(0, 181)); }).report().number,
            ipp::error::kAngleOutOfRange);
  EXPECT_THROW(cmm_->goTo({0, 0, 400}, ToolOrientation{0, 0, 0.1}), std::invalid_argument);
  EXPECT_THROW(cmm_->goTo({0, 0, 400}, ToolOrientation{NAN, 0, 0}), std::invalid_argument);
}

TEST_F(CmmHead, AnIndexingHeadRefusesAnAngleOffItsGrid) {
  sim::VirtualCmmConfig config = test::quickCmmConfig();
  config.head_kind = sim::VirtualCmmConfig::HeadKind::Indexing;
  config.head_index_step_deg = 7.5;
  start(config);

  const ToolOrientation indexed = ToolOrientation::fromDegrees(15, -37.5);
  ASSERT_EQ(cmm_->goTo({0, 0, 400}, indexed), MoveOutcome::Reached);
  const CmmPose on_grid = cmm_->pose();
  EXPECT_NEAR(on_grid.orientation.aDegrees(), 15, 1e-12);
  EXPECT_NEAR(on_grid.orientation.bDegrees(), -37.5, 1e-12);

  const IppError e = expectIppError([&] { cmm_->goTo({0, 0, 350}, ToolOrientation::fromDegrees(2, -37.5)); });
  EXPECT_EQ(e.report().number, ipp::error::kAngleOutOfRange);
  EXPECT_EQ(e.report().severity, 2);
  EXPECT_NE(e.info().find("not an index position"), std::string::npos) << e.info();
  const CmmPose after = cmm_->pose();
  EXPECT_EQ(after.position.z, 400) << "nothing moves";
  expectOrientation(after.orientation, indexed, "nothing moves");

  cmm_->clearAllErrors();
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  const ToolOrientation next = ToolOrientation::fromDegrees(22.5, 90);
  EXPECT_EQ(cmm_->goTo({0, 0, 350}, next), MoveOutcome::Reached);
  expectOrientation(cmm_->pose().orientation, next, "usable after ClearAllErrors");
}

TEST_F(CmmHead, AThreeAxisHeadTurnsC) {
  sim::VirtualCmmConfig config = test::quickCmmConfig();
  config.head_min_deg[2] = -90;
  config.head_max_deg[2] = 90;
  IppCmmOptions options;
  options.head_has_c = true;
  start(config, options);

  const ToolOrientation turned = ToolOrientation::fromDegrees(10, 20, -45);
  ASSERT_EQ(cmm_->goTo({0, 0, 400}, turned), MoveOutcome::Reached);
  expectOrientation(cmm_->pose().orientation, turned, "with Tool.C");
  EXPECT_NEAR(server_->status().head_c, -45 * kRad, kAngleTolerance);
  EXPECT_EQ(expectIppError([&] { cmm_->goTo({0, 0, 400}, ToolOrientation::fromDegrees(0, 0, 95)); }).report().number,
            ipp::error::kAngleOutOfRange);
}

}  // namespace
}  // namespace stampscan::drivers::cmm
