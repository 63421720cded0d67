// The result's analysis views: GET /api/runs/{id}/elements (the grid elements with their
// major-strain directions, for the arrows), /api/runs/{id}/section (a section cut's strain
// profile), /api/compare (run B minus run A on A's surface). The figures come from
// strain_views.hpp; this file only reads the request and writes the JSON. See API.md.
#include "server_impl.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/hmi/run_files.hpp"
#include "stampscan/hmi/strain_views.hpp"
#include "stampscan/run_folder/run_record.hpp"

#include <cmath>
#include <fstream>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// A whole part's stereo and laser elements (about 17,000) are light enough; beyond this the page
// gets every k-th one, and is told so.
constexpr std::size_t kMaxElementsShown = 60000;

double numberParam(const httplib::Request& req, const char* name, std::optional<double> fallback) {
  if (!req.has_param(name)) {
    if (fallback) return *fallback;
    throw BadRequest(std::string("'") + name + "' is required");
  }
  const std::string text = req.get_param_value(name);
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw BadRequest(std::string("'") + name + "' must be a number, not '" + text + "'");
}

// A run's record (run.json), for its program and part id; an empty one when the folder has none.
run_folder::RunRecord runRecordOf(const fs::path& dir) {
  try {
    return run_folder::readRunRecord(dir).value_or(run_folder::RunRecord{});
  } catch (const run_folder::RunRecordError& e) {
    throw BadRequest(e.what());
  }
}

// Rounded so that the JSON stays short: a micrometre, a millionth of strain.
double round6(double v) { return std::round(v * 1e6) / 1e6; }
double round3(double v) { return std::round(v * 1e3) / 1e3; }

void elementsRoute(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  const fs::path dir = runFolder(impl.runsDir(), req.matches[1]);
  const RunElements e = loadRunElements(dir / "cloud4d.ply");
  const std::size_t step = (e.size() + kMaxElementsShown - 1) / kMaxElementsShown;
  json xyz = json::array(), thickness = json::array(), major = json::array(), minor = json::array(), dirs = json::array(),
       normals = json::array();
  const bool has_normals = e.normals.size() == e.size();
  for (std::size_t i = 0; i < e.size(); i += std::max<std::size_t>(step, 1)) {
    for (int k = 0; k < 3; ++k) xyz.push_back(round3(e.positions[i][k]));
    thickness.push_back(round6(e.thickness[i]));
    major.push_back(round6(e.major[i]));
    minor.push_back(round6(e.minor[i]));
    if (e.hasDirections())
      for (int k = 0; k < 3; ++k) dirs.push_back(round6(e.directions[i][k]));
    if (has_normals)
      for (int k = 0; k < 3; ++k) normals.push_back(round6(e.normals[i][k]));
  }
  json out = {{"run_id", dir.filename().string()}, {"elements", e.size()}, {"shown", thickness.size()},
              {"xyz", xyz}, {"thickness", thickness}, {"major", major}, {"minor", minor},
              {"has_directions", e.hasDirections()}, {"major_direction", e.hasDirections() ? dirs : json(nullptr)},
              {"normal", has_normals ? normals : json(nullptr)}};
  if (!e.hasDirections())
    out["note"] = "cloud4d.ply has no major_dir_x/y/z (written before the measurement kept the direction): no arrows";
  sendJson(res, out);
}

void sectionRoute(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  const fs::path dir = runFolder(impl.runsDir(), req.matches[1]);
  const std::string axis = req.has_param("axis") ? req.get_param_value("axis") : "x";
  if (axis != "x" && axis != "y" && axis != "z") throw BadRequest("'axis' must be x, y or z, not '" + axis + "'");
  SectionParams p;
  p.axis = axis[0] - 'x';
  p.at_mm = numberParam(req, "at", std::nullopt);
  p.half_width_mm = numberParam(req, "width", 2 * p.half_width_mm) / 2;
  if (!(p.half_width_mm > 0) || p.half_width_mm > 50) throw BadRequest("'width' must be more than 0 and at most 100 mm");
  const RunElements e = loadRunElements(dir / "cloud4d.ply");
  double lo = 0, hi = 0;
  for (std::size_t i = 0; i < e.size(); ++i) {
    lo = i == 0 ? e.positions[i][p.axis] : std::min(lo, e.positions[i][p.axis]);
    hi = i == 0 ? e.positions[i][p.axis] : std::max(hi, e.positions[i][p.axis]);
  }
  json points = json::array();
  for (const SectionPoint& s : sectionProfile(e, p))
    points.push_back({{"element", s.element}, {"along_mm", round3(s.along_mm)},
                      {"x", round3(s.position.x())}, {"y", round3(s.position.y())}, {"z", round3(s.position.z())},
                      {"thinning_percent", round3(s.thinning_percent)}, {"major_percent", round3(s.major_percent)},
                      {"minor_percent", round3(s.minor_percent)}});
  sendJson(res, {{"run_id", dir.filename().string()}, {"axis", axis}, {"at_mm", p.at_mm},
                 {"width_mm", 2 * p.half_width_mm}, {"range_mm", {round3(lo), round3(hi)}}, {"points", points}});
}

