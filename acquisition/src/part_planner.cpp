// Plans from a part's nominal model (part_planner.hpp): laser passes laid across the grid area by
// what each one's fan claims, stereo views on a lattice, and the sweeps the head's body cannot fly
// left out. What a plan is predicted to see is in coverage_prediction.cpp.
#include "stampscan/acquisition/part_planner.hpp"

#include "grid_samples.hpp"

#include "stampscan/acquisition/plan_collisions.hpp"
#include "stampscan/acquisition/sensor_sight.hpp"
#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace stampscan::acquisition {

namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kDeg = std::numbers::pi / 180;

Eigen::Matrix3d headRotation(double a, double b) { return trace::headPose(Vec3::Zero(), a, b).linear(); }

class PartPlanner {
 public:
  PartPlanner(const GridSamples& samples, const PartSpec& part, const CellGeometry& cell, const MachineLimits& limits,
              const PlannerOptions& o)
      : samples_(samples), cell_(cell), limits_(limits), o_(o), sweep_speed_(sweepSpeed(o, cell, limits)),
        mount_(trace::toIsometry(toRigidPose(cell.digitizer.mount))) {
    plan_.name = "generated for " + (cell.fixture.name.empty() ? std::string("the cell") : cell.fixture.name);
    plan_.part = part;
    plan_.travel_speed = o.travel_speed;
    plan_.park = parkingPose(limits);
    lo_ = Vec3::Constant(std::numeric_limits<double>::infinity());
    hi_ = -lo_;
    for (const Vec3& p : samples.points) {
      lo_ = lo_.cwiseMin(p);
      hi_ = hi_.cwiseMax(p);
    }
  }

  ScanPlan plan() {
    if (o_.laser) laserPasses();
    if (o_.stereo) stereoViews();
    return std::move(plan_);
  }

 private:
  double stop(double angle) const { return nearestHeadStop(angle, limits_); }
  HeadPose headAt(const Vec3& sensor, double a, double b) const {
    const Vec3 head = sensor - headRotation(a, b) * mount_.translation();
    return {{head.x(), head.y(), head.z()}, a, b};
  }

  // One height a pass is flown at: the depth band it measures and the part of the grid area under it.
  struct Band {
    double z_mid = 0;           // the band's middle: which samples it measures
    double z_top = 0;           // the highest sample in it: where the stripe is narrowest
    double z_fly = 0;           // where the sensor's standoff is put: as high as the band's lowest sample allows
    double y_lo = 0, y_hi = 0;  // the samples' extent along the pass
  };

  // The depth bands of a pass at x whose stripe is `width` wide: where the surface under it spans
  // more than a band, several, the top one first (the head comes down from the park). Empty over
  // nothing.
  std::vector<Band> bandsUnder(double x, double width) const {
    const double band = o_.depth_use * cell_.digitizer.measuring_range_mm;
    const auto [first, last] = within(x - 0.5 * width, x + 0.5 * width);
    double z_lo = std::numeric_limits<double>::infinity(), z_hi = -z_lo;
    for (std::size_t k = first; k < last; ++k) {
      const double z = samples_.points[by_x_[k]].z();
      z_lo = std::min(z_lo, z), z_hi = std::max(z_hi, z);
    }
    std::vector<Band> out;
    if (!(z_hi >= z_lo)) return out;
    const int bands = std::max(1, static_cast<int>(std::ceil((z_hi - z_lo) / band - 1e-9)));
    for (int layer = 0; layer < bands; ++layer) {
      Band b;
      b.z_mid = bands == 1 ? 0.5 * (z_lo + z_hi) : z_hi - (layer + 0.5) * (z_hi - z_lo) / bands;
      const double half_band = 0.5 * std::max(band, (z_hi - z_lo) / bands);
      b.y_lo = b.z_top = std::numeric_limits<double>::infinity();
      b.y_hi = -b.y_lo;
      b.z_top = -b.z_top;
      double z_bottom = b.z_mid;
      for (std::size_t k = first; k < last; ++k)
        if (const Vec3& p = samples_.points[by_x_[k]]; std::abs(p.z() - b.z_mid) <= half_band) {
          b.y_lo = std::min(b.y_lo, p.y());
          b.y_hi = std::max(b.y_hi, p.y());
          b.z_top = std::max(b.z_top, p.z());
          z_bottom = std::min(z_bottom, p.z());
        }
      // The stripe is wider the further the surface lies: the sensor flies as high as keeps the
      // band's lowest sample within the share of the measuring range a band may take.
      b.z_fly = std::max(b.z_top - 0.5 * band, z_bottom + 0.5 * band);
      if (b.y_hi >= b.y_lo) out.push_back(b);
    }
    return out;
  }

