// The virtual CMM on raw I++ DME lines, as a user with netcat would see it: exact response lines,
// error numbers and classes of §8.2, the queues, AbortE, daemons, one connection at a time.
#include "ipp_test_support.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <numbers>

namespace stampscan::sim {
namespace {

using namespace std::chrono_literals;
using Lines = std::vector<std::string>;

class VirtualCmmRaw : public ::testing::Test {
 protected:
  void SetUp() override {
    server_.start();
    nc_ = std::make_unique<test::RawIppClient>(server_.port());
  }

  void startSession() { ASSERT_EQ(nc_->transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"})); }
  void homeAt(double speed) {
    ASSERT_EQ(nc_->transact("00002", "Home()"), (Lines{"00002 &", "00002 %"}));
    const std::string set = "SetProp(Tool.GoToPar.Speed(" + std::to_string(static_cast<int>(speed)) + "))";
    ASSERT_EQ(nc_->transact("00003", set), (Lines{"00003 &", "00003 %"}));
  }
  // `TAG command` must fail with `error` (the whole `! Error(...)` text after the tag), then the
  // error state is cleared.
  void expectError(const std::string& tag, const std::string& command, const std::string& error) {
    EXPECT_EQ(nc_->transact(tag, command), (Lines{tag + " &", tag + " ! " + error, tag + " %"})) << command;
    EXPECT_EQ(nc_->transact("09999", "ClearAllErrors()"), (Lines{"09999 &", "09999 %"}));
  }

  VirtualCmm server_{test::quickCmmConfig()};
  std::unique_ptr<test::RawIppClient> nc_;
};

TEST_F(VirtualCmmRaw, SessionLifecycle) {
  // §6.3.1: without a session only StartSession and EndSession are served.
  EXPECT_EQ(nc_->transact("00007", "Get(X())"),
            (Lines{"00007 &", "00007 ! Error(3, 0008, \"Get\", \"Protocol error\")", "00007 %"}));
  EXPECT_EQ(nc_->transact("00008", "EndSession()"), (Lines{"00008 &", "00008 %"}));
  startSession();
  EXPECT_EQ(nc_->transact("00002", "GetDMEVersion()"), (Lines{"00002 &", "00002 # DMEVersion(\"1.4.3\")", "00002 %"}));
  EXPECT_EQ(nc_->transact("00003", "GetMachineClass()"),
            (Lines{"00003 &", "00003 # GetMachineClass(CartCMM)", "00003 %"}));
  EXPECT_EQ(nc_->transact("00004", "IsHomed()"), (Lines{"00004 &", "00004 # IsHomed(0)", "00004 %"}));
  expectError("00005", "StartSession()", "Error(3, 0008, \"StartSession\", \"Protocol error\")");
  EXPECT_EQ(nc_->transact("00006", "EndSession()"), (Lines{"00006 &", "00006 %"}));
  EXPECT_EQ(nc_->transact("00009", "Home()"),
            (Lines{"00009 &", "00009 ! Error(3, 0008, \"Home\", \"Protocol error\")", "00009 %"}));
}

TEST_F(VirtualCmmRaw, RejectsBadCommandsWithTheSpecErrors) {
  startSession();
  expectError("00010", "Fly()", "Error(3, 0501, \"Fly\", \"Unsupported command\")");
  expectError("00011", "GoTo(X(1))", "Error(2, 1011, \"GoTo\", \"Unable to move\")");  // not homed
  homeAt(500);
  expectError("00012", "GoTo(X(1000))",
              "Error(3, 2500, \"GoTo\", \"Machine limit encountered [Move Out Of Limits]\")");
  EXPECT_EQ(nc_->transact("00013", "GetErrorInfo(2500)"),
            (Lines{"00013 &",
                   "00013 # \"Machine limit encountered [Move Out Of Limits]: X(1000) is outside the travel [-400, 400]\"",
                   "00013 %"}));
  expectError("00014", "GoTo(Q(1))", "Error(3, 0505, \"GoTo\", \"Argument not recognized\")");
  expectError("00015", "GoTo(R(5))", "Error(3, 0506, \"GoTo\", \"Argument not supported\")");  // no rotary table
  expectError("00016", "GoTo(X(1), X(2))", "Error(3, 0502, \"GoTo\", \"Incorrect arguments\")");
  expectError("00017", "Get(X(1))", "Error(3, 0508, \"Get\", \"Bad context\")");
  expectError("00018", "SetProp(Tool.GoToPar.Speed.Max(5))", "Error(3, 0510, \"SetProp\", \"Bad property\")");
  expectError("00019", "ChangeTool(\"Nope\")", "Error(3, 1502, \"ChangeTool\", \"Tool not found\")");
  expectError("00020", "GoTo(X(1)", "Error(3, 0008, \"CommandLine\", \"Protocol error\")");
  expectError("00021", "AbortE()", "Error(3, 0008, \"AbortE\", \"Protocol error\")");  // needs an E tag
  // §6.1.1: a stray control character, or LF without CR.
  nc_->sendRaw("00022 Home()\x01\r\n");
  EXPECT_EQ(nc_->readThrough("00022 %"),
            (Lines{"00022 &", "00022 ! Error(3, 0007, \"CommandLine\", \"Illegal character\")", "00022 %"}));
  nc_->sendRaw("00023 Home()\n");
  EXPECT_EQ(nc_->readThrough("00023 %"),
            (Lines{"00023 &", "00023 ! Error(3, 0007, \"CommandLine\", \"Illegal character\")", "00023 %"}));
  nc_->sendLine("00024Home()");
  EXPECT_EQ(nc_->readThrough("00024 %"),
            (Lines{"00024 &", "00024 ! Error(2, 0002, \"CommandLine\", \"No space at pos. 6\")", "00024 %"}));
  // §6.2.1: an unreadable tag is answered on E0000.
  nc_->sendLine("0025 Home()");
  EXPECT_EQ(nc_->readLine(), "E0000 ! Error(2, 0001, \"CommandLine\", \"Illegal tag\")");
  // In the error state, everything but ClearAllErrors and a few queries gets 0511 and 0514 (§6.3.1.7),
  // each with the class of the table of §8.2 (the example of §6.3.1.7 shows 0511 as class 2).
  EXPECT_EQ(nc_->transact("00026", "Get(X())"),
            (Lines{"00026 &", "00026 ! Error(3, 0511, \"Get\", \"Error processing method\")",
                   "00026 ! Error(2, 0514, \"Get\", \"Use ClearAllErrors to continue\")", "00026 %"}));
  EXPECT_EQ(nc_->transact("00027", "ClearAllErrors()"), (Lines{"00027 &", "00027 %"}));
  EXPECT_EQ(nc_->transact("00028", "Get(X(), Z())"), (Lines{"00028 &", "00028 # X(0), Z(500)", "00028 %"}));
}

TEST_F(VirtualCmmRaw, WarningsNeedNoClearing) {
  startSession();
  EXPECT_EQ(nc_->transact("00002", "SetProp(Tool.GoToPar.Speed(5000))"),
            (Lines{"00002 &", "00002 ! Error(1, 0504, \"SetProp\", \"Argument out of range\")", "00002 %"}));
  EXPECT_EQ(nc_->transact("00003", "GetProp(Tool.GoToPar.Speed(), Tool.GoToPar.Speed.Max(), Tool.Name())"),
            (Lines{"00003 &", "00003 # Tool.GoToPar.Speed(1000), Tool.GoToPar.Speed.Max(1000), Tool.Name(\"RefTool\")",
                   "00003 %"}));
  EXPECT_EQ(nc_->transact("00004", "StopAllDaemons()"),
            (Lines{"00004 &", "00004 ! Error(1, 0512, \"StopAllDaemons\", \"No daemons are active\")", "00004 %"}));
  EXPECT_EQ(nc_->transact("00005", "EnumTools()"),
            (Lines{"00005 &", "00005 # \"RefTool\"", "00005 # \"NoTool\"", "00005 # \"Probe1\"",
                   "00005 # \"LaserDigitizer\"", "00005 %"}));
  EXPECT_EQ(nc_->transact("00006", "FindTool(\"Probe1\")"), (Lines{"00006 &", "00006 %"}));
  EXPECT_EQ(nc_->transact("00007", "GetProp(FoundTool.Name())"),
            (Lines{"00007 &", "00007 # FoundTool.Name(\"Probe1\")", "00007 %"}));
}

TEST_F(VirtualCmmRaw, MoveReportDaemon) {
  startSession();
  homeAt(500);
  EXPECT_EQ(nc_->transact("E0004", "OnMoveReportE(Time(0.1), X(), Y(), Z())"), (Lines{"E0004 &", "E0004 %"}));
  Lines lines = nc_->transact("00005", "GoTo(Z(300))");  // 200 mm, 0.5 s
  ASSERT_GE(lines.size(), 5u);
  EXPECT_EQ(lines.front(), "00005 &");
  EXPECT_EQ(lines.back(), "00005 %");
  // The `%` comes when the machine arrives; the report at the target comes then too, or within the
  // daemon's rate limit (0.1 s) after it.
  if (lines[lines.size() - 2] != "E0004 # X(0), Y(0), Z(300)") {
    const std::optional<std::string> last = nc_->readLine(1000ms);
    ASSERT_TRUE(last.has_value()) << "no report at the target after the move";
    lines.push_back(*last);
  }
  const auto reports = std::count_if(lines.begin(), lines.end(), [](const std::string& l) { return l.rfind("E0004 # X(0), Y(0), Z(", 0) == 0; });
  EXPECT_GE(reports, 4);
  EXPECT_TRUE(lines.back() == "E0004 # X(0), Y(0), Z(300)" || lines[lines.size() - 2] == "E0004 # X(0), Y(0), Z(300)")
      << "the last report is at the target";
  expectError("E0006", "OnMoveReportE(Time(0.5), X())", "Error(2, 0515, \"OnMoveReportE\", \"Daemon already exists\")");
  EXPECT_EQ(nc_->transact("00007", "StopDaemon(E0004)"), (Lines{"00007 &", "00007 %"}));
  expectError("00008", "StopDaemon(E0004)", "Error(2, 0513, \"StopDaemon\", \"Daemon does not exist\")");
  expectError("E0009", "OnMoveReportE(Q())", "Error(3, 0510, \"OnMoveReportE\", \"Bad property\")");
  EXPECT_EQ(nc_->transact("E0010", "OnMoveReportE(Time(0.01), X())"),
            (Lines{"E0010 &", "E0010 ! Error(1, 0504, \"OnMoveReportE\", \"Argument out of range\")", "E0010 %"}));
  EXPECT_EQ(nc_->transact("00011", "EndSession()"), (Lines{"00011 &", "00011 %"}));  // stops the daemon too
}

TEST_F(VirtualCmmRaw, HeadAnglesInDegreesOnTheWire) {
  startSession();
  homeAt(500);
  EXPECT_EQ(nc_->transact("00004", "Get(Tool.A(), Tool.B(), Tool.C())"),
            (Lines{"00004 &", "00004 # Tool.A(0), Tool.B(0), Tool.C(0)", "00004 %"}));
  EXPECT_EQ(nc_->transact("00005", "GoTo(Tool.A(30), Tool.B(-45))"), (Lines{"00005 &", "00005 %"}));
  // §6.3.2.12: X, Y, Z were not named and stay where Home() left them.
  EXPECT_EQ(nc_->transact("00006", "Get(X(), Z(), Tool.B(), Tool.A())"),
            (Lines{"00006 &", "00006 # X(0), Z(500), Tool.B(-45), Tool.A(30)", "00006 %"}));
  EXPECT_EQ(nc_->transact("00007", "GetProp(Tool.A(), Tool.C())"),
            (Lines{"00007 &", "00007 # Tool.A(30), Tool.C(0)", "00007 %"}));
  const VirtualCmmStatus status = server_.status();
  EXPECT_NEAR(status.head_a, 30 * std::numbers::pi / 180, 1e-12) << "radians in the status";
  EXPECT_NEAR(status.head_b, -45 * std::numbers::pi / 180, 1e-12);
  EXPECT_EQ(status.head_c, 0);

  expectError("00008", "GoTo(Z(400), Tool.A(120))", "Error(2, 2505, \"GoTo\", \"Specified angle out of range\")");
  EXPECT_EQ(nc_->transact("00009", "GetErrorInfo(2505)"),
            (Lines{"00009 &",
                   "00009 # \"Specified angle out of range: Tool.A(120) is outside the head's range [-115, 115] degrees\"",
                   "00009 %"}));
  expectError("00010", "GoTo(Tool.C(5))", "Error(2, 2505, \"GoTo\", \"Specified angle out of range\")");  // C is fixed
  expectError("00011", "GoTo(A(5))", "Error(3, 0506, \"GoTo\", \"Argument not supported\")");  // a table's axis
  expectError("00012", "GoTo(Tool.A())", "Error(3, 0508, \"GoTo\", \"Bad context\")");
  expectError("00013", "Get(Tool.A(5))", "Error(3, 0508, \"Get\", \"Bad context\")");
  EXPECT_EQ(nc_->transact("00014", "Get(Z(), Tool.A())"),
            (Lines{"00014 &", "00014 # Z(500), Tool.A(30)", "00014 %"}))
      << "a refused GoTo moves no axis (6.3.3.9)";
}

TEST(VirtualCmmIndexingHead, TakesTheGridAngleExactlyAndRefusesOthers) {
  VirtualCmmConfig config = test::quickCmmConfig();
  config.head_kind = VirtualCmmConfig::HeadKind::Indexing;
  config.head_index_step_deg = 7.5;
  VirtualCmm server(config);
  server.start();
  test::RawIppClient nc(server.port());
  ASSERT_EQ(nc.transact("00001", "StartSession()"), (Lines{"00001 &", "00001 %"}));
  ASSERT_EQ(nc.transact("00002", "Home()"), (Lines{"00002 &", "00002 %"}));
  // A client's radian round trip may add an ulp; the head still stops at its index position.
  EXPECT_EQ(nc.transact("00003", "GoTo(Tool.A(7.500000000000001), Tool.B(-15))"), (Lines{"00003 &", "00003 %"}));
  EXPECT_EQ(nc.transact("00004", "Get(Tool.A(), Tool.B())"),
            (Lines{"00004 &", "00004 # Tool.A(7.5), Tool.B(-15)", "00004 %"}));
  EXPECT_EQ(nc.transact("00005", "GoTo(Tool.B(8))"),
            (Lines{"00005 &", "00005 ! Error(2, 2505, \"GoTo\", \"Specified angle out of range\")", "00005 %"}));
  EXPECT_EQ(nc.transact("00006", "GetErrorInfo(2505)"),
            (Lines{"00006 &",
                   "00006 # \"Specified angle out of range: Tool.B(8) is not an index position of this indexing head "
                   "(every 7.5 degrees)\"",
                   "00006 %"}));
}

TEST(VirtualCmmHeadConfig, RefusesAHeadThatCannotWork) {
  VirtualCmmConfig no_step = test::quickCmmConfig();
  no_step.head_kind = VirtualCmmConfig::HeadKind::Indexing;
  no_step.head_index_step_deg = 0;
  EXPECT_THROW(VirtualCmm{no_step}, std::invalid_argument);
  VirtualCmmConfig outside = test::quickCmmConfig();
  outside.head_power_on_deg = {0, 0, 10};  // C is fixed at 0
  EXPECT_THROW(VirtualCmm{outside}, std::invalid_argument);
  VirtualCmmConfig still = test::quickCmmConfig();
  still.head_max_rate_deg_s = 0;
  EXPECT_THROW(VirtualCmm{still}, std::invalid_argument);
}

TEST_F(VirtualCmmRaw, AbortEAnswersTheRunningAndTheQueuedCommands) {
  startSession();
  homeAt(100);
  nc_->sendLine("00010 GoTo(Z(100))");  // 4 s at 100 mm/s
  EXPECT_EQ(nc_->readLine(), "00010 &");
  nc_->sendLine("00011 GoTo(Z(400))");
  EXPECT_EQ(nc_->readLine(), "00011 &");
  ASSERT_TRUE(test::waitUntil([&] { return server_.status().position[2] < 490; })) << "00010 is not running";
  // The fast queue answers while the move runs (§4); a tag in use is illegal (§6.2.1), and as a
  // class 2 error it aborts the queued 00011 (§6.2.5).
  EXPECT_EQ(nc_->transact("E0012", "GetErrStatusE()"), (Lines{"E0012 &", "E0012 # ErrStatus(0)", "E0012 %"}));
  nc_->sendLine("00010 Get(X())");
  EXPECT_EQ(nc_->readLine(), "E0000 ! Error(2, 0001, \"CommandLine\", \"Illegal tag\")");

  const std::string aborted = "Error(2, 0006, \"GoTo\", \"Transaction aborted (Use ClearAllErrors To Continue)\")";
  EXPECT_EQ(nc_->transact("E0013", "AbortE()"),
            (Lines{"E0013 &", "00010 ! " + aborted, "00010 %", "00011 ! " + aborted, "00011 %", "E0013 %"}));
  EXPECT_FALSE(server_.status().moving);
  EXPECT_EQ(nc_->transact("00014", "Get(Z())").size(), 4u) << "0511 and 0514: ClearAllErrors must come next";
  EXPECT_EQ(nc_->transact("00015", "ClearAllErrors()"), (Lines{"00015 &", "00015 %"}));
  const Lines z = nc_->transact("00016", "Get(Z())");
  ASSERT_EQ(z.size(), 3u);
  const double stopped = std::stod(z[1].substr(std::string("00016 # Z(").size()));
  EXPECT_GT(stopped, 100);
  EXPECT_LT(stopped, 490);
}

TEST_F(VirtualCmmRaw, ServesOneConnectionAtATime) {
  startSession();
  test::RawIppClient second(server_.port());
  second.sendLine("00001 StartSession()");
  EXPECT_EQ(second.readLine(300ms), std::nullopt) << "the second client waits in the listen queue";
  nc_.reset();  // the first one hangs up (§9.3)
  EXPECT_EQ(second.readThrough("00001 %"), (Lines{"00001 &", "00001 %"}));
  EXPECT_EQ(server_.status().connections_served, 2u);
}

}  // namespace
}  // namespace stampscan::sim
