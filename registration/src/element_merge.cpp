#include "stampscan/registration/element_merge.hpp"

#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/median.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace stampscan::registration {

namespace {

// Union-find over the measurements, joined where two stand within the twin radius.
class Groups {
 public:
  explicit Groups(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), std::uint32_t{0}); }
  std::uint32_t root(std::uint32_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void join(std::uint32_t a, std::uint32_t b) {
    a = root(a);
    b = root(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // the smaller index leads: order-independent groups
  }

 private:
  std::vector<std::uint32_t> parent_;
};

// The difference of two measurements with independent normal errors of variances s1 and s2 is
// normal with variance s1 + s2: its square's median is 0.4549 (s1 + s2) for a scalar, and
// 2.366 (s1 + s2) for the squared distance of two 3D positions (the medians of chi-square with one
// and three degrees of freedom). Medians, so that a rare wrong measurement does not inflate them.
constexpr double kMedianChi2One = 0.454936, kMedianChi2Three = 2.365974;
// Fewer same-path pairs than this say too little about a path's noise.
constexpr std::size_t kLeastPairs = 8;

struct PairDifferences {
  std::vector<double> strain_sq, position_sq;
  // Each pair's members' squared qualities (GridElement::fit_rms): for pairs of one path their sum,
  // for mixed pairs the laser's and the stereo view's apart.
  std::vector<double> quality_sq, laser_quality_sq, stereo_quality_sq;
};

// One measurement's own strain variance as its quality q (GridElement::fit_rms: how far its outline
// strays from the shape it was fitted with) says: a + b q^2. A stereo cell seen obliquely, its
// corners off their affine image by 0.02 mm, reads its strain four times worse than one seen
// squarely; a ring whose edge strays from its ellipse likewise.
struct OwnStrainVariance {
  double a = 0, b = 0;
};

// The squared quality of a measurement: 0 where its path gives none.
double qualitySq(const GridElement& g) { return std::isfinite(g.fit_rms) ? g.fit_rms * g.fit_rms : 0.0; }

// The variance of pair differences as a line in x (a pair's squared qualities): v = c0 + c1 x. The
// pairs in up to eight bins of equal count along x, each bin's variance from its median (robust to
// the rare wrong measurement), and a line through the bins' (mean x, variance) weighted by their
// counts. Where the line would fall with x, or one bin is all there is, c1 = 0 and c0 is the
// variance of all pairs.
struct VarianceLine {
  double c0 = 0, c1 = 0;
};
VarianceLine binnedVarianceLine(const std::vector<double>& strain_sq, const std::vector<double>& x) {
  const std::size_t n = strain_sq.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return x[i] < x[j]; });
  constexpr std::size_t kMostBins = 8, kPairsPerBin = 40;
  const std::size_t bins = std::clamp<std::size_t>(n / kPairsPerBin, 1, kMostBins);
  double sw = 0, sx = 0, sv = 0, sxx = 0, sxv = 0;
  std::vector<double> in_bin;
  for (std::size_t k = 0; k < bins; ++k) {
    const std::size_t from = k * n / bins, to = (k + 1) * n / bins;
    in_bin.clear();
    double mean_x = 0;
    for (std::size_t i = from; i < to; ++i) {
      in_bin.push_back(strain_sq[order[i]]);
      mean_x += x[order[i]];
    }
    const double w = static_cast<double>(to - from);
    mean_x /= w;
    const double v = fitting::median(in_bin) / kMedianChi2One;
    sw += w, sx += w * mean_x, sv += w * v, sxx += w * mean_x * mean_x, sxv += w * mean_x * v;
  }
  const double spread = sw * sxx - sx * sx;
  const double slope = bins > 1 && spread > 0 ? (sw * sxv - sx * sv) / spread : 0.0;
  if (slope > 0) return {std::max(0.0, (sv - slope * sx) / sw), slope};
  return {fitting::median(strain_sq) / kMedianChi2One, 0.0};
}

