// The cell and its jobs: GET /api/cell, /api/status, /api/health, /api/cell/health, /api/materials, /api/calibration,
// /api/scan/cloud, /api/programs (a program's model and predicted coverage); POST /api/scan/start,
// /api/scan/abort, /api/verify, /api/calibrate, /api/programs/NAME/plan; GET /api/actions. See API.md.
#include "json_views.hpp"
#include "server_impl.hpp"
#include "stampscan/hmi/cell_health.hpp"
#include "stampscan/report/material.hpp"

#include <algorithm>
#include <fstream>

namespace stampscan::hmi {

using nlohmann::json;

namespace {

// A text field of a request body: absent is "", anything but a short string is refused.
std::optional<std::string> textField(const json& body, const char* name, std::size_t max_length, std::string& error) {
  if (!body.contains(name) || body[name].is_null()) return std::string();
  if (!body[name].is_string()) {
    error = std::string("'") + name + "' must be a string";
    return std::nullopt;
  }
  std::string v = body[name].get<std::string>();
  if (v.size() > max_length) {
    error = std::string("'") + name + "' is longer than " + std::to_string(max_length) + " characters";
    return std::nullopt;
  }
  return v;
}

// What a program's plan is predicted to see (API.md: GET /api/programs/NAME/coverage).
json coverageJson(const ProgramCoverage& c) {
  return {{"grid_area_mm2", c.grid_area_mm2}, {"spacing_mm", c.spacing_mm}, {"laser", c.laser}, {"stereo", c.stereo},
          {"either", c.either}, {"sweeps", c.sweeps}, {"views", c.views}, {"xyz", c.xyz}, {"seen", c.seen}};
}

// Part ids become folder names: letters, digits and - _ . only.
void startScan(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  const json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded() || !body.is_object())
    return sendError(res, 400, "the body must be a JSON object: {\"part_id\": ..., \"program\": ..., \"material\": ...}");
  std::string error;
  const auto part_id = textField(body, "part_id", 64, error);
  const auto program = part_id ? textField(body, "program", 64, error) : std::nullopt;
  const auto material = program ? textField(body, "material", 32, error) : std::nullopt;
  const auto part_program = material ? textField(body, "part_program", 64, error) : std::nullopt;
  if (!part_program) return sendError(res, 400, error);
  if (!part_program->empty() && !isPartId(*part_program))
    return sendError(res, 400, "'part_program' is a program's name in the cell's library: letters, digits, '-', '_' and '.'");
  if (!isPartId(*part_id))
    return sendError(res, 400, "'part_id' is required: letters, digits, '-', '_' and '.' (it names the run folder)");
  if (!material->empty() && !report::builtInMaterials().contains(*material))
    return sendError(res, 400, "unknown material '" + *material + "' (known: " + report::builtInMaterials().names() + ")");
  const Session who = *impl.sessionOf(req);
  const ScanRequest request{*part_id, *program, *material, *part_program};
  if (const auto refused = impl.jobs.startScan(request, who.user)) {
    impl.recordAction(who, "scan refused", {{"part_id", *part_id}, {"reason", *refused}}, req);
    return sendError(res, 409, *refused);
  }
  impl.recordAction(who, "scan start",
                    {{"part_id", *part_id}, {"program", *program}, {"material", *material}, {"part_program", *part_program}}, req);
  sendJson(res, {{"started", true}, {"job", statusJson(impl.jobs.status())}}, 202);
}

// The cell's part programs: the list, a program's nominal model (binary STL) for the 3D view, what
// its plan is predicted to see, and planning it.
void addProgramRoutes(httplib::Server& s, HmiServer::Impl& impl) {
  s.Get("/api/programs", [&impl](const httplib::Request&, httplib::Response& res) {
    const CellPrograms& programs = impl.jobs.setup().programs;
    json list = json::array();
    try {
      if (programs.list)
        for (const ProgramSummary& p : programs.list())
          list.push_back({{"name", p.name}, {"description", p.description}, {"grid", p.grid}, {"pitch_mm", p.pitch_mm},
                          {"material", p.material}, {"sheet_thickness_mm", p.sheet_thickness_mm}, {"note", p.note},
                          {"line_number", p.line_number ? json(*p.line_number) : json(nullptr)}, {"has_plan", p.has_plan}});
    } catch (const std::exception& e) {
      return sendError(res, 500, std::string("the program library cannot be read: ") + e.what());
    }
    sendJson(res, {{"programs", list}});
  });
  s.Get(R"(/api/programs/([A-Za-z0-9._-]+)/model\.stl)", [&impl](const httplib::Request& req, httplib::Response& res) {
    const CellPrograms& programs = impl.jobs.setup().programs;
    const std::string name = req.matches[1];
    if (!programs.model_stl || !isPartId(name)) return sendError(res, 404, "no such program");
    try {
      res.set_content(programs.model_stl(name), "model/stl");
    } catch (const std::exception& e) {
      return sendError(res, 404, e.what());
    }
  });
  s.Get(R"(/api/programs/([A-Za-z0-9._-]+)/coverage)", [&impl](const httplib::Request& req, httplib::Response& res) {
    const CellPrograms& programs = impl.jobs.setup().programs;
    const std::string name = req.matches[1];
    if (!programs.coverage || !isPartId(name)) return sendError(res, 404, "no such program");
    try {
      sendJson(res, coverageJson(programs.coverage(name)));
    } catch (const std::exception& e) {
      return sendError(res, 404, e.what());
    }
  });
  // Plans a program from its nominal model and makes the plan its own (maintenance: it changes the
  // program); refused while a job runs, which may be scanning it.
  s.Post(R"(/api/programs/([A-Za-z0-9._-]+)/plan)", [&impl](const httplib::Request& req, httplib::Response& res) {
    const CellPrograms& programs = impl.jobs.setup().programs;
    const std::string name = req.matches[1];
    if (!programs.plan || !isPartId(name)) return sendError(res, 404, "no such program");
    const Session who = *impl.sessionOf(req);
    if (programs.list) {
      const std::vector<ProgramSummary> listed = programs.list();
      if (std::none_of(listed.begin(), listed.end(), [&](const ProgramSummary& p) { return p.name == name; }))
        return sendError(res, 404, "no such program: " + name);
    }
    if (impl.jobs.status().busy) return sendError(res, 409, "a job is running: plan the program when it has finished");
    try {
      const ProgramCoverage c = programs.plan(name);
      impl.recordAction(who, "program planned", {{"program", name}, {"laser", c.laser}, {"either", c.either}}, req);
      sendJson(res, coverageJson(c));
    } catch (const std::exception& e) {
      impl.recordAction(who, "program plan refused", {{"program", name}, {"reason", e.what()}}, req);
      return sendError(res, 422, e.what());
    }
  });
}

}  // namespace

