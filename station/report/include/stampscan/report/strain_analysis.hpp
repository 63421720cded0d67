// Forming-limit analysis of a measured part: per grid element its strains in the measures a press
// shop reads (true and engineering, thinning), its safety margin to the FLC along its strain path
// and its zone; for the part a verdict that one noisy element cannot decide, and the worst spots.
//
// Zones, in the order they are decided (engineering strains e1 >= e2 in %, true strains eps1, eps2):
//  failure               the element lies on or above the FLC (margin <= 0);
//  marginal              below the FLC by less than the material's safety margin, measured along
//                        the element's strain path (0 < margin < safety margin);
//  wrinkling             the sheet thickened (eps1 + eps2 < 0) and the element is compressed at
//                        least as hard as in uniaxial compression, eps1 <= -eps2 / 2 (the
//                        uniaxial-compression line, r = 1), with a minor strain beyond the stretch
//                        threshold: the metal had nowhere to go but up;
//  wrinkling tendency    thickened (between the pure-shear line eps1 = -eps2 and the
//                        uniaxial-compression line), minor strain beyond the stretch threshold;
//  insufficient stretch  major strain below the stretch threshold (default 2% engineering): the
//                        metal was barely formed (loose metal, springback, soft panels);
//  safe                  everything else.
// The stretch threshold doubles as the noise floor for the compression zones, so that an
// undeformed flange measured with a little noise reads as insufficient stretch, not wrinkling.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/report/material.hpp"

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace stampscan::report {

enum class Zone : std::uint8_t { Failure, Marginal, Safe, InsufficientStretch, WrinklingTendency, Wrinkling };
inline constexpr std::size_t kZoneCount = 6;
const char* toString(Zone zone);  // "failure", "marginal", ...

enum class Verdict { Good, Marginal, Failed };
const char* toString(Verdict verdict);  // "good", "marginal", "failed"

struct AnalysisParams {
  double stretch_threshold_percent = 2.0;  // insufficient stretch below this major strain (engineering %)
  // A failure or marginal patch must have at least this many grid elements, each within the patch
  // radius of another in the patch, to decide the verdict. The radius is this factor times the
  // median distance between neighbouring elements (the grid pitch, 2.54 mm on the standard grids),
  // so that the patch is made of adjacent grid elements, diagonals included. An element measured
  // twice (overlapping sweeps: two records within 0.5 mm) counts once.
  std::size_t min_patch_elements = 3;
  double patch_radius_factor = 1.6;
  std::size_t worst_spots = 8;
  // An element whose strains are not finite or beyond any sheet's (kMostTrueStrain) is a damaged
  // measurement or file: by default the whole analysis is refused. Left out when this is set, and
  // then the verdict is never good (the elements left out may be the ones that fail).
  bool leave_out_invalid = false;
  // Worst spots closer than this many grid pitches to a worse one are the same spot.
  double worst_spot_separation_factor = 4.0;
};

struct ElementStrain {
  std::uint32_t index = 0;  // the element's index in the analysed cloud
  fitting::Vec3 position;
  double major_true = 0, minor_true = 0, thickness_true = 0;  // eps1, eps2, eps3
  double major_percent = 0, minor_percent = 0;                // e1, e2 (engineering)
  double thinning_percent = 0;                                // (1 - exp(eps3)) * 100
  double flc_major_percent = 0;                               // the FLC's e1 at this element's e2
  double margin_percent = 0;  // along the strain path to the FLC; +infinity when the path never meets it
  Zone zone = Zone::Safe;
  std::uint32_t patch_size = 1;  // grid elements in its patch (failure: of failures; marginal: of either)
  // The thickness strain's standard uncertainty (k = 1) when the cloud states it (fitting::kStrainUncertainty).
  double thickness_uncertainty = std::numeric_limits<double>::quiet_NaN();
};

struct WorstSpot {
  std::uint32_t element = 0;  // index into StrainAnalysis::elements
  std::uint32_t patch_size = 0;
  bool counted = false;  // in a patch large enough to count in the verdict
};

// The largest true strain (major, minor or thickness, either sign) an element may have: a stretch
// of 4.5 (350 %), beyond any sheet metal's forming limit.
inline constexpr double kMostTrueStrain = 1.5;

struct StrainAnalysis {
  std::vector<ElementStrain> elements;  // the elements judged
  std::size_t elements_in_cloud = 0;    // all of the cloud's, judged or not
  std::size_t left_out = 0;             // invalid elements left out (AnalysisParams::leave_out_invalid)
  std::string left_out_reason;          // the first of them, and why
  std::array<std::size_t, kZoneCount> zone_counts{};
  Verdict verdict = Verdict::Good;
  std::string verdict_reason;
  double grid_pitch_mm = 0;  // median distance between neighbouring elements
  double max_thinning_percent = 0;
  double min_margin_percent = 0;
  std::vector<WorstSpot> worst_spots;  // the lowest margins first, one per spot
  std::size_t isolated_failures = 0;   // failure elements outside any counted patch (noise)

  std::size_t count(Zone z) const { return zone_counts[static_cast<std::size_t>(z)]; }
};

// One element's strains and zone from its true strains. eps3 is taken as given (the measured
// thickness strain), not recomputed from eps1 and eps2. With its standard uncertainty (k = 1; NaN:
// not stated), an element whose margin to the FLC is within its expanded uncertainty (k = 2, the
// strain's taken for the major's, in engineering %) is marginal even beyond the safety band: the
// measurement cannot tell it from one on the curve.
ElementStrain analyseElement(const fitting::Vec3& position, double major_true, double minor_true, double thickness_true,
                             const Material& material, const AnalysisParams& params = {},
                             double thickness_uncertainty = std::numeric_limits<double>::quiet_NaN());

// The whole part. The cloud needs `strain` (eps3) and the scalars major_strain and minor_strain
// (true strains); throws std::invalid_argument naming what is missing, and naming the invalid
// elements (non-finite strains, or beyond kMostTrueStrain) unless they are to be left out.
StrainAnalysis analyseStrains(const fitting::Cloud& cloud, const Material& material, const AnalysisParams& params = {});

}  // namespace stampscan::report