// Variances (own part, shared part) of one path's measurement, for the strain and the position.
struct PathVariances {
  std::optional<OwnStrainVariance> strain_own;
  std::optional<double> position_own;
  // The shared strain variance: strain_shared + shared_slope q^2 for a measurement of quality q.
  double strain_shared = 0, shared_slope = 0, position_shared = 0;
  double typical_quality_sq = 0;  // the median of its measurements'
  bool shared_known = false;      // from the two paths' disagreement; 0 without it
  bool known() const { return strain_own.has_value(); }
  double ownStrain(double quality_sq) const { return strain_own->a + strain_own->b * quality_sq; }
  double sharedStrain(double quality_sq) const { return strain_shared + shared_slope * quality_sq; }
  double strain(double quality_sq) const { return ownStrain(quality_sq) + sharedStrain(quality_sq); }
  double position() const { return *position_own + position_shared; }
};

// Each path's own variance from its twins. The mixed pairs' spread is the two paths' whole
// variances together: what exceeds their own parts is shared. Two paths' differences cannot tell
// whose that shared part is; it is split in proportion to the paths' own variances, as the same
// causes (resolution, the view's obliqueness) make both parts of a path's error. Half to each had
// given a laser with fine returns the shared error of a coarse camera pair. What of it grows with
// the stereo view's quality, beyond the stereo twins' own growth, is error the stereo views of one
// element share (a cell on a wall every camera pose sees obliquely): the stereo path's, growing with
// its quality likewise. A path without twins of its own takes its whole variance from the mixed
// pairs less the other's (at least a quarter of the other's own: the mixed pairs also carry any
// offset between the paths, an error of one of them).
void estimateNoise(const PairDifferences& laser, const PairDifferences& stereo, const PairDifferences& mixed,
                   PathVariances& l, PathVariances& s) {
  const auto own = [](const PairDifferences& d, PathVariances& v) {
    if (d.strain_sq.size() < kLeastPairs) return;
    const VarianceLine twins = binnedVarianceLine(d.strain_sq, d.quality_sq);  // 2 a + b (q1^2 + q2^2)
    v.strain_own = OwnStrainVariance{0.5 * twins.c0, twins.c1};
    v.position_own = fitting::median(d.position_sq) / (2 * kMedianChi2Three);
  };
  own(laser, l);
  own(stereo, s);
  if (mixed.strain_sq.size() < kLeastPairs || (!l.known() && !s.known())) return;
  const double sum_strain = fitting::median(mixed.strain_sq) / kMedianChi2One;
  const double sum_position = fitting::median(mixed.position_sq) / kMedianChi2Three;
  // The mixed pairs' own variances, as their members' qualities say (0 for a path not known).
  const auto ownOfMixed = [&](const PathVariances& v, const std::vector<double>& quality_sq) {
    std::vector<double> own_sq;
    for (double q2 : quality_sq) own_sq.push_back(v.known() ? v.ownStrain(q2) : 0.0);
    return own_sq;
  };
  const std::vector<double> laser_own = ownOfMixed(l, mixed.laser_quality_sq);
  const std::vector<double> stereo_own = ownOfMixed(s, mixed.stereo_quality_sq);
  if (l.known() && s.known()) {
    const VarianceLine spread = binnedVarianceLine(mixed.strain_sq, mixed.stereo_quality_sq);
    const double stereo_growth = std::max(0.0, spread.c1 - s.strain_own->b);
    const double typical_laser_own = fitting::median(laser_own), typical_stereo_own = fitting::median(stereo_own);
    double shared = 0;
    if (stereo_growth > 0) {
      shared = std::max(0.0, spread.c0 - typical_laser_own - s.strain_own->a);
      s.shared_slope = stereo_growth;
    } else {
      std::vector<double> both(laser_own.size());
      for (std::size_t i = 0; i < both.size(); ++i) both[i] = laser_own[i] + stereo_own[i];
      shared = std::max(0.0, sum_strain - fitting::median(both));
    }
    const double own_sum = typical_laser_own + typical_stereo_own;
    const double laser_share = own_sum > 0 ? typical_laser_own / own_sum : 0.5;
    l.strain_shared = laser_share * shared;
    s.strain_shared = (1 - laser_share) * shared;
    l.position_shared = s.position_shared = std::max(0.0, 0.5 * (sum_position - *l.position_own - *s.position_own));
    l.shared_known = s.shared_known = true;
    return;
  }
  const PathVariances& known = l.known() ? l : s;
  PathVariances& unknown = l.known() ? s : l;
  const double known_own = fitting::median(l.known() ? laser_own : stereo_own);
  unknown.strain_own = OwnStrainVariance{std::max(sum_strain - known_own, 0.25 * known_own), 0.0};
  unknown.position_own = std::max(sum_position - *known.position_own, 0.25 * *known.position_own);
}

