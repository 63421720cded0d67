// Sheet materials for the forming-limit analysis, and the library they are looked up in.
//
// The library is a TOML file (the format is in station/materials.toml, which is built into the
// station program): one [[material]] table per entry. A cell config can add its own file later
// with loadMaterials() and merge it over the built-in one with MaterialLibrary::add().
#pragma once

#include "stampscan/report/forming_limit.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::report {

enum class MaterialFamily { Steel, Aluminium };
const char* toString(MaterialFamily family);

// The marginal band below the FLC by default, in engineering major strain percent: the shop-floor
// rule of thumb of 10% for steels and 8% for aluminium alloys (aluminium necks with less warning).
double defaultSafetyMarginPercent(MaterialFamily family);

struct Material {
  std::string name;
  MaterialFamily family = MaterialFamily::Steel;
  double thickness_mm = 1.0;
  double n = 0.2;                     // strain-hardening exponent
  double safety_margin_percent = 10;  // the marginal band below the FLC, engineering strain %
  std::string description;
  FormingLimitCurve flc = FormingLimitCurve::keelerBrazier(30.0);  // measured, or Keeler-Brazier from n and t
};

// Malformed library: names the file (and line where the TOML parser gives one) and the entry.
class MaterialError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class MaterialLibrary {
 public:
  // Adds or replaces (same name, compared without case) an entry.
  void add(Material material);
  // Throws MaterialError naming the unknown material and the known ones.
  const Material& find(const std::string& name) const;
  bool contains(const std::string& name) const;
  const std::vector<Material>& materials() const { return materials_; }
  std::string names() const;  // "DC04, DC06, ..." for messages

 private:
  std::vector<Material> materials_;
};

// Parses a library from TOML text; `source` names it in errors.
MaterialLibrary parseMaterials(const std::string& toml_text, const std::string& source);
// Reads a library file. Throws MaterialError naming the file when it is missing or malformed.
MaterialLibrary loadMaterials(const std::filesystem::path& file);
// The library shipped with the project (station/materials.toml, built into the program).
const MaterialLibrary& builtInMaterials();
// The built-in library with a plant's own file's entries added (or replacing theirs); the built-in
// one alone when `file` is empty. Throws MaterialError naming the file when it cannot be read.
MaterialLibrary materialsWith(const std::filesystem::path& file);
// The built-in library's text, as shipped.
const std::string& builtInMaterialsText();

// The material a report uses when neither the command line nor the run names one.
inline constexpr const char* kDefaultMaterial = "DC04";

}  // namespace stampscan::report
