#include "stampscan/hmi/auth.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sodium.h>
#include <sys/socket.h>
#include <toml++/toml.h>

#include <algorithm>
#include <memory>
#include <semaphore>

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

namespace {
// A password verification takes crypto_pwhash's interactive memory (64 MiB) for a moment: at most
// this many run at once, whatever the number of parallel logins; the others wait their turn.
std::counting_semaphore<2> verifications(2);
}  // namespace

std::optional<Session> Authenticator::login(const std::string& user, const std::string& password) {
  if (!login_required_) return local_;
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard lock(mutex_);
    if (const auto it = failures_.find(user); it != failures_.end() && it->second.locked_until > now) return std::nullopt;
  }
  const User* found = nullptr;
  for (const User& u : users_)
    if (u.name == user) found = &u;
  // An unknown name costs a verification too, so the answer's time does not tell names apart.
  static const std::string dummy = hashPassword(randomToken());
  bool ok = false;
  {
    verifications.acquire();
    const std::unique_ptr<std::counting_semaphore<2>, void (*)(std::counting_semaphore<2>*)> release(
        &verifications, [](std::counting_semaphore<2>* s) { s->release(); });
    ok = verifyPassword(password, found != nullptr ? found->password_hash : dummy) && found != nullptr;
  }
  std::lock_guard lock(mutex_);
  if (!ok) {
    // Failures count per name (known or not) within the lockout window; the table is bounded, so a
    // flood of made-up names cannot grow it without end.
    std::erase_if(failures_, [&](const auto& kv) { return kv.second.window_end <= now && kv.second.locked_until <= now; });
    if (failures_.size() >= kMostTrackedNames && !failures_.contains(user)) return std::nullopt;
    Failures& f = failures_[user];
    if (f.window_end <= now) f = Failures{0, now + kLockout, {}};
    if (++f.count >= kMostFailures) f.locked_until = now + kLockout;
    return std::nullopt;
  }
  failures_.erase(user);
  Session s{randomToken(), randomToken(), found->name, found->role, now + idle_timeout_};
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

bool Authenticator::locked(const std::string& user) {
  std::lock_guard lock(mutex_);
  const auto it = failures_.find(user);
  return it != failures_.end() && it->second.locked_until > std::chrono::steady_clock::now();
}

bool isLoopbackHost(const std::string& host) {
  if (host == "localhost" || host == "::1" || host == "[::1]") return true;
  // An address literal exactly (inet_pton takes only the four dotted numbers): "127.0.0.1.example"
  // is a name any site's DNS may point anywhere.
  in_addr address{};
  return inet_pton(AF_INET, host.c_str(), &address) == 1 && (ntohl(address.s_addr) >> 24) == 127;
}

std::vector<std::string> resolveListenAddress(const std::string& host) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  if (const int error = getaddrinfo(host.c_str(), nullptr, &hints, &found); error != 0)
    throw std::runtime_error("cannot resolve the listen address '" + host + "': " + gai_strerror(error));
  std::vector<std::string> out;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    char text[INET6_ADDRSTRLEN] = "";
    const void* raw = a->ai_family == AF_INET ? static_cast<const void*>(&reinterpret_cast<const sockaddr_in*>(a->ai_addr)->sin_addr)
                                              : static_cast<const void*>(&reinterpret_cast<const sockaddr_in6*>(a->ai_addr)->sin6_addr);
    if ((a->ai_family == AF_INET || a->ai_family == AF_INET6) && inet_ntop(a->ai_family, raw, text, sizeof text))
      if (std::find(out.begin(), out.end(), text) == out.end()) out.emplace_back(text);
  }
  freeaddrinfo(found);
  if (out.empty()) throw std::runtime_error("cannot resolve the listen address '" + host + "': no IP address");
  return out;
}

}  // namespace stampscan::hmi
