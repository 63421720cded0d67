#include "joined_surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace stampscan::fitting::detail {

namespace {
constexpr int kBits = 21;
constexpr std::int64_t kBias = std::int64_t{1} << (kBits - 1);
constexpr std::int64_t kMax = (std::int64_t{1} << kBits) - 1;

std::array<std::int64_t, 3> cellOf(const Vec3& p, const Vec3& origin, double cell) {
  const Vec3 g = (p - origin) / cell;
  return {static_cast<std::int64_t>(std::floor(g.x())), static_cast<std::int64_t>(std::floor(g.y())),
          static_cast<std::int64_t>(std::floor(g.z()))};
}

std::uint64_t keyOf(std::int64_t i, std::int64_t j, std::int64_t k) {
  const auto c = [](std::int64_t v) { return static_cast<std::uint64_t>(std::clamp(v + kBias, std::int64_t{0}, kMax)); };
  return (c(i) << (2 * kBits)) | (c(j) << kBits) | c(k);
}
}  // namespace

PieceDensity::PieceDensity(const std::vector<Vec3>& points, double cell) : cell_(cell) {
  if (!(cell > 0)) throw std::invalid_argument("joined surface: the density cell must be positive");
  const Bounds bounds = boundsOf(points);
  origin_ = bounds.min;
  low_ = bounds.min - Vec3::Constant(cell);
  high_ = bounds.max + Vec3::Constant(cell);
  for (const Vec3& p : points) {
    const auto c = cellOf(p, origin_, cell_);
    CellSums& s = cells_[keyOf(c[0], c[1], c[2])];
    s.sum += p;
    s.count += 1;
  }
  for (auto& [key, s] : cells_) {
    s.sum /= s.count;  // the centroid from here on
    const auto b = cellOf(s.sum, origin_, 2 * cell_);
    for (std::int64_t di = -1; di <= 1; ++di)
      for (std::int64_t dj = -1; dj <= 1; ++dj)
        for (std::int64_t dk = -1; dk <= 1; ++dk) near_blocks_.insert(keyOf(b[0] + di, b[1] + dj, b[2] + dk));
  }
}

bool PieceDensity::inBounds(const Vec3& x) const {
  return (x.array() >= low_.array()).all() && (x.array() <= high_.array()).all();
}

bool PieceDensity::reaches(const Vec3& x) const {
  if (!inBounds(x)) return false;
  const auto b = cellOf(x, origin_, 2 * cell_);
  return near_blocks_.contains(keyOf(b[0], b[1], b[2]));
}

double PieceDensity::at(const Vec3& x) const {
  if (!inBounds(x)) return 0;
  // Every centroid within one cell of x lies in the 27 cells around x's.
  const auto c = cellOf(x, origin_, cell_);
  const double support_sq = cell_ * cell_;
  double density = 0;
  for (std::int64_t di = -1; di <= 1; ++di)
    for (std::int64_t dj = -1; dj <= 1; ++dj)
      for (std::int64_t dk = -1; dk <= 1; ++dk) {
        const auto it = cells_.find(keyOf(c[0] + di, c[1] + dj, c[2] + dk));
        if (it == cells_.end()) continue;
        const double u = (it->second.sum - x).squaredNorm() / support_sq;
        if (u < 1) density += it->second.count * (1 - u) * (1 - u);
      }
  return density;
}

JoinedSurface::JoinedSurface(const std::vector<const FittedSurface*>& fits) {
  if (fits.empty()) throw std::invalid_argument("joined surface: no pieces");
  pieces_.reserve(fits.size());
  data_.reserve(fits.size());
  for (const FittedSurface* fit : fits) {
    // Cells as wide as the piece's typical smoothing bandwidth: its fits' support.
    const double cell = fit->preparationStats().bandwidth.median;
    pieces_.push_back({fit, PieceDensity(fit->input().positions, cell > 0 ? cell : 1.0)});
    data_.emplace_back(fit->tree(), fit->input().positions);
  }
}

