// How true can any strain field be between the printed elements? Interpolates the simulator's *true*
// element strains and scores them against the true strain at the surface points halfway between
// elements, chosen as `station scan` chooses them (station/jobs/src/scan_job.cpp,
// surfaceAccuracyAgainst): 0.4 to 0.6 pitch from the nearest element, the pitch being the elements'
// median nearest-neighbour distance. What the best interpolator misses there is the floor of the
// scan's own "halfway" figure: its field has only measured elements to go by.
//
//   bench_strain_between [--step MM]     (surface points on an in-plane lattice, default 0.5 mm)
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/sim/formed_part.hpp"
#include "stampscan/sim/grid.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace {

using namespace stampscan;
using fitting::Vec3;

struct Neighbourhood {
  std::vector<fitting::Neighbor> near;
  Eigen::MatrixXd uv;   // tangent-plane coordinates about the query, in pitches
  Eigen::MatrixXd xyz;  // offsets from the query, in pitches
  Eigen::VectorXd strain;
};

// The k nearest elements in the plane of their mean normal.
void gather(const fitting::Cloud& truth, const fitting::KdTree& tree, double pitch, const Vec3& p, std::size_t k,
            Neighbourhood& n) {
  tree.knn(p, k, n.near);
  const auto count = static_cast<Eigen::Index>(n.near.size());
  Vec3 normal = Vec3::Zero();
  for (const fitting::Neighbor& e : n.near) normal += truth.normals[e.index];
  const Eigen::Matrix3d frame = fitting::frameAround(normal.normalized());
  n.uv.resize(count, 2);
  n.xyz.resize(count, 3);
  n.strain.resize(count);
  for (Eigen::Index i = 0; i < count; ++i) {
    const auto index = n.near[static_cast<std::size_t>(i)].index;
    const Vec3 d = (truth.positions[index] - p) / pitch;
    n.xyz.row(i) = d.transpose();
    n.uv(i, 0) = d.dot(frame.col(0));
    n.uv(i, 1) = d.dot(frame.col(1));
    n.strain(i) = truth.strain[index];
  }
}

// A quadric in the tangent plane through the 12 nearest, Gaussian weights of 0.75 pitch.
double quadric(const Neighbourhood& n) {
  const Eigen::Index count = n.strain.size();
  Eigen::MatrixXd a(count, 6);
  Eigen::VectorXd b(count);
  for (Eigen::Index i = 0; i < count; ++i) {
    const double u = n.uv(i, 0), v = n.uv(i, 1);
    const double w = std::sqrt(std::exp(-0.5 * n.xyz.row(i).squaredNorm() / (0.75 * 0.75)));
    a.row(i) << w, w * u, w * v, w * u * u, w * u * v, w * v * v;
    b(i) = w * n.strain(i);
  }
  return a.colPivHouseholderQr().solve(b)(0);
}

// A cubic radial basis function (r^3 of the 3D distance) with a plane, through the 25 nearest.
double cubicSpline(const Neighbourhood& n) {
  const Eigen::Index count = n.strain.size();
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(count + 3, count + 3);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(count + 3);
  for (Eigen::Index i = 0; i < count; ++i) {
    for (Eigen::Index j = 0; j < count; ++j) m(i, j) = std::pow((n.xyz.row(i) - n.xyz.row(j)).norm(), 3);
    m(i, count) = m(count, i) = 1;
    m(i, count + 1) = m(count + 1, i) = n.uv(i, 0);
    m(i, count + 2) = m(count + 2, i) = n.uv(i, 1);
    rhs(i) = n.strain(i);
  }
  const Eigen::VectorXd x = m.fullPivLu().solve(rhs);
  double value = x(count);  // the plane at the query, the origin
  for (Eigen::Index i = 0; i < count; ++i) value += x(i) * std::pow(n.xyz.row(i).norm(), 3);
  return value;
}

struct Halfway {
  Vec3 point;
  double strain;  // the truth there
};

