#include "core/types.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace sherd {
namespace {

// A 3 × 2 grid on the plane z = 100 with 1 mm spacing.
OrganisedView flat_grid() {
  OrganisedView v;
  v.width = 3;
  v.height = 2;
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) {
      v.points.emplace_back(x, y, 100.0f);
      v.normals.emplace_back(0, 0, -1);
      v.colours.push_back({10, 20, 30});
      v.valid.push_back(1);
    }
  }
  return v;
}

TEST(OrganisedView, FullGridGivesTwoTrianglesPerCell) {
  const auto mesh = flat_grid().to_mesh(2.0f);
  EXPECT_EQ(mesh.vertices.size(), 6u);
  EXPECT_EQ(mesh.triangles.size(), 4u);  // (3-1) × (2-1) cells × 2
  EXPECT_TRUE(mesh.vertices.has_normals());
  EXPECT_TRUE(mesh.vertices.has_colours());
}

TEST(OrganisedView, InvalidCellsAndDepthJumpsBreakTheSurface) {
  auto v = flat_grid();
  v.valid[0] = 0;
  v.points[0] = Vec3f::Constant(std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(v.valid_count(), 5u);
  EXPECT_EQ(v.to_mesh(2.0f).triangles.size(), 3u);  // the triangle on cell 0 is gone

  auto jump = flat_grid();
  jump.points[2].z() = 150.0f;  // an occlusion edge, 50 mm behind
  EXPECT_EQ(jump.to_mesh(2.0f).triangles.size(), 2u);  // both triangles touching cell 2 dropped
}

TEST(Cloud, TransformMovesPointsAndTurnsNormals) {
  Cloud c;
  c.points = {Vec3f(1, 0, 0)};
  c.normals = {Vec3f(1, 0, 0)};
  Pose pose = Pose::Identity();
  pose.rotate(Eigen::AngleAxisd(M_PI / 2, Vec3d::UnitZ()));
  pose.pretranslate(Vec3d(0, 0, 5));
  c.transform(pose);
  EXPECT_NEAR((c.points[0] - Vec3f(0, 1, 5)).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((c.normals[0] - Vec3f(0, 1, 0)).norm(), 0.0f, 1e-6f);
}

TEST(Cloud, AppendKeepsAttributesOnlyWhereBothHaveThem) {
  Cloud a, b;
  a.points = {Vec3f(0, 0, 0)};
  a.normals = {Vec3f(0, 0, 1)};
  b.points = {Vec3f(1, 1, 1)};
  a.append(b);
  EXPECT_EQ(a.size(), 2u);
  EXPECT_FALSE(a.has_normals());
}

TEST(Mesh, SubsetKeepsOnlyTrianglesWithAllCornersAndRenumbers) {
  const auto mesh = flat_grid().to_mesh(2.0f);
  const auto part = mesh.subset({1, 2, 4, 5});  // the right column of cells
  EXPECT_EQ(part.vertices.size(), 4u);
  EXPECT_EQ(part.triangles.size(), 2u);
  for (const auto& t : part.triangles) {
    for (auto i : t) EXPECT_LT(i, 4u);
  }
  const auto box = Box3::of(part.vertices);
  EXPECT_DOUBLE_EQ(box.min.x(), 1.0);
  EXPECT_DOUBLE_EQ(box.max.x(), 2.0);
  EXPECT_DOUBLE_EQ(box.extent().y(), 1.0);
}

}  // namespace
}  // namespace sherd
