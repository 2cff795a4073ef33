// segment() on a holding frame seen by the simulated scanner from 8 turntable angles: the frame
// painted in the clay colour of the sherds, so that only its known geometry (frame_height_mm)
// can take it away. Judged point by point against the scanner's truth labels.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>

#include "processing/segmentation/segmentation.h"
#include "simulators/pottery.h"
#include "simulators/sim_scanner.h"

namespace seg = sherd::segmentation;
namespace sim = sherd::sim;

namespace {

constexpr double kPlinthHeightMm = 8.0;  // simulators/pottery.h: the frame's plinths

struct LabelledCloud {
  sherd::Mesh cloud;
  std::vector<int> labels;  // 0 = plate or frame, k = truth sherd k
};

// A frame of `sherds`, its plinths in the colour of the first sherd's clay, scanned every 45°
// and brought into the turntable frame (the plate turned back by its angle).
LabelledCloud clay_coloured_frame_scan(std::uint64_t seed, int sherds) {
  sim::Scene scene =
      sim::make_scene({.seed = seed, .kind = sim::SceneKind::Frame, .sherds = sherds});
  const sim::SceneObject* first = nullptr;
  for (const auto& object : scene.objects) {
    if (object.label == 1) first = &object;
  }
  EXPECT_NE(first, nullptr);
  const sherd::Rgb8 clay = first->mesh.vertices.colours.front();
  for (auto& object : scene.objects) {
    if (object.name == "frame")
      std::fill(object.mesh.vertices.colours.begin(), object.mesh.vertices.colours.end(), clay);
  }
  double angle = 0.0;
  const sim::ScannerModel model = sim::default_station_scanner();
  sim::SimulatedScanner scanner(scene, model, [&angle] { return angle; });
  LabelledCloud out;
  for (int view = 0; view < 8; ++view) {
    angle = 2 * std::numbers::pi * view / 8;
    const sherd::OrganisedView v = scanner.capture();
    const sherd::Pose to_plate =
        sherd::Pose(Eigen::AngleAxisd(-angle, sherd::Vec3d::UnitZ())) * model.scanner_to_world;
    for (std::size_t c = 0; c < v.cells(); ++c) {
      if (!v.valid[c]) continue;
      out.cloud.vertices.points.push_back((to_plate * v.points[c].cast<double>()).cast<float>());
      out.cloud.vertices.colours.push_back(v.colours[c]);
      out.labels.push_back(scanner.last_labels()[c]);
    }
  }
  return out;
}

TEST(FrameRemoval, AClayColouredFrameGoesByItsGeometry) {
  const int sherds = 4;
  const LabelledCloud scan = clay_coloured_frame_scan(3, sherds);
  std::size_t frame_points = 0;
  for (std::size_t i = 0; i < scan.labels.size(); ++i) {
    frame_points += scan.labels[i] == 0 && scan.cloud.vertices.points[i].z() > 1.0f;
  }
  ASSERT_GT(frame_points, 5000u) << "the scan must see the frame for this test to mean anything";

  seg::Params params;
  params.background = seg::BackgroundColour::None;  // colour cannot tell this frame from clay
  params.frame_height_mm = kPlinthHeightMm;
  const auto result = seg::segment(scan.cloud, params);

  ASSERT_EQ(result.sherds.size(), static_cast<std::size_t>(sherds));
  std::map<int, std::size_t> truth_size;
  for (int label : scan.labels) ++truth_size[label];
  std::map<int, int> found_as;
  for (const auto& part : result.sherds) {
    std::map<int, std::size_t> counts;
    for (auto i : part.indices) ++counts[scan.labels[i]];
    const auto best = std::max_element(counts.begin(), counts.end(),
                                       [](auto& a, auto& b) { return a.second < b.second; });
    ASSERT_NE(best->first, 0) << part.id << ": mostly frame or plate";
    ++found_as[best->first];
    // Frame points left on a sherd: at most where the sherd meets the plinth's top.
    EXPECT_GE(static_cast<double>(best->second) / part.indices.size(), 0.99) << part.id;
    // The sherd's points lost: at most those within plane_distance_mm above the plinth's top.
    EXPECT_GE(static_cast<double>(best->second) / truth_size[best->first], 0.97) << part.id;
  }
  for (const auto& [label, n] : found_as) EXPECT_EQ(n, 1) << "truth sherd " << label;
}

}  // namespace
