#include "stampscan/acquisition/part_program.hpp"

#include "stampscan/fitting/atomic_file.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>

namespace stampscan::acquisition {

namespace fs = std::filesystem;

namespace {

// Reading one program file: every error is one line naming the file, the section and the key.
class ProgramReader {
 public:
  explicit ProgramReader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& section, const std::string& key, const std::string& what) const {
    throw ProgramError(source_ + ": " + (section.empty() ? "" : section + " ") + key + " " + what);
  }

  // A section ([grid]) or nullptr when it is absent and optional.
  const toml::table* section(const toml::table& top, const char* key, bool required) const {
    const toml::node* n = top.get(key);
    if (!n) {
      if (required) fail("", std::string("[") + key + "]", "is missing");
      return nullptr;
    }
    if (!n->is_table()) fail("", key, "must be a table ([" + std::string(key) + "])");
    return n->as_table();
  }

  std::optional<std::string> text(const toml::table& t, const std::string& section, const char* key, bool required) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(section, key, "is missing");
      return std::nullopt;
    }
    const std::optional<std::string> v = n->value<std::string>();
    if (!v) fail(section, key, "must be a string, found " + typeOf(*n));
    return v;
  }

  std::optional<double> positive(const toml::table& t, const std::string& section, const char* key, bool required) const {
    const toml::node* n = t.get(key);
    if (!n) {
      if (required) fail(section, key, "is missing");
      return std::nullopt;
    }
    const std::optional<double> v = n->value<double>();
    if (!v) fail(section, key, "must be a positive number, found " + typeOf(*n));
    if (!std::isfinite(*v) || !(*v > 0)) fail(section, key, "must be a positive number");
    return v;
  }

  // An optional integer in [low, high].
  std::optional<std::int64_t> integer(const toml::table& t, const std::string& section, const char* key,
                                      std::int64_t low, std::int64_t high) const {
    const toml::node* n = t.get(key);
    if (!n) return std::nullopt;
    const std::optional<std::int64_t> v = n->as_integer() ? n->value<std::int64_t>() : std::nullopt;
    const std::string range = "must be a whole number from " + std::to_string(low) + " to " + std::to_string(high);
    if (!v) fail(section, key, range + ", found " + typeOf(*n));
    if (*v < low || *v > high) fail(section, key, range);
    return v;
  }

  std::array<double, 2> pair(const toml::table& t, const std::string& section, const char* key) const {
    const toml::node* n = t.get(key);
    if (!n) fail(section, key, "is missing");
    const toml::array* a = n->as_array();
    const std::string expected = "must be a list of 2 numbers (x, y in mm)";
    if (!a || a->size() != 2) fail(section, key, expected);
    std::array<double, 2> out{};
    for (std::size_t i = 0; i < 2; ++i) {
      const std::optional<double> v = (*a)[i].value<double>();
      if (!v || !std::isfinite(*v)) fail(section, key, expected);
      out[i] = *v;
    }
    return out;
  }

  void onlyKeys(const toml::table& t, const std::string& section, std::initializer_list<const char*> keys) const {
    for (const auto& [key, node] : t) {
      const bool known = std::any_of(keys.begin(), keys.end(), [&](const char* k) { return key.str() == k; });
      if (!known) fail(section, std::string(key.str()), "is not a known key");
    }
  }

 private:
  static std::string typeOf(const toml::node& n) {
    std::ostringstream type;
    type << n.type();  // toml++'s name: string, integer, boolean, array, table, ...
    return (type.str().find_first_of("aeiou") == 0 ? "an " : "a ") + type.str();
  }

  std::string source_;
};

// A file named in program.toml: relative to the program's folder, of an expected kind.
fs::path relativeFile(const ProgramReader& in, const toml::table& top, const char* key, bool required = true) {
  const std::optional<std::string> given = in.text(top, "", key, required);
  if (!given) return {};
  const fs::path file = *given;
  if (file.empty()) in.fail("", key, "must name a file");
  if (file.is_absolute()) in.fail("", key, "must be a path relative to the program's folder");
  return file;
}

std::string number(double v) {
  // The shortest text that reads back as the same double.
  char buf[32];
  const auto [end, error] = std::to_chars(buf, buf + sizeof buf, v);
  return error == std::errc() ? std::string(buf, end) : std::string("nan");
}

std::string quoted(const std::string& s) {
  std::ostringstream o;
  o << toml::value<std::string>(s);
  return o.str();
}

