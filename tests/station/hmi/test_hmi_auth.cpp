// The panel off loopback: a login is required, with two roles. Unauthenticated and operator
// requests to maintenance actions are refused; state-changing requests need the session's CSRF
// token and this server's Origin; every action is recorded with who did it.
#include "hmi_test_support.hpp"

#include <chrono>
#include <cstdio>
#include <sstream>
#include <thread>

namespace stampscan::hmi::test {
namespace {

class HmiAuthTest : public HmiTest {
 protected:
  void startWithUsers() {
    const std::string op = hashOf("op-secret"), mt = hashOf("mt-secret");
    ASSERT_EQ(op.rfind("$argon2id$", 0), 0u) << op;
    std::ofstream(root_ / "users.toml") << "[[user]]\nname = \"olga\"\nrole = \"operator\"\npassword_hash = \"" << op
                                         << "\"\n\n[[user]]\nname = \"max\"\nrole = \"maintenance\"\npassword_hash = \""
                                         << mt << "\"\n";
    ASSERT_NO_FATAL_FAILURE(
        startPanel({"--listen", "0.0.0.0:0", "--allow-plain-http", "--users", (root_ / "users.toml").string()}));
  }
  // Logs in; returns the CSRF token and keeps the session cookie for the next requests.
  std::string login(const std::string& user, const std::string& password, int expected = 200) {
    auto r = client_->Post("/api/login", json{{"user", user}, {"password", password}}.dump(), "application/json");
    EXPECT_TRUE(r);
    if (!r) return "";
    EXPECT_EQ(r->status, expected) << r->body;
    if (r->status != 200) return "";
    const std::string cookie = r->get_header_value("Set-Cookie");
    EXPECT_NE(cookie.find("HttpOnly"), std::string::npos);
    EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos);
    client_->set_default_headers({{"Cookie", cookie.substr(0, cookie.find(';'))}});
    return body(r)["csrf"].get<std::string>();
  }
};

TEST_F(HmiAuthTest, OffLoopbackAUsersFileIsRequired) {
  // Off loopback the panel is served through its TLS front, or in clear text only when asked for.
  station_ = std::make_unique<StationHmi>(root_, std::vector<std::string>{"--listen", "0.0.0.0:0"});
  EXPECT_EQ(station_->waitReady(), 0);
  EXPECT_EQ(station_->exit_code, 1);
  EXPECT_NE(station_->log().find("clear text"), std::string::npos) << station_->log();
  EXPECT_NE(station_->log().find("--front-config"), std::string::npos) << station_->log();
  // And with a login, whose users the panel must know.
  station_ = std::make_unique<StationHmi>(root_, std::vector<std::string>{"--listen", "0.0.0.0:0", "--allow-plain-http"});
  EXPECT_EQ(station_->waitReady(), 0);
  EXPECT_EQ(station_->exit_code, 1);
  EXPECT_NE(station_->log().find("needs a login"), std::string::npos) << station_->log();
}

TEST_F(HmiAuthTest, UnauthenticatedAndOperatorRequestsToMaintenanceActionsAreRefused) {
  ASSERT_NO_FATAL_FAILURE(startWithUsers());
  EXPECT_TRUE(body(client_->Get("/api/session"))["login_required"].get<bool>());
  // The page itself is public (it shows the login); the API is not.
  EXPECT_EQ(client_->Get("/")->status, 200);
  EXPECT_EQ(client_->Get("/api/cell")->status, 401);
  EXPECT_EQ(client_->Get("/api/runs")->status, 401);
  // Served under the plant's address: an address literal is no rebinding, a name it is not served
  // under is refused before any token is handed out.
  EXPECT_EQ(client_->Get("/", {{"Host", "192.0.2.7:8080"}})->status, 200);
  EXPECT_EQ(client_->Get("/api/session", {{"Host", "evil.example:8080"}})->status, 421);
  EXPECT_EQ(post("/api/verify", "{}", "")->status, 401);
  EXPECT_EQ(post("/api/calibrate", "{}", "")->status, 401);
  EXPECT_EQ(post("/api/scan/start", R"({"part_id": "x"})", "")->status, 401);
  EXPECT_EQ(client_->Get("/api/actions")->status, 401);

  login("olga", "wrong", 401);
  login("nobody", "op-secret", 401);
  const std::string op_csrf = login("olga", "op-secret");
  ASSERT_FALSE(op_csrf.empty());
  EXPECT_EQ(client_->Get("/api/cell")->status, 200);
  // An operator may not verify nor read the actions log.
  auto verify = post("/api/verify", "{}", op_csrf);
  ASSERT_TRUE(verify);
  EXPECT_EQ(verify->status, 403);
  EXPECT_NE(body(verify)["error"].get<std::string>().find("maintenance"), std::string::npos) << verify->body;
  EXPECT_EQ(client_->Get("/api/actions")->status, 403);
  auto calibrate = post("/api/calibrate", R"({"sensors": "digitizer"})", op_csrf);
  ASSERT_TRUE(calibrate);
  EXPECT_EQ(calibrate->status, 403) << calibrate->body;
  // Nor read or change the cell's settings.
  EXPECT_EQ(client_->Get("/api/settings")->status, 403);
  auto settings = post("/api/settings", R"({"validity_days": 30})", op_csrf);
  ASSERT_TRUE(settings);
  EXPECT_EQ(settings->status, 403) << settings->body;
  EXPECT_NE(body(settings)["error"].get<std::string>().find("maintenance"), std::string::npos) << settings->body;
  // The analysis views are the operator's too.
  EXPECT_EQ(client_->Get("/api/scan/cloud")->status, 200);
  // State-changing requests without the CSRF token, or from another site, are refused.
  EXPECT_EQ(post("/api/scan/abort", "{}", "")->status, 403);
  EXPECT_EQ(post("/api/scan/abort", "{}", "forged")->status, 403);
  EXPECT_EQ(post("/api/scan/abort", "{}", op_csrf, {{"Origin", "http://evil.example"}})->status, 403);
  // With both, the operator's action goes through (nothing runs: 409, but not refused for rights).
  EXPECT_EQ(post("/api/scan/abort", "{}", op_csrf)->status, 409);
  // A forged session cookie is no session.
  client_->set_default_headers({{"Cookie", "stampscan_session=forged"}});
  EXPECT_EQ(client_->Get("/api/cell")->status, 401);

  // Maintenance may verify (and abort it again at once).
  const std::string mt_csrf = login("max", "mt-secret");
  EXPECT_EQ(post("/api/verify", "{}", "")->status, 403) << "no CSRF token";
  EXPECT_EQ(post("/api/settings", R"({"validity_days": 30})", "")->status, 403) << "no CSRF token";
  EXPECT_EQ(post("/api/settings", R"({"validity_days": 30})", mt_csrf, {{"Origin", "http://evil.example"}})->status, 403);
  EXPECT_EQ(body(client_->Get("/api/settings"))["settings"]["validity_days"], 7) << "nothing refused was applied";
  auto changed = post("/api/settings", R"({"validity_days": 30})", mt_csrf);
  ASSERT_TRUE(changed);
  EXPECT_EQ(changed->status, 200) << changed->body;
  EXPECT_EQ(body(changed)["settings"]["validity_days"], 30);
  auto started = post("/api/verify", "{}", mt_csrf);
  ASSERT_TRUE(started);
  EXPECT_EQ(started->status, 202) << started->body;
  EXPECT_EQ(post("/api/scan/abort", "{}", mt_csrf)->status, 202);
  // ... and calibrate, once the verification has ended: a bad request is named, a good one starts.
  for (int i = 0; i < 600 && body(client_->Get("/api/status"))["busy"].get<bool>(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  auto bad = post("/api/calibrate", R"({"sensors": "lens"})", mt_csrf);
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400) << bad->body;
  EXPECT_NE(body(bad)["error"].get<std::string>().find("lens"), std::string::npos) << bad->body;
  EXPECT_EQ(post("/api/calibrate", R"({"accept": "yes"})", mt_csrf)->status, 400);
  auto calibrating = post("/api/calibrate", R"({"sensors": "digitizer"})", mt_csrf);
  ASSERT_TRUE(calibrating);
  EXPECT_EQ(calibrating->status, 202) << calibrating->body;
  EXPECT_EQ(body(calibrating)["job"]["kind"], "calibrate") << calibrating->body;
  EXPECT_EQ(post("/api/scan/abort", "{}", mt_csrf)->status, 202);
  auto actions = client_->Get("/api/actions");
  ASSERT_TRUE(actions);
  EXPECT_EQ(actions->status, 200);
  // Every action with who did it, the refused ones too.
  const std::string log = readText(root_ / "runs" / "hmi-actions.jsonl");
  EXPECT_NE(log.find(R"("action":"refused")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("user":"olga")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("action":"verify start")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("action":"calibrate start")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("user":"max")"), std::string::npos) << log;
  bool max_changed_settings = false;
  std::istringstream lines(log);
  for (std::string line; std::getline(lines, line);) {
    const json entry = json::parse(line, nullptr, false);
    max_changed_settings |= entry.value("action", "") == "settings change" && entry.value("user", "") == "max" &&
                            entry.value("role", "") == "maintenance";
  }
  EXPECT_TRUE(max_changed_settings) << log;
  EXPECT_NE(log.find(R"("validity_days":{"from":7.0,"to":30.0})"), std::string::npos) << log;
  // The operator's try was refused for the role, and recorded with the path.
  EXPECT_NE(log.find(R"("path":"/api/settings")"), std::string::npos) << log;
  EXPECT_NE(log.find(R"("action":"login refused")"), std::string::npos) << log;
  EXPECT_EQ(log.find("secret"), std::string::npos) << "passwords never go into the log";

  // After logging out the session is gone.
  EXPECT_EQ(post("/api/logout", "{}", mt_csrf)->status, 200);
  EXPECT_EQ(client_->Get("/api/cell")->status, 401);
}

}  // namespace
}  // namespace stampscan::hmi::test
