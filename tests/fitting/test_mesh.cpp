// The viewing mesh: on the surface, carrying strain, and leaving holes in the data open.
#include "shapes.hpp"
#include "stampscan/fitting/mesh.hpp"

#include <gtest/gtest.h>

using namespace stampscan::fitting;
using namespace stampscan::fitting::test;

TEST(Mesh, SphereCapMeshLiesOnTheSurface) {
  Cloud c = sampleSphereCap(8000, 10.0, 0.9, 0.01, 41);
  for (const Vec3& p : c.positions) c.strain.push_back(-0.05 * p.z() / 10.0);
  FittedSurface fitted(c, {});
  const Cloud projected = fitted.projectAll();
  MeshStats stats;
  const Mesh mesh = meshSurface(fitted, projected, {}, &stats);
  ASSERT_GT(mesh.triangles.size(), 1000u);
  ASSERT_EQ(mesh.vertices.strain.size(), mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& v = mesh.vertices.positions[i];
    EXPECT_NEAR(v.norm(), 10.0, 0.02) << "vertex at polar angle " << std::acos(v.normalized().z());
    EXPECT_NEAR(mesh.vertices.strain[i], -0.05 * v.z() / 10.0, 0.005);
    EXPECT_GT(mesh.vertices.normals[i].dot(v.normalized()), 0.9);
  }
  // Triangles wind with the normals (outwards).
  std::size_t outward = 0;
  for (const Triangle& t : mesh.triangles) {
    const Vec3& a = mesh.vertices.positions[t.v[0]];
    const Vec3 face = (mesh.vertices.positions[t.v[1]] - a).cross(mesh.vertices.positions[t.v[2]] - a);
    outward += face.dot(a) > 0;
  }
  EXPECT_EQ(outward, mesh.triangles.size());
}

TEST(Mesh, HolesStayHoles) {
  // A plane with a 4 mm hole: no triangle may cover its middle.
  Cloud c = samplePlane(20000, 10.0, 0.01, 42);
  Cloud holed;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c.positions[i].head<2>().norm() > 4.0) holed.appendPoint(c, i);
  FittedSurface fitted(holed, {});
  const Cloud projected = fitted.projectAll();
  const Mesh mesh = meshSurface(fitted, projected);
  ASSERT_GT(mesh.triangles.size(), 1000u);
  for (const Triangle& t : mesh.triangles) {
    const Vec3 centroid = (mesh.vertices.positions[t.v[0]] + mesh.vertices.positions[t.v[1]] +
                           mesh.vertices.positions[t.v[2]]) / 3.0;
    ASSERT_GT(centroid.head<2>().norm(), 2.5) << "triangle bridges the hole at " << centroid.transpose();
  }
}
