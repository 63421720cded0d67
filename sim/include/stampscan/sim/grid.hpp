// The grid printed on the blank before forming (circles or squares, 2.54 mm pitch by default), how
// much ink covers any material point, and the ground truth at every grid element of a formed part.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/sim/formed_part.hpp"

#include <Eigen/Geometry>

#include <filesystem>
#include <string>
#include <vector>

namespace stampscan::sim {

enum class GridKind { Circle, Square };

struct GridSpec {
  GridKind kind = GridKind::Circle;
  double pitch = 2.54;            // mm between circle centres or grid lines
  double circle_diameter = 2.54;  // mm, of the printed circles' centre line
  double line_width = 0.15;       // mm, of the printed lines
  double margin = 2.0;            // mm of blank left unprinted at its edge
};

std::string toString(GridKind kind);
GridKind gridKindFromString(const std::string& name);  // "circle" or "square"; throws otherwise

// Fraction of a footprint-wide square around material point m covered by ink (box filter along the
// distance to the nearest line): 0 on bare sheet, 1 on a line much wider than the footprint.
double inkCoverage(const GridSpec& grid, const BlankRect& printed, const Vec2& m, double footprint);

// The printed area of a blank.
BlankRect printedArea(const GridSpec& grid, const BlankRect& blank);

// Grid elements of the printed area, in material coordinates: circle centres, or square cell
// centres. Row-major, rows along v.
std::vector<Vec2> gridElements(const GridSpec& grid, const BlankRect& blank);

// The truth's scalars beyond the Cloud4D's (fitting/cloud.hpp): where the element was printed on
// the blank (mm).
inline constexpr char kMaterialU[] = "material_u";
inline constexpr char kMaterialV[] = "material_v";

// Ground truth at every grid element of a formed part: positions, normals, thickness strain and the
// Cloud4D's scalars kMajorStrain, kMinorStrain, kMajorDirection (unit, tangent), and kMaterialU/V. Positions,
// normals and directions are in the part's datum frame, or carried by `machine_from_datum` (where the
// fixture holds the part: machineFromDatum in scan_scenario.hpp) into the machine frame.
fitting::Cloud groundTruth(const FormedPart& part, const GridSpec& grid,
                           const Eigen::Isometry3d& machine_from_datum = Eigen::Isometry3d::Identity());
void writeGroundTruth(const std::filesystem::path& file, const fitting::Cloud& truth);

}  // namespace stampscan::sim
