// sherd.json follows the output contract of DESIGN.md, with values from the analysis unchanged.
#include "daemon/documents.h"

#include <gtest/gtest.h>

namespace sherd::station {
namespace {

Mesh two_points() {
  Mesh mesh;
  mesh.vertices.points = {Vec3f(-1.0f, 2.0f, 3.0f), Vec3f(4.0f, -5.0f, 6.5f)};
  return mesh;
}

TEST(SherdDocument, CarriesEveryContractFieldWithTheAnalysisValues) {
  profile::Analysis analysis;
  analysis.axis.found = true;
  analysis.axis.point = Vec3d(10, 20, 0);
  analysis.axis.direction = Vec3d(0, 0, 1);
  analysis.axis.method = "normal-line-complex";
  analysis.axis.angle_sd_deg = 0.25;
  analysis.rim_up_certain = true;
  analysis.measurements.rim_diameter_mm = 182.5;
  analysis.measurements.rim_percent = 12.5;
  analysis.measurements.wall_thickness_mm = {4.0, 5.0, 6.0};
  analysis.profile.outer = {{91.25, 0.0}, {90.0, 30.0}};

  const auto doc = sherd_document("scan-1", "s01", two_points(), analysis.axis, &analysis);
  EXPECT_EQ(doc["schema"], "sherdscan.sherd/1");
  EXPECT_EQ(doc["points"], 2);
  EXPECT_EQ(doc["bbox_mm"], nlohmann::json({{-1.0, -5.0, 3.0}, {4.0, 2.0, 6.5}}));
  EXPECT_EQ(doc["axis"]["point_mm"], nlohmann::json({10.0, 20.0, 0.0}));
  EXPECT_TRUE(doc["axis"]["reason"].is_null());
  EXPECT_DOUBLE_EQ(doc["axis"]["confidence"]["angle_sd_deg"], 0.25);
  EXPECT_TRUE(doc["orientation"]["rim_up_certain"].get<bool>());
  EXPECT_DOUBLE_EQ(doc["measurements"]["rim_diameter_mm"], 182.5);
  EXPECT_DOUBLE_EQ(doc["measurements"]["wall_thickness_mm"]["mean"], 5.0);
  EXPECT_TRUE(doc["measurements"]["base_diameter_mm"].is_null());
  EXPECT_EQ(doc["profile"]["outer"], nlohmann::json({{91.25, 0.0}, {90.0, 30.0}}));
  EXPECT_EQ(doc["artifacts"]["plate"], "plate.png");
}

TEST(SherdDocument, WithoutAxisKeepsTheKeysAndSaysWhy) {
  axis::AxisEstimate axis;
  axis.found = false;
  axis.reason = "too flat";
  const auto doc = sherd_document("scan-1", "s02", two_points(), axis, nullptr);
  EXPECT_FALSE(doc["axis"]["found"].get<bool>());
  EXPECT_EQ(doc["axis"]["reason"], "too flat");
  EXPECT_TRUE(doc["axis"]["direction"].is_null());
  EXPECT_TRUE(doc["measurements"].contains("rim_diameter_mm"));
  EXPECT_TRUE(doc["measurements"]["rim_diameter_mm"].is_null());
  EXPECT_TRUE(doc["profile"]["outer"].empty());
}

}  // namespace
}  // namespace sherd::station
