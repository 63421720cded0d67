#include "stampscan/hmi/strain_views.hpp"

#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/hmi/run_files.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace stampscan::hmi {

namespace fs = std::filesystem;
using fitting::Vec3;

RunElements loadRunElements(const fs::path& cloud4d) {
  std::error_code ec;
  if (!fs::is_regular_file(cloud4d, ec)) throw RunFileError(404, "the run has no grid elements (" + cloud4d.filename().string() + ")");
  fitting::Cloud cloud = fitting::readPly(cloud4d);
  const auto scalar = [&](const char* name) -> std::vector<double>& {
    const auto it = cloud.scalars.find(name);
    if (it == cloud.scalars.end())
      throw std::runtime_error(cloud4d.string() + ": no vertex property '" + name + "' (a Cloud4D of the measurement has it)");
    return it->second;
  };
  if (!cloud.hasStrain())
    throw std::runtime_error(cloud4d.string() + ": no vertex property 'strain' (the thickness strain of a Cloud4D)");
  RunElements e;
  e.major = std::move(scalar(fitting::kMajorStrain));
  e.minor = std::move(scalar(fitting::kMinorStrain));
  e.thickness = std::move(cloud.strain);
  e.positions = std::move(cloud.positions);
  e.normals = std::move(cloud.normals);
  const auto has = [&](const char* name) { return cloud.scalars.contains(name); };
  if (has(fitting::kMajorDirection[0]) && has(fitting::kMajorDirection[1]) && has(fitting::kMajorDirection[2])) {
    const auto &x = cloud.scalars[fitting::kMajorDirection[0]], &y = cloud.scalars[fitting::kMajorDirection[1]],
               &z = cloud.scalars[fitting::kMajorDirection[2]];
    e.directions.reserve(e.size());
    for (std::size_t i = 0; i < e.size(); ++i) {
      Vec3 d(x[i], y[i], z[i]);
      // A zero or broken direction stays zero: the page draws no arrow for it.
      e.directions.push_back(d.allFinite() && d.norm() > 1e-9 ? Vec3(d.normalized()) : Vec3(Vec3::Zero()));
    }
  }
  return e;
}

StrainQuantity strainQuantityFromString(const std::string& text) {
  if (text == "thinning") return StrainQuantity::Thinning;
  if (text == "major") return StrainQuantity::Major;
  if (text == "minor") return StrainQuantity::Minor;
  throw std::invalid_argument("unknown strain '" + text + "' (thinning, major or minor)");
}

const char* toString(StrainQuantity quantity) {
  switch (quantity) {
    case StrainQuantity::Thinning: return "thinning";
    case StrainQuantity::Major: return "major";
    case StrainQuantity::Minor: return "minor";
  }
  return "?";
}

double percentOf(StrainQuantity quantity, const RunElements& e, std::size_t i) {
  switch (quantity) {
    case StrainQuantity::Thinning: return (1.0 - std::exp(e.thickness[i])) * 100.0;
    case StrainQuantity::Major: return (std::exp(e.major[i]) - 1.0) * 100.0;
    case StrainQuantity::Minor: return (std::exp(e.minor[i]) - 1.0) * 100.0;
  }
  return 0;
}