// The merged element of `members` (indices into `m`). Each path's measurements are averaged, each
// weighted by the inverse of its own variance (own errors shrink with their number, the shared part
// does not), and the paths' means weighted by the inverse of their variances. A member whose strain
// stands further than kOutlierSigmas of its uncertainty from the median of three or more of its own
// path's members is a wrong measurement (a ring misread across a fold) and left out. One path's
// measurements of an element share part of their error, so they are no independent votes against
// the other path: three stereo views of a strongly thinned cell on a wall, all reading it 0.02 too
// thin, had outvoted the laser's one right reading of it.
constexpr double kOutlierSigmas = 5.0;

GridElement mergeGroup(const std::vector<GridElement>& m, std::vector<std::uint32_t> members, const PathVariances& l,
                       const PathVariances& s) {
  const bool known = l.known() && s.known();
  const auto path = [&](std::uint32_t i) -> const PathVariances& { return m[i].source == Source::Laser ? l : s; };
  const auto path_index = [&](std::uint32_t i) { return m[i].source == Source::Laser ? 0 : 1; };  // laser, stereo
  if (known && members.size() >= 3) {
    std::vector<double> strains[2];
    for (std::uint32_t i : members) strains[path_index(i)].push_back(m[i].thickness_strain);
    const std::size_t count[2] = {strains[0].size(), strains[1].size()};
    const double centre[2] = {count[0] >= 3 ? fitting::median(strains[0]) : 0.0,
                              count[1] >= 3 ? fitting::median(strains[1]) : 0.0};
    std::vector<std::uint32_t> kept;
    for (std::uint32_t i : members) {
      const int p = path_index(i);
      if (count[p] < 3 ||
          std::abs(m[i].thickness_strain - centre[p]) <= kOutlierSigmas * std::sqrt(path(i).strain(qualitySq(m[i]))))
        kept.push_back(i);
    }
    if (!kept.empty()) members = std::move(kept);
  }
  // Each member's weight: its share of its path's mean (by the inverse of its own variance) times
  // that mean's inverse variance. No better than a micrometre and a ten-thousandth of strain is
  // claimed for a path's mean, nor a tenth of that of one measurement's own strain.
  const auto own_strain = [&](std::uint32_t i) { return std::max(path(i).ownStrain(qualitySq(m[i])), 1e-10); };
  std::size_t counts[2] = {0, 0};
  double own_weight[2] = {0, 0};  // laser, stereo: the sums of 1 / own variance
  for (std::uint32_t i : members) {
    const int p = path_index(i);
    ++counts[p];
    if (known) own_weight[p] += 1 / own_strain(i);
  }
  // The shared error of a path's mean: the members' shared errors are one error, weighted as they are.
  double shared_sigma[2] = {0, 0};
  if (known)
    for (std::uint32_t i : members) {
      const int p = path_index(i);
      shared_sigma[p] += (1 / own_strain(i)) / own_weight[p] * std::sqrt(path(i).sharedStrain(qualitySq(m[i])));
    }
  const auto weights = [&](std::uint32_t i) -> std::pair<double, double> {  // strain, position
    if (!known) return {1.0, 1.0};
    const PathVariances& v = path(i);
    const int p = path_index(i);
    const double n = static_cast<double>(counts[p]);
    const double strain_var = std::max(1 / own_weight[p] + shared_sigma[p] * shared_sigma[p], 1e-8);
    const double position_var = std::max(*v.position_own / n + v.position_shared, 1e-6);
    return {(1 / own_strain(i)) / own_weight[p] / strain_var, 1 / (n * position_var)};
  };
  GridElement g;
  double ws = 0, wp = 0, best = -1;
  Vec3 position = Vec3::Zero(), normal = Vec3::Zero(), direction = Vec3::Zero();
  double major = 0, minor = 0, thickness = 0, semi_major = 0, semi_minor = 0, fit_rms = 0, gauge = 0;
  std::size_t edge_points = 0;
  const GridElement* leader = &m[members.front()];
  for (std::uint32_t i : members) {
    const auto [w, w_position] = weights(i);
    if (w > best) best = w, leader = &m[i];
    ws += w;
    wp += w_position;
    position += w_position * m[i].position;
    normal += w * m[i].normal;
    major += w * m[i].major_strain;
    minor += w * m[i].minor_strain;
    thickness += w * m[i].thickness_strain;
    semi_major += w * m[i].semi_major;
    semi_minor += w * m[i].semi_minor;
    fit_rms += w * m[i].fit_rms;
    gauge += w * m[i].gauge_mm2;  // the mean strain's averaging is the same mean of the members'
    edge_points += m[i].edge_points;
  }
  // The major direction is an axis (its sign means nothing): each is turned towards the leader's.
  for (std::uint32_t i : members) {
    const double w = weights(i).first;
    const Vec3& d = m[i].major_direction;
    direction += (d.dot(leader->major_direction) < 0 ? -w : w) * d;
  }
  g.position = position / wp;
  g.normal = normal.norm() > 0 ? Vec3(normal.normalized()) : leader->normal;
  direction -= direction.dot(g.normal) * g.normal;
  g.major_direction = direction.norm() > 0 ? Vec3(direction.normalized()) : leader->major_direction;
  g.major_strain = major / ws;
  g.minor_strain = minor / ws;
  g.thickness_strain = thickness / ws;
  g.semi_major = semi_major / ws;
  g.semi_minor = semi_minor / ws;
  g.fit_rms = fit_rms / ws;
  g.gauge_mm2 = gauge / ws;
  g.edge_points = edge_points;
  g.source = leader->source;
  g.view = leader->view;
  g.measurements = static_cast<std::uint32_t>(members.size());
  if (known) {
    g.strain_sigma = g.strain_noise = 1 / std::sqrt(ws);
    g.position_sigma_mm = 1 / std::sqrt(wp);
  }
  return g;
}

}  // namespace