  // The stripe a pass lays on the surface it flies over: narrowest where the surface comes nearest
  // the sensor (the fan widens with the distance). Over nothing, the stripe at the standoff.
  double stripeOver(const std::vector<Band>& bands) const {
    const DigitizerDrawing& d = cell_.digitizer;
    const double half_fan = 0.5 * d.fan_angle_deg * kDeg;
    if (bands.empty()) return stripeWidth(d);
    double width = std::numeric_limits<double>::infinity();
    for (const Band& b : bands)
      width = std::min(width, 2 * std::max(0.0, d.standoff_mm - (b.z_top - b.z_fly)) * std::tan(half_fan));
    return width;
  }

  // The sweep of a pass in one band: the head's turn (the passes cross at +-2 degrees) and the
  // line its stripe's middle follows over the datum plane, x = x_at_ref + (y - y_ref_) * slope.
  struct Track {
    double turn = 0;
    double x_at_ref = 0, slope = 0;
    Vec3 along = Vec3::UnitY();  // the sweep's direction (forward)
    double xAt(double y, double y_ref) const { return x_at_ref + (y - y_ref) * slope; }
  };
  Track trackOf(double x, std::uint32_t index) const {
    Track t;
    t.turn = stop((index % 2 ? 2.0 : -2.0) * kDeg);
    const Eigen::Matrix3d R = headRotation(0, t.turn) * mount_.linear();
    t.along = Vec3(R(0, 1), R(1, 1), 0).normalized();
    t.x_at_ref = x;
    t.slope = std::abs(t.along.y()) > 1e-9 ? t.along.x() / t.along.y() : 0.0;
    return t;
  }

  // Whether the sweep along `track`, in `band`, claims sample i: the ray from the mirror to it (in
  // the fan's plane) lies within the claimed share of the fan, the band's share of the measuring range
  // and the incidence limit. Claims are what passes are laid by; the prediction (predictCoverage)
  // asks the full model of what the sensor sees, lines of sight included.
  bool claims(const Band& band, const Track& track, std::size_t i) const {
    const DigitizerDrawing& d = cell_.digitizer;
    const Vec3& p = samples_.points[i];
    const double dx = p.x() - track.xAt(p.y(), y_ref_), dz = band.z_fly + d.standoff_mm - p.z();
    if (!(dz > 0)) return false;
    // The band's depth is taken upright, as the bands are cut; the rest of the measuring range
    // (1 - depth_use) is more than the fan's slant adds at its edges.
    if (std::abs(dz - d.standoff_mm) > 0.5 * o_.depth_use * d.measuring_range_mm + 1e-6) return false;
    if (std::abs(dx) > std::min(dz * claimed_tan_, dz * fan_tan_ - whole_margin_)) return false;
    const Vec3& n = samples_.normals[i];
    const double facing = -dx * n.x() + dz * n.z();  // |ray| cos(incidence)
    return facing > 0 && facing * facing >= cos_incidence_ * cos_incidence_ * (dx * dx + dz * dz);
  }

  // The samples whose x lies within [x0, x1], as a range of positions in by_x_.
  std::pair<std::size_t, std::size_t> within(double x0, double x1) const {
    const auto lo = std::lower_bound(by_x_.begin(), by_x_.end(), x0, [&](std::size_t i, double v) { return samples_.points[i].x() < v; });
    const auto hi = std::upper_bound(lo, by_x_.end(), x1, [&](double v, std::size_t i) { return v < samples_.points[i].x(); });
    return {static_cast<std::size_t>(lo - by_x_.begin()), static_cast<std::size_t>(hi - by_x_.begin())};
  }

  // One pass flown at x: its depth bands and the not yet covered samples each one claims.
  struct Pass {
    double x = 0;
    std::vector<Band> bands;
    std::vector<Track> tracks;  // per band
    std::vector<std::vector<std::size_t>> claimed;  // per band
    std::size_t claimed_count = 0;
    bool complete = false;  // it claims every waiting sample left of it (nextPass)
  };

