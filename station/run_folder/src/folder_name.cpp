#include "stampscan/run_folder/folder_name.hpp"

#include <cctype>
#include <regex>

namespace stampscan::run_folder {

std::string runFolderName(const std::string& part_id, std::time_t started) {
  std::tm tm{};
  gmtime_r(&started, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", &tm);
  std::string id;
  for (char c : part_id) id.push_back(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_');
  std::string name = stamp;
  name += '-';
  name += id.empty() ? "part" : id;
  return name;
}

std::optional<FolderName> parseRunFolderName(const std::string& name) {
  static const std::regex pattern(R"((\d{4})(\d{2})(\d{2})-(\d{2})(\d{2})(\d{2})-(.+))");
  std::smatch m;
  if (!std::regex_match(name, m, pattern)) return std::nullopt;
  FolderName f;
  f.started_utc = m[1].str() + "-" + m[2].str() + "-" + m[3].str() + "T" + m[4].str() + ":" + m[5].str() + ":" + m[6].str() + "Z";
  f.part_id = m[7].str();
  return f;
}

}  // namespace stampscan::run_folder