void compareRoute(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  if (!req.has_param("a") || !req.has_param("b")) throw BadRequest("give the two runs: /api/compare?a=RUN_A&b=RUN_B");
  const fs::path dir_a = runFolder(impl.runsDir(), req.get_param_value("a"));
  const fs::path dir_b = runFolder(impl.runsDir(), req.get_param_value("b"));
  StrainQuantity quantity = StrainQuantity::Thinning;
  try {
    if (req.has_param("strain")) quantity = strainQuantityFromString(req.get_param_value("strain"));
  } catch (const std::invalid_argument& e) {
    throw BadRequest(e.what());
  }
  const double max_distance = numberParam(req, "max_distance", 2.54);
  if (!(max_distance > 0) || max_distance > 20) throw BadRequest("'max_distance' must be more than 0 and at most 20 mm");
  const run_folder::RunRecord run_a = runRecordOf(dir_a), run_b = runRecordOf(dir_b);
  const std::string& program_a = run_a.program;
  const std::string& program_b = run_b.program;
  // Elements are matched by place: that means something only on parts of one press program.
  if (program_a != program_b)
    throw BadRequest("run A is of program '" + program_a + "', run B of '" + program_b + "': compare two runs of one program");
  const RunElements a = loadRunElements(dir_a / "cloud4d.ply");
  const RunElements b = loadRunElements(dir_b / "cloud4d.ply");
  const Comparison c = compareRuns(a, b, quantity, max_distance);

  json out = {{"a", {{"run_id", dir_a.filename().string()}, {"part_id", run_a.part_id}, {"elements", a.size()}}},
              {"b", {{"run_id", dir_b.filename().string()}, {"part_id", run_b.part_id}, {"elements", b.size()}}},
              {"program", program_a}, {"strain", toString(quantity)}, {"max_distance_mm", max_distance},
              {"matched", c.matched}, {"unmatched", a.size() - c.matched}, {"mean", round3(c.mean)},
              {"rms", round3(c.rms)}, {"min", round3(c.min)}, {"max", round3(c.max)}};
  const auto values = [](const std::vector<std::optional<double>>& v) {
    json list = json::array();
    for (const auto& x : v) list.push_back(x ? json(round3(*x)) : json(nullptr));
    return list;
  };
  json xyz = json::array();
  for (const auto& p : a.positions)
    for (int k = 0; k < 3; ++k) xyz.push_back(round3(p[k]));
  out["elements"] = {{"xyz", xyz}, {"difference", values(c.difference)}};
  // On A's fitted surface, when it has one: each vertex takes its nearest matched element's difference.
  std::error_code ec;
  if (fs::is_regular_file(dir_a / "mesh.ply", ec)) {
    const fitting::Mesh mesh = fitting::readPlyMesh(dir_a / "mesh.ply");
    json positions = json::array(), indices = json::array();
    for (const auto& p : mesh.vertices.positions)
      for (int k = 0; k < 3; ++k) positions.push_back(round3(p[k]));
    for (const auto& t : mesh.triangles)
      for (auto v : t.v) indices.push_back(v);
    out["mesh"] = {{"positions", positions}, {"indices", indices},
                   {"difference", values(onPoints(mesh.vertices.positions, a, c.difference, max_distance))}};
  } else {
    out["mesh"] = nullptr;
  }
  sendJson(res, out);
}

}  // namespace

void addAnalysisRoutes(HmiServer::Impl& impl) {
  auto& s = impl.server;
  s.Get(R"(/api/runs/([^/]+)/elements)", [&impl](const httplib::Request& req, httplib::Response& res) {
    elementsRoute(impl, req, res);
  });
  s.Get(R"(/api/runs/([^/]+)/section)", [&impl](const httplib::Request& req, httplib::Response& res) {
    sectionRoute(impl, req, res);
  });
  s.Get("/api/compare", [&impl](const httplib::Request& req, httplib::Response& res) { compareRoute(impl, req, res); });
}

}  // namespace stampscan::hmi
