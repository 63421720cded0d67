#include "stampscan/acquisition/scan_plan.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <sstream>

namespace stampscan::acquisition {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

// Numbers in a plan file: enough digits to read back what was written.
std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

// Numbers in a message for the operator.
std::string shown(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}


// Reading one plan file: every error names the file, the line and the field.
class PlanReader {
 public:
  PlanReader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const toml::node* node, const std::string& field, const std::string& what) const {
    std::string where = source_;
    if (node && node->source().begin.line > 0) where += ":" + std::to_string(node->source().begin.line);
    throw PlanError(where + ": " + field + " " + what);
  }
  [[noreturn]] void fail(const toml::table& owner, const std::string& field, const std::string& what) const {
    fail(static_cast<const toml::node*>(&owner), field, what);
  }

  double number(const toml::table& t, const std::string& key, const std::string& field, double fallback, bool required = false) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(t, field, "is missing");
      return fallback;
    }
    const std::optional<double> v = n->value<double>();
    if (!v || !std::isfinite(*v)) fail(n, field, "must be a number");
    return *v;
  }
  std::string text(const toml::table& t, const std::string& key, const std::string& field, const std::string& fallback,
                   bool required = false) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(t, field, "is missing");
      return fallback;
    }
    const std::optional<std::string> v = n->value<std::string>();
    if (!v) fail(n, field, "must be a string");
    return *v;
  }
  template <std::size_t N>
  std::array<double, N> numbers(const toml::table& t, const std::string& key, const std::string& field,
                                std::array<double, N> fallback, bool required = false) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(t, field, "is missing");
      return fallback;
    }
    const toml::array* a = n->as_array();
    if (!a || a->size() != N) fail(n, field, "must be a list of " + std::to_string(N) + " numbers");
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) {
      const std::optional<double> v = (*a)[i].value<double>();
      if (!v || !std::isfinite(*v)) fail(n, field, "must be a list of " + std::to_string(N) + " numbers");
      out[i] = *v;
    }
    return out;
  }
  void onlyKeys(const toml::table& t, const std::string& where, std::initializer_list<const char*> keys) const {
    for (const auto& [key, node] : t) {
      bool known = false;
      for (const char* k : keys) known = known || key.str() == k;
      if (!known) fail(&node, where + std::string(key.str()), "is not a known field");
    }
  }

 private:
  std::string source_;
};

HeadPose headPose(const PlanReader& in, const toml::table& t, const std::string& prefix, const char* position_key) {
  HeadPose p;
  p.position = in.numbers<3>(t, position_key, prefix + position_key, {}, true);
  const std::array<double, 2> head = in.numbers<2>(t, "head", prefix + "head", {0, 0});
  p.a = head[0] * kDeg;
  p.b = head[1] * kDeg;
  return p;
}

double moveSeconds(double distance, double speed, double accel) {
  if (distance <= 0) return 0;
  // Trapezoid: accelerate, cruise, brake; a triangle when the move is too short to reach speed.
  if (distance >= speed * speed / accel) return distance / speed + speed / accel;
  return 2 * std::sqrt(distance / accel);
}

