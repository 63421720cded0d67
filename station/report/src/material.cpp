#include "stampscan/report/material.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <sstream>

namespace stampscan::report {

namespace {

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// Reads one [[material]] table; `where` is "FILE: material N" for messages.
class EntryReader {
 public:
  EntryReader(const toml::table& t, std::string where) : t_(t), where_(std::move(where)) {}

  std::string text(const char* key, bool required) const {
    const auto node = t_[key];
    if (!node) {
      if (required) fail(std::string("has no ") + key);
      return {};
    }
    const auto value = node.value<std::string>();
    if (!value) fail(std::string(key) + " must be a string");
    return *value;
  }
  // A number (integer or float) above zero.
  double positive(const char* key, bool required, double fallback) const {
    const auto node = t_[key];
    if (!node) {
      if (required) fail(std::string("has no ") + key);
      return fallback;
    }
    const auto value = node.value<double>();
    if (!value || !std::isfinite(*value) || *value <= 0) fail(std::string(key) + " must be a number above zero");
    return *value;
  }
  std::vector<FldPoint> points(const char* key) const {
    std::vector<FldPoint> out;
    const auto node = t_[key];
    if (!node) return out;
    const toml::array* list = node.as_array();
    if (!list) fail(std::string(key) + " must be a list of [minor, major] pairs");
    for (std::size_t i = 0; i < list->size(); ++i) {
      const toml::array* pair = (*list)[i].as_array();
      const auto minor = pair && pair->size() == 2 ? (*pair)[0].value<double>() : std::nullopt;
      const auto major = pair && pair->size() == 2 ? (*pair)[1].value<double>() : std::nullopt;
      if (!minor || !major)
        fail(std::string(key) + " entry " + std::to_string(i + 1) + " must be a [minor, major] pair of numbers");
      out.push_back({*minor, *major});
    }
    return out;
  }
  void onlyKnownKeys(const std::set<std::string>& known) const {
    for (const auto& [key, value] : t_)
      if (!known.contains(std::string(key.str())))
        fail("has an unknown key '" + std::string(key.str()) +
             "' (known: name, family, thickness_mm, n, "
             "safety_margin_percent, flc_engineering_percent, description)");
  }
  [[noreturn]] void fail(const std::string& what) const { throw MaterialError(where_ + ": " + what); }
  const std::string& where() const { return where_; }

 private:
  const toml::table& t_;
  std::string where_;
};

Material readMaterial(const toml::table& t, const std::string& where) {
  const EntryReader in(t, where);
  in.onlyKnownKeys(
      {"name", "family", "thickness_mm", "n", "safety_margin_percent", "flc_engineering_percent", "description"});
  Material m;
  m.name = in.text("name", true);
  if (m.name.empty()) in.fail("has an empty name");
  const EntryReader named(t, where + " (" + m.name + ")");
  const std::string family = lower(named.text("family", true));
  if (family == "steel")
    m.family = MaterialFamily::Steel;
  else if (family == "aluminium" || family == "aluminum")
    m.family = MaterialFamily::Aluminium;
  else
    named.fail("family must be \"steel\" or \"aluminium\", not \"" + family + "\"");
  m.thickness_mm = named.positive("thickness_mm", true, 0);
  m.n = named.positive("n", true, 0);
  m.safety_margin_percent = named.positive("safety_margin_percent", false, defaultSafetyMarginPercent(m.family));
  m.description = named.text("description", false);
  std::vector<FldPoint> points = named.points("flc_engineering_percent");
  try {
    m.flc = points.empty() ? FormingLimitCurve::keelerBrazier(keelerBrazierFlc0(m.thickness_mm, m.n))
                           : FormingLimitCurve::measured(std::move(points));
  } catch (const std::invalid_argument& e) {
    named.fail(e.what());
  }
  return m;
}

}  // namespace

const char* toString(MaterialFamily family) { return family == MaterialFamily::Steel ? "steel" : "aluminium"; }

double defaultSafetyMarginPercent(MaterialFamily family) { return family == MaterialFamily::Steel ? 10.0 : 8.0; }

void MaterialLibrary::add(Material material) {
  const std::string key = lower(material.name);
  for (Material& m : materials_)
    if (lower(m.name) == key) {
      m = std::move(material);
      return;
    }
  materials_.push_back(std::move(material));
}

bool MaterialLibrary::contains(const std::string& name) const {
  const std::string key = lower(name);
  return std::any_of(materials_.begin(), materials_.end(), [&](const Material& m) { return lower(m.name) == key; });
}

const Material& MaterialLibrary::find(const std::string& name) const {
  const std::string key = lower(name);
  for (const Material& m : materials_)
    if (lower(m.name) == key) return m;
  throw MaterialError("unknown material '" + name + "' (known: " + names() + ")");
}

std::string MaterialLibrary::names() const {
  std::string out;
  for (const Material& m : materials_) out += (out.empty() ? "" : ", ") + m.name;
  return out.empty() ? "none" : out;
}

MaterialLibrary parseMaterials(const std::string& text, const std::string& source) {
  toml::table t;
  try {
    t = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    throw MaterialError(source + ":" + std::to_string(e.source().begin.line) + ":" +
                        std::to_string(e.source().begin.column) + ": " + std::string(e.description()));
  }
  for (const auto& [key, value] : t)
    if (key.str() != "material")
      throw MaterialError(source + ": unknown top-level key '" + std::string(key.str()) +
                          "' (expected [[material]] tables)");
  MaterialLibrary library;
  const toml::array* entries = t["material"].as_array();
  if (!entries || entries->empty()) throw MaterialError(source + ": no [[material]] entry");
  std::set<std::string> seen;
  for (std::size_t i = 0; i < entries->size(); ++i) {
    const std::string where = source + ": material " + std::to_string(i + 1);
    const toml::table* entry = (*entries)[i].as_table();
    if (!entry) throw MaterialError(where + ": not a table");
    Material m = readMaterial(*entry, where);
    if (!seen.insert(lower(m.name)).second) throw MaterialError(where + ": '" + m.name + "' is defined twice");
    library.add(std::move(m));
  }
  return library;
}

MaterialLibrary loadMaterials(const std::filesystem::path& file) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error))
    throw MaterialError(file.string() + ": no such material library (not a regular file)");
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in && !in.eof()) throw MaterialError(file.string() + ": cannot be read");
  return parseMaterials(text.str(), file.string());
}

const MaterialLibrary& builtInMaterials() {
  static const MaterialLibrary library = parseMaterials(builtInMaterialsText(), "materials.toml (built in)");
  return library;
}

MaterialLibrary materialsWith(const std::filesystem::path& file) {
  MaterialLibrary library = builtInMaterials();
  if (!file.empty()) {
    const MaterialLibrary plant = loadMaterials(file);
    for (const Material& m : plant.materials()) library.add(m);
  }
  return library;
}

}  // namespace stampscan::report
