// The default surface: robust WLS quadric patches (quadric_patch.hpp) fitted at adaptive anchors
// and blended into one implicit surface, with a per-region bandwidth chosen from the data. Beyond
// the paper, and built to remove its stated weaknesses:
//
//  - Bandwidth. Probes spread over the cloud fit patches at growing bandwidths h_j = h_start 1.5^j
//    and keep the largest h at which the patch still explains the neighbourhood down to the noise
//    (the residual variance stays at its floor; misfit would raise it), and at most about
//    max_effective_count points carry weight. Near-duplicates cannot shrink h because the start
//    scale is the 16th neighbour distance (more than the 12-15 repeats of stereo data). The probe
//    values are Shepard-interpolated into a smooth h(P*) (Eqs. (13)-(14)).
//  - Shrinkage at peaks. Each local fit is a quadric height field over the weighted plane's frame
//    (Eqs. (2), (6), (7)), which follows curvature where the plane of Eq. (1) cuts corners.
//  - Outliers. Each fit is refitted with Tukey's biweight on its residuals.
//  - Cost. Neighbouring points share almost all of their WLS neighbourhood, so fitting at every point
//    repeats work. Fits are made at anchors spaced one or two h apart and blended with a compact
//    partition of unity (as in multi-level partition-of-unity implicits, Ohtake et al. 2003); the
//    work per point no longer grows with the neighbourhood size.
//  - Widening (AnchoredParams::widen). The cap on the effective count keeps the cost bounded but
//    stops accuracy from growing with density. Where the data are dense against the shape (most
//    probes stopped at the cap, not at misfit), every point gets a weight from the nearest probe's
//    narrow patch (Tukey's biweight: outliers get none) and the weighted moments (count, centroid,
//    covariance, strain) are accumulated once over a pyramid of cells (cell_pyramid.hpp). A fit at
//    bandwidth h reads the level whose cells are about h/2 wide, so its cost is bounded whatever h
//    and the density, and no point's contribution is subsampled away; only fits narrower than
//    about 1.4 typical narrow bandwidths read the points themselves. Probes and then anchors choose h by
//    Lepski's balancing rule: the widest fit whose offset agrees with every narrower fit's to
//    within agreement_sigmas standard deviations of their difference. The probes' choice only
//    says where each anchor starts its own, so the widening probes are thinned to one per cube of
//    wide_probe_spacing narrow bandwidths: on dense data their count then follows the part's
//    area, not the number of points. The widened patches are cubic
//    height fields: the cubic terms leave the offset at the centre as it is, but let a patch be read
//    up to a bandwidth away, where a quadric's error grows with the shape's third derivatives; so
//    the anchors stay about one h apart. Strain gets a bandwidth of its own by the same rule (it
//    changes faster than the curvature where the sheet stretches) and is fitted at each projected
//    point. On sparse data (the probes stopped by misfit) the narrow fits are kept: there the
//    widened ones were measured as good or worse.
//
// Thread safety: after construction every method is const and safe from many threads.
#pragma once

#include "stampscan/fitting/bandwidth.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/normals.hpp"
#include "stampscan/fitting/projection.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace stampscan::fitting {

struct AnchoredParams {
  int start_rank = 16;          // h_start = distance to this neighbour at a probe
  double scale_step = 1.5;      // ratio between successive probe bandwidths and anchor levels
  int max_scales = 8;           // probe bandwidths tried: h_start * 1.5^(0..max_scales-1)
  double misfit_tolerance = 0.2;  // a wider h is rejected when it raises the residual variance by this
  double max_effective_count = 120;  // h stops growing once this many points carry weight
  std::size_t probe_stride = 64;  // one probe per this many points (in spatial order)
  double anchor_spacing = 2.0;  // anchor cell size as a multiple of h where the surface is smooth
  double fine_anchor_spacing = 1.0;  // the same where curvature limited h
  double blend_radius = 1.6;    // partition-of-unity support as a multiple of the anchor cell size
  // Widening: after the narrow fits above, each region's bandwidth is chosen again by Lepski's rule
  // over fits on the cell pyramid, from the narrow h up to h * scale_step^(wide_scales - 1), and
  // the anchors are fitted there (see the header's comment). It is done where the data are dense
  // against the shape: when at least widen_min_capped_share of the probes stopped at the count cap
  // rather than at misfit (0 widens always). On sparse data the narrow fits are as good or better.
  bool widen = true;
  double widen_min_capped_share = 0.7;
  int wide_scales = 10;
  double agreement_sigmas = 1.5;  // a wider fit must agree with the narrower ones to this many SDs
  double wide_anchor_spacing = 1.0;  // anchor cell size as a multiple of the wide h
  // Widening probes at most one per cube of this many narrow bandwidths (the median's): the wide
  // field only says where each anchor starts its own choice.
  double wide_probe_spacing = 3.0;
  bool robust = true;
  int max_iterations = 10;
  double tolerance = 1e-3;      // the projection stops when a step (or the next, predicted) is below tolerance * h
  std::size_t min_points = 10;  // a fit needs at least this many points
  OrientationParams orientation;
  // Smooth: the patches' linear strain fields, blended. Shepard: the paper's Eqs. (15)-(16) over the
  // data around the projected point.
  ScalarFieldType scalar = ScalarFieldType::Smooth;
};

struct AnchoredStats {
  std::size_t probes = 0;
  std::size_t anchors = 0;
  std::size_t invalid_anchors = 0;
  std::size_t wide_probes = 0;        // probes the wide field was chosen at (widened)
  double count_capped_share = 0;      // probes whose narrow h stopped at max_effective_count
  bool widened = false;
  std::size_t pyramid_cells = 0;      // over all levels (0 without widening)
  std::size_t pyramid_bytes = 0;
  double shape_limited_share = 0;       // probes whose widening the shape stopped (not the cap)
  BandwidthSummary narrow_bandwidth;  // over the probes, before widening
  std::size_t orientation_components = 0;
  BandwidthSummary bandwidth;  // over the probes
  std::map<std::string, double> stage_seconds;
};

class AnchoredSurface : public ImplicitSurface {
 public:
  using Progress = std::function<void(const std::string& stage, double fraction)>;
  // `strain` may be null. `points`, `tree` and `strain` must outlive the surface.
  AnchoredSurface(const std::vector<Vec3>& points, const KdTree& tree, const std::vector<double>* strain,
                  const AnchoredParams& params = {}, const Progress& progress = {});
  ~AnchoredSurface();
  AnchoredSurface(const AnchoredSurface&) = delete;
  AnchoredSurface& operator=(const AnchoredSurface&) = delete;

  Projection projectPoint(std::size_t i) const override;
  Projection project(const Vec3& x) const override;
  double bandwidthAt(const Vec3& x) const override;
  bool hasScalar() const override;
  const AnchoredStats& stats() const { return stats_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  AnchoredStats stats_;
};

}  // namespace stampscan::fitting