double distance(const HeadPose& p, const HeadPose& q) {
  const double dx = p.position[0] - q.position[0], dy = p.position[1] - q.position[1], dz = p.position[2] - q.position[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace

std::size_t ScanPlan::sweepCount(std::optional<Scene> scene) const {
  std::size_t n = 0;
  for (const PlanStep& s : steps)
    if (const auto* w = std::get_if<SweepStep>(&s)) n += !scene || w->scene == *scene;
  return n;
}

std::size_t ScanPlan::stereoCount(std::optional<Scene> scene) const {
  std::size_t n = 0;
  for (const PlanStep& s : steps)
    if (const auto* v = std::get_if<StereoStep>(&s)) n += !scene || v->scene == *scene;
  return n;
}

HeadPose parkingPose(const MachineLimits& limits) {
  const auto& lo = limits.travel_min;
  const auto& hi = limits.travel_max;
  const double z = hi[2] - lo[2] >= 300 ? hi[2] - 150 : 0.5 * (lo[2] + hi[2]);
  return {{0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), z}, 0, 0};
}

std::string stepName(std::size_t k, const PlanStep& step) {
  return std::visit(
      [&](const auto& s) {
        const char* kind = std::is_same_v<std::decay_t<decltype(s)>, SweepStep> ? "sweep" : "stereo";
        return "step " + std::to_string(k + 1) + " (" + kind + " " + std::string(toString(s.scene)) + " " + std::to_string(s.index) + ")";
      },
      step);
}

double nearestHeadStop(double angle, const MachineLimits& limits) {
  if (limits.index_step <= 0) return angle;
  return std::round(angle / limits.index_step) * limits.index_step;
}

std::vector<std::string> checkPlan(const ScanPlan& plan, const MachineLimits& limits) {
  std::vector<std::string> problems;
  const char* axes = "xyz";
  auto checkPose = [&](const std::string& what, const HeadPose& p) {
    for (std::size_t i = 0; i < 3; ++i)
      if (p.position[i] < limits.travel_min[i] || p.position[i] > limits.travel_max[i])
        problems.push_back(what + " " + axes[i] + " = " + shown(p.position[i]) + " mm is outside the travel " +
                           shown(limits.travel_min[i]) + ".." + shown(limits.travel_max[i]));
    if (std::fabs(p.a) > limits.max_tilt + 1e-12)
      problems.push_back(what + " head tilt " + shown(p.a / kDeg) + " deg is beyond the head's +-" + shown(limits.max_tilt / kDeg));
    if (std::fabs(p.b) > limits.max_turn + 1e-12)
      problems.push_back(what + " head turn " + shown(p.b / kDeg) + " deg is beyond the head's +-" + shown(limits.max_turn / kDeg));
    if (limits.index_step > 0)
      for (const auto& [angle, name] : {std::pair{p.a, "tilt"}, std::pair{p.b, "turn"}}) {
        // The plan file holds degrees with a few decimals: a stop within 1e-4 degrees is the stop.
        const double steps = angle / limits.index_step;
        if (std::fabs(steps - std::round(steps)) * limits.index_step > 1e-4 * kDeg)
          problems.push_back(what + " head " + name + " " + shown(angle / kDeg) + " deg is not a stop of the indexing head (every " +
                             shown(limits.index_step / kDeg) + " deg)");
      }
  };
  auto checkSpeed = [&](const std::string& what, double v) {
    if (!(v >= limits.min_speed && v <= limits.max_speed))
      problems.push_back(what + " speed " + shown(v) + " mm/s is outside the machine's " + shown(limits.min_speed) + ".." +
                         shown(limits.max_speed));
  };
  if (plan.steps.empty()) problems.push_back("the plan has no steps");
  checkSpeed("travel", plan.travel_speed);
  checkPose("park", plan.park);
  for (std::size_t k = 0; k < plan.steps.size(); ++k) {
    const std::string name = stepName(k, plan.steps[k]);
    if (const auto* s = std::get_if<SweepStep>(&plan.steps[k])) {
      checkPose(name + ": start", s->start);
      checkPose(name + ": end", s->end);
      checkSpeed(name + ":", s->speed);
      if (s->start.a != s->end.a || s->start.b != s->end.b)
        problems.push_back(name + ": the head angles must not change during a sweep");
      if (distance(s->start, s->end) < 1e-3) problems.push_back(name + ": start and end are the same point");
    } else {
      const auto& v = std::get<StereoStep>(plan.steps[k]);
      checkPose(name + ": pose", v.pose);
      if (!(v.settle_s >= 0 && v.settle_s < 60)) problems.push_back(name + ": settle time must be 0..60 s");
    }
  }
  return problems;
}

double moveSeconds(const HeadPose& from, const HeadPose& to, double speed, const MachineLimits& limits) {
  // All axes of a GoTo on one trapezoidal progress from 0 to 1 (I++ DME §6.3.2.12: they start and
  // finish together), as fast as the slowest axis group allows: the ram at `speed` and the
  // acceleration, the head's angles at its own rate and acceleration.
  const double length = distance(from, to);
  const double turn = std::max(std::fabs(to.a - from.a), std::fabs(to.b - from.b));
  if (turn <= 0) return moveSeconds(length, speed, limits.acceleration);
  double rate = limits.head_rate / turn, accel = limits.head_acceleration / turn;
  if (length > 0) {
    rate = std::min(rate, speed / length);
    accel = std::min(accel, limits.acceleration / length);
  }
  return moveSeconds(1.0, rate, accel);
}

double sweepRunUp(double speed, double acceleration, double report_interval_s) {
  return 2 * report_interval_s * speed + speed * speed / (2 * acceleration);
}

double motionSeconds(const ScanPlan& plan, const MachineLimits& limits) {
  double t = 0;
  HeadPose at = plan.park;
  for (const PlanStep& step : plan.steps) {
    if (const auto* s = std::get_if<SweepStep>(&step)) {
      t += moveSeconds(at, s->start, plan.travel_speed, limits);
      t += moveSeconds(s->start, s->end, s->speed, limits);
      at = s->end;
    } else {
      const auto& v = std::get<StereoStep>(step);
      t += moveSeconds(at, v.pose, plan.travel_speed, limits) + v.settle_s;
      at = v.pose;
    }
  }
  return t + moveSeconds(at, plan.park, plan.travel_speed, limits);
}

ScanPlan parseScanPlan(const std::string& text, const std::string& source) {
  toml::table t;
  try {
    t = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    throw PlanError(source + ":" + std::to_string(e.source().begin.line) + ":" + std::to_string(e.source().begin.column) +
                    ": " + std::string(e.description()));
  }
  const PlanReader in(source);
  in.onlyKeys(t, "", {"name", "travel_speed", "park", "part", "step"});
  ScanPlan plan;
  plan.name = in.text(t, "name", "name", "");
  plan.travel_speed = in.number(t, "travel_speed", "travel_speed", plan.travel_speed);
  plan.park.position = in.numbers<3>(t, "park", "park", plan.park.position);
  if (const toml::node* part = t.get("part")) {
    const toml::table* p = part->as_table();
    if (!p) in.fail(part, "part", "must be a table ([part])");
    in.onlyKeys(*p, "part.", {"kind", "grid", "pitch", "circle_diameter", "line_width"});
    plan.part.kind = in.text(*p, "kind", "part.kind", plan.part.kind);
    plan.part.grid = in.text(*p, "grid", "part.grid", plan.part.grid);
    if (plan.part.grid != "circle" && plan.part.grid != "square")
      in.fail(p->get("grid"), "part.grid", "must be \"circle\" or \"square\"");
    for (auto [key, value] : {std::pair{"pitch", &plan.part.pitch}, std::pair{"circle_diameter", &plan.part.circle_diameter},
                              std::pair{"line_width", &plan.part.line_width}}) {
      *value = in.number(*p, key, std::string("part.") + key, *value);
      if (!(*value > 0)) in.fail(p->get(key), std::string("part.") + key, "must be positive");
    }
  }
  const toml::node* steps = t.get("step");
  if (!steps) in.fail(t, "step", "is missing: a plan needs at least one [[step]]");
  const toml::array* list = steps->as_array();
  if (!list) in.fail(steps, "step", "must be an array of tables ([[step]])");
  for (std::size_t k = 0; k < list->size(); ++k) {
    const toml::table* s = (*list)[k].as_table();
    const std::string prefix = "step[" + std::to_string(k + 1) + "].";
    if (!s) in.fail(&(*list)[k], prefix, "must be a table");
    const std::string kind = in.text(*s, "kind", prefix + "kind", "", true);
    const std::optional<Scene> named = trace::sceneFromString(in.text(*s, "scene", prefix + "scene", std::string(toString(Scene::Part))));
    if (!named) in.fail(s->get("scene"), prefix + "scene", "must be one of " + trace::sceneNames());
    const Scene scene = *named;
    const double index = in.number(*s, "index", prefix + "index", -1);
    if (kind == "sweep") {
      in.onlyKeys(*s, prefix, {"kind", "scene", "index", "start", "end", "head", "speed", "expected_elements"});
      SweepStep w;
      w.scene = scene;
      w.index = index >= 0 ? static_cast<std::uint32_t>(index) : static_cast<std::uint32_t>(plan.sweepCount(scene));
      w.start = headPose(in, *s, prefix, "start");
      w.end = headPose(in, *s, prefix, "end");
      w.end.a = w.start.a;
      w.end.b = w.start.b;
      w.speed = in.number(*s, "speed", prefix + "speed", w.speed);
      if (!(w.speed > 0)) in.fail(s->get("speed"), prefix + "speed", "must be positive");
      const double expected = in.number(*s, "expected_elements", prefix + "expected_elements", 0);
      if (!(expected >= 0 && expected < 1e9 && expected == std::floor(expected)))
        in.fail(s->get("expected_elements"), prefix + "expected_elements", "must be a whole number of elements, 0 or more");
      w.expected_elements = static_cast<std::uint32_t>(expected);
      plan.steps.emplace_back(w);
    } else if (kind == "stereo") {
      in.onlyKeys(*s, prefix, {"kind", "scene", "index", "pose", "head", "settle"});
      StereoStep v;
      v.scene = scene;
      v.index = index >= 0 ? static_cast<std::uint32_t>(index) : static_cast<std::uint32_t>(plan.stereoCount(scene));
      v.pose = headPose(in, *s, prefix, "pose");
      v.settle_s = in.number(*s, "settle", prefix + "settle", v.settle_s);
      plan.steps.emplace_back(v);
    } else {
      in.fail(s->get("kind"), prefix + "kind", "must be \"sweep\" or \"stereo\", is \"" + kind + "\"");
    }
  }
  return plan;
}

ScanPlan loadScanPlan(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw PlanError(file.string() + ": the plan file does not exist");
  // Only regular files: a FIFO would block the read forever.
  if (!std::filesystem::is_regular_file(file, ec))
    throw PlanError(file.string() + ": not a regular file (a folder, FIFO or device), not a plan file");
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) throw PlanError(file.string() + ": cannot be read");
  return parseScanPlan(text.str(), file.string());
}

