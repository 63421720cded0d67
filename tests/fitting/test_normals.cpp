// Normals from the weighted covariance (Eqs. (6)-(7)) and their consistent orientation.
#include "shapes.hpp"
#include "stampscan/fitting/normals.hpp"

#include <gtest/gtest.h>

using namespace stampscan::fitting;
using namespace stampscan::fitting::test;

namespace {
PointNormals normalsOf(const Cloud& c, double h) {
  const KdTree tree(c.positions);
  return estimateNormals(c.positions, tree, std::vector<double>(c.size(), h));
}
}  // namespace

TEST(Normals, PropagationOrientsASphereCapOutwards) {
  const Cloud c = sampleSphereCap(5000, 10.0, 1.2, 0.01, 31);
  PointNormals pn = normalsOf(c, 1.0);
  const OrientationReport report = orientNormals(c.positions, pn, {});
  EXPECT_EQ(report.components, 1u);
  for (std::size_t i = 0; i < c.size(); ++i)
    ASSERT_GT(pn.normals[i].cast<double>().dot(c.positions[i].normalized()), 0.95) << "point " << i;
}

TEST(Normals, PropagationOrientsAVerticalWallConsistently) {
  // Half a cylinder: normals near the sides are horizontal, so "face +z" alone cannot orient them;
  // propagation over the graph does.
  const Cloud c = sampleCylinder(6000, 6.0, 8.0, 0.01, 32);
  PointNormals pn = normalsOf(c, 1.0);
  orientNormals(c.positions, pn, {});
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3 radial = Vec3(c.positions[i].x(), 0, c.positions[i].z()).normalized();
    ASSERT_GT(pn.normals[i].cast<double>().dot(radial), 0.95) << "point " << i;
  }
}

TEST(Normals, TowardsViewpoint) {
  const Cloud c = samplePlane(2000, 5.0, 0.0, 33);
  PointNormals pn = normalsOf(c, 1.0);
  OrientationParams params;
  params.mode = OrientationMode::TowardsViewpoint;
  params.viewpoint = Vec3(0, 0, -100);
  orientNormals(c.positions, pn, params);
  for (const Vec3f& n : pn.normals) EXPECT_LT(n.z(), -0.99);
}

TEST(Normals, SeparatePiecesEachFaceTheSensor) {
  Cloud c = samplePlane(1500, 3.0, 0.0, 34);
  const Cloud far = samplePlane(1500, 3.0, 0.0, 35);
  for (const Vec3& p : far.positions) c.positions.push_back(p + Vec3(50, 0, 0));
  PointNormals pn = normalsOf(c, 0.5);
  const OrientationReport report = orientNormals(c.positions, pn, {});
  EXPECT_EQ(report.components, 2u);
  for (const Vec3f& n : pn.normals) EXPECT_GT(n.z(), 0.99);
}
