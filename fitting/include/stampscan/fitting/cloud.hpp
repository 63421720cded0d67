// Point-cloud types shared by every stage: a cloud of positions with optional per-point normals,
// thickness strain, colours and further named scalars (the Cloud4D of ARCHITECTURE.md), and a
// triangle mesh that carries the same per-vertex attributes.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace stampscan::fitting {

using Vec3 = Eigen::Vector3d;

// A point cloud in millimetres. `positions` is always filled; each optional attribute is either
// empty or holds exactly one entry per position (checked by validate()). The kd-tree indexes
// `positions` in place, without a copy.
struct Cloud {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;                    // unit normals, optional
  std::vector<double> strain;                   // thickness true strain, optional
  std::vector<std::array<std::uint8_t, 3>> colors;  // red green blue, optional
  // Further per-point scalars kept through read/fit/write, e.g. major_strain, minor_strain.
  std::map<std::string, std::vector<double>> scalars;

  std::size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool hasNormals() const { return !normals.empty(); }
  bool hasStrain() const { return !strain.empty(); }
  bool hasColors() const { return !colors.empty(); }

  // Throws std::invalid_argument naming the attribute whose length does not match.
  void validate() const;
  // Appends point i of `other` (same attribute layout required).
  void appendPoint(const Cloud& other, std::size_t i);
};

// The Cloud4D's scalars, named here once. A grid element carries, beside its thickness strain
// (Cloud::strain), its in-plane true strains, the major strain's direction in the surface (unit,
// machine frame), the sensor path that measured it (registration::Source as a number), the sweep or
// view, its fit's RMS (mm) and how many measurements were merged into it.
inline constexpr char kMajorStrain[] = "major_strain";
inline constexpr char kMinorStrain[] = "minor_strain";
inline constexpr const char* kMajorDirection[3] = {"major_dir_x", "major_dir_y", "major_dir_z"};
inline constexpr char kSource[] = "source";
inline constexpr char kView[] = "view";
inline constexpr char kFitQuality[] = "quality";
inline constexpr char kMeasurementCount[] = "measurements";
// Cloud4D scalars with a meaning downstream stages rely on: the standard (k = 1) uncertainty of a
// point's strain, and of its position along each axis (mm); of the strain's, the part that is the
// measurements' noise (what repeating them shrinks, against what the field around it leaves
// unexplained: a strain field weights its samples by it, or by the whole when a cloud has only
// that); the fitted surface's strain there.
inline constexpr char kStrainUncertainty[] = "strain_uncertainty";
inline constexpr char kStrainNoise[] = "strain_noise";
inline constexpr char kPositionUncertainty[] = "position_uncertainty";
// The fitted surface's strain at a grid element (fitShapeAndStrain), beside the element's own.
inline constexpr char kFittedStrain[] = "fitted_strain";

// Axis-aligned bounds of a cloud; an empty cloud gives min = +inf, max = -inf.
struct Bounds {
  Vec3 min;
  Vec3 max;
  Vec3 extent() const { return max - min; }
  double diagonal() const { return extent().norm(); }
};
Bounds boundsOf(const std::vector<Vec3>& points);

// A right-handed orthonormal frame (t1, t2, n) as matrix columns, for a unit normal n.
inline Eigen::Matrix3d frameAround(const Vec3& n) {
  const Vec3 helper = n.x() * n.x() < 0.81 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 t1 = n.cross(helper).normalized();
  Eigen::Matrix3d frame;
  frame.col(0) = t1;
  frame.col(1) = n.cross(t1);
  frame.col(2) = n;
  return frame;
}

struct Triangle {
  std::array<std::uint32_t, 3> v;
};

// A triangle mesh: vertices with the same optional attributes as a cloud, and triangles indexing them.
struct Mesh {
  Cloud vertices;
  std::vector<Triangle> triangles;
};

}  // namespace stampscan::fitting