void addApiRoutes(HmiServer::Impl& impl) {
  auto& s = impl.server;
  s.Get("/api/cell", [&impl](const httplib::Request&, httplib::Response& res) {
    json cell = cellJson(impl.jobs);
    if (impl.line_handshake) cell["line"] = lineJson(impl.line_handshake->state());
    sendJson(res, cell);
  });
  s.Get("/api/status", [&impl](const httplib::Request&, httplib::Response& res) {
    sendJson(res, statusJson(impl.jobs.status()));
  });
  // For the plant's monitoring: 200 while the cell can scan (findings may warn), 503 when it cannot.
  // Without a session (a monitoring probe on a panel with a login) only the status and findings.
  s.Get("/api/health", [&impl](const httplib::Request& req, httplib::Response& res) {
    const CellHealth health = impl.health();
    const bool with_detail = !impl.auth.loginRequired() || impl.sessionOf(req).has_value();
    sendJson(res, healthJson(health, with_detail), health.level == HealthLevel::Fault ? 503 : 200);
  });
  // The same findings for the panel's banner, always 200: a fault is what the banner shows, not a failed
  // request (a browser logs every 5xx as an error, and the cameras' first seconds are a fault).
  s.Get("/api/cell/health", [&impl](const httplib::Request&, httplib::Response& res) {
    sendJson(res, healthJson(impl.health(), true));
  });
  s.Get("/api/materials", [](const httplib::Request&, httplib::Response& res) {
    json names = json::array();
    for (const auto& m : report::builtInMaterials().materials()) names.push_back(m.name);
    sendJson(res, {{"materials", names}, {"default", report::kDefaultMaterial}});
  });
  s.Get("/api/calibration", [&impl](const httplib::Request&, httplib::Response& res) {
    json j = calibrationJson(impl.jobs.setup().calibration_dir, configInUse(impl.jobs));
    j["verify_available"] = impl.jobs.setup().verify.has_value();
    sendJson(res, j);
  });
  s.Get("/api/scan/cloud", [&impl](const httplib::Request&, httplib::Response& res) {
    // Everything the live view has been sent so far, for a page opened mid-scan (live_cloud.hpp).
    const LiveCloud::Snapshot c = impl.jobs.liveCloud().snapshot();
    sendJson(res, {{"run_id", c.run_id}, {"measured", c.measured}, {"shown", c.points.size()}, {"batches", c.batches},
                   {"xyz", c.points.xyz}, {"thickness", c.points.thickness}});
  });
  s.Post("/api/scan/start", [&impl](const httplib::Request& req, httplib::Response& res) { startScan(impl, req, res); });
  addProgramRoutes(s, impl);
  s.Post("/api/scan/abort", [&impl](const httplib::Request& req, httplib::Response& res) {
    const Session who = *impl.sessionOf(req);
    const auto refused = impl.jobs.abort("operator abort (" + who.user + ", on the panel)");
    impl.recordAction(who, "abort", {{"refused", refused.value_or("")}}, req);
    if (refused) return sendError(res, 409, *refused);
    sendJson(res, {{"aborting", true}}, 202);
  });
  s.Post("/api/verify", [&impl](const httplib::Request& req, httplib::Response& res) {
    const Session who = *impl.sessionOf(req);
    if (const auto refused = impl.jobs.startVerify(who.user)) {
      impl.recordAction(who, "verify refused", {{"reason", *refused}}, req);
      return sendError(res, 409, *refused);
    }
    impl.recordAction(who, "verify start", json::object(), req);
    sendJson(res, {{"started", true}, {"job", statusJson(impl.jobs.status())}}, 202);
  });
  s.Post("/api/calibrate", [&impl](const httplib::Request& req, httplib::Response& res) {
    const Session who = *impl.sessionOf(req);
    const json body = json::parse(req.body.empty() ? std::string("{}") : req.body, nullptr, false);
    if (body.is_discarded() || !body.is_object()) return sendError(res, 400, "the body is not a JSON object");
    if ((body.contains("sensors") && !body["sensors"].is_string()) || (body.contains("accept") && !body["accept"].is_boolean()))
      return sendError(res, 400, "\"sensors\" must be a string (digitizer, cameras, all) and \"accept\" true or false");
    const std::string sensors = body.value("sensors", std::string("all"));
    const bool accept = body.value("accept", false);
    if (sensors != "digitizer" && sensors != "cameras" && sensors != "all")
      return sendError(res, 400, "\"sensors\" must be digitizer, cameras or all, not \"" + sensors + "\"");
    if (const auto refused = impl.jobs.startCalibrate(sensors, accept, who.user)) {
      impl.recordAction(who, "calibrate refused", {{"reason", *refused}, {"sensors", sensors}}, req);
      return sendError(res, 409, *refused);
    }
    impl.recordAction(who, "calibrate start", {{"sensors", sensors}, {"accept", accept}}, req);
    sendJson(res, {{"started", true}, {"job", statusJson(impl.jobs.status())}}, 202);
  });
  s.Get("/api/actions", [&impl](const httplib::Request&, httplib::Response& res) {
    // The last 200 lines of the actions log, newest last.
    std::deque<std::string> lines;
    {
      std::lock_guard lock(impl.actions_mutex);
      std::ifstream in(impl.options.actions_log);
      for (std::string line; std::getline(in, line);) {
        lines.push_back(line);
        if (lines.size() > 200) lines.pop_front();
      }
    }
    json out = json::array();
    for (const auto& l : lines) out.push_back(json::parse(l, nullptr, false));
    sendJson(res, {{"actions", out}});
  });
}

}  // namespace stampscan::hmi
