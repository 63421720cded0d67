#include "stampscan/report/strain_analysis.hpp"

#include "stampscan/fitting/kdtree.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <numeric>
#include <stdexcept>
#include <utility>

namespace stampscan::report {

namespace {

// Overlapping sweeps measure some grid elements twice: two records closer than this are one
// element on the part. (Grid pitches are millimetres; repeated measurements agree to hundredths.)
constexpr double kSameElementMm = 0.5;

// Union-find over element indices, for the patches. A patch's size counts grid elements on the
// part: a record that repeats one already in the patch (closer than kSameElementMm) adds nothing.
class Patches {
 public:
  explicit Patches(std::size_t n) : parent_(n), size_(n, 1) { std::iota(parent_.begin(), parent_.end(), 0u); }
  void markRepeat(std::uint32_t i) { size_[i] = 0; }  // before any join
  std::uint32_t root(std::uint32_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void join(std::uint32_t a, std::uint32_t b) {
    a = root(a);
    b = root(b);
    if (a == b) return;
    if (size_[a] < size_[b]) std::swap(a, b);
    parent_[b] = a;
    size_[a] += size_[b];
  }
  std::uint32_t sizeOf(std::uint32_t i) { return size_[root(i)]; }

 private:
  std::vector<std::uint32_t> parent_, size_;
};

bool atRisk(Zone z) { return z == Zone::Failure || z == Zone::Marginal; }

// The median distance from an element to its nearest other element (repeats of the same element
// left out): the grid pitch as measured.
double medianNeighbourDistance(const fitting::KdTree& tree, const std::vector<fitting::Vec3>& positions) {
  constexpr double kStandardGridPitchMm = 2.54;
  std::vector<double> nearest(positions.size(), 0.0);
  tbb::parallel_for(std::size_t{0}, positions.size(), [&](std::size_t i) {
    std::vector<fitting::Neighbor> found;
    tree.knn(positions[i], 8, found);
    for (const fitting::Neighbor& n : found)
      if (n.distance_sq > kSameElementMm * kSameElementMm) {
        nearest[i] = std::sqrt(n.distance_sq);
        break;
      }
  });
  std::erase(nearest, 0.0);
  if (nearest.empty()) return kStandardGridPitchMm;
  auto middle = nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2);
  std::nth_element(nearest.begin(), middle, nearest.end());
  return *middle;
}

std::string formatPosition(const fitting::Vec3& p) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.1f, %.1f, %.1f) mm", p.x(), p.y(), p.z());
  return text;
}

}  // namespace

const char* toString(Zone zone) {
  switch (zone) {
    case Zone::Failure: return "failure";
    case Zone::Marginal: return "marginal";
    case Zone::Safe: return "safe";
    case Zone::InsufficientStretch: return "insufficient stretch";
    case Zone::WrinklingTendency: return "wrinkling tendency";
    case Zone::Wrinkling: return "wrinkling";
  }
  return "?";
}

const char* toString(Verdict verdict) {
  switch (verdict) {
    case Verdict::Good: return "good";
    case Verdict::Marginal: return "marginal";
    case Verdict::Failed: return "failed";
  }
  return "?";
}

ElementStrain analyseElement(const fitting::Vec3& position, double major_true, double minor_true, double thickness_true,
                             const Material& material, const AnalysisParams& params, double thickness_uncertainty) {
  ElementStrain e;
  e.position = position;
  e.thickness_uncertainty = thickness_uncertainty;
  // The measurement names the larger in-plane strain major; keep that convention whatever the input.
  if (minor_true > major_true) std::swap(minor_true, major_true);
  e.major_true = major_true;
  e.minor_true = minor_true;
  e.thickness_true = thickness_true;
  e.major_percent = engineeringPercent(major_true);
  e.minor_percent = engineeringPercent(minor_true);
  e.thinning_percent = thinningPercent(thickness_true);
  e.flc_major_percent = material.flc.majorAt(e.minor_percent);
  e.margin_percent = material.flc.marginAlongPath(e.minor_percent, e.major_percent);

  const double threshold = params.stretch_threshold_percent;
  const bool thickened = major_true + minor_true < 0;
  const bool compressed = e.minor_percent < -threshold;
  // The expanded uncertainty of the major engineering strain, % (d e1 = 100 exp(eps1) d eps1).
  const double expanded_percent =
      std::isfinite(thickness_uncertainty) ? 2 * thickness_uncertainty * 100 * std::exp(major_true) : 0.0;
  if (e.margin_percent <= 0)
    e.zone = Zone::Failure;
  else if (e.margin_percent < material.safety_margin_percent || e.margin_percent <= expanded_percent)
    e.zone = Zone::Marginal;
  else if (thickened && compressed)
    e.zone = major_true <= -minor_true / 2 ? Zone::Wrinkling : Zone::WrinklingTendency;
  else if (e.major_percent < threshold)
    e.zone = Zone::InsufficientStretch;
  else
    e.zone = Zone::Safe;
  return e;
}