std::vector<SectionPoint> sectionProfile(const RunElements& e, const SectionParams& p) {
  if (p.axis < 0 || p.axis > 2) throw std::invalid_argument("the section's axis must be x, y or z");
  if (!(p.half_width_mm > 0) || !std::isfinite(p.half_width_mm))
    throw std::invalid_argument("the section's width must be a positive number of millimetres");
  if (!std::isfinite(p.at_mm)) throw std::invalid_argument("the section's position must be a number of millimetres");
  std::vector<SectionPoint> out;
  for (std::size_t i = 0; i < e.size(); ++i) {
    if (std::abs(e.positions[i][p.axis] - p.at_mm) > p.half_width_mm) continue;
    SectionPoint s;
    s.element = i;
    s.position = e.positions[i];
    s.thinning_percent = percentOf(StrainQuantity::Thinning, e, i);
    s.major_percent = percentOf(StrainQuantity::Major, e, i);
    s.minor_percent = percentOf(StrainQuantity::Minor, e, i);
    out.push_back(s);
  }
  if (out.empty()) return out;
  // The order along the cut: along the plane's first other axis, or around the contour of a z cut.
  std::vector<double> key(out.size());
  if (p.axis == 2) {
    Vec3 centre = Vec3::Zero();
    for (const auto& s : out) centre += s.position;
    centre /= static_cast<double>(out.size());
    for (std::size_t k = 0; k < out.size(); ++k)
      key[k] = std::atan2(out[k].position.y() - centre.y(), out[k].position.x() - centre.x());
  } else {
    const int along = p.axis == 0 ? 1 : 0;
    for (std::size_t k = 0; k < out.size(); ++k) key[k] = out[k].position[along];
  }
  std::vector<std::size_t> order(out.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key[a] < key[b]; });
  std::vector<SectionPoint> sorted;
  sorted.reserve(out.size());
  for (std::size_t k : order) sorted.push_back(out[k]);
  // The length along the polyline in the plane: the offset across the band is not part of the cut.
  for (std::size_t k = 1; k < sorted.size(); ++k) {
    Vec3 step = sorted[k].position - sorted[k - 1].position;
    step[p.axis] = 0;
    sorted[k].along_mm = sorted[k - 1].along_mm + step.norm();
  }
  return sorted;
}

Comparison compareRuns(const RunElements& a, const RunElements& b, StrainQuantity quantity, double max_distance_mm) {
  if (!(max_distance_mm > 0)) throw std::invalid_argument("the match distance must be a positive number of millimetres");
  Comparison c;
  c.difference.assign(a.size(), std::nullopt);
  if (b.size() == 0) return c;
  const fitting::KdTree tree(b.positions);
  std::vector<fitting::Neighbor> nearest;
  double sum = 0, sum_sq = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    tree.knn(a.positions[i], 1, nearest);
    if (nearest.empty() || nearest[0].distance_sq > max_distance_mm * max_distance_mm) continue;
    const double d = percentOf(quantity, b, nearest[0].index) - percentOf(quantity, a, i);
    c.difference[i] = d;
    c.min = c.matched == 0 ? d : std::min(c.min, d);
    c.max = c.matched == 0 ? d : std::max(c.max, d);
    sum += d;
    sum_sq += d * d;
    ++c.matched;
  }
  if (c.matched > 0) {
    c.mean = sum / static_cast<double>(c.matched);
    c.rms = std::sqrt(sum_sq / static_cast<double>(c.matched));
  }
  return c;
}

std::vector<std::optional<double>> onPoints(const std::vector<Vec3>& points, const RunElements& e,
                                            const std::vector<std::optional<double>>& values, double max_distance_mm) {
  if (values.size() != e.size()) throw std::invalid_argument("onPoints: one value per element is needed");
  // Only the elements that have a value take part, so a point next to an unmatched element still
  // takes the nearest matched one within reach.
  std::vector<Vec3> with_value;
  std::vector<double> value;
  for (std::size_t i = 0; i < e.size(); ++i)
    if (values[i]) {
      with_value.push_back(e.positions[i]);
      value.push_back(*values[i]);
    }
  std::vector<std::optional<double>> out(points.size());
  if (with_value.empty()) return out;
  const fitting::KdTree tree(with_value);
  std::vector<fitting::Neighbor> nearest;
  for (std::size_t i = 0; i < points.size(); ++i) {
    tree.knn(points[i], 1, nearest);
    if (!nearest.empty() && nearest[0].distance_sq <= max_distance_mm * max_distance_mm) out[i] = value[nearest[0].index];
  }
  return out;
}

}  // namespace stampscan::hmi
