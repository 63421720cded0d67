// The CMM driver when things go wrong: I++ DME error responses and their recovery, AbortE during a
// move, a dropped connection, a silent controller, nobody listening.
#include "ipp_test_support.hpp"
#include "stampscan/drivers/cmm/ipp_client.hpp"
#include "stampscan/drivers/cmm/ipp_errors.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <gtest/gtest.h>

#include <future>
#include <memory>

namespace stampscan::drivers::cmm {
namespace {

using namespace std::chrono_literals;

class CmmDriverFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    server_.start();
    options_.port = server_.port();
    options_.reply_timeout = 1000ms;
    options_.motion_timeout = 10000ms;
    cmm_ = std::make_unique<IppCmm>(options_);
    cmm_->connect();
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

  template <typename Call>
  std::string expectDeviceErrorCode(Call call) {
    try {
      call();
    } catch (const IppError& e) {
      ADD_FAILURE() << "IppError " << e.what();
    } catch (const DeviceError& e) {
      return e.code();
    }
    ADD_FAILURE() << "no DeviceError";
    return {};
  }

  sim::VirtualCmm server_{test::quickCmmConfig()};
  IppCmmOptions options_;
  std::unique_ptr<IppCmm> cmm_;
};

TEST_F(CmmDriverFaults, GoToOutsideTravelFaultsThenRecovers) {
  cmm_->home();
  const IppError e = expectIppError([&] { cmm_->goTo({1000, 0, 0}); });
  EXPECT_EQ(e.code(), "device-error");
  EXPECT_EQ(e.report().number, ipp::error::kMachineLimit);
  EXPECT_EQ(e.report().severity, 3);
  EXPECT_EQ(e.report().method, "GoTo");
  EXPECT_EQ(e.report().text, "Machine limit encountered [Move Out Of Limits]");
  EXPECT_NE(e.info().find("X(1000) is outside the travel"), std::string::npos) << e.info();  // from GetErrorInfo

  // The fault stays on record; GetErrorInfo and ClearAllErrors have brought the driver back.
  ASSERT_EQ(cmm_->faults().size(), 1u);
  EXPECT_EQ(cmm_->faults()[0].code, "device-error");
  EXPECT_NE(cmm_->faults()[0].text.find("2500"), std::string::npos) << cmm_->faults()[0].text;
  EXPECT_NE(cmm_->faults()[0].text.find("GoTo(X(1000), Y(0), Z(0))"), std::string::npos) << cmm_->faults()[0].text;
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_FALSE(server_.status().error_state);
  const auto home = server_.config().home_position;
  EXPECT_EQ(cmm_->position().z, home[2]) << "a move out of limits does not move at all (6.3.3.9)";
  EXPECT_EQ(cmm_->goTo({10, 10, 400}), MoveOutcome::Reached);
}

TEST_F(CmmDriverFaults, GoToBeforeHomeIsRefused) {
  const IppError e = expectIppError([&] { cmm_->goTo({0, 0, 400}); });
  EXPECT_EQ(e.report().number, ipp::error::kUnableToMove);
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  cmm_->home();
  EXPECT_EQ(cmm_->goTo({0, 0, 400}), MoveOutcome::Reached);
}

TEST_F(CmmDriverFaults, UnknownToolFaultsThenRecovers) {
  const IppError e = expectIppError([&] { cmm_->changeTool("NoSuchProbe"); });
  EXPECT_EQ(e.report().number, ipp::error::kToolNotFound);
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_EQ(cmm_->currentTool(), "RefTool");
}

TEST_F(CmmDriverFaults, InjectedErrorIsRecordedWithItsNumber) {
  server_.failNextCommand(1009);  // Air pressure out of range, class 3
  const IppError e = expectIppError([&] { cmm_->position(); });
  EXPECT_EQ(e.report().number, 1009);
  EXPECT_EQ(e.report().text, "Air pressure out of range");
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_NO_THROW(cmm_->position());
  EXPECT_EQ(cmm_->errorInfo(1009), "Air pressure out of range: injected by the test (VirtualCmm::failNextCommand)");
}

TEST_F(CmmDriverFaults, InjectedWarningDoesNotFail) {
  server_.failNextCommand(ipp::error::kNoDaemonsActive);  // class 1
  EXPECT_NO_THROW(cmm_->position());
  EXPECT_TRUE(cmm_->faults().empty());
}

TEST_F(CmmDriverFaults, AbortStopsAMoveShortOfItsTarget) {
  cmm_->home();
  cmm_->setSpeed(100);  // 500 mm at 100 mm/s: 5 s unless aborted
  const CmmPosition target{0, 0, 0};
  auto move = std::async(std::launch::async, [&] { return cmm_->goTo(target); });
  ASSERT_TRUE(test::waitUntil([&] { return server_.status().position[2] < 480; })) << "the machine did not move";
  EXPECT_EQ(cmm_->state(), DeviceState::Busy);
  cmm_->abort();
  ASSERT_EQ(move.wait_for(3s), std::future_status::ready);
  EXPECT_EQ(move.get(), MoveOutcome::Aborted);

  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_TRUE(cmm_->faults().empty()) << "an abort we asked for is no fault";
  const sim::VirtualCmmStatus status = server_.status();
  EXPECT_FALSE(status.moving);
  EXPECT_FALSE(status.error_state);
  EXPECT_EQ(status.moves_aborted, 1u);
  const CmmPosition stopped = cmm_->position();
  EXPECT_GT(stopped.z, 100) << "stopped far short of the target";
  EXPECT_LT(stopped.z, 480);
  EXPECT_NEAR(stopped.z, status.position[2], 1e-9);  // I++ DME numbers carry 16 digits (6.1.4.2)
  EXPECT_EQ(cmm_->goTo({0, 0, stopped.z + 10}), MoveOutcome::Reached) << "usable again";
}

TEST_F(CmmDriverFaults, AbortWhileIdleLeavesTheDriverReady) {
  cmm_->abort();
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_NO_THROW(cmm_->position());
}

TEST_F(CmmDriverFaults, DroppedConnectionFaultsAndReconnects) {
  cmm_->home();
  server_.dropConnection();
  ASSERT_TRUE(test::waitUntil([&] { return cmm_->state() == DeviceState::Faulted; }));
  ASSERT_FALSE(cmm_->faults().empty());
  EXPECT_EQ(cmm_->faults().back().code, "disconnected");
  EXPECT_EQ(expectDeviceErrorCode([&] { cmm_->position(); }), "not-ready");
  EXPECT_FALSE(cmm_->check());

  cmm_->connect();
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_TRUE(cmm_->isHomed()) << "the machine keeps its state across connections";
  EXPECT_NO_THROW(cmm_->position());
}

TEST_F(CmmDriverFaults, DroppedConnectionDuringAMoveEndsTheCall) {
  cmm_->home();
  cmm_->setSpeed(100);
  auto move = std::async(std::launch::async, [&] { return cmm_->goTo({0, 0, 0}); });
  ASSERT_TRUE(test::waitUntil([&] { return server_.status().moving; }));
  server_.dropConnection();
  ASSERT_EQ(move.wait_for(3s), std::future_status::ready);
  EXPECT_EQ(expectDeviceErrorCode([&] { move.get(); }), "disconnected");
  EXPECT_EQ(cmm_->state(), DeviceState::Faulted);
  EXPECT_TRUE(test::waitUntil([&] { return !server_.status().moving; })) << "the server stops with the connection";
  cmm_->connect();
  const CmmPosition stopped = cmm_->position();
  EXPECT_EQ(cmm_->goTo({stopped.x, stopped.y, stopped.z - 10}), MoveOutcome::Reached);
}

TEST_F(CmmDriverFaults, SilenceTimesOut) {
  cmm_->disconnect();
  options_.reply_timeout = 300ms;
  cmm_ = std::make_unique<IppCmm>(options_);
  cmm_->connect();
  server_.setSilent(true);
  const auto began = std::chrono::steady_clock::now();
  EXPECT_EQ(expectDeviceErrorCode([&] { cmm_->position(); }), "timeout");
  EXPECT_GE(std::chrono::steady_clock::now() - began, 300ms);
  EXPECT_EQ(cmm_->state(), DeviceState::Faulted);
  ASSERT_FALSE(cmm_->faults().empty());
  EXPECT_EQ(cmm_->faults().back().code, "timeout");
  EXPECT_NE(cmm_->faults().back().text.find("Get(X(), Y(), Z())"), std::string::npos) << cmm_->faults().back().text;

  server_.setSilent(false);
  cmm_->connect();
  EXPECT_EQ(cmm_->state(), DeviceState::Ready);
  EXPECT_NO_THROW(cmm_->position());
}

TEST_F(CmmDriverFaults, NobodyListening) {
  cmm_->disconnect();
  server_.stop();
  EXPECT_EQ(expectDeviceErrorCode([&] { cmm_->connect(); }), "connect");
  EXPECT_EQ(cmm_->state(), DeviceState::Faulted);
  EXPECT_NE(cmm_->faults().back().text.find("127.0.0.1:" + std::to_string(options_.port)), std::string::npos);
}

}  // namespace
}  // namespace stampscan::drivers::cmm
