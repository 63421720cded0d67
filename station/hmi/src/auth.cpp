#include "stampscan/hmi/auth.hpp"

#include <sodium.h>
#include <toml++/toml.h>

namespace stampscan::hmi {

namespace {

void initSodium() {
  // sodium_init is safe to call repeatedly and from several threads; < 0 means no usable RNG.
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot be initialised (no random source)");
}

}  // namespace

const char* toString(Role role) { return role == Role::Maintenance ? "maintenance" : "operator"; }

Role roleFromString(const std::string& text) {
  if (text == "operator") return Role::Operator;
  if (text == "maintenance") return Role::Maintenance;
  throw std::invalid_argument("unknown role '" + text + "' (operator or maintenance)");
}

std::vector<User> loadUsers(const std::filesystem::path& file) {
  toml::table doc;
  try {
    doc = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(file.string() + ":" + std::to_string(e.source().begin.line) + ": " +
                             std::string(e.description()));
  }
  const toml::array* list = doc["user"].as_array();
  if (list == nullptr || list->empty()) throw std::runtime_error(file.string() + ": no [[user]] entries");
  std::vector<User> users;
  for (std::size_t i = 0; i < list->size(); ++i) {
    const toml::table* t = (*list)[i].as_table();
    const std::string where = file.string() + ": user " + std::to_string(i + 1);
    if (t == nullptr) throw std::runtime_error(where + " is not a table");
    User u;
    u.name = (*t)["name"].value_or(std::string());
    u.password_hash = (*t)["password_hash"].value_or(std::string());
    const std::string role = (*t)["role"].value_or(std::string());
    if (u.name.empty()) throw std::runtime_error(where + ": 'name' is missing");
    if (u.password_hash.rfind("$argon2", 0) != 0)
      throw std::runtime_error(where + " (" + u.name + "): 'password_hash' is missing or not a crypto_pwhash string "
                                                       "(make one with `station hmi --hash-password`)");
    try {
      u.role = roleFromString(role);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(where + " (" + u.name + "): " + e.what());
    }
    users.push_back(std::move(u));
  }
  return users;
}

std::string hashPassword(const std::string& password) {
  initSodium();
  char out[crypto_pwhash_STRBYTES];
  if (crypto_pwhash_str(out, password.data(), password.size(), crypto_pwhash_OPSLIMIT_INTERACTIVE,
                        crypto_pwhash_MEMLIMIT_INTERACTIVE) != 0)
    throw std::runtime_error("hashing the password failed (out of memory)");
  return out;
}

bool verifyPassword(const std::string& password, const std::string& hash) {
  initSodium();
  return crypto_pwhash_str_verify(hash.c_str(), password.data(), password.size()) == 0;
}

std::string randomToken(std::size_t bytes) {
  initSodium();
  std::vector<unsigned char> raw(bytes);
  randombytes_buf(raw.data(), raw.size());
  std::string hex(bytes * 2 + 1, '\0');
  sodium_bin2hex(hex.data(), hex.size(), raw.data(), raw.size());
  hex.pop_back();
  return hex;
}

Authenticator::Authenticator(bool login_required, std::vector<User> users, std::chrono::seconds idle_timeout)
    : login_required_(login_required), users_(std::move(users)), idle_timeout_(idle_timeout) {
  local_.token = "local";
  local_.csrf = randomToken();
  local_.user = "local";
  local_.role = Role::Maintenance;
}

std::optional<Session> Authenticator::login(const std::string& user, const std::string& password) {
  if (!login_required_) return local_;
  const User* found = nullptr;
  for (const User& u : users_)
    if (u.name == user) found = &u;
  // An unknown name costs a verification too, so the answer's time does not tell names apart.
  static const std::string dummy = hashPassword(randomToken());
  const bool ok = verifyPassword(password, found != nullptr ? found->password_hash : dummy) && found != nullptr;
  if (!ok) return std::nullopt;
  Session s{randomToken(), randomToken(), found->name, found->role, std::chrono::steady_clock::now() + idle_timeout_};
  std::lock_guard lock(mutex_);
  sessions_[s.token] = s;
  return s;
}

void Authenticator::logout(const std::string& token) {
  std::lock_guard lock(mutex_);
  sessions_.erase(token);
}

std::optional<Session> Authenticator::session(const std::string& token) {
  if (!login_required_) return local_;
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(mutex_);
  std::erase_if(sessions_, [&](const auto& kv) { return kv.second.expires <= now; });
  const auto it = sessions_.find(token);
  if (it == sessions_.end()) return std::nullopt;
  it->second.expires = now + idle_timeout_;
  return it->second;
}

bool isLoopbackHost(const std::string& host) {
  return host == "localhost" || host == "::1" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

}  // namespace stampscan::hmi
