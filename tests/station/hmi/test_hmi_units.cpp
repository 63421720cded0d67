// The panel's parts that need no cell: sessions and their expiry, the users file, the event hub's
// bounded queues, the advice for faults.
#include "stampscan/hmi/auth.hpp"
#include "stampscan/hmi/cell_jobs.hpp"
#include "stampscan/hmi/event_hub.hpp"
#include "stampscan/jobs/scan_job.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace stampscan::hmi {
namespace {

std::vector<User> twoUsers() {
  return {User{"olga", Role::Operator, hashPassword("op-secret")}, User{"max", Role::Maintenance, hashPassword("mt")}};
}

TEST(HmiAuth, PasswordsAreStoredHashedAndVerified) {
  const std::string hash = hashPassword("correct horse");
  EXPECT_EQ(hash.rfind("$argon2id$", 0), 0u);
  EXPECT_EQ(hash.find("correct horse"), std::string::npos);
  EXPECT_TRUE(verifyPassword("correct horse", hash));
  EXPECT_FALSE(verifyPassword("correct horse ", hash));
  EXPECT_NE(hashPassword("correct horse"), hash) << "each hash has its own salt";
}

TEST(HmiAuth, LoginGivesASessionWithItsRoleAndCsrfToken) {
  Authenticator auth(true, twoUsers(), std::chrono::seconds(60));
  EXPECT_FALSE(auth.login("olga", "wrong"));
  EXPECT_FALSE(auth.login("nobody", "op-secret"));
  const auto s = auth.login("olga", "op-secret");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->role, Role::Operator);
  EXPECT_NE(s->token, s->csrf);
  EXPECT_TRUE(auth.session(s->token));
  EXPECT_FALSE(auth.session("forged"));
  auth.logout(s->token);
  EXPECT_FALSE(auth.session(s->token));
  EXPECT_FALSE(allows(Role::Operator, Role::Maintenance));
  EXPECT_TRUE(allows(Role::Maintenance, Role::Operator));
}

TEST(HmiAuth, SessionsExpireWhenIdle) {
  Authenticator auth(true, twoUsers(), std::chrono::seconds(0));
  const auto s = auth.login("max", "mt");
  ASSERT_TRUE(s);
  EXPECT_FALSE(auth.session(s->token)) << "an idle timeout of 0 ends the session at once";
}

TEST(HmiAuth, LoopbackNeedsNoLogin) {
  Authenticator auth(false, {}, std::chrono::seconds(60));
  const auto s = auth.session("");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->role, Role::Maintenance);
  EXPECT_FALSE(s->csrf.empty());
  EXPECT_TRUE(isLoopbackHost("127.0.0.1"));
  EXPECT_TRUE(isLoopbackHost("::1"));
  EXPECT_TRUE(isLoopbackHost("localhost"));
  EXPECT_FALSE(isLoopbackHost("0.0.0.0"));
  EXPECT_FALSE(isLoopbackHost("192.168.1.20"));
  // Exactly: a name that starts like a loopback address may resolve anywhere.
  EXPECT_TRUE(isLoopbackHost("127.1.2.3"));
  EXPECT_FALSE(isLoopbackHost("127.0.0.1.evil.example"));
  EXPECT_FALSE(isLoopbackHost("127.example"));
  EXPECT_FALSE(isLoopbackHost("127.0.0.1 "));
  EXPECT_FALSE(isLoopbackHost("localhost.evil.example"));
}

TEST(HmiAuth, AListenNameIsResolvedBeforeItIsTrusted) {
  EXPECT_EQ(resolveListenAddress("127.0.0.1"), std::vector<std::string>{"127.0.0.1"});
  for (const std::string& a : resolveListenAddress("localhost")) EXPECT_TRUE(isLoopbackHost(a)) << a;
  EXPECT_FALSE(isLoopbackHost(resolveListenAddress("0.0.0.0").front()));
  try {
    resolveListenAddress("no-such-host.invalid");
    ADD_FAILURE() << "an unknown name resolved";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-host.invalid"), std::string::npos) << e.what();
  }
}

TEST(HmiAuth, RepeatedWrongPasswordsLockTheName) {
  Authenticator auth(true, {User{"olga", Role::Operator, hashPassword("right")}, User{"max", Role::Maintenance, hashPassword("mt")}},
                     std::chrono::seconds(60));
  EXPECT_TRUE(auth.login("max", "mt")) << "the right password logs in";
  for (int i = 0; i < Authenticator::kMostFailures; ++i) {
    EXPECT_FALSE(auth.locked("olga"));
    EXPECT_FALSE(auth.login("olga", "wrong"));
  }
  EXPECT_TRUE(auth.locked("olga"));
  EXPECT_FALSE(auth.login("olga", "right")) << "a locked name does not log in, even with its password";
  EXPECT_FALSE(auth.locked("max"));
  EXPECT_TRUE(auth.login("max", "mt")) << "another name is not locked with it";
}