  // The places a pass may take: a lattice across the grid area and a fan's reach beyond it, each with
  // its depth bands (they depend on the ground under it, not on what is covered yet).
  double latticeX(std::size_t k) const { return lattice_x0_ + static_cast<double>(k) * lattice_step_; }
  void layLattice() {
    const double nominal = stripeWidth(cell_.digitizer);
    lattice_step_ = std::max(0.25, 0.5 * o_.sample_spacing_mm);
    lattice_x0_ = lo_.x() - reach_ - slant_;
    const auto count = static_cast<std::size_t>(std::ceil((hi_.x() + reach_ + slant_ - lattice_x0_) / lattice_step_)) + 1;
    lattice_bands_.assign(count, {});
    for (std::size_t k = 0; k < count; ++k) {
      // The bands' heights depend on the stripe, the stripe on what lies under it: a few rounds settle it.
      double width = nominal;
      for (int round = 0; round < 4; ++round) {
        lattice_bands_[k] = bandsUnder(latticeX(k), width);
        width = std::max(0.2 * nominal, stripeOver(lattice_bands_[k]));
      }
    }
  }
  std::pair<std::size_t, std::size_t> latticeWithin(double x0, double x1) const {
    const double k0 = std::ceil((x0 - lattice_x0_) / lattice_step_), k1 = std::floor((x1 - lattice_x0_) / lattice_step_);
    const double last = static_cast<double>(lattice_bands_.size());
    return {static_cast<std::size_t>(std::clamp(k0, 0.0, last)), static_cast<std::size_t>(std::clamp(k1 + 1, 0.0, last))};
  }

  // One pass at lattice place k, its first sweep numbered `index`: the samples not yet covered that
  // each of its bands claims.
  Pass passAt(std::size_t k, std::uint32_t index, const std::vector<char>& covered) const {
    Pass pass;
    pass.x = latticeX(k);
    pass.bands = lattice_bands_[k];
    pass.claimed.assign(pass.bands.size(), {});
    for (std::size_t b = 0; b < pass.bands.size(); ++b)
      pass.tracks.push_back(trackOf(pass.x, index + static_cast<std::uint32_t>(b)));
    const auto [first, last] = within(pass.x - reach_ - slant_, pass.x + reach_ + slant_);
    for (std::size_t j = first; j < last; ++j) {
      const std::size_t i = by_x_[j];
      if (covered[i]) continue;
      for (std::size_t b = 0; b < pass.bands.size(); ++b)
        if (claims(pass.bands[b], pass.tracks[b], i)) {
          pass.claimed[b].push_back(i);
          ++pass.claimed_count;
          break;
        }
    }
    return pass;
  }

  // The samples some pass can claim (either way of crossing): those the passes wait for. The others
  // (too steep, too deep for any band) the prediction names as unseen.
  std::vector<char> claimable() const {
    std::vector<char> out(samples_.points.size(), 0);
    for (std::size_t k = 0; k < lattice_bands_.size(); ++k)
      for (std::uint32_t parity = 0; parity < 2; ++parity) {
        const std::vector<char> none(samples_.points.size(), 0);
        for (const auto& band : passAt(k, parity, none).claimed)
          for (std::size_t i : band) out[i] = 1;
      }
    return out;
  }

  // Greedy cover from the left: the pass reaching furthest right while still claiming every waiting
  // sample left of it (and the leftmost one). Passes thus lie wider apart over flat ground and low
  // ground (where the fan is wide) than over slopes and crowns. When none claims all of them, the
  // furthest right that claims the leftmost (`first`); empty when no pass claims that one.
  std::optional<Pass> nextPass(std::size_t first, std::uint32_t index, const std::vector<char>& waiting) const {
    const double x_min = samples_.points[first].x();
    std::optional<Pass> best, fallback;
    std::vector<char> covered(waiting.size());
    for (std::size_t i = 0; i < waiting.size(); ++i) covered[i] = !waiting[i];
    const auto [k0, k1] = latticeWithin(x_min - reach_ - slant_, x_min + reach_ + slant_);
    std::vector<char> claimed(waiting.size(), 0);
    for (std::size_t k = k0; k < k1; ++k) {
      Pass pass = passAt(k, index, covered);
      for (const auto& band : pass.claimed)
        for (std::size_t i : band) claimed[i] = 1;
      // Left of the pass: of its first band's line, slanted by the turn.
      const Track& line = pass.tracks.empty() ? trackOf(pass.x, index) : pass.tracks.front();
      const auto [from, to] = within(x_min, std::max(pass.x, x_min) + slant_);
      bool all = true;
      for (std::size_t j = from; j < to && all; ++j) {
        const std::size_t i = by_x_[j];
        if (waiting[i] && !claimed[i] && (i == first || samples_.points[i].x() <= line.xAt(samples_.points[i].y(), y_ref_)))
          all = false;
      }
      const bool first_claimed = claimed[first] != 0;
      for (const auto& band : pass.claimed)
        for (std::size_t i : band) claimed[i] = 0;
      pass.complete = all;
      if (all)
        best = std::move(pass);
      else if (first_claimed)
        fallback = std::move(pass);
    }
    return best ? best : fallback;
  }

