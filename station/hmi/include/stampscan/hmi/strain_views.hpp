// What the panel shows of a run's measured strain beyond the fitted map: the grid elements of its
// cloud4d.ply with their major-strain directions (the arrows), the strain profile along a section
// cut, and the difference of two runs' strains (run B minus run A, on A's elements, each matched to
// the nearest element of B). Read-only functions of the run's files; the measurement itself
// (registration::measureScan) wrote the directions, nothing here estimates them.
//
// Strains are true (logarithmic) strains as the Cloud4D holds them; the percentages the page shows
// are the report's: thinning % = (1 - e^thickness) * 100, major and minor % engineering (e^e - 1) * 100.
//
// Thread safety: the functions touch only their arguments and the files named.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::hmi {

// A run's grid elements (cloud4d.ply), one entry per element in the file's order.
struct RunElements {
  std::vector<fitting::Vec3> positions;   // mm, machine frame
  std::vector<fitting::Vec3> normals;     // unit surface normal (sensor side); empty when the file has none
  std::vector<fitting::Vec3> directions;  // unit major-strain direction in the surface; empty when the file has none
  std::vector<double> thickness, major, minor;  // true strains
  std::size_t size() const { return positions.size(); }
  bool hasDirections() const { return !directions.empty(); }
};

// Throws RunFileError 404 when the file is missing, std::runtime_error naming the file when it cannot
// be read or lacks `strain`, `major_strain` or `minor_strain`. The direction (`major_dir_x/y/z`) is
// optional: older Cloud4D files and imported clouds may lack it.
RunElements loadRunElements(const std::filesystem::path& cloud4d);

// What the page plots: the report's percentages.
enum class StrainQuantity { Thinning, Major, Minor };
// "thinning", "major", "minor"; throws std::invalid_argument naming the text otherwise.
StrainQuantity strainQuantityFromString(const std::string& text);
const char* toString(StrainQuantity quantity);
double percentOf(StrainQuantity quantity, const RunElements& elements, std::size_t i);

// A section cut: the plane `axis` = `at_mm` (axis 0, 1, 2 for x, y, z). The profile takes the
// elements within `half_width_mm` of the plane (the default, half the 2.54 mm grid's pitch, takes
// one row of elements) and orders them along the cut: by y for an x cut, by x for a y cut, by the
// angle about their centre for a z cut (a contour around the part). `along_mm` is the length along
// that polyline in the plane (the curvilinear abscissa of commercial section plots), so a wall
// counts with its true length.
struct SectionParams {
  int axis = 0;
  double at_mm = 0;
  double half_width_mm = 1.27;
};
struct SectionPoint {
  std::size_t element = 0;
  double along_mm = 0;
  fitting::Vec3 position = fitting::Vec3::Zero();
  double thinning_percent = 0, major_percent = 0, minor_percent = 0;
};
// Throws std::invalid_argument for an axis not 0-2, a width not > 0 or a position that is not finite.
std::vector<SectionPoint> sectionProfile(const RunElements& elements, const SectionParams& params);

// B minus A on A's elements: each element of A matched to the nearest element of B within
// `max_distance_mm` (default one grid pitch: the grids of two parts are printed independently, so
// their elements lie up to half a diagonal apart).
struct Comparison {
  std::vector<std::optional<double>> difference;  // per element of A, percentage points; none when no match
  std::size_t matched = 0;
  double mean = 0, rms = 0, min = 0, max = 0;  // over the matched elements
};
Comparison compareRuns(const RunElements& a, const RunElements& b, StrainQuantity quantity, double max_distance_mm = 2.54);

// Per-element values carried onto surface points (e.g. the vertices of A's mesh): each point takes
// the value of the nearest element that has one, when that element is within `max_distance_mm`.
std::vector<std::optional<double>> onPoints(const std::vector<fitting::Vec3>& points, const RunElements& elements,
                                            const std::vector<std::optional<double>>& values,
                                            double max_distance_mm = 2.54);

}  // namespace stampscan::hmi