namespace {

// The elements whose strains can be judged: finite and within any sheet's. The others are counted,
// the first named.
struct ValidElements {
  std::vector<std::uint32_t> kept;
  std::size_t invalid = 0;
  std::string first_invalid;
};

ValidElements validElements(const fitting::Cloud& cloud, const std::vector<double>& major, const std::vector<double>& minor) {
  ValidElements v;
  v.kept.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const std::pair<const char*, double> values[] = {
        {fitting::kMajorStrain, major[i]}, {fitting::kMinorStrain, minor[i]}, {"strain", cloud.strain[i]}};
    const auto bad = std::find_if(std::begin(values), std::end(values), [](const auto& value) {
      return !std::isfinite(value.second) || std::abs(value.second) > kMostTrueStrain;
    });
    if (bad == std::end(values)) {
      v.kept.push_back(static_cast<std::uint32_t>(i));
      continue;
    }
    if (v.invalid++ == 0) {
      char text[160];
      std::snprintf(text, sizeof text, "element %zu: %s = %g, %s", i, bad->first, bad->second,
                    std::isfinite(bad->second) ? "beyond any sheet's strain" : "not a number");
      v.first_invalid = text;
    }
  }
  return v;
}

// Patches: failure elements joined with failure neighbours; failure-or-marginal elements with
// failure-or-marginal neighbours (within patch_radius_factor pitches).
void joinPatches(const StrainAnalysis& a, const fitting::KdTree& tree, const std::vector<fitting::Vec3>& positions,
                 const AnalysisParams& params, Patches& failure_patches, Patches& risk_patches) {
  const std::size_t n = a.elements.size();
  std::vector<fitting::Neighbor> found;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (!atRisk(a.elements[i].zone)) continue;
    tree.radius(positions[i], kSameElementMm, found);
    for (const fitting::Neighbor& nb : found) {
      if (nb.index >= i || !atRisk(a.elements[nb.index].zone)) continue;
      risk_patches.markRepeat(i);
      if (a.elements[i].zone == Zone::Failure && a.elements[nb.index].zone == Zone::Failure) failure_patches.markRepeat(i);
    }
  }
  const double radius = params.patch_radius_factor * a.grid_pitch_mm;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (!atRisk(a.elements[i].zone)) continue;
    tree.radius(positions[i], radius, found);
    for (const fitting::Neighbor& nb : found) {
      if (!atRisk(a.elements[nb.index].zone)) continue;
      risk_patches.join(i, nb.index);
      if (a.elements[i].zone == Zone::Failure && a.elements[nb.index].zone == Zone::Failure)
        failure_patches.join(i, nb.index);
    }
  }
}

// The largest patch of failure elements, and of failure-or-marginal ones, and an element of each.
struct LargestPatches {
  std::uint32_t failure = 0, risk = 0;
  std::uint32_t failure_at = 0, risk_at = 0;
};

// Counts the zones, the extremes and each element's patch; returns the largest patches.
LargestPatches tally(StrainAnalysis& a, Patches& failure_patches, Patches& risk_patches,
                     const AnalysisParams& params) {
  LargestPatches largest;
  for (std::uint32_t i = 0; i < a.elements.size(); ++i) {
    ElementStrain& e = a.elements[i];
    ++a.zone_counts[static_cast<std::size_t>(e.zone)];
    a.max_thinning_percent = i == 0 ? e.thinning_percent : std::max(a.max_thinning_percent, e.thinning_percent);
    a.min_margin_percent = i == 0 ? e.margin_percent : std::min(a.min_margin_percent, e.margin_percent);
    if (e.zone == Zone::Failure) {
      e.patch_size = failure_patches.sizeOf(i);
      if (e.patch_size > largest.failure) {
        largest.failure = e.patch_size;
        largest.failure_at = i;
      }
      if (e.patch_size < params.min_patch_elements) ++a.isolated_failures;
    } else if (e.zone == Zone::Marginal) {
      e.patch_size = risk_patches.sizeOf(i);
    }
    if (atRisk(e.zone)) {
      const std::uint32_t risk = risk_patches.sizeOf(i);
      if (risk > largest.risk) {
        largest.risk = risk;
        largest.risk_at = i;
      }
    }
  }
  return largest;
}

// The verdict and its reason: failed on a patch above the FLC, marginal on one within the safety
// margin or when elements were left out, good otherwise; isolated failures are named as noise.
void judge(StrainAnalysis& a, const LargestPatches& largest, const Material& material, const AnalysisParams& params) {
  const std::size_t need = std::max<std::size_t>(params.min_patch_elements, 1);
  const auto noise = [&]() -> std::string {
    if (a.isolated_failures == 0) return "";
    return "; " + std::to_string(a.isolated_failures) + " failure element" + (a.isolated_failures == 1 ? "" : "s") +
           " in patches under " + std::to_string(need) + " elements ignored as noise";
  };
  if (largest.failure >= need) {
    a.verdict = Verdict::Failed;
    a.verdict_reason = "above the FLC: a patch of " + std::to_string(largest.failure) + " elements at " +
                       formatPosition(a.elements[largest.failure_at].position);
  } else if (largest.risk >= need) {
    a.verdict = Verdict::Marginal;
    a.verdict_reason = "within the " + std::to_string(static_cast<int>(std::lround(material.safety_margin_percent))) +
                       "% safety margin of the FLC: a patch of " + std::to_string(largest.risk) + " elements at " +
                       formatPosition(a.elements[largest.risk_at].position) + noise();
  } else if (a.left_out > 0) {
    a.verdict = Verdict::Marginal;
    a.verdict_reason = "no patch of " + std::to_string(need) +
                       " or more judged elements above the FLC or within its safety margin, but " +
                       std::to_string(a.left_out) + " elements were left out as invalid (" + a.left_out_reason +
                       "): they may be the ones that fail; measure the part again" + noise();
  } else {
    a.verdict = Verdict::Good;
    a.verdict_reason =
        "no patch of " + std::to_string(need) + " or more elements above the FLC or within its safety margin" + noise();
  }
  if (a.left_out > 0)
    a.verdict_reason += " (judged on " + std::to_string(a.elements.size()) + " of " + std::to_string(a.elements_in_cloud) +
                        " elements)";
}