  // Passes along y, side by side in x, laid from one side of the grid area to the other (see
  // nextPass). Each pass claims its fan but for a margin on either side, so that neighbouring stripes
  // overlap: by the stated share of the fan, and never by less than an element's outline and the
  // part's placement tolerance, so that every element lies whole within one stripe. Where less
  // overlap (down to that minimum) saves passes, the passes are as few as it allows, spread with the
  // most overlap that count leaves.
  void laserPasses() {
    if (!(stripeWidth(cell_.digitizer) > 0)) return;
    const DigitizerDrawing& d = cell_.digitizer;
    cos_incidence_ = std::cos(d.incidence_limit_deg * kDeg);
    fan_tan_ = std::tan(0.5 * d.fan_angle_deg * kDeg);
    // An element straddling one stripe's claimed edge lies whole in the neighbour's fan: half a
    // formed element (a 40 % stretch of the printed one) and the part's placement on the fixture.
    whole_margin_ = 0.5 * 1.4 * std::max(plan_.part.pitch, plan_.part.circle_diameter) + o_.placement_tolerance_mm;
    reach_ = (d.standoff_mm + 0.5 * d.measuring_range_mm) * std::tan(0.5 * d.fan_angle_deg * kDeg);
    y_ref_ = 0.5 * (lo_.y() + hi_.y());
    slant_ = 0.5 * (hi_.y() - lo_.y()) * std::tan(2.5 * kDeg);
    by_x_.resize(samples_.points.size());
    for (std::size_t i = 0; i < by_x_.size(); ++i) by_x_[i] = i;
    std::sort(by_x_.begin(), by_x_.end(), [&](std::size_t a, std::size_t b) { return samples_.points[a].x() < samples_.points[b].x(); });
    layLattice();
    std::vector<SweepStep> best = sweepsWith(o_.strip_overlap);
    const double best_s = sweepsSeconds(best);
    std::vector<SweepStep> fewest = sweepsWith(0.0);
    if (sweepsSeconds(fewest) < 0.99 * best_s) {
      const double fewest_s = sweepsSeconds(fewest);
      double lo = 0, hi = o_.strip_overlap;
      for (int round = 0; round < 5; ++round) {
        const double mid = 0.5 * (lo + hi);
        std::vector<SweepStep> tried = sweepsWith(mid);
        if (sweepsSeconds(tried) <= 1.01 * fewest_s) {
          fewest = std::move(tried);
          lo = mid;
        } else {
          hi = mid;
        }
      }
      best = std::move(fewest);
    }
    for (SweepStep& s : best) plan_.steps.emplace_back(std::move(s));
  }

  // The passes' motion: their sweeps and the moves from the park, between them and back.
  double sweepsSeconds(const std::vector<SweepStep>& sweeps) const {
    ScanPlan p;
    p.park = plan_.park;
    p.travel_speed = plan_.travel_speed;
    for (const SweepStep& s : sweeps) p.steps.emplace_back(s);
    return motionSeconds(p, limits_);
  }

