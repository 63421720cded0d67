#include "stampscan/sim/grid.hpp"

#include "stampscan/fitting/ply_io.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stampscan::sim {

std::string toString(GridKind kind) { return kind == GridKind::Circle ? "circle" : "square"; }

GridKind gridKindFromString(const std::string& name) {
  if (name == "circle") return GridKind::Circle;
  if (name == "square") return GridKind::Square;
  throw std::invalid_argument("unknown grid '" + name + "' (expected circle or square)");
}

BlankRect printedArea(const GridSpec& grid, const BlankRect& blank) {
  return {blank.min.array() + grid.margin, blank.max.array() - grid.margin};
}

namespace {
// Length of [d - f/2, d + f/2] inside the band [-w/2, w/2], over f: the box-filtered coverage of a
// line of width w seen at distance d through a footprint f.
double bandCoverage(double d, double w, double f) {
  if (f <= 1e-12) return std::abs(d) <= 0.5 * w ? 1.0 : 0.0;
  const double overlap = std::min(d + 0.5 * f, 0.5 * w) - std::max(d - 0.5 * f, -0.5 * w);
  return std::clamp(overlap / f, 0.0, 1.0);
}
}  // namespace

double inkCoverage(const GridSpec& grid, const BlankRect& printed, const Vec2& m, double footprint) {
  if (!printed.contains(m)) return 0.0;
  const double p = grid.pitch;
  if (grid.kind == GridKind::Square) {
    const double du = m.x() - p * std::round(m.x() / p), dv = m.y() - p * std::round(m.y() / p);
    // The union of two crossing lines: cover = 1 - (1 - a)(1 - b) for independent bands.
    const double a = bandCoverage(du, grid.line_width, footprint), b = bandCoverage(dv, grid.line_width, footprint);
    return 1 - (1 - a) * (1 - b);
  }
  // Circles centred on the lattice: the nearest ring line among the 3x3 neighbouring centres.
  const double radius = 0.5 * grid.circle_diameter;
  const double ci = std::round(m.x() / p), cj = std::round(m.y() / p);
  double nearest = std::numeric_limits<double>::infinity();
  for (int di = -1; di <= 1; ++di)
    for (int dj = -1; dj <= 1; ++dj) {
      const Vec2 centre((ci + di) * p, (cj + dj) * p);
      nearest = std::min(nearest, std::abs((m - centre).norm() - radius));
    }
  return bandCoverage(nearest, grid.line_width, footprint);
}

std::vector<Vec2> gridElements(const GridSpec& grid, const BlankRect& blank) {
  const BlankRect printed = printedArea(grid, blank);
  const double p = grid.pitch;
  // Circles whose whole ring is printed; square cells whose four corners are.
  const double half = grid.kind == GridKind::Circle ? 0.5 * grid.circle_diameter : 0.5 * p;
  const double offset = grid.kind == GridKind::Circle ? 0.0 : 0.5 * p;
  std::vector<Vec2> out;
  const auto first = [&](double lo) { return std::ceil((lo + half - offset) / p - 1e-9); };
  const auto last = [&](double hi) { return std::floor((hi - half - offset) / p + 1e-9); };
  for (double j = first(printed.min.y()); j <= last(printed.max.y()); ++j)
    for (double i = first(printed.min.x()); i <= last(printed.max.x()); ++i)
      out.emplace_back(i * p + offset, j * p + offset);
  return out;
}

fitting::Cloud groundTruth(const FormedPart& part, const GridSpec& grid, const Eigen::Isometry3d& machine_from_datum) {
  const std::vector<Vec2> elements = gridElements(grid, part.blank());
  const std::size_t n = elements.size();
  fitting::Cloud truth;
  truth.positions.resize(n);
  truth.normals.resize(n);
  truth.strain.resize(n);
  for (const char* name : {fitting::kMajorStrain, fitting::kMinorStrain, fitting::kMajorDirection[0],
                           fitting::kMajorDirection[1], fitting::kMajorDirection[2], kMaterialU, kMaterialV})
    truth.scalars[name].resize(n);
  auto& major = truth.scalars[fitting::kMajorStrain];
  auto& minor = truth.scalars[fitting::kMinorStrain];
  auto& dx = truth.scalars[fitting::kMajorDirection[0]];
  auto& dy = truth.scalars[fitting::kMajorDirection[1]];
  auto& dz = truth.scalars[fitting::kMajorDirection[2]];
  auto& mu = truth.scalars[kMaterialU];
  auto& mv = truth.scalars[kMaterialV];
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    const Deformation d = part.deformationOfMaterial(elements[i]);
    truth.positions[i] = machine_from_datum * d.point;
    truth.normals[i] = machine_from_datum.linear() * d.normal;
    truth.strain[i] = d.thickness_strain;
    major[i] = d.major_strain;
    minor[i] = d.minor_strain;
    const Vec3 direction = machine_from_datum.linear() * d.major_direction;
    dx[i] = direction.x();
    dy[i] = direction.y();
    dz[i] = direction.z();
    mu[i] = elements[i].x();
    mv[i] = elements[i].y();
  });
  return truth;
}

void writeGroundTruth(const std::filesystem::path& file, const fitting::Cloud& truth) {
  fitting::PlyWriteOptions options;
  options.precision = fitting::PlyPrecision::Double;
  options.comment = "StampScan ground truth: grid element centres with true strains";
  fitting::writePly(file, truth, options);
}

}  // namespace stampscan::sim