double medianPitch(const fitting::Cloud& truth, const fitting::KdTree& tree) {
  std::vector<fitting::Neighbor> nn;
  std::vector<double> nearest;
  for (std::size_t i = 0; i < truth.size(); i += std::max<std::size_t>(1, truth.size() / 500)) {
    tree.knn(truth.positions[i], 2, nn);
    if (nn.size() == 2) nearest.push_back(std::sqrt(nn[1].distance_sq));
  }
  std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2), nearest.end());
  return nearest[nearest.size() / 2];
}

std::vector<Halfway> halfwayPoints(const sim::FormedPart& part, const fitting::KdTree& tree, double pitch, double step) {
  std::vector<Halfway> out;
  std::vector<fitting::Neighbor> nn;
  const sim::BlankRect footprint = part.footprint();
  for (double y = footprint.min.y(); y <= footprint.max.y(); y += step)
    for (double x = footprint.min.x(); x <= footprint.max.x(); x += step) {
      if (!part.onPart(x, y)) continue;
      const Vec3 p = part.surfacePoint(x, y);
      tree.knn(p, 2, nn);
      if (nn.size() < 2) continue;
      const double d = std::sqrt(nn[0].distance_sq);
      if (d >= 0.4 * pitch && d <= 0.6 * pitch) out.push_back({p, part.deformationAt(x, y).thickness_strain});
    }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The floor of any strain field between the printed elements: the true element strains interpolated"};
  double step = 0.5;
  app.add_option("--step", step, "In-plane spacing of the surface points scored, mm")->check(CLI::Range(0.05, 5.0));
  CLI11_PARSE(app, argc, argv);

  std::printf("%-6s %-7s %9s %8s %10s %10s %10s %10s\n", "part", "grid", "halfway", "pitch", "spread", "nearest",
              "quadric", "cubic RBF");
  for (const sim::PartKind kind : {sim::PartKind::Pan, sim::PartKind::Dome}) {
    const std::unique_ptr<sim::FormedPart> part = sim::makePart(kind);
    for (const sim::GridKind grid_kind : {sim::GridKind::Circle, sim::GridKind::Square}) {
      sim::GridSpec grid;
      grid.kind = grid_kind;
      const fitting::Cloud truth = sim::groundTruth(*part, grid);
      const fitting::KdTree tree(truth.positions);
      const double pitch = medianPitch(truth, tree);
      const std::vector<Halfway> points = halfwayPoints(*part, tree, pitch, step);
      const std::vector<std::function<double(const Vec3&)>> interpolators = {
          [&](const Vec3& p) {
            std::vector<fitting::Neighbor> nn;
            tree.knn(p, 1, nn);
            return truth.strain[nn[0].index];
          },
          [&](const Vec3& p) {
            Neighbourhood n;
            gather(truth, tree, pitch, p, 12, n);
            return quadric(n);
          },
          [&](const Vec3& p) {
            Neighbourhood n;
            gather(truth, tree, pitch, p, 25, n);
            return cubicSpline(n);
          }};
      double mean = 0, spread = 0;
      for (const Halfway& h : points) mean += h.strain / static_cast<double>(points.size());
      for (const Halfway& h : points) spread += std::pow(h.strain - mean, 2);
      std::printf("%-6s %-7s %9zu %8.3f %10.4f", part->name().c_str(), sim::toString(grid_kind).c_str(), points.size(), pitch,
                  std::sqrt(spread / static_cast<double>(points.size())));
      for (const auto& interpolate : interpolators) {
        double sq = 0;
        for (const Halfway& h : points) sq += std::pow(interpolate(h.point) - h.strain, 2);
        std::printf(" %10.4f", std::sqrt(sq / static_cast<double>(points.size())));
      }
      std::printf("\n");
      std::fflush(stdout);
    }
  }
  std::printf("(RMS of each interpolator's miss against the true thickness strain at the halfway points; spread: the\n"
              " truth's own standard deviation there)\n");
  return 0;
}