  // The passes laid with the fan's margins for the overlap share `overlap` (see laserPasses).
  std::vector<SweepStep> sweepsWith(double overlap) {
    const DigitizerDrawing& d = cell_.digitizer;
    claimed_tan_ = std::tan((1.0 - overlap) * 0.5 * d.fan_angle_deg * kDeg);
    std::vector<char> waiting = claimable();
    // Beyond the grid each pass runs on by an element's outline and the sweep's run-up, so that the
    // elements at its ends are crossed where the head's track can be trusted.
    const double lead = plan_.part.pitch + sweepRunUp(sweep_speed_, limits_.acceleration);
    std::vector<SweepStep> sweeps;
    std::uint32_t index = 0;
    bool forward = true;
    for (std::size_t k = 0; k < by_x_.size(); ++k) {
      if (!waiting[by_x_[k]]) continue;
      // Crossing one way or the other (+-2 degrees): whichever reaches further.
      std::optional<Pass> pass = nextPass(by_x_[k], index, waiting);
      std::optional<Pass> other = nextPass(by_x_[k], index + 1, waiting);
      const auto reach = [](const std::optional<Pass>& p) { return !p ? -1e300 : p->complete ? p->x : p->x - 1e6; };
      if (reach(other) > reach(pass) + 1e-9) {
        pass = std::move(other);
        ++index;
      }
      if (!pass || pass->claimed_count == 0) {
        waiting[by_x_[k]] = 0;  // no pass claims it: the prediction names what stays unseen
        continue;
      }
      for (std::size_t b = 0; b < pass->bands.size(); ++b) {
        if (pass->claimed[b].empty()) continue;
        double y_lo = std::numeric_limits<double>::infinity(), y_hi = -y_lo;
        for (std::size_t i : pass->claimed[b]) {
          waiting[i] = 0;
          y_lo = std::min(y_lo, samples_.points[i].y());
          y_hi = std::max(y_hi, samples_.points[i].y());
        }
        const Track& track = pass->tracks[b];
        const Eigen::Matrix3d R = headRotation(0, track.turn) * mount_.linear();
        const double y_mid = 0.5 * (y_lo + y_hi);
        const Vec3 centre = Vec3(track.xAt(y_mid, y_ref_), y_mid, pass->bands[b].z_fly) + d.standoff_mm * R.col(2);
        // Along the slanted track, as far as the claimed samples' ends in y.
        const double half = (0.5 * (y_hi - y_lo) + lead) / std::max(1e-9, std::abs(track.along.y()));
        const double direction = forward ? 1.0 : -1.0;
        SweepStep s;
        s.scene = Scene::Part;
        s.index = index++;
        s.start = headAt(centre - direction * half * track.along, 0, track.turn);
        s.end = headAt(centre + direction * half * track.along, 0, track.turn);
        s.speed = sweep_speed_;
        sweeps.push_back(s);
        forward = !forward;
      }
    }
    return sweeps;
  }

  // A rows x columns lattice over the grid area at the cameras' working distance; the outer views
  // stand further out and look inwards.
  void stereoViews() {
    const int rows = std::max(0, o_.stereo_rows), cols = std::max(0, o_.stereo_columns);
    if (rows == 0 || cols == 0) return;
    const Eigen::Vector2d mid(0.5 * (lo_.x() + hi_.x()), 0.5 * (lo_.y() + hi_.y()));
    const Eigen::Vector2d half(0.5 * (hi_.x() - lo_.x()), 0.5 * (hi_.y() - lo_.y()));
    const double z_mid = 0.5 * (lo_.z() + hi_.z());
    const double max_reach = half.norm() + 1e-9;
    std::uint32_t index = 0;
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < cols; ++i) {
        const double fx = cols == 1 ? 0.0 : 2.0 * i / (cols - 1) - 1.0;
        const double fy = rows == 1 ? 0.0 : 2.0 * j / (rows - 1) - 1.0;
        const Eigen::Vector2d offset(fx * 0.6 * half.x(), fy * 0.6 * half.y());
        const double reach = std::min(1.0, offset.norm() / max_reach);
        const double a = stop(0.35 * reach);
        const double phi = std::atan2(offset.y(), offset.x());
        const double b = stop(reach > 1e-6 ? std::atan2(std::cos(phi), -std::sin(phi)) : 0.0);
        const Vec3 target(mid.x() + offset.x(), mid.y() + offset.y(), z_mid);
        const Vec3 head =
            target + headRotation(a, b) * Vec3(0, 0, cell_.cameras.drop_mm + cell_.cameras.convergence_mm);
        StereoStep v;
        v.scene = Scene::Part;
        v.index = index++;
        v.pose = {{head.x(), head.y(), head.z()}, a, b};
        v.settle_s = 0.4;
        plan_.steps.emplace_back(v);
      }
  }

  const GridSamples& samples_;
  const CellGeometry& cell_;
  const MachineLimits& limits_;
  const PlannerOptions& o_;
  double sweep_speed_;  // mm/s, see sweepSpeed
  Eigen::Isometry3d mount_;
  Vec3 lo_, hi_;
  ScanPlan plan_;
  // Laying the passes: the samples in order of x, and the claimed share of the fan.
  std::vector<std::size_t> by_x_;
  double claimed_tan_ = 0, fan_tan_ = 0, whole_margin_ = 0, cos_incidence_ = 0, reach_ = 0;
  double y_ref_ = 0, slant_ = 0;  // the tracks' reference y; how far a track's x strays from its value there
  double lattice_x0_ = 0, lattice_step_ = 1;
  std::vector<std::vector<Band>> lattice_bands_;
};

}  // namespace