bool same(double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(std::fabs(a), std::fabs(b)); }

fs::path programFileOf(const fs::path& dir_or_file) {
  std::error_code ec;
  if (fs::is_directory(dir_or_file, ec)) return dir_or_file / kProgramFile;
  return dir_or_file;
}

}  // namespace

PartProgram parseProgramFile(const std::string& text, const std::string& source) {
  toml::table top;
  try {
    top = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    throw ProgramError(source + ":" + std::to_string(e.source().begin.line) + ":" + std::to_string(e.source().begin.column) +
                       ": " + std::string(e.description()));
  }
  const ProgramReader in(source);
  in.onlyKeys(top, "", {"name", "description", "model", "plan", "press_program", "line_number", "grid", "sheet", "region", "simulation"});
  PartProgram p;
  p.name = *in.text(top, "", "name", true);
  if (p.name.empty()) in.fail("", "name", "must not be empty");
  p.description = in.text(top, "", "description", false).value_or("");
  p.press_program = in.text(top, "", "press_program", false).value_or("");
  if (const auto number = in.integer(top, "", "line_number", 1, 65535)) p.line_number = static_cast<std::uint16_t>(*number);
  p.model_file = relativeFile(in, top, "model");
  std::string ext = p.model_file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext != ".stl" && ext != ".step" && ext != ".stp") in.fail("", "model", "must name a .stl, .step or .stp file");
  p.plan_file = relativeFile(in, top, "plan", false);  // none yet: `station plan --into-program` makes one

  const toml::table& grid = *in.section(top, "grid", true);
  in.onlyKeys(grid, "[grid]", {"kind", "pitch_mm", "circle_diameter_mm", "line_width_mm"});
  p.grid.kind = *in.text(grid, "[grid]", "kind", true);
  if (p.grid.kind != "circle" && p.grid.kind != "square") in.fail("[grid]", "kind", "must be \"circle\" or \"square\"");
  p.grid.pitch_mm = *in.positive(grid, "[grid]", "pitch_mm", true);
  // A square grid has no circles: the diameter is optional there (the plan file carries one anyway).
  p.grid.circle_diameter_mm = in.positive(grid, "[grid]", "circle_diameter_mm", p.grid.kind == "circle").value_or(p.grid.pitch_mm);
  p.grid.line_width_mm = *in.positive(grid, "[grid]", "line_width_mm", true);
  if (p.grid.line_width_mm >= p.grid.pitch_mm) in.fail("[grid]", "line_width_mm", "must be less than pitch_mm");

  const toml::table& sheet = *in.section(top, "sheet", true);
  in.onlyKeys(sheet, "[sheet]", {"material", "thickness_mm"});
  p.material = *in.text(sheet, "[sheet]", "material", true);
  if (p.material.empty()) in.fail("[sheet]", "material", "must not be empty");
  p.sheet_thickness_mm = *in.positive(sheet, "[sheet]", "thickness_mm", true);

  if (const toml::node* regions = top.get("region")) {
    const toml::array* list = regions->as_array();
    if (!list) in.fail("", "region", "must be an array of tables ([[region]])");
    for (std::size_t k = 0; k < list->size(); ++k) {
      const std::string where = "[[region]] " + std::to_string(k + 1);
      const toml::table* r = (*list)[k].as_table();
      if (!r) in.fail(where, "", "must be a table");
      in.onlyKeys(*r, where, {"name", "min_mm", "max_mm"});
      RegionOfInterest roi;
      roi.name = *in.text(*r, where, "name", true);
      roi.min_mm = in.pair(*r, where, "min_mm");
      roi.max_mm = in.pair(*r, where, "max_mm");
      if (!(roi.min_mm[0] < roi.max_mm[0] && roi.min_mm[1] < roi.max_mm[1]))
        in.fail(where, "max_mm", "must be greater than min_mm in x and y");
      p.regions.push_back(roi);
    }
  }

  if (const toml::table* sim = in.section(top, "simulation", false)) {
    in.onlyKeys(*sim, "[simulation]", {"part", "scale", "depth_mm", "peak_strain"});
    p.simulated_part = *in.text(*sim, "[simulation]", "part", true);
    if (p.simulated_part != "dome" && p.simulated_part != "pan") in.fail("[simulation]", "part", "must be \"dome\" or \"pan\"");
    // Within these the families stay parts a press makes and the virtual cell's sensors can scan.
    p.simulation.scale = in.positive(*sim, "[simulation]", "scale", false).value_or(1.0);
    if (p.simulation.scale < 0.5 || p.simulation.scale > 2) in.fail("[simulation]", "scale", "must be within 0.5 .. 2");
    p.simulation.depth_mm = in.positive(*sim, "[simulation]", "depth_mm", false).value_or(0.0);
    if (p.simulation.depth_mm > 60) in.fail("[simulation]", "depth_mm", "must be at most 60 mm");
    p.simulation.peak_strain = in.positive(*sim, "[simulation]", "peak_strain", false).value_or(0.0);
    if (p.simulation.peak_strain > 0.5) in.fail("[simulation]", "peak_strain", "must be at most 0.5");
  }
  return p;
}

