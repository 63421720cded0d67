// Who may do what on the panel. On loopback the panel is the station's own screen: no login, the
// local user has every role. On any other address a login is required, with two roles:
//   operator     scan, abort, view
//   maintenance  also verify the calibration and change settings
// Passwords are stored only as libsodium crypto_pwhash strings (Argon2id, with their salt and
// cost); sessions are random tokens that expire after a time idle; each session carries its own
// CSRF token, which every state-changing request must echo in the X-CSRF-Token header.
//
// The users file (TOML), given with --users or as [hmi] users = "..." in the cell config:
//   [[user]]
//   name = "anna"
//   role = "operator"            # or "maintenance"
//   password_hash = "$argon2id$v=19$m=65536,t=2,p=1$..."   # from `station hmi --hash-password`
//
// Thread safety: every method may be called from any thread.
#pragma once

#include <chrono>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::hmi {

enum class Role { Operator, Maintenance };
const char* toString(Role role);
// Throws std::invalid_argument naming the text when it is no role.
Role roleFromString(const std::string& text);
// True when `held` may do what `needed` may.
inline bool allows(Role held, Role needed) { return held == Role::Maintenance || needed == Role::Operator; }

struct User {
  std::string name;
  Role role = Role::Operator;
  std::string password_hash;  // crypto_pwhash_str form
};

// Throws std::runtime_error naming the file, the user and the field when it is not a users file.
std::vector<User> loadUsers(const std::filesystem::path& file);
// The crypto_pwhash_str of a password (interactive cost: about a tenth of a second).
std::string hashPassword(const std::string& password);
bool verifyPassword(const std::string& password, const std::string& hash);
// A fresh random token, hex.
std::string randomToken(std::size_t bytes = 24);

struct Session {
  std::string token, csrf, user;
  Role role = Role::Operator;
  std::chrono::steady_clock::time_point expires;
};

class Authenticator {
 public:
  // login_required false: every request is the local user with the maintenance role (one CSRF
  // token for the server's life, since a page of another site must still not act for it).
  Authenticator(bool login_required, std::vector<User> users, std::chrono::seconds idle_timeout);

  bool loginRequired() const { return login_required_; }
  // A new session, or nothing when the name or password is wrong (the same answer for both) or the
  // name is locked: kMostFailures wrong passwords within kLockout lock it for kLockout. At most two
  // verifications run at once (each takes 64 MiB), however many logins arrive together.
  std::optional<Session> login(const std::string& user, const std::string& password);
  bool locked(const std::string& user);  // by failed logins, now
  static constexpr int kMostFailures = 5;
  static constexpr std::chrono::minutes kLockout{15};
  void logout(const std::string& token);
  // The session of a cookie token, renewed; nothing when unknown or expired. Without login, the
  // local session whatever the token.
  std::optional<Session> session(const std::string& token);

 private:
  bool login_required_;
  std::vector<User> users_;
  std::chrono::seconds idle_timeout_;
  Session local_;
  std::mutex mutex_;
  std::map<std::string, Session> sessions_;
  struct Failures {
    int count = 0;
    std::chrono::steady_clock::time_point window_end, locked_until;
  };
  static constexpr std::size_t kMostTrackedNames = 10000;
  std::map<std::string, Failures> failures_;
};

// True for "localhost" and the address literals of 127.0.0.0/8 and ::1, exactly (a name that
// merely starts with "127." is not).
bool isLoopbackHost(const std::string& host);
// The IP addresses a listen name resolves to (numeric, each once; a literal is itself). Throws
// std::runtime_error naming the name when it does not resolve.
std::vector<std::string> resolveListenAddress(const std::string& host);

}  // namespace stampscan::hmi