MergedElements mergeMeasurements(const std::vector<GridElement>& m, double twin_radius_mm) {
  if (!(twin_radius_mm > 0)) throw std::invalid_argument("mergeMeasurements: the twin radius must be positive");
  if (m.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("mergeMeasurements: more than 4 billion measurements");
  MergedElements out;
  out.measurements = m.size();
  if (m.empty()) return out;
  std::vector<Vec3> positions(m.size());
  for (std::size_t i = 0; i < m.size(); ++i) positions[i] = m[i].position;
  const fitting::KdTree tree(positions);
  Groups groups(m.size());
  std::vector<fitting::Neighbor> near;
  for (std::size_t i = 0; i < m.size(); ++i) {
    tree.radius(positions[i], twin_radius_mm, near);
    for (const fitting::Neighbor& n : near) groups.join(static_cast<std::uint32_t>(i), n.index);
  }
  // The groups in the order of their first measurement.
  std::vector<std::vector<std::uint32_t>> members;
  std::vector<std::uint32_t> group_of_root(m.size(), std::numeric_limits<std::uint32_t>::max());
  out.element_of.resize(m.size());
  for (std::uint32_t i = 0; i < m.size(); ++i) {
    const std::uint32_t r = groups.root(i);
    if (group_of_root[r] == std::numeric_limits<std::uint32_t>::max()) {
      group_of_root[r] = static_cast<std::uint32_t>(members.size());
      members.emplace_back();
    }
    out.element_of[i] = group_of_root[r];
    members[group_of_root[r]].push_back(i);
  }

  // Every pair within a group, by the paths of the two.
  PairDifferences laser, stereo, mixed;
  for (const auto& group : members)
    for (std::size_t a = 0; a < group.size(); ++a)
      for (std::size_t b = a + 1; b < group.size(); ++b) {
        const GridElement& p = m[group[a]];
        const GridElement& q = m[group[b]];
        PairDifferences& d = p.source != q.source ? mixed : p.source == Source::Laser ? laser : stereo;
        d.strain_sq.push_back(std::pow(p.thickness_strain - q.thickness_strain, 2));
        d.position_sq.push_back((p.position - q.position).squaredNorm());
        if (&d != &mixed) {
          d.quality_sq.push_back(qualitySq(p) + qualitySq(q));
        } else {
          d.laser_quality_sq.push_back(qualitySq(p.source == Source::Laser ? p : q));
          d.stereo_quality_sq.push_back(qualitySq(p.source == Source::Laser ? q : p));
        }
      }
  PathVariances l, st;
  estimateNoise(laser, stereo, mixed, l, st);
  for (const Source source : {Source::Laser, Source::Stereo}) {
    std::vector<double> quality_sq;
    for (const GridElement& g : m)
      if (g.source == source) quality_sq.push_back(qualitySq(g));
    (source == Source::Laser ? l : st).typical_quality_sq = quality_sq.empty() ? 0.0 : fitting::median(quality_sq);
  }
  // A path measured alone (a laser-only scan) has no twins of the other to compare: its own part is
  // all that is known, and it stands for both.
  if (l.known() && !st.known()) st = l;
  if (st.known() && !l.known()) l = st;
  const auto describe = [](const PathVariances& v, std::size_t pairs, PathNoise& noise) {
    noise.twin_pairs = pairs;
    if (!v.known()) return;
    noise.strain = std::sqrt(v.strain(v.typical_quality_sq));
    noise.position_mm = std::sqrt(v.position());
    if (!v.shared_known) return;
    noise.strain_shared = std::sqrt(v.sharedStrain(v.typical_quality_sq));
    noise.position_shared_mm = std::sqrt(v.position_shared);
  };
  describe(l, laser.strain_sq.size(), out.laser);
  describe(st, stereo.strain_sq.size(), out.stereo);
  out.elements.reserve(members.size());
  for (const auto& group : members) out.elements.push_back(mergeGroup(m, group, l, st));
  out.strain_sigma_of.assign(m.size(), std::numeric_limits<double>::quiet_NaN());
  out.position_sigma_mm_of.assign(m.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < m.size(); ++i) {
    const PathVariances& v = m[i].source == Source::Laser ? l : st;
    if (!v.known()) continue;
    out.strain_sigma_of[i] = std::sqrt(v.strain(qualitySq(m[i])));
    out.position_sigma_mm_of[i] = std::sqrt(v.position());
  }
  return out;
}

namespace {

// The strain field around one merged element: a quadratic in the printed grid's coordinates over
// its tangent plane, through it and its neighbours.
struct LocalField {
  Eigen::Vector2d laplacian = Eigen::Vector2d::Zero();  // of the major and the minor strain (1/mm^2)
  // How far the thickness strains stray from the quadratic beyond their own stated noise: what a
  // smooth field around the element does not explain (variance; 0 where the noise is not known).
  double misfit_beyond_noise = 0;
};

// Nothing where the neighbours do not surround the element.
std::optional<LocalField> localField(const std::vector<GridElement>& elements, std::size_t e, const fitting::KdTree& tree,
                                     double pitch, std::vector<fitting::Neighbor>& near) {
  const GridElement& g = elements[e];
  const Vec3 d1 = g.major_direction;
  const Vec3 d2 = g.normal.cross(d1).normalized();
  // Distances in pitches of the printed grid: the stretches undone along the principal axes.
  const double l1 = std::exp(g.major_strain), l2 = std::exp(g.minor_strain);
  constexpr double kReach = 1.6;  // pitches: the eight neighbours of a square lattice, not the next ring
  tree.radius(g.position, kReach * pitch * std::max(l1, l2), near);
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 2> atb = Eigen::Matrix<double, 6, 2>::Zero();
  std::vector<std::pair<Eigen::Matrix<double, 6, 1>, std::uint32_t>> rows;
  int sides = 0;
  for (const fitting::Neighbor& n : near) {
    const Vec3 q = elements[n.index].position - g.position;
    const double x = d1.dot(q) / (l1 * pitch), y = d2.dot(q) / (l2 * pitch);  // printed pitches
    if (x * x + y * y > kReach * kReach) continue;
    Eigen::Matrix<double, 6, 1> row;
    row << 1, x, y, x * x, x * y, y * y;
    ata += row * row.transpose();
    atb += row * Eigen::RowVector2d(elements[n.index].major_strain, elements[n.index].minor_strain);
    sides |= (x > 0.5 ? 1 : 0) | (x < -0.5 ? 2 : 0) | (y > 0.5 ? 4 : 0) | (y < -0.5 ? 8 : 0);
    rows.emplace_back(row, n.index);
  }
  if (rows.size() < 8 || sides != 15) return std::nullopt;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> solve(ata);
  if (solve.info() != Eigen::Success || !(solve.vectorD().minCoeff() > 1e-6 * solve.vectorD().maxCoeff()))
    return std::nullopt;
  const Eigen::Matrix<double, 6, 2> c = solve.solve(atb);
  if (!c.allFinite()) return std::nullopt;
  LocalField field;
  // f = ... + c3 x^2 + c5 y^2 in pitches: the Laplacian over the printed grid is 2 (c3 + c5) / pitch^2.
  field.laplacian = Eigen::Vector2d(2 * (c(3, 0) + c(5, 0)), 2 * (c(3, 1) + c(5, 1))) / (pitch * pitch);
  double residual_sq = 0, noise_sq = 0;
  bool noise_known = true;
  for (const auto& [row, index] : rows) {
    const GridElement& n = elements[index];
    const Eigen::RowVector2d fitted = row.transpose() * c;
    residual_sq += std::pow(n.thickness_strain + fitted.sum(), 2);  // thickness = -(major + minor)
    noise_sq += n.strain_noise * n.strain_noise;
    noise_known = noise_known && std::isfinite(n.strain_noise);
  }
  const double count = static_cast<double>(rows.size());
  if (noise_known) field.misfit_beyond_noise = std::max(0.0, residual_sq / (count - 6) - noise_sq / count);
  return field;
}

// Every merged element's local field.
std::vector<std::optional<LocalField>> localFields(const std::vector<GridElement>& elements, double pitch) {
  std::vector<std::optional<LocalField>> fields(elements.size());
  if (elements.empty()) return fields;
  std::vector<Vec3> positions(elements.size());
  for (std::size_t i = 0; i < elements.size(); ++i) positions[i] = elements[i].position;
  const fitting::KdTree tree(positions);
  std::vector<fitting::Neighbor> near;
  for (std::size_t e = 0; e < elements.size(); ++e) fields[e] = localField(elements, e, tree, pitch, near);
  return fields;
}

}  // namespace

std::vector<GridElement> strainsAtCentres(const std::vector<GridElement>& measurements, const MergedElements& merged,
                                          double pitch_mm) {
  if (!(pitch_mm > 0)) throw std::invalid_argument("strainsAtCentres: the pitch must be positive");
  if (merged.element_of.size() != measurements.size())
    throw std::invalid_argument("strainsAtCentres: the merged elements are not those of these measurements");
  std::vector<GridElement> out = measurements;
  const std::vector<std::optional<LocalField>> fields = localFields(merged.elements, pitch_mm);
  for (std::size_t i = 0; i < out.size(); ++i) {
    const std::optional<LocalField>& field = fields[merged.element_of[i]];
    GridElement& g = out[i];
    if (!field || !(g.gauge_mm2 > 0)) continue;
    const Eigen::Vector2d& lap = field->laplacian;
    g.major_strain -= g.gauge_mm2 * lap.x();
    g.minor_strain -= g.gauge_mm2 * lap.y();
    g.thickness_strain = -(g.major_strain + g.minor_strain);
    g.semi_major *= std::exp(-g.gauge_mm2 * lap.x());
    g.semi_minor *= std::exp(-g.gauge_mm2 * lap.y());
  }
  return out;
}

namespace {

// Whether `p` lies within g's outline: the ellipse of its semi-axes in its tangent plane.
bool outlineHolds(const GridElement& g, const Vec3& p) {
  if (!(g.semi_major > 0) || !(g.semi_minor > 0)) return false;
  const Vec3 d = p - g.position;
  const double x = d.dot(g.major_direction), y = d.dot(g.normal.cross(g.major_direction));
  return std::pow(x / g.semi_major, 2) + std::pow(y / g.semi_minor, 2) < 1;
}

}  // namespace

std::vector<std::uint32_t> overlappingElements(const MergedElements& merged) {
  const std::vector<GridElement>& elements = merged.elements;
  std::vector<std::uint32_t> out;
  if (elements.size() < 2) return out;
  std::vector<Vec3> positions(elements.size());
  double widest = 0;
  for (std::size_t i = 0; i < elements.size(); ++i) {
    positions[i] = elements[i].position;
    if (std::isfinite(elements[i].semi_major)) widest = std::max(widest, elements[i].semi_major);
  }
  const fitting::KdTree tree(positions);
  const auto weaker = [&](std::size_t a, std::size_t b) {  // a has less support than b
    if (elements[a].measurements != elements[b].measurements) return elements[a].measurements < elements[b].measurements;
    const double na = elements[a].strain_noise, nb = elements[b].strain_noise;
    if (std::isfinite(na) && std::isfinite(nb) && na != nb) return na > nb;
    return a > b;  // a tie: the later one, so that the result does not depend on which is asked first
  };
  std::vector<fitting::Neighbor> near;
  for (std::size_t a = 0; a < elements.size(); ++a) {
    tree.radius(positions[a], widest, near);
    for (const fitting::Neighbor& n : near) {
      const std::size_t b = n.index;
      if (b == a) continue;
      const bool overlap = outlineHolds(elements[a], positions[b]) || outlineHolds(elements[b], positions[a]);
      if (overlap && weaker(a, b)) {
        out.push_back(static_cast<std::uint32_t>(a));
        break;
      }
    }
  }
  return out;
}

void addFieldUncertainty(MergedElements& merged, double pitch_mm) {
  if (!(pitch_mm > 0)) throw std::invalid_argument("addFieldUncertainty: the pitch must be positive");
  const std::vector<std::optional<LocalField>> fields = localFields(merged.elements, pitch_mm);
  for (std::size_t e = 0; e < merged.elements.size(); ++e) {
    GridElement& g = merged.elements[e];
    if (!fields[e] || !std::isfinite(g.strain_sigma)) continue;
    const double centre_shift = g.gauge_mm2 * (fields[e]->laplacian.x() + fields[e]->laplacian.y());
    g.strain_sigma = std::sqrt(g.strain_sigma * g.strain_sigma + fields[e]->misfit_beyond_noise + centre_shift * centre_shift);
  }
}

}  // namespace stampscan::registration