Projection JoinedSurface::projectPoint(std::size_t) const {
  throw std::logic_error("joined surface: project points by position (the pieces keep their own data)");
}

Projection JoinedSurface::project(const Vec3& x) const {
  struct Foot {
    Projection p;
    double weight;
  };
  thread_local std::vector<Foot> feet;
  feet.clear();
  Projection nearest_unweighted;
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (const JoinedPiece& piece : pieces_) {
    if (!piece.density.reaches(x)) continue;
    const Projection p = piece.fit->surface().project(x);
    if (!p.valid) continue;
    const double density = piece.density.at(p.point);
    if (density > 0) {
      feet.push_back({p, density * density});
    } else if ((p.point - x).norm() < nearest_distance) {
      nearest_distance = (p.point - x).norm();
      nearest_unweighted = p;
    }
  }
  if (feet.empty()) return nearest_unweighted;  // beyond every piece's data: the nearest projection, or none
  if (feet.size() == 1) return feet[0].p;
  const auto heaviest =
      std::max_element(feet.begin(), feet.end(), [](const Foot& a, const Foot& b) { return a.weight < b.weight; });
  const Vec3 reference = heaviest->p.normal;
  Projection out = heaviest->p;
  Vec3 point = Vec3::Zero(), normal = Vec3::Zero();
  double total = 0;
  out.neighbors = 0;
  for (const Foot& f : feet) {
    point += f.weight * f.p.point;
    normal += f.weight * (f.p.normal.dot(reference) < 0 ? Vec3(-f.p.normal) : f.p.normal);
    total += f.weight;
    out.converged = out.converged && f.p.converged;
    out.iterations = std::max(out.iterations, f.p.iterations);
    out.neighbors += f.p.neighbors;
  }
  out.point = point / total;
  out.normal = normal.normalized();
  return out;
}

double JoinedSurface::bandwidthAt(const Vec3& x) const {
  // The densest piece near x, or the one with the nearest data.
  const JoinedPiece* best = nullptr;
  double best_density = 0;
  for (const JoinedPiece& piece : pieces_) {
    if (!piece.density.reaches(x)) continue;
    const double density = piece.density.at(x);
    if (!best || density > best_density) {
      best = &piece;
      best_density = density;
    }
  }
  if (!best) {
    double nearest_sq = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < pieces_.size(); ++k) {
      const auto near = data_[k].nearest(x);
      if (near && near->second < nearest_sq) {
        nearest_sq = near->second;
        best = &pieces_[k];
      }
    }
  }
  return best ? best->fit->surface().bandwidthAt(x) : 0.0;
}

std::optional<std::pair<Vec3, double>> JoinedSurface::nearest(const Vec3& x) const {
  // The pieces near x first; all of them only when none is (the nearest data are then far).
  std::optional<std::pair<Vec3, double>> best;
  for (int pass = 0; pass < 2 && !best; ++pass)
    for (std::size_t k = 0; k < pieces_.size(); ++k) {
      if (pass == 0 && !pieces_[k].density.reaches(x)) continue;
      const auto near = data_[k].nearest(x);
      if (near && (!best || near->second < best->second)) best = near;
    }
  return best;
}

double JoinedSurface::spacingAt(const Vec3& data_point) const {
  // The 16th neighbour among all pieces' points: each piece's 17 nearest, merged.
  thread_local std::vector<Neighbor> near;
  thread_local std::vector<double> distances;
  distances.clear();
  for (const JoinedPiece& piece : pieces_) {
    if (!piece.density.reaches(data_point)) continue;  // no point of it among the nearest
    piece.fit->tree().knn(data_point, 17, near);
    for (const Neighbor& n : near) distances.push_back(n.distance_sq);
  }
  if (distances.empty()) return 0;
  const std::size_t k = std::min<std::size_t>(16, distances.size() - 1);
  std::nth_element(distances.begin(), distances.begin() + static_cast<std::ptrdiff_t>(k), distances.end());
  return std::sqrt(distances[k]);
}

}  // namespace stampscan::fitting::detail
