// The CMM driver against the virtual CMM over TCP on loopback: session, homing, moves with position
// reports checked against the trapezoid, speed limits, position queries and tools.
#include "ipp_test_support.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/sim/trapezoid_move.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <mutex>

namespace stampscan::drivers::cmm {
namespace {

using namespace std::chrono_literals;

using test::ReportLog;

double seconds(std::chrono::steady_clock::duration d) { return std::chrono::duration<double>(d).count(); }

double distanceBetween(const CmmPosition& a, const CmmPosition& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
}

class CmmDriver : public ::testing::Test {
 protected:
  void SetUp() override {
    server_.start();
    IppCmmOptions options;
    options.port = server_.port();
    options.reply_timeout = 2000ms;
    options.motion_timeout = 10000ms;
    options.device_time_in_reports = true;
    cmm_ = std::make_unique<IppCmm>(options);
    cmm_->connect();
  }

  sim::VirtualCmm server_{test::quickCmmConfig()};
  std::unique_ptr<IppCmm> cmm_;  // destroyed before the server
};

TEST_F(CmmDriver, ConnectStartsASessionAndIdentifiesTheMachine) {
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  const DeviceIdentity id = cmm_->identity();
  EXPECT_EQ(id.family, "cmm");
  EXPECT_EQ(id.model, "CartCMM");
  EXPECT_EQ(id.firmware, "I++ DME 1.4.3");
  EXPECT_EQ(id.address, "127.0.0.1:" + std::to_string(server_.port()));
  EXPECT_TRUE(server_.status().session_active);
  EXPECT_TRUE(cmm_->check());

  cmm_->disconnect();  // EndSession, then the connection closes
  EXPECT_EQ(cmm_->state(), DeviceState::Disconnected);
  EXPECT_TRUE(test::waitUntil([&] { return !server_.status().connected; }));
  cmm_->connect();  // the server takes the next connection
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_EQ(server_.status().connections_served, 2u);
  EXPECT_TRUE(cmm_->faults().empty());
}

TEST_F(CmmDriver, HomesToTheHomePosition) {
  EXPECT_FALSE(cmm_->isHomed());
  EXPECT_EQ(cmm_->home(), MoveOutcome::Reached);
  EXPECT_TRUE(cmm_->isHomed());
  const CmmPosition p = cmm_->position();
  const auto home = server_.config().home_position;
  EXPECT_EQ(p.x, home[0]);
  EXPECT_EQ(p.y, home[1]);
  EXPECT_EQ(p.z, home[2]);
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
}

TEST_F(CmmDriver, GoToReportsPositionsAlongTheTrapezoid) {
  cmm_->home();
  const CmmPosition start = cmm_->position();
  const CmmPosition target{200, 100, 300};
  const double length = distanceBetween(start, target);  // 300 mm
  const double speed = server_.config().default_speed;
  const double accel = server_.config().default_accel;
  const double expected = test::trapezoidSeconds(length, speed, accel);

  ReportLog log;
  cmm_->startMoveReports(0.1, log.callback());
  const auto began = std::chrono::steady_clock::now();
  EXPECT_EQ(cmm_->goTo(target), MoveOutcome::Reached);
  const double took = seconds(std::chrono::steady_clock::now() - began);
  // The move takes the trapezoid's time: the `%` comes when the machine arrives.
  EXPECT_GE(took, expected - 0.01);
  EXPECT_LE(took, expected + 0.25);

  const std::vector<MoveReport> reports =
      log.reportsEndingWith([&](const MoveReport& r) { return distanceBetween(r.position, target) == 0; });
  ASSERT_GE(reports.size(), 6u);
  const MoveReport& first = reports.front();
  const MoveReport& last = reports.back();
  EXPECT_LT(distanceBetween(first.position, start), 0.01);  // the first report as the move starts
  EXPECT_EQ(last.position.x, target.x);                      // the last one exactly at the target
  EXPECT_EQ(last.position.y, target.y);
  EXPECT_EQ(last.position.z, target.z);

  const CmmPosition direction{(target.x - start.x) / length, (target.y - start.y) / length, (target.z - start.z) / length};
  const sim::TrapezoidMove profile = sim::planTrapezoid(length, speed, accel);
  // The device time of the move's start: the first report comes a moment later, while the machine
  // still accelerates, so how far it got tells how long after the start it was (s = a t^2 / 2).
  const double first_along = distanceBetween(first.position, start);
  ASSERT_LT(first_along, 0.5 * accel * profile.accel_time * profile.accel_time);
  const double move_start = *first.device_time_s - std::sqrt(2 * first_along / accel);
  double previous_along = -1;
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const MoveReport& r = reports[i];
    ASSERT_TRUE(r.device_time_s.has_value());
    const CmmPosition d{r.position.x - start.x, r.position.y - start.y, r.position.z - start.z};
    const double along = d.x * direction.x + d.y * direction.y + d.z * direction.z;
    const CmmPosition cross{d.y * direction.z - d.z * direction.y, d.z * direction.x - d.x * direction.z,
                            d.x * direction.y - d.y * direction.x};
    const double off_path = std::sqrt(cross.x * cross.x + cross.y * cross.y + cross.z * cross.z);
    EXPECT_GE(along, previous_along) << "report " << i << " went backwards";
    EXPECT_LT(off_path, 1e-6) << "report " << i << " left the straight path";
    // Where the trapezoid says the machine is at the report's device time.
    EXPECT_NEAR(along, profile.distanceAt(*r.device_time_s - move_start), 0.01) << "report " << i;
    if (i > 0) {
      const double dt = *r.device_time_s - *reports[i - 1].device_time_s;
      EXPECT_GE(dt, 0.1 - 1e-9) << "more than 10 reports a second (6.3.2.7)";
      EXPECT_LE((along - previous_along) / dt, speed * (1 + 1e-9)) << "report " << i << " faster than the speed";
    }
    EXPECT_GT(r.arrival_steady_ns, 0);
    previous_along = along;
  }

