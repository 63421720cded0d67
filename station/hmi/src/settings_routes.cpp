// The cell's settings (maintenance role, checked by the gate in hmi_server.cpp): GET and POST
// /api/settings. What may be set, and where a change goes, is cell_settings.hpp's; every change and
// every refused one is written to the actions log with who asked. See API.md.
#include "server_impl.hpp"
#include "stampscan/hmi/cell_settings.hpp"

namespace stampscan::hmi {

using nlohmann::json;

namespace {

// The cell file a change is written to; empty for the built-in virtual cell, which has none.
std::filesystem::path cellFile(const HmiServer::Impl& impl) {
  const std::string& source = impl.jobs.cell().config().source;
  return source.empty() || source == "built-in" ? std::filesystem::path() : std::filesystem::path(source);
}

json settingsJson(const HmiServer::Impl& impl) {
  json ranges = json::array();
  for (const SettingRange& r : cellSettingRanges())
    ranges.push_back({{"key", r.key}, {"unit", r.unit}, {"min", r.min}, {"max", r.max}, {"what", r.what}});
  const auto file = cellFile(impl);
  return {{"settings", settingsOf(impl.jobs.calibrationPolicy())},
          {"ranges", ranges},
          {"cell_file", file.empty() ? json(nullptr) : json(file.string())},
          {"persisted", !file.empty()},
          {"note", file.empty() ? "the built-in virtual cell has no cell file: a change holds until the panel stops"
                                : "a change is written to the cell file's [calibration] table"}};
}

void changeSettings(HmiServer::Impl& impl, const httplib::Request& req, httplib::Response& res) {
  const Session who = *impl.sessionOf(req);
  const json body = json::parse(req.body, nullptr, false);
  const auto refuse = [&](int status, const std::string& why) {
    impl.recordAction(who, "settings refused", {{"reason", why}}, req);
    sendError(res, status, why);
  };
  if (body.is_discarded() || !body.is_object() || body.empty())
    return refuse(400, "the body must be a JSON object of settings to change, e.g. {\"validity_days\": 5}");
  std::map<std::string, double> changes;
  for (const auto& [key, value] : body.items()) {
    if (!value.is_number()) return refuse(400, "'" + key + "' must be a number");
    changes[key] = value.get<double>();
  }
  std::lock_guard lock(impl.settings_mutex);
  const acquisition::CalibrationPolicy before = impl.jobs.calibrationPolicy();
  acquisition::CalibrationPolicy after;
  try {
    after = withSettings(before, changes);
  } catch (const SettingsError& e) {
    return refuse(400, e.what());
  }
  // The file first: a change that cannot be kept is not applied either.
  if (const auto file = cellFile(impl); !file.empty()) {
    try {
      writeCellSettings(file, changes);
    } catch (const std::exception& e) {
      return refuse(500, e.what());
    }
  }
  impl.jobs.setCalibrationPolicy(after);
  json detail = json::object();
  const auto old_values = settingsOf(before);
  for (const auto& [key, value] : changes) detail[key] = {{"from", old_values.at(key)}, {"to", value}};
  json what = {{"changes", detail}};
  if (const auto file = cellFile(impl); !file.empty()) what["cell_file"] = file.string();
  impl.recordAction(who, "settings change", what, req);
  sendJson(res, settingsJson(impl));
}

}  // namespace

void addSettingsRoutes(HmiServer::Impl& impl) {
  impl.server.Get("/api/settings", [&impl](const httplib::Request&, httplib::Response& res) {
    sendJson(res, settingsJson(impl));
  });
  impl.server.Post("/api/settings", [&impl](const httplib::Request& req, httplib::Response& res) {
    changeSettings(impl, req, res);
  });
}

}  // namespace stampscan::hmi
