#include "stampscan/run_folder/run_record.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

namespace stampscan::run_folder {

namespace {

using json = nlohmann::json;

json optionalNumber(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

json encode(const PathUncertainty& p) {
  return {{"strain", p.strain},
          {"strain_shared", optionalNumber(p.strain_shared)},
          {"position_mm", p.position_mm},
          {"position_shared_mm", optionalNumber(p.position_shared_mm)},
          {"twin_pairs", p.twin_pairs}};
}

json encode(const ScanFigures& s) {
  const TimeSpent& t = s.spent_seconds;
  return {{"sweeps", s.sweeps},
          {"wall_seconds", s.wall_seconds},
          {"motion_seconds", s.motion_seconds},
          {"profiles", s.profiles},
          {"lost_profiles", s.lost_profiles},
          {"sweeps_repeated", s.sweeps_repeated},
          {"sweeps_over_loss_limit", s.sweeps_over_loss_limit},
          {"stereo_views", s.stereo_views},
          {"stereo_views_missing", s.stereo_views_missing},
          {"positions", s.positions},
          {"spent_seconds", {{"moving", t.moving},
                             {"settling", t.settling},
                             {"waiting_for_frames", t.waiting_for_frames},
                             {"clock_sync", t.clock_sync},
                             {"digitizer_start_drain_stop", t.digitizer_start_drain_stop},
                             {"other", t.other}}}};
}

json encode(const MeasurementFigures& m) {
  json j = {{"elements", m.elements},
            {"measurements", m.measurements},
            {"seconds_after_scan", m.seconds_after_scan},
            {"cloud4d_seconds_after_scan", m.cloud4d_seconds_after_scan},
            {"digitizer_latency_ms", m.digitizer_latency_ms}};
  j["uncertainty"] = {{"laser", m.laser_uncertainty ? encode(*m.laser_uncertainty) : json(nullptr)},
                      {"stereo", m.stereo_uncertainty ? encode(*m.stereo_uncertainty) : json(nullptr)}};
  if (m.sphere_residual_mm) j["sphere_residual_mm"] = *m.sphere_residual_mm;
  if (const auto& s = m.surface)
    j["surface"] = {{"laser_returns", s->laser_returns},
                    {"points", s->points},
                    {"points_without_strain", s->points_without_strain},
                    {"mesh_triangles", s->mesh_triangles},
                    {"shape_bandwidth_median_mm", s->shape_bandwidth_median_mm},
                    {"strain_bandwidth_median_mm", s->strain_bandwidth_median_mm},
                    {"seconds", s->seconds}};
  return j;
}

json encode(const AccuracyFigures& a) {
  json j = {{"matched", a.matched},
            {"position_rms_mm", a.position_rms_mm},
            {"strain_rms", a.strain_rms},
            {"strain_within_expanded_uncertainty", a.strain_within_expanded_uncertainty},
            {"true_latency_ms", a.true_latency_ms}};
  if (const auto& v = a.visible)
    j["visible"] = {{"elements", v->elements}, {"found", v->found}, {"found_not_visible", v->found_not_visible}};
  if (const auto& f = a.surface_strain)
    j["surface_strain"] = {{"elements", f->elements},
                           {"at_elements_rms", f->at_elements_rms},
                           {"elements_own_rms", f->elements_own_rms},
                           {"between_points", f->between_points},
                           {"between_rms", f->between_rms},
                           {"within_grid_points", f->within_grid_points},
                           {"within_grid_without_strain", f->within_grid_without_strain}};
  for (const auto& [key, figures] : {std::pair{"laser", &a.laser_led}, std::pair{"stereo", &a.stereo_led}})
    if (const auto& f = *figures)
      j["by_sensor"][key] = {{"matched", f->matched}, {"position_rms_mm", f->position_rms_mm}, {"strain_rms", f->strain_rms}};
  return j;
}

// One JSON object of the record, read member by member: a member that is absent or null leaves the
// field as it is; one of the wrong type throws RunRecordError naming the file and the member's path.
class Members {
 public:
  Members(const json& object, const std::string& file, std::string path)
      : object_(object), file_(file), path_(std::move(path)) {}

  void text(const char* key, std::string& out) const {
    if (const json* v = find(key)) {
      if (!v->is_string()) wrong(key, "a text", *v);
      out = v->get<std::string>();
    }
  }
  void number(const char* key, double& out) const {
    if (const json* v = find(key)) out = numberOf(key, *v);
  }
  void number(const char* key, std::optional<double>& out) const {
    if (const json* v = find(key)) out = numberOf(key, *v);
  }
  void count(const char* key, std::int64_t& out) const {
    if (const json* v = find(key)) {
      if (!v->is_number_integer()) wrong(key, "a whole number", *v);
      out = v->get<std::int64_t>();
    }
  }
  void flag(const char* key, bool& out) const {
    if (const json* v = find(key)) {
      if (!v->is_boolean()) wrong(key, "true or false", *v);
      out = v->get<bool>();
    }
  }
  void triple(const char* key, std::array<double, 3>& out) const {
    if (const json* v = find(key)) {
      if (!v->is_array() || v->size() != 3) wrong(key, "three numbers", *v);
      for (std::size_t k = 0; k < 3; ++k) out[k] = numberOf(key, (*v)[k]);
    }
  }
  void texts(const char* key, std::vector<std::string>& out) const {
    if (const json* v = find(key)) {
      if (!v->is_array()) wrong(key, "a list of texts", *v);
      for (const json& item : *v) {
        if (!item.is_string()) wrong(key, "a list of texts", *v);
        out.push_back(item.get<std::string>());
      }
    }
  }
  // A nested object: read by `fill` into `out` when present.
  template <typename T, typename Fill>
  void object(const char* key, std::optional<T>& out, Fill fill) const {
    if (const json* v = find(key)) {
      if (!v->is_object()) wrong(key, "an object", *v);
      T value;
      fill(Members(*v, file_, pathOf(key)), value);
      out = std::move(value);
    }
  }
  template <typename Each>
  void objects(const char* key, Each each) const {
    if (const json* v = find(key)) {
      if (!v->is_array()) wrong(key, "a list", *v);
      for (std::size_t k = 0; k < v->size(); ++k) {
        const std::string at = pathOf(key) + "[" + std::to_string(k) + "]";
        if (!(*v)[k].is_object()) throw RunRecordError(file_ + ": " + at + ": expected an object, found " + kindOf((*v)[k]));
        each(Members((*v)[k], file_, at));
      }
    }
  }

 private:
  const json* find(const char* key) const {
    const auto it = object_.find(key);
    return it == object_.end() || it->is_null() ? nullptr : &*it;
  }
  std::string pathOf(const char* key) const { return path_.empty() ? std::string(key) : path_ + "." + key; }
  static std::string kindOf(const json& v) {
    if (v.is_string()) return "a text";
    if (v.is_boolean()) return "true or false";
    if (v.is_number_integer()) return "a whole number";
    if (v.is_number()) return "a fractional number";
    if (v.is_array()) return "a list";
    if (v.is_object()) return "an object";
    return "null";
  }
  double numberOf(const char* key, const json& v) const {
    if (!v.is_number()) wrong(key, "a number", v);
    return v.get<double>();
  }
  [[noreturn]] void wrong(const char* key, const char* expected, const json& found) const {
    throw RunRecordError(file_ + ": " + pathOf(key) + ": expected " + expected + ", found " + kindOf(found));
  }

  const json& object_;
  const std::string& file_;
  std::string path_;
};

void readUncertainty(const Members& m, PathUncertainty& p) {
  m.number("strain", p.strain);
  m.number("strain_shared", p.strain_shared);
  m.number("position_mm", p.position_mm);
  m.number("position_shared_mm", p.position_shared_mm);
  m.count("twin_pairs", p.twin_pairs);
}

void readScan(const Members& m, ScanFigures& s) {
  m.count("sweeps", s.sweeps);
  m.number("wall_seconds", s.wall_seconds);
  m.number("motion_seconds", s.motion_seconds);
  m.count("profiles", s.profiles);
  m.count("lost_profiles", s.lost_profiles);
  m.count("sweeps_repeated", s.sweeps_repeated);
  m.count("sweeps_over_loss_limit", s.sweeps_over_loss_limit);
  m.count("stereo_views", s.stereo_views);
  m.count("stereo_views_missing", s.stereo_views_missing);
  m.count("positions", s.positions);
  std::optional<TimeSpent> spent;
  m.object("spent_seconds", spent, [](const Members& t, TimeSpent& out) {
    t.number("moving", out.moving);
    t.number("settling", out.settling);
    t.number("waiting_for_frames", out.waiting_for_frames);
    t.number("clock_sync", out.clock_sync);
    t.number("digitizer_start_drain_stop", out.digitizer_start_drain_stop);
    t.number("other", out.other);
  });
  if (spent) s.spent_seconds = *spent;
}

void readMeasurement(const Members& m, MeasurementFigures& f) {
  m.count("elements", f.elements);
  m.count("measurements", f.measurements);
  m.number("seconds_after_scan", f.seconds_after_scan);
  m.number("cloud4d_seconds_after_scan", f.cloud4d_seconds_after_scan);
  m.number("digitizer_latency_ms", f.digitizer_latency_ms);
  struct Paths {
    std::optional<PathUncertainty> laser, stereo;
  };
  std::optional<Paths> paths;
  m.object("uncertainty", paths, [](const Members& u, Paths& out) {
    u.object("laser", out.laser, readUncertainty);
    u.object("stereo", out.stereo, readUncertainty);
  });
  if (paths) {
    f.laser_uncertainty = paths->laser;
    f.stereo_uncertainty = paths->stereo;
  }
  m.number("sphere_residual_mm", f.sphere_residual_mm);
  m.object("surface", f.surface, [](const Members& s, SurfaceFigures& out) {
    s.count("laser_returns", out.laser_returns);
    s.count("points", out.points);
    s.count("points_without_strain", out.points_without_strain);
    s.count("mesh_triangles", out.mesh_triangles);
    s.number("shape_bandwidth_median_mm", out.shape_bandwidth_median_mm);
    s.number("strain_bandwidth_median_mm", out.strain_bandwidth_median_mm);
    s.number("seconds", out.seconds);
  });
}

void readAccuracy(const Members& m, AccuracyFigures& a) {
  m.count("matched", a.matched);
  m.number("position_rms_mm", a.position_rms_mm);
  m.number("strain_rms", a.strain_rms);
  m.number("strain_within_expanded_uncertainty", a.strain_within_expanded_uncertainty);
  m.number("true_latency_ms", a.true_latency_ms);
  m.object("visible", a.visible, [](const Members& v, VisibleFigures& out) {
    v.count("elements", out.elements);
    v.count("found", out.found);
    v.count("found_not_visible", out.found_not_visible);
  });
  m.object("surface_strain", a.surface_strain, [](const Members& s, SurfaceStrainFigures& out) {
    s.count("elements", out.elements);
    s.number("at_elements_rms", out.at_elements_rms);
    s.number("elements_own_rms", out.elements_own_rms);
    s.count("between_points", out.between_points);
    s.number("between_rms", out.between_rms);
    s.count("within_grid_points", out.within_grid_points);
    s.count("within_grid_without_strain", out.within_grid_without_strain);
  });
  struct BySensor {
    std::optional<SensorAccuracyFigures> laser, stereo;
  };
  std::optional<BySensor> by_sensor;
  m.object("by_sensor", by_sensor, [](const Members& b, BySensor& out) {
    const auto figures = [](const Members& f, SensorAccuracyFigures& x) {
      f.count("matched", x.matched);
      f.number("position_rms_mm", x.position_rms_mm);
      f.number("strain_rms", x.strain_rms);
    };
    b.object("laser", out.laser, figures);
    b.object("stereo", out.stereo, figures);
  });
  if (by_sensor) a.laser_led = by_sensor->laser, a.stereo_led = by_sensor->stereo;
}

}  // namespace

json toJson(const RunRecord& r) {
  json j = {{"part_id", r.part_id},
            {"plan", r.plan},
            {"cell", r.cell},
            {"trace", r.trace},
            {"completed", r.completed},
            {"fixture", {{"name", r.fixture.name},
                         {"datum_mm", r.fixture.datum_mm},
                         {"datum_rotation_deg", r.fixture.datum_rotation_deg}}},
            {"data_loss", r.data_loss.empty() ? json(nullptr) : json(r.data_loss)}};
  if (!r.completed) j["abort_reason"] = r.abort_reason;
  if (!r.started_by.empty()) j["started_by"] = r.started_by;
  if (!r.safety_events.empty()) j["safety_events"] = r.safety_events;
  for (const DeviceRecord& d : r.devices)
    j["devices"].push_back({{"family", d.family}, {"model", d.model}, {"serial", d.serial}, {"firmware", d.firmware}});
  if (r.calibration) j["calibration"] = {{"digitizer", r.calibration->digitizer}, {"cameras", r.calibration->cameras}};
  if (r.scan) j["scan"] = encode(*r.scan);
  if (r.measurement) j["measurement"] = encode(*r.measurement);
  if (r.accuracy) j["accuracy"] = encode(*r.accuracy);
  if (const auto& p = r.replay)
    j["replay"] = {{"recording", p->recording},
                   {"reference_measurements", p->reference_measurements},
                   {"matched", p->matched},
                   {"position_rms_mm", p->position_rms_mm},
                   {"strain_rms", p->strain_rms}};
  if (!r.material.empty()) j["material"] = r.material;
  if (!r.program.empty()) j["program"] = r.program;
  if (r.part_program) j["part_program"] = {{"name", r.part_program->name}, {"folder", r.part_program->folder}};
  return j;
}

RunRecord runRecordFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw RunRecordError(where + ": damaged (not a JSON object)");
  RunRecord r;
  const Members m(j, where, "");
  m.text("part_id", r.part_id);
  m.text("plan", r.plan);
  m.text("cell", r.cell);
  m.text("trace", r.trace);
  m.flag("completed", r.completed);
  m.text("abort_reason", r.abort_reason);
  m.text("started_by", r.started_by);
  m.texts("safety_events", r.safety_events);
  m.objects("devices", [&r](const Members& d) {
    DeviceRecord device;
    d.text("family", device.family);
    d.text("model", device.model);
    d.text("serial", device.serial);
    d.text("firmware", device.firmware);
    r.devices.push_back(std::move(device));
  });
  std::optional<FixtureRecord> fixture;
  m.object("fixture", fixture, [](const Members& f, FixtureRecord& out) {
    f.text("name", out.name);
    f.triple("datum_mm", out.datum_mm);
    f.triple("datum_rotation_deg", out.datum_rotation_deg);
  });
  if (fixture) r.fixture = *fixture;
  m.object("calibration", r.calibration, [](const Members& c, CalibrationUsed& out) {
    c.text("digitizer", out.digitizer);
    c.text("cameras", out.cameras);
  });
  m.object("scan", r.scan, readScan);
  m.object("measurement", r.measurement, readMeasurement);
  m.object("accuracy", r.accuracy, readAccuracy);
  m.object("replay", r.replay, [](const Members& p, ReplayFigures& out) {
    p.text("recording", out.recording);
    p.count("reference_measurements", out.reference_measurements);
    p.count("matched", out.matched);
    p.number("position_rms_mm", out.position_rms_mm);
    p.number("strain_rms", out.strain_rms);
  });
  m.text("data_loss", r.data_loss);
  m.text("material", r.material);
  m.text("program", r.program);
  m.object("part_program", r.part_program, [](const Members& p, PartProgramUsed& out) {
    p.text("name", out.name);
    p.text("folder", out.folder);
  });
  return r;
}

void writeRunRecord(const std::filesystem::path& run_dir, const RunRecord& record) {
  fitting::writeFileAtomically(run_dir / kRunRecordFile, toJson(record).dump(2) + "\n");
}

std::optional<RunRecord> readRunRecord(const std::filesystem::path& run_dir) {
  const std::filesystem::path file = run_dir / kRunRecordFile;
  std::error_code error;
  if (!std::filesystem::exists(file, error)) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw RunRecordError(file.string() + ": cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  json j;
  try {
    j = json::parse(text.str());
  } catch (const json::exception& e) {
    throw RunRecordError(file.string() + ": damaged (not valid JSON: " + e.what() + ")");
  }
  return runRecordFromJson(j, file.string());
}

}  // namespace stampscan::run_folder