std::string toToml(const ScanPlan& plan) {
  std::ostringstream o;
  // (Streams rather than string sums: GCC 12 warns falsely on the latter, -Wrestrict.)
  auto triple = [](const std::array<double, 3>& p) {
    std::ostringstream t;
    t << '[' << fmt(p[0]) << ", " << fmt(p[1]) << ", " << fmt(p[2]) << ']';
    return t.str();
  };
  auto head = [](const HeadPose& p) {
    std::ostringstream t;
    t << '[' << fmt(p.a / kDeg) << ", " << fmt(p.b / kDeg) << ']';
    return t.str();
  };
  o << "name = " << toml::value<std::string>(plan.name) << "\n";
  o << "travel_speed = " << fmt(plan.travel_speed) << "\n";
  o << "park = " << triple(plan.park.position) << "\n\n";
  o << "[part]\nkind = " << toml::value<std::string>(plan.part.kind) << "\ngrid = " << toml::value<std::string>(plan.part.grid)
    << "\npitch = " << fmt(plan.part.pitch) << "\ncircle_diameter = " << fmt(plan.part.circle_diameter)
    << "\nline_width = " << fmt(plan.part.line_width) << "\n";
  for (const PlanStep& step : plan.steps) {
    if (const auto* s = std::get_if<SweepStep>(&step)) {
      o << "\n[[step]]\nkind = \"sweep\"\nscene = \"" << toString(s->scene) << "\"\nindex = " << s->index << "\nstart = "
        << triple(s->start.position) << "\nend = " << triple(s->end.position) << "\nhead = " << head(s->start)
        << "\nspeed = " << fmt(s->speed) << "\n";
      if (s->expected_elements > 0) o << "expected_elements = " << s->expected_elements << "\n";
    } else {
      const auto& v = std::get<StereoStep>(step);
      o << "\n[[step]]\nkind = \"stereo\"\nscene = \"" << toString(v.scene) << "\"\nindex = " << v.index << "\npose = "
        << triple(v.pose.position) << "\nhead = " << head(v.pose) << "\nsettle = " << fmt(v.settle_s) << "\n";
    }
  }
  return o.str();
}

}  // namespace stampscan::acquisition
