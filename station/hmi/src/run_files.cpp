#include "stampscan/hmi/run_files.hpp"

#include "stampscan/fitting/ply_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>

namespace stampscan::hmi {

namespace fs = std::filesystem;

bool isSafeName(const std::string& name) {
  if (name.empty() || name.size() > 200 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '-' ||
           c == '_';
  });
}

namespace {

// True when `inner`, resolved, lies inside `outer`, resolved.
bool inside(const fs::path& outer, const fs::path& inner) {
  std::error_code ec;
  const fs::path o = fs::canonical(outer, ec);
  if (ec) return false;
  const fs::path i = fs::canonical(inner, ec);
  if (ec) return false;
  const auto [end, _] = std::mismatch(o.begin(), o.end(), i.begin(), i.end());
  return end == o.end();
}

}  // namespace

fs::path runFolder(const fs::path& runs_dir, const std::string& run_id) {
  if (!isSafeName(run_id)) throw RunFileError(400, "not a run id: '" + run_id + "'");
  const fs::path dir = runs_dir / run_id;
  std::error_code ec;
  if (!fs::is_directory(dir, ec) || !fs::exists(dir / "run.json", ec) || !inside(runs_dir, dir))
    throw RunFileError(404, "no run '" + run_id + "' in " + runs_dir.string());
  return dir;
}

fs::path runFile(const fs::path& runs_dir, const std::string& run_id, const std::string& name) {
  const fs::path dir = runFolder(runs_dir, run_id);
  if (!isSafeName(name)) throw RunFileError(400, "not a file name: '" + name + "'");
  const fs::path file = dir / name;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec) || !inside(dir, file))
    throw RunFileError(404, "run '" + run_id + "' has no file '" + name + "'");
  return file;
}

std::string contentType(const std::string& name) {
  static const std::map<std::string, std::string> types = {
      {".pdf", "application/pdf"}, {".png", "image/png"},       {".json", "application/json"},
      {".csv", "text/csv"},        {".html", "text/html; charset=utf-8"}, {".ply", "application/octet-stream"},
      {".js", "text/javascript"},  {".mjs", "text/javascript"}, {".css", "text/css"},
      {".svg", "image/svg+xml"},   {".mcap", "application/octet-stream"}};
  const auto it = types.find(fs::path(name).extension().string());
  return it == types.end() ? "application/octet-stream" : it->second;
}

std::string meshJson(const fs::path& ply) {
  std::error_code ec;
  if (!fs::is_regular_file(ply, ec)) throw RunFileError(404, "the run has no mesh (" + ply.filename().string() + ")");
  const fitting::Mesh mesh = fitting::readPlyMesh(ply);
  std::vector<float> positions;
  positions.reserve(mesh.vertices.size() * 3);
  for (const auto& p : mesh.vertices.positions)
    for (int k = 0; k < 3; ++k) positions.push_back(static_cast<float>(p[k]));
  std::vector<std::uint32_t> indices;
  indices.reserve(mesh.triangles.size() * 3);
  for (const auto& t : mesh.triangles) indices.insert(indices.end(), t.v.begin(), t.v.end());
  nlohmann::json j = {{"positions", positions}, {"indices", indices}};
  if (mesh.vertices.hasStrain()) j["strain"] = mesh.vertices.strain;
  return j.dump();
}

}  // namespace stampscan::hmi