std::vector<std::string> checkConsistency(const PartProgram& p) {
  std::vector<std::string> problems;
  if (!p.hasPlan()) return problems;
  const PartSpec& part = p.plan.part;
  const std::string plan = "the plan's [part] ";
  if (part.grid != p.grid.kind) problems.push_back("[grid] kind is \"" + p.grid.kind + "\" but " + plan + "grid is \"" + part.grid + "\"");
  if (!same(part.pitch, p.grid.pitch_mm))
    problems.push_back("[grid] pitch_mm is " + number(p.grid.pitch_mm) + " but " + plan + "pitch is " + number(part.pitch));
  if (p.grid.kind == "circle" && !same(part.circle_diameter, p.grid.circle_diameter_mm))
    problems.push_back("[grid] circle_diameter_mm is " + number(p.grid.circle_diameter_mm) + " but " + plan + "circle_diameter is " +
                       number(part.circle_diameter));
  if (!same(part.line_width, p.grid.line_width_mm))
    problems.push_back("[grid] line_width_mm is " + number(p.grid.line_width_mm) + " but " + plan + "line_width is " +
                       number(part.line_width));
  if (!p.simulated_part.empty() && part.kind != p.simulated_part)
    problems.push_back("[simulation] part is \"" + p.simulated_part + "\" but " + plan + "kind is \"" + part.kind + "\"");
  return problems;
}

PartProgram loadPartProgram(const fs::path& dir_or_file) {
  std::error_code ec;
  if (!fs::exists(dir_or_file, ec)) throw ProgramError(dir_or_file.string() + ": no such part program folder or program file");
  const fs::path file = programFileOf(dir_or_file);
  if (!fs::exists(file, ec)) throw ProgramError(dir_or_file.string() + ": not a part program folder (it has no " + kProgramFile + ")");
  if (!fs::is_regular_file(file, ec)) throw ProgramError(file.string() + ": not a regular file, not a program file");
  std::ifstream stream(file, std::ios::binary);
  std::ostringstream text;
  text << stream.rdbuf();
  if (!stream) throw ProgramError(file.string() + ": cannot be read");
  PartProgram p = parseProgramFile(text.str(), file.string());
  p.folder = file.parent_path();

  const ProgramReader in(file.string());
  for (const auto& [key, name] : {std::pair{"plan", p.plan_file}, std::pair{"model", p.model_file}}) {
    if (name.empty()) continue;  // a program without a plan yet
    const fs::path path = p.folder / name;
    if (!fs::exists(path, ec)) in.fail("", key, "names \"" + name.string() + "\", which does not exist in " + p.folder.string());
    if (!fs::is_regular_file(path, ec)) in.fail("", key, "names \"" + name.string() + "\", which is not a regular file");
  }
  if (p.hasPlan()) p.plan = loadScanPlan(p.folder / p.plan_file);
  const std::vector<std::string> problems = checkConsistency(p);
  if (!problems.empty()) {
    std::string line = file.string() + ": disagrees with " + (p.folder / p.plan_file).string() + ": ";
    for (std::size_t i = 0; i < problems.size(); ++i) line += (i ? "; " : "") + problems[i];
    throw ProgramError(line);
  }
  p.model = loadNominalModel(p.folder / p.model_file);
  return p;
}