  const CmmPosition now = cmm_->position();
  EXPECT_EQ(now.x, target.x);
  EXPECT_EQ(now.y, target.y);
  EXPECT_EQ(now.z, target.z);

  cmm_->stopMoveReports();
  log.clear();
  EXPECT_EQ(cmm_->goTo(start), MoveOutcome::Reached);
  EXPECT_TRUE(log.reports().empty()) << "reports after StopDaemon";
}

// A sensor whose data are built late (a loaded host) asks for the machine's pose at its exposure:
// after the move has ended, a time during it is on the move, not at its end; a time before it is
// where it started.
TEST_F(CmmDriver, ThePoseAtAPastTimeIsWhereTheMachineWasThen) {
  cmm_->home();
  const auto before = std::chrono::steady_clock::now();
  const CmmPosition start = cmm_->position();
  const CmmPosition target{start.x + 60, start.y, start.z};
  const auto began = std::chrono::steady_clock::now();
  ASSERT_EQ(cmm_->goTo(target), MoveOutcome::Reached);
  const auto ended = std::chrono::steady_clock::now();
  ASSERT_FALSE(server_.status().moving);
  const sim::VirtualCmmStatus middle = server_.statusAt(began + (ended - began) / 2);
  EXPECT_GT(middle.position[0], start.x + 5) << "the middle of the move is not at its start";
  EXPECT_LT(middle.position[0], target.x - 5) << "the middle of the move is not at its end";
  EXPECT_NEAR(server_.statusAt(before).position[0], start.x, 1e-9);
  EXPECT_NEAR(server_.statusAt(ended + std::chrono::seconds(1)).position[0], target.x, 1e-9);
}

TEST_F(CmmDriver, SpeedStaysWithinTheLimits) {
  cmm_->home();
  const double max_speed = server_.config().max_speed;
  EXPECT_EQ(cmm_->setSpeed(5 * max_speed), max_speed);  // clamped by the CMM with warning 0504
  EXPECT_EQ(cmm_->speed(), max_speed);
  EXPECT_EQ(cmm_->setSpeed(0.001), server_.config().min_speed);
  EXPECT_EQ(cmm_->setSpeed(300), 300);
  EXPECT_EQ(cmm_->setAcceleration(1e6), server_.config().max_accel);
  EXPECT_EQ(cmm_->acceleration(), server_.config().max_accel);
  EXPECT_EQ(cmm_->setAcceleration(4000), 4000);
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_TRUE(cmm_->faults().empty()) << "a warning is no fault";

  // A move with its own, slower speed.
  ReportLog log;
  cmm_->startMoveReports(0.1, log.callback());
  const CmmPosition start = cmm_->position();
  const CmmPosition target{start.x, start.y, start.z - 40};
  const auto began = std::chrono::steady_clock::now();
  EXPECT_EQ(cmm_->goTo(target, 100.0), MoveOutcome::Reached);
  EXPECT_GE(seconds(std::chrono::steady_clock::now() - began), test::trapezoidSeconds(40, 100, 4000) - 0.01);
  const std::vector<MoveReport> reports = log.reports();
  ASSERT_GE(reports.size(), 3u);
  for (std::size_t i = 1; i < reports.size(); ++i) {
    const double dt = *reports[i].device_time_s - *reports[i - 1].device_time_s;
    EXPECT_LE(distanceBetween(reports[i].position, reports[i - 1].position) / dt, 100 * (1 + 1e-9));
  }
  // The next move without a speed of its own runs at the setting again.
  EXPECT_EQ(cmm_->goTo(start), MoveOutcome::Reached);
  EXPECT_EQ(cmm_->speed(), 300);
}

TEST_F(CmmDriver, ChangesTools) {
  const std::vector<std::string> tools = cmm_->tools();
  EXPECT_EQ(tools, server_.config().tools);
  EXPECT_EQ(cmm_->currentTool(), "RefTool");
  cmm_->setSpeed(123);
  cmm_->changeTool("Probe1");
  EXPECT_EQ(cmm_->currentTool(), "Probe1");
  EXPECT_EQ(server_.status().active_tool, "Probe1");
  EXPECT_EQ(cmm_->speed(), server_.config().default_speed) << "a new tool starts with its own GoToPar (6.3.6)";
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
}

TEST_F(CmmDriver, EnablesAndDisablesTheUser) {
  cmm_->enableUser();
  cmm_->disableUser();
  EXPECT_TRUE(cmm_->faults().empty());
}

}  // namespace
}  // namespace stampscan::drivers::cmm
