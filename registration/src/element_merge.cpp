#include "stampscan/registration/element_merge.hpp"

#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/median.hpp"

#include <algorithm>
#include <cmath>
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
};

// Variances (own part, shared part) of one path's measurement, for the strain and the position.
struct PathVariances {
  std::optional<double> strain_own, position_own;
  double strain_shared = 0, position_shared = 0;
  bool shared_known = false;  // from the two paths' disagreement; 0 without it
  bool known() const { return strain_own.has_value(); }
  double strain() const { return *strain_own + strain_shared; }
  double position() const { return *position_own + position_shared; }
};

// Each path's own variance from its twins. The mixed pairs' spread is the two paths' whole
// variances together: what exceeds their own parts is shared, half to each. A path without twins of
// its own takes its whole variance from the mixed pairs less the other's (at least a quarter of
// the other's own: the mixed pairs also carry any offset between the paths, an error of one of them).
void estimateNoise(const PairDifferences& laser, const PairDifferences& stereo, const PairDifferences& mixed,
                   PathVariances& l, PathVariances& s) {
  const auto own = [](const PairDifferences& d, PathVariances& v) {
    if (d.strain_sq.size() < kLeastPairs) return;
    v.strain_own = fitting::median(d.strain_sq) / (2 * kMedianChi2One);
    v.position_own = fitting::median(d.position_sq) / (2 * kMedianChi2Three);
  };
  own(laser, l);
  own(stereo, s);
  if (mixed.strain_sq.size() < kLeastPairs || (!l.known() && !s.known())) return;
  const double sum_strain = fitting::median(mixed.strain_sq) / kMedianChi2One;
  const double sum_position = fitting::median(mixed.position_sq) / kMedianChi2Three;
  if (l.known() && s.known()) {
    l.strain_shared = s.strain_shared = std::max(0.0, 0.5 * (sum_strain - *l.strain_own - *s.strain_own));
    l.position_shared = s.position_shared = std::max(0.0, 0.5 * (sum_position - *l.position_own - *s.position_own));
    l.shared_known = s.shared_known = true;
    return;
  }
  const PathVariances& known = l.known() ? l : s;
  PathVariances& unknown = l.known() ? s : l;
  unknown.strain_own = std::max(sum_strain - *known.strain_own, 0.25 * *known.strain_own);
  unknown.position_own = std::max(sum_position - *known.position_own, 0.25 * *known.position_own);
}

// The merged element of `members` (indices into `m`). Each path's measurements are averaged (their
// own errors shrink with their number, the shared part does not), and the paths' means weighted by
// the inverse of those variances. A member whose strain stands further than kOutlierSigmas of its
// path's uncertainty from the median of three or more is a wrong measurement (a ring misread
// across a fold) and left out.
constexpr double kOutlierSigmas = 5.0;

GridElement mergeGroup(const std::vector<GridElement>& m, std::vector<std::uint32_t> members, const PathVariances& l,
                       const PathVariances& s) {
  const bool known = l.known() && s.known();
  const auto path = [&](std::uint32_t i) -> const PathVariances& { return m[i].source == Source::Laser ? l : s; };
  if (known && members.size() >= 3) {
    std::vector<double> strains;
    for (std::uint32_t i : members) strains.push_back(m[i].thickness_strain);
    const double centre = fitting::median(strains);
    std::vector<std::uint32_t> kept;
    for (std::uint32_t i : members)
      if (std::abs(m[i].thickness_strain - centre) <= kOutlierSigmas * std::sqrt(path(i).strain())) kept.push_back(i);
    if (!kept.empty()) members = std::move(kept);
  }
  // Each member's weight: its path's mean's inverse variance, shared among the path's members.
  std::size_t laser_count = 0;
  for (std::uint32_t i : members) laser_count += m[i].source == Source::Laser;
  const std::size_t counts[2] = {laser_count, members.size() - laser_count};
  const auto weights = [&](std::uint32_t i) -> std::pair<double, double> {  // strain, position
    if (!known) return {1.0, 1.0};
    const PathVariances& v = path(i);
    const double n = static_cast<double>(counts[m[i].source == Source::Laser ? 0 : 1]);
    // No better than a micrometre and a ten-thousandth of strain is claimed for a path's mean.
    const double strain_var = std::max(*v.strain_own / n + v.strain_shared, 1e-8);
    const double position_var = std::max(*v.position_own / n + v.position_shared, 1e-6);
    return {1 / (n * strain_var), 1 / (n * position_var)};
  };
  GridElement g;
  double ws = 0, wp = 0, best = -1;
  Vec3 position = Vec3::Zero(), normal = Vec3::Zero(), direction = Vec3::Zero();
  double major = 0, minor = 0, thickness = 0, semi_major = 0, semi_minor = 0, fit_rms = 0;
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
  g.edge_points = edge_points;
  g.source = leader->source;
  g.view = leader->view;
  g.measurements = static_cast<std::uint32_t>(members.size());
  if (known) {
    g.strain_sigma = 1 / std::sqrt(ws);
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
      }
  PathVariances l, st;
  estimateNoise(laser, stereo, mixed, l, st);
  // A path measured alone (a laser-only scan) has no twins of the other to compare: its own part is
  // all that is known, and it stands for both.
  if (l.known() && !st.known()) st = l;
  if (st.known() && !l.known()) l = st;
  const auto describe = [](const PathVariances& v, std::size_t pairs, PathNoise& noise) {
    noise.twin_pairs = pairs;
    if (!v.known()) return;
    noise.strain = std::sqrt(v.strain());
    noise.position_mm = std::sqrt(v.position());
    if (!v.shared_known) return;
    noise.strain_shared = std::sqrt(v.strain_shared);
    noise.position_shared_mm = std::sqrt(v.position_shared);
  };
  describe(l, laser.strain_sq.size(), out.laser);
  describe(st, stereo.strain_sq.size(), out.stereo);
  out.elements.reserve(members.size());
  for (const auto& group : members) out.elements.push_back(mergeGroup(m, group, l, st));
  return out;
}

}  // namespace stampscan::registration