std::string toToml(const PartProgram& p) {
  std::ostringstream o;
  o << "name = " << quoted(p.name) << "\n";
  if (!p.description.empty()) o << "description = " << quoted(p.description) << "\n";
  o << "model = " << quoted(p.model_file.generic_string()) << "\n";
  if (p.hasPlan()) o << "plan = " << quoted(p.plan_file.generic_string()) << "\n";
  if (!p.press_program.empty()) o << "press_program = " << quoted(p.press_program) << "\n";
  if (p.line_number) o << "line_number = " << *p.line_number << "\n";
  o << "\n[grid]\nkind = " << quoted(p.grid.kind) << "\npitch_mm = " << number(p.grid.pitch_mm)
    << "\ncircle_diameter_mm = " << number(p.grid.circle_diameter_mm) << "\nline_width_mm = " << number(p.grid.line_width_mm)
    << "\n";
  o << "\n[sheet]\nmaterial = " << quoted(p.material) << "\nthickness_mm = " << number(p.sheet_thickness_mm) << "\n";
  for (const RegionOfInterest& r : p.regions)
    o << "\n[[region]]\nname = " << quoted(r.name) << "\nmin_mm = [" << number(r.min_mm[0]) << ", " << number(r.min_mm[1])
      << "]\nmax_mm = [" << number(r.max_mm[0]) << ", " << number(r.max_mm[1]) << "]\n";
  if (!p.simulated_part.empty()) {
    o << "\n[simulation]\npart = " << quoted(p.simulated_part) << "\n";
    if (p.simulation.scale != 1) o << "scale = " << number(p.simulation.scale) << "\n";
    if (p.simulation.depth_mm > 0) o << "depth_mm = " << number(p.simulation.depth_mm) << "\n";
    if (p.simulation.peak_strain > 0) o << "peak_strain = " << number(p.simulation.peak_strain) << "\n";
  }
  return o.str();
}

void writePartProgram(const PartProgram& program, const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw ProgramError(dir.string() + ": cannot create the program folder: " + ec.message());
  fitting::writeFileAtomically(dir / kProgramFile, toToml(program));
}

std::vector<fs::path> listPrograms(const fs::path& library) {
  std::error_code ec;
  if (!fs::is_directory(library, ec)) throw ProgramError(library.string() + ": not a folder of part programs");
  std::vector<fs::path> programs;
  for (const fs::directory_entry& entry : fs::directory_iterator(library, ec))
    if (entry.is_directory(ec) && fs::is_regular_file(entry.path() / kProgramFile, ec)) programs.push_back(entry.path());
  std::sort(programs.begin(), programs.end());
  return programs;
}

fs::path findProgram(const fs::path& library, const std::string& name_or_dir) {
  std::error_code ec;
  const fs::path given(name_or_dir);
  if (fs::is_regular_file(programFileOf(given), ec)) return fs::is_directory(given, ec) ? given : given.parent_path();
  std::vector<std::string> known;
  std::vector<fs::path> found;
  for (const fs::path& dir : listPrograms(library)) {
    std::ifstream stream(dir / kProgramFile, std::ios::binary);
    std::ostringstream text;
    text << stream.rdbuf();
    std::string name;
    try {
      name = parseProgramFile(text.str(), (dir / kProgramFile).string()).name;
    } catch (const ProgramError&) {
      name = dir.filename().string() + " (unreadable program file)";  // listed, never matched
    }
    if (name == name_or_dir) found.push_back(dir);
    known.push_back(name);
  }
  if (found.size() == 1) return found.front();
  if (found.size() > 1)
    throw ProgramError(library.string() + ": several programs are named \"" + name_or_dir + "\": " + found[0].string() + ", " +
                       found[1].string());
  std::string list;
  for (std::size_t i = 0; i < known.size(); ++i) list += (i ? ", " : "") + known[i];
  throw ProgramError("no part program \"" + name_or_dir + "\" in " + library.string() +
                     (known.empty() ? " (it holds none)" : " (it holds: " + list + ")"));
}

std::optional<std::string> findProgramByLineNumber(const fs::path& library, std::uint16_t number) {
  std::optional<std::string> found;
  fs::path found_dir;
  for (const fs::path& dir : listPrograms(library)) {
    std::ifstream stream(dir / kProgramFile, std::ios::binary);
    std::ostringstream text;
    text << stream.rdbuf();
    PartProgram program;
    try {
      program = parseProgramFile(text.str(), (dir / kProgramFile).string());
    } catch (const ProgramError&) {
      continue;  // one unreadable program must not keep the line from starting the others
    }
    if (program.line_number != number) continue;
    if (found)
      throw ProgramError(library.string() + ": two programs have line_number " + std::to_string(number) + ": " +
                         found_dir.string() + " and " + dir.string());
    found = program.name;
    found_dir = dir;
  }
  return found;
}

}  // namespace stampscan::acquisition