// A sweep along which the head's body would come nearer the part or the fixture than the clearance
// is left out: the part is planned as far as it can be, and the prediction names what is then not
// seen (a pocket too narrow for the sensor carrier). The moves between steps are not changed; the
// plan's check names any that come too near.
void leaveOutCollidingSweeps(ScanPlan& plan, const NominalModel& model, const CellGeometry& cell, double clearance_mm) {
  if (cell.head.body.empty()) return;
  CollisionOptions options;
  options.clearance_mm = clearance_mm;
  std::vector<char> colliding(plan.steps.size(), 0);
  for (const PlanCollision& c : checkCollisions(model, cell.fixture.body, trace::RigidPose{}, plan, cell.head, options))
    if (!c.during_move && std::holds_alternative<SweepStep>(plan.steps[c.step])) colliding[c.step] = 1;
  std::vector<PlanStep> kept;
  std::uint32_t index = 0;
  bool forward = true;
  for (std::size_t i = 0; i < plan.steps.size(); ++i) {
    if (colliding[i]) continue;
    if (auto* sweep = std::get_if<SweepStep>(&plan.steps[i])) {
      sweep->index = index++;
      // Keep the passes alternating so that each starts where the last one ended.
      const bool sweep_forward = sweep->end.position[1] >= sweep->start.position[1];
      if (sweep_forward != forward) std::swap(sweep->start, sweep->end);
      forward = !forward;
    }
    kept.push_back(std::move(plan.steps[i]));
  }
  plan.steps = std::move(kept);
}

double sweepSpeed(const PlannerOptions& options, const CellGeometry& cell, const MachineLimits& limits) {
  const double speed = options.sweep_speed > 0 ? options.sweep_speed
                                               : options.profile_spacing_mm * cell.digitizer.profile_rate_hz;
  return std::clamp(speed, limits.min_speed, limits.max_speed);
}

ScanPlan planPart(const NominalModel& model, const PartSpec& part, const CellGeometry& cell, const MachineLimits& limits,
                  const PlannerOptions& options) {
  if (!(options.strip_overlap >= 0 && options.strip_overlap < 0.9))
    throw std::invalid_argument("the strip overlap must be within 0 .. 0.9, not " + std::to_string(options.strip_overlap));
  if (!(options.sweep_speed >= 0) || !(options.profile_spacing_mm > 0) || !(options.travel_speed > 0))
    throw std::invalid_argument("the profile spacing and the travel speed must be positive, the sweep speed positive or 0 (from the spacing)");
  if (!(options.depth_use > 0 && options.depth_use <= 1))
    throw std::invalid_argument("depth_use must be within (0, 1]");
  if (!(options.sample_spacing_mm > 0)) throw std::invalid_argument("the sample spacing must be positive");
  const GridSamples samples = sampleGridArea(model, options.sample_spacing_mm, options.grid_normal_z);
  if (samples.points.empty())
    throw std::invalid_argument((model.source.empty() ? std::string("the model") : model.source) +
                                ": no facet faces the sensors' side (+z of the datum frame): nothing to plan");
  ScanPlan plan = PartPlanner(thinned(samples, options.sample_spacing_mm), part, cell, limits, options).plan();
  if (options.leave_out_colliding_sweeps) leaveOutCollidingSweeps(plan, model, cell, options.clearance_mm);
  return plan;
}

}  // namespace stampscan::acquisition
