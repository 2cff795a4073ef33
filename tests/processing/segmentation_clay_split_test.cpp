// split_by_clay (processing/segmentation/clay_split.h) on voxels built here: a part whose voxels
// do not all hang together in 3-D, as the levels rule joins two levels across their unseen wall.
#include "processing/segmentation/clay_split.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

#include "processing/segmentation/voxel_graph.h"

namespace detail = sherd::segmentation::detail;
using sherd::Vec3f;

namespace {

constexpr double kRadius = 2.5;  // the clustering distance of bench_segmentation's trays
constexpr double kLeaf = kRadius / detail::kVoxelsPerTolerance;

// One clay of a 60 × 20 mm patch (0 ≤ x < 30 red, 30 ≤ x < 60 green) or the 6 × 6 mm red patch
// that lies 10 mm beyond it (70 ≤ x < 76), out of reach in 3-D.
enum class Region { Red, Green, Apart };

Region region_at(const Vec3f& p) {
  if (p.x() >= 70.0f) return Region::Apart;
  return p.x() < 30.0f ? Region::Red : Region::Green;
}

TEST(SplitByClay, APieceOfThePartThatNoSeedReachesIsAPieceOfItsOwn) {
  std::vector<Vec3f> points, colours;
  auto patch = [&](float x0, float x1, float y1, const Vec3f& rgb) {
    for (float x = x0; x < x1; x += 0.5f) {
      for (float y = 0.0f; y < y1; y += 0.5f)
        points.emplace_back(x, y, 0.0f), colours.push_back(rgb);
    }
  };
  const Vec3f red(190, 110, 70), green(100, 160, 90);  // neither is the other mixed with grey
  patch(0.0f, 30.0f, 20.0f, red);
  patch(30.0f, 60.0f, 20.0f, green);
  patch(70.0f, 76.0f, 6.0f, red);
  std::vector<std::uint32_t> all(points.size());
  std::iota(all.begin(), all.end(), 0u);
  const detail::Voxels voxels = detail::voxelise(points, all, kLeaf);
  const detail::Graph near = detail::neighbourhoods(voxels, kRadius);
  const std::size_t n = voxels.centres.size();
  std::vector<Vec3f> voxel_rgb(n, Vec3f::Zero());
  for (std::size_t v = 0; v < n; ++v) {
    for (std::size_t k = voxels.begin[v]; k < voxels.begin[v + 1]; ++k)
      voxel_rgb[v] += colours[voxels.keyed[k].second];
  }
  std::vector<std::uint32_t> part(n);
  std::iota(part.begin(), part.end(), 0u);
  ASSERT_EQ(detail::components(near, part, {}).size(), 2u) << "the part lies apart in 3-D";

  std::vector<float> distance(n);
  std::vector<int> tag(n), split_from;
  const auto pieces = detail::split_by_clay({part}, near, voxels.centres, voxel_rgb, kRadius, kLeaf,
                                            distance, tag, split_from);

  // Three pieces cut from the part: the red and the green half, and the patch apart on its own.
  ASSERT_EQ(pieces.size(), 3u);
  EXPECT_EQ(split_from, std::vector<int>(3, 0));
  std::vector<int> times_found(n, 0);
  for (const auto& piece : pieces) {
    ASSERT_FALSE(piece.empty());
    const Region first = region_at(voxels.centres[piece.front()]);
    std::size_t same = 0;
    for (auto v : piece) {
      ++times_found[v];
      same += region_at(voxels.centres[v]) == first;
    }
    // The halves meet along a band whose voxels' colours mix; the patch apart is wholly its own.
    if (first == Region::Apart) {
      EXPECT_EQ(same, piece.size());
    } else {
      EXPECT_GE(static_cast<double>(same) / piece.size(), 0.95);
    }
  }
  EXPECT_EQ(std::count(times_found.begin(), times_found.end(), 1), static_cast<long>(n))
      << "every voxel in exactly one piece";
}

}  // namespace