// The worst spots: the lowest margins, one element per spot.
void findWorstSpots(StrainAnalysis& a, const AnalysisParams& params) {
  const std::size_t need = std::max<std::size_t>(params.min_patch_elements, 1);
  std::vector<std::uint32_t> order(a.elements.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
    if (a.elements[x].margin_percent != a.elements[y].margin_percent)
      return a.elements[x].margin_percent < a.elements[y].margin_percent;
    return a.elements[x].thinning_percent > a.elements[y].thinning_percent;
  });
  const double separation = params.worst_spot_separation_factor * a.grid_pitch_mm;
  for (const std::uint32_t i : order) {
    if (a.worst_spots.size() >= params.worst_spots) break;
    const ElementStrain& e = a.elements[i];
    if (!std::isfinite(e.margin_percent)) break;
    const bool same_spot = std::any_of(a.worst_spots.begin(), a.worst_spots.end(), [&](const WorstSpot& s) {
      return (a.elements[s.element].position - e.position).norm() < separation;
    });
    if (same_spot) continue;
    WorstSpot spot;
    spot.element = i;
    spot.patch_size = atRisk(e.zone) ? e.patch_size : 0;
    spot.counted = atRisk(e.zone) && e.patch_size >= need;
    a.worst_spots.push_back(spot);
  }
}

}  // namespace

StrainAnalysis analyseStrains(const fitting::Cloud& cloud, const Material& material, const AnalysisParams& params) {
  cloud.validate();
  const auto major_it = cloud.scalars.find(fitting::kMajorStrain);
  const auto minor_it = cloud.scalars.find(fitting::kMinorStrain);
  if (!cloud.hasStrain()) throw std::invalid_argument("the cloud has no thickness strain (vertex property 'strain')");
  if (major_it == cloud.scalars.end() || minor_it == cloud.scalars.end())
    throw std::invalid_argument(
        "the cloud has no major and minor strains (vertex properties 'major_strain', 'minor_strain')");
  const std::vector<double>& major = major_it->second;
  const std::vector<double>& minor = minor_it->second;

  // A verdict is never better than the data allow: an element whose strains are not finite or
  // beyond any sheet's refuses the analysis, or is left out (and the verdict cannot be good).
  const ValidElements valid = validElements(cloud, major, minor);
  if (valid.invalid > 0 && !params.leave_out_invalid)
    throw std::invalid_argument(std::to_string(valid.invalid) + " of " + std::to_string(cloud.size()) +
                                " elements have invalid strains (" + valid.first_invalid +
                                "); a verdict rests on every element (leave them out explicitly to judge the rest, "
                                "never as good)");
  if (valid.kept.empty()) throw std::invalid_argument("the cloud has no element with valid strains (" + valid.first_invalid + ")");

  const auto uncertainty = cloud.scalars.find(fitting::kStrainUncertainty);
  StrainAnalysis a;
  a.elements_in_cloud = cloud.size();
  a.left_out = valid.invalid;
  a.left_out_reason = valid.first_invalid;
  a.elements.resize(valid.kept.size());
  tbb::parallel_for(std::size_t{0}, valid.kept.size(), [&](std::size_t k) {
    const std::uint32_t i = valid.kept[k];
    const double u = uncertainty != cloud.scalars.end() ? uncertainty->second[i] : std::numeric_limits<double>::quiet_NaN();
    a.elements[k] = analyseElement(cloud.positions[i], major[i], minor[i], cloud.strain[i], material, params, u);
    a.elements[k].index = i;
  });

  std::vector<fitting::Vec3> positions(a.elements.size());
  for (std::size_t i = 0; i < a.elements.size(); ++i) positions[i] = a.elements[i].position;
  const fitting::KdTree tree(positions);
  a.grid_pitch_mm = medianNeighbourDistance(tree, positions);
  Patches failure_patches(a.elements.size()), risk_patches(a.elements.size());
  joinPatches(a, tree, positions, params, failure_patches, risk_patches);
  const LargestPatches largest = tally(a, failure_patches, risk_patches, params);
  judge(a, largest, material, params);
  findWorstSpots(a, params);
  return a;
}

}  // namespace stampscan::report