TEST(HmiAuth, AUsersFileThatIsWrongIsNamed) {
  const auto file = std::filesystem::temp_directory_path() / "stampscan_hmi_users_test.toml";
  std::ofstream(file) << "[[user]]\nname = \"olga\"\nrole = \"operator\"\npassword_hash = \"plain\"\n";
  try {
    loadUsers(file);
    ADD_FAILURE() << "a plain password was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("olga"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("password_hash"), std::string::npos) << e.what();
  }
  std::ofstream(file) << "[[user]]\nname = \"olga\"\nrole = \"boss\"\npassword_hash = \"" << hashPassword("x") << "\"\n";
  EXPECT_THROW(loadUsers(file), std::runtime_error);
  std::filesystem::remove(file);
}

TEST(HmiEvents, EverySubscriberGetsEveryEventStampedWithItsTime) {
  EventHub hub;
  auto a = hub.subscribe(), b = hub.subscribe();
  hub.publish("progress", R"({"step":1})");
  for (auto& s : {a, b}) {
    const auto e = s->next(std::chrono::milliseconds(100));
    ASSERT_TRUE(e);
    EXPECT_EQ(e->name, "progress");
    EXPECT_EQ(e->json.rfind("{\"t_ms\":", 0), 0u) << e->json;
    EXPECT_NE(e->json.find("\"step\":1"), std::string::npos);
    EXPECT_NE(formatServerSentEvent(*e).find("event: progress\ndata: {"), std::string::npos);
  }
  EXPECT_FALSE(a->next(std::chrono::milliseconds(1)));
}

TEST(HmiEvents, ASlowSubscriberLosesItsOldestEventsNotTheScan) {
  EventHub hub(3);
  auto s = hub.subscribe();
  for (int i = 0; i < 10; ++i) hub.publish("progress", "{\"step\":" + std::to_string(i) + "}");
  const auto first = s->next(std::chrono::milliseconds(10));
  ASSERT_TRUE(first);
  EXPECT_NE(first->json.find("\"step\":7"), std::string::npos) << first->json;
  hub.close();
  EXPECT_TRUE(s->closed());
}

TEST(HmiAdvice, FaultsComeWithWhatToDo) {
  using acquisition::FaultKind;
  EXPECT_NE(faultAdvice(FaultKind::DoorOpen).find("Close the cell door"), std::string::npos);
  EXPECT_NE(faultAdvice(FaultKind::EStop).find("emergency stop"), std::string::npos);
  EXPECT_NE(faultAdvice(FaultKind::LightCurtain).find("light curtain"), std::string::npos);
  EXPECT_NE(faultAdvice(FaultKind::NoAir).find("air"), std::string::npos);
  EXPECT_NE(faultAdvice(FaultKind::DeviceSilent).find("does not answer"), std::string::npos);
  EXPECT_EQ(faultAdvice(FaultKind::Other), "");
}

// The kind travels with the error, whatever its words: a door in a part's name is no open door.
TEST(HmiAdvice, TheKindComesFromTheErrorNotItsWords) {
  using acquisition::FaultKind;
  EXPECT_EQ(acquisition::faultKindOf(acquisition::ScanError("the plan 'door-panel' cannot run on this cell")),
            FaultKind::Other);
  EXPECT_EQ(acquisition::faultKindOf(acquisition::ScanError("the cell door is open", FaultKind::DoorOpen)),
            FaultKind::DoorOpen);
  EXPECT_EQ(acquisition::faultKindOf(jobs::ScanStopped(FaultKind::LightCurtain, "the scan was aborted: ...")),
            FaultKind::LightCurtain);
  EXPECT_EQ(acquisition::faultKindOf(drivers::DeviceError("cmm", "timeout", "no reply in 5 s")), FaultKind::DeviceSilent);
  EXPECT_EQ(acquisition::faultKindOf(drivers::DeviceError("cmm", "protocol", "a reply out of order")), FaultKind::Other);
  EXPECT_EQ(acquisition::faultKindOf(std::runtime_error("air")), FaultKind::Other);
  EXPECT_EQ(acquisition::faultKindOf(drivers::plc::PlcEventKind::DoorOpened), FaultKind::DoorOpen);
  EXPECT_EQ(acquisition::faultKindOf(drivers::plc::PlcEventKind::DoorClosed), FaultKind::Other);
  // A trip of the PLC's interlock read before the input that caused it: its fault word says what.
  using drivers::plc::FaultBit;
  const auto trip = [](std::initializer_list<FaultBit> causes) {
    drivers::plc::PlcEvent e{{}, drivers::plc::PlcEventKind::InterlockTripped, "interlock tripped", 0};
    for (const FaultBit b : causes) e.fault_word = static_cast<std::uint16_t>(e.fault_word | (1U << static_cast<unsigned>(b)));
    return e;
  };
  EXPECT_EQ(acquisition::faultKindOf(trip({FaultBit::DoorOpen})), FaultKind::DoorOpen);
  EXPECT_EQ(acquisition::faultKindOf(trip({FaultBit::DoorOpen, FaultBit::EStopBroken})), FaultKind::EStop);
  EXPECT_EQ(acquisition::faultKindOf(trip({FaultBit::AirPressureLow})), FaultKind::NoAir);
  EXPECT_EQ(acquisition::faultKindOf(trip({FaultBit::StationHeartbeatLost})), FaultKind::Interlock);
  EXPECT_STREQ(acquisition::toString(FaultKind::DeviceSilent), "device_silent");
}

}  // namespace
}  // namespace stampscan::hmi
