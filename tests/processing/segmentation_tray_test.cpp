// segment() on simulated trays (simulators/tray.h) whose sherds all lie against a neighbour:
// each truth sherd must come out as exactly one sherd, judged point by point against the
// simulator's labels; and the overview image at its documented scale.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <set>
#include <string>

#include "processing/segmentation/overview.h"
#include "processing/segmentation/segmentation.h"
#include "simulators/tray.h"

namespace seg = sherd::segmentation;
namespace sim = sherd::sim;

namespace {

sim::Tray touching_tray(std::uint64_t seed, sim::Background background) {
  sim::TraySpec spec;
  spec.seed = seed;
  spec.sherds = 6;
  spec.background = background;
  spec.touching_share = 1.0;  // every sherd after the first laid against another
  spec.leaning_share = 0.0;
  return sim::make_tray(spec);
}

seg::Params tray_params(sim::Background background) {
  seg::Params params;
  params.background = background == sim::Background::Black ? seg::BackgroundColour::Black
                                                           : seg::BackgroundColour::White;
  params.contact_erosion_mm = 5.0;
  return params;
}

// Every truth sherd of `tray` stands for exactly one found sherd, which holds at least these
// shares of its points (recall) and of its own points (precision).
void expect_each_sherd_found_once(const sim::Tray& tray, const seg::Result& result,
                                  double min_precision, double min_recall) {
  ASSERT_EQ(result.sherds.size(), static_cast<std::size_t>(tray.sherds));
  std::map<int, std::size_t> truth_size;
  for (int label : tray.labels) ++truth_size[label];
  std::map<int, int> found_as;  // truth label → how many found sherds stand for it
  for (const auto& part : result.sherds) {
    std::map<int, std::size_t> counts;
    for (auto i : part.indices) ++counts[tray.labels[i]];
    const auto best = std::max_element(counts.begin(), counts.end(),
                                       [](auto& a, auto& b) { return a.second < b.second; });
    ASSERT_NE(best->first, 0) << part.id << ": mostly background";
    ++found_as[best->first];
    const double precision = static_cast<double>(best->second) / part.indices.size();
    const double recall = static_cast<double>(best->second) / truth_size[best->first];
    EXPECT_GE(precision, min_precision) << part.id;
    EXPECT_GE(recall, min_recall) << part.id;
  }
  for (const auto& [label, n] : found_as) EXPECT_EQ(n, 1) << "truth sherd " << label;
}

class TouchingTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(TouchingTray, EverySherdFoundWholeAndAlone) {
  for (auto background : {sim::Background::Black, sim::Background::White}) {
    const sim::Tray tray = touching_tray(GetParam(), background);
    ASSERT_GE(tray.touching, 3);
    // Where two sherds meet at the same height the cut can miss the contact by a few mm
    // (bench_segmentation follows the finer figures; the goal there is 99.5 %).
    expect_each_sherd_found_once(tray, seg::segment(tray.cloud, tray_params(background)), 0.95,
                                 0.9);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, TouchingTray, ::testing::Values(1u, 2u, 3u));

// How many truth sherds each part of `parts` holds at least a tenth of.
std::vector<int> sherds_held(const sim::Tray& tray,
                             const std::vector<std::vector<std::uint32_t>>& parts) {
  std::map<int, std::size_t> truth_size;
  for (int label : tray.labels) ++truth_size[label];
  std::vector<int> held;
  for (const auto& part : parts) {
    std::map<int, std::size_t> counts;
    for (auto i : part) ++counts[tray.labels[i]];
    int n = 0;
    for (const auto& [label, count] : counts) n += label > 0 && 10 * count >= truth_size[label];
    held.push_back(n);
  }
  return held;
}

// The steps kept for the benchmark show what the splitting did: on a tray of touching sherds the
// Euclidean clusters hold two or more truth sherds together, the parts after the contacts are
// split hold one each, and the last step's parts are the sherds found (the size filters pass them
// all); keeping the steps changes nothing found.
TEST(ClusteringSteps, TouchingSherdsAreOneClusterAndApartAfterTheContacts) {
  const sim::Tray tray = touching_tray(1, sim::Background::Black);
  const seg::Params params = tray_params(sim::Background::Black);
  std::vector<seg::ClusteringStep> steps;
  const seg::Result traced = seg::segment(tray.cloud, params, &steps);

  std::vector<std::string> names;
  for (const auto& step : steps) names.push_back(step.name);
  EXPECT_EQ(names, (std::vector<std::string>{"clusters", "basins", "small cores", "contacts",
                                             "clay", "levels", "walls", "faces", "narrow", "folds",
                                             "detached", "under"}));
  ASSERT_EQ(steps.size(), 12u);
  const auto clustered = sherds_held(tray, steps[0].parts);
  EXPECT_GE(*std::max_element(clustered.begin(), clustered.end()), 2);
  // Each stage of the contact split parts the clusters further or joins parts again: every
  // voxel is in one part of each, and the basins are at least as many as the parts after them.
  for (int held : sherds_held(tray, steps[3].parts)) EXPECT_LE(held, 1);
  EXPECT_GE(steps[1].parts.size(), steps[2].parts.size());
  EXPECT_GE(steps[2].parts.size(), steps[3].parts.size());
  EXPECT_GE(steps[1].parts.size(), steps[0].parts.size());
  for (std::size_t s = 1; s <= 3; ++s) {
    std::size_t points = 0, clustered_points = 0;
    for (const auto& part : steps[s].parts) points += part.size();
    for (const auto& part : steps[0].parts) clustered_points += part.size();
    EXPECT_EQ(points, clustered_points) << steps[s].name;
  }

  std::set<std::vector<std::uint32_t>> last(steps.back().parts.begin(), steps.back().parts.end());
  std::set<std::vector<std::uint32_t>> found;
  for (const auto& part : traced.sherds) found.insert(part.indices);
  for (const auto& rejected : traced.rejected) found.insert(rejected.indices);
  EXPECT_EQ(last, found);

  const seg::Result plain = seg::segment(tray.cloud, params);
  ASSERT_EQ(plain.sherds.size(), traced.sherds.size());
  for (std::size_t k = 0; k < plain.sherds.size(); ++k)
    EXPECT_EQ(plain.sherds[k].indices, traced.sherds[k].indices) << plain.sherds[k].id;
}

// Trays of bench_segmentation (seed, sherd count and background as it lays them) in which a
// narrow sherd touches a larger one: the erosion leaves it a core under contact_min_core_mm2,
// and before contact_own_basin_mm2 its part was joined to its neighbour's (truth sherd 8 of
// tray 4 into sherd 4, sherd 10 of tray 42 into sherd 14: one sherd short).
class NarrowSherdTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(NarrowSherdTray, TheNarrowSherdIsFoundOnItsOwn) {
  const sim::Tray tray = sim::make_tray(sim::bench_tray_spec(GetParam(), sim::Background::White));
  expect_each_sherd_found_once(tray, seg::segment(tray.cloud, tray_params(tray.spec.background)),
                               0.95, 0.9);
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, NarrowSherdTray, ::testing::Values(4u, 42u));

// One sherd with a step inside it (a 14 mm recess 6 mm deep, as a ring foot's inside seen from
// above: the vertical wall between the levels is never sampled; a 2 mm ramp joins them, as the
// fracture face does on a real sherd) and a second sherd touching it at one corner, on a black
// plate seen from above every 0.5 mm. The step leaves a core of ≈ 16 mm² beyond the erosion; the
// touching sherd one of ≈ 96 mm² (hand-computed from the shapes).
TEST(ContactSplitting, AStepInsideASherdKeepsItWholeATouchingSherdIsCutOff) {
  sherd::Mesh cloud;
  std::vector<int> truth;  // 0 plate, 1 stepped sherd, 2 touching sherd
  for (int j = -120; j <= 120; ++j) {
    for (int i = -120; i <= 120; ++i) {
      const float x = 0.5f * i, y = 0.5f * j;
      float z = 0.0f;
      int label = 0;
      if (x >= -40 && x <= 10 && std::abs(y) <= 25) {
        label = 1;
        z = x >= -22 && x <= -8 && std::abs(y) <= 7 ? 4.0f : 10.0f;
        if (x > -28 && x < -22 && std::abs(y) <= 1) z = 4.0f + (-22 - x);  // 45° ramp down
      } else if (std::abs(x - 24.0f) + std::abs(y) <= 14.0f) {             // its corner at x = 10
        label = 2;
        z = 9.0f;
      }
      cloud.vertices.points.emplace_back(x, y, z);
      cloud.vertices.colours.push_back(label ? sherd::Rgb8{180, 120, 80} : sherd::Rgb8{12, 12, 12});
      truth.push_back(label);
    }
  }
  seg::Params params;
  params.contact_erosion_mm = 5.0;
  params.plane_min_extent_mm = 100.0;  // the 120 mm plate is the support
  const auto result = seg::segment(cloud, params);
  ASSERT_EQ(result.sherds.size(), 2u);
  std::map<int, std::size_t> truth_size;
  for (int label : truth) ++truth_size[label];
  std::set<int> found;
  for (const auto& part : result.sherds) {
    std::map<int, std::size_t> counts;
    for (auto i : part.indices) ++counts[truth[i]];
    const auto best = std::max_element(counts.begin(), counts.end(),
                                       [](auto& a, auto& b) { return a.second < b.second; });
    found.insert(best->first);
    // The cut through the corner contact may put the corner's tip (≈ 1 %) on the wrong side.
    EXPECT_GE(static_cast<double>(best->second) / part.indices.size(), 0.995) << part.id;
    EXPECT_GE(static_cast<double>(best->second) / truth_size[best->first], 0.98) << part.id;
  }
  EXPECT_EQ(found, (std::set<int>{1, 2}));
}

// A tray of bench_segmentation (seed, sherd count and background as it lays them, on either
// background) in which one sherd lies with a step inside it whose two levels the erosion leaves
// a sherd-sized core each (truth sherd 1 of tray 64, found as two sherds before the levels were
// joined by their step and colour).
class SteppedSherdTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(SteppedSherdTray, BothLevelsOfTheSherdAreOneSherd) {
  for (auto background : {sim::Background::Black, sim::Background::White}) {
    const sim::Tray tray = sim::make_tray(sim::bench_tray_spec(GetParam(), background));
    expect_each_sherd_found_once(tray, seg::segment(tray.cloud, tray_params(background)), 0.95,
                                 0.9);
  }
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, SteppedSherdTray, ::testing::Values(64u));

// A 80 × 50 mm patch on a black plate seen from above every 0.5 mm, in two levels: x < 0 at
// `upper_z(y)`, x ≥ 0 at 5 mm, joined only by a 2 mm wide ramp at y = 0 (the step's vertical wall
// is never sampled). Each level is 40 × 50 mm, so the erosion leaves each a large core. Returns
// the points and the truth (0 plate, 1 the x < 0 level, 2 the x ≥ 0 level).
struct TwoLevels {
  sherd::Mesh cloud;
  std::vector<int> truth;
};

template <typename UpperZ>
TwoLevels two_levels(UpperZ upper_z, sherd::Rgb8 upper_colour) {
  TwoLevels scene;
  for (int j = -80; j <= 80; ++j) {
    for (int i = -120; i <= 120; ++i) {
      const float x = 0.5f * i, y = 0.5f * j;
      float z = 0.0f;
      int label = 0;
      if (std::abs(x) <= 40 && std::abs(y) <= 25) {
        label = x < 0 ? 1 : 2;
        z = x < 0 ? upper_z(y) : 5.0f;
        if (x >= 0 && x < 6 && std::abs(y) <= 1) z = 5.0f + (upper_z(y) - 5.0f) * (6 - x) / 6;
      }
      scene.cloud.vertices.points.emplace_back(x, y, z);
      scene.cloud.vertices.colours.push_back(label == 0   ? sherd::Rgb8{12, 12, 12}
                                             : label == 1 ? upper_colour
                                                          : sherd::Rgb8{180, 120, 80});
      scene.truth.push_back(label);
    }
  }
  return scene;
}

std::size_t sherds_found(const TwoLevels& scene) {
  seg::Params params;
  params.contact_erosion_mm = 5.0;
  params.plane_min_extent_mm = 100.0;  // the 120 mm plate is the support
  const auto result = seg::segment(scene.cloud, params);
  std::size_t truth_points = 0;
  for (int label : scene.truth) truth_points += label != 0;
  std::size_t found_points = 0;
  for (const auto& part : result.sherds) found_points += part.indices.size();
  EXPECT_GE(found_points, 0.99 * truth_points);
  return result.sherds.size();
}

// A 5 mm step of the same height all along its 50 mm, the same clay on both levels: one sherd
// (a ring foot's recess, a lip), although its levels meet in 3-D only across the ramp.
TEST(SteppedSherd, AnEvenStepInOneClayIsOneSherd) {
  const auto scene = two_levels([](float) { return 10.0f; }, sherd::Rgb8{144, 96, 64});
  EXPECT_EQ(sherds_found(scene), 1u);
}

// The same step between two clays (hue (g/r, b/r) 0.67, 0.44 against 0.82, 0.65): two sherds.
TEST(SteppedSherd, AnEvenStepBetweenTwoClaysIsTwoSherds) {
  const auto scene = two_levels([](float) { return 10.0f; }, sherd::Rgb8{170, 140, 110});
  EXPECT_EQ(sherds_found(scene), 2u);
}

// One clay, but a step that grows from 1 to 9 mm along the border, as where a sherd leans on
// another and rests on one end: two sherds.
TEST(SteppedSherd, AStepGrowingAlongTheBorderIsTwoSherds) {
  const auto scene = two_levels([](float y) { return 6.0f + 8.0f * (y + 25.0f) / 50.0f; },
                                sherd::Rgb8{144, 96, 64});
  EXPECT_EQ(sherds_found(scene), 2u);
}

// Trays of bench_segmentation (seed, sherd count and background as it lays them) in which a sherd
// leaning on another shows its raised edge — its fracture face, greyer than its surfaces — as a
// strip cut off from the rest of it by a wall too steep to be seen from above: a cluster of its
// own, with no core (truth sherd 3 of tray 1062, 5 of 1068, 7 of 1099 found as two sherds before).
class LeaningSherdStripTray : public ::testing::TestWithParam<std::uint64_t> {};

struct SegmentedTray {
  sim::Tray tray;
  seg::Result result;
};

// Tray `seed` of `bench_segmentation --seed first`, segmented.
SegmentedTray segmented_bench_tray(std::uint64_t first, std::uint64_t seed) {
  // The bench alternates black and white from its first tray on.
  const auto background = (seed - first) % 2 == 0 ? sim::Background::Black : sim::Background::White;
  sim::Tray tray = sim::make_tray(sim::bench_tray_spec(seed, background));
  seg::Result result = seg::segment(tray.cloud, tray_params(background));
  return {std::move(tray), std::move(result)};
}

// Tray `seed` of `bench_segmentation --seed first`, segmented: each sherd found once, to these
// shares.
void expect_bench_tray_found(std::uint64_t first, std::uint64_t seed, double min_precision,
                             double min_recall) {
  const SegmentedTray segmented = segmented_bench_tray(first, seed);
  expect_each_sherd_found_once(segmented.tray, segmented.result, min_precision, min_recall);
}

TEST_P(LeaningSherdStripTray, TheStripIsPartOfItsSherd) {
  // The strips hold 24–34 % of their sherds: joined to the wrong one, the recall falls below 0.9.
  // Other sherds there lose a few mm to their neighbours (precision down to 0.94).
  expect_bench_tray_found(1001, GetParam(), 0.9, 0.9);
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, LeaningSherdStripTray, ::testing::Values(1062u, 1068u, 1099u));

// Trays of bench_segmentation in which the erosion leaves one sherd two sherd-sized cores where it
// narrows a little (a long rim strip, a lip band): the border between their parts is as long as
// the narrower part is wide, no neck (truth sherd 2 of tray 1026, 5 of 1059, 16 of 1088 found as
// two sherds before). Each part holds over 30 % of its sherd: left split, the recall is < 0.7.
class NoNeckTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(NoNeckTray, TheSherdIsFoundWhole) { expect_bench_tray_found(1001, GetParam(), 0.95, 0.9); }

INSTANTIATE_TEST_SUITE_P(BenchTrays, NoNeckTray, ::testing::Values(1026u, 1059u, 1088u));

// A tray of bench_segmentation (seed 1's tray 69, black plate) in which a stepped sherd (truth
// sherd 4, a ring foot's recess) touches a larger one of another clay (sherd 2) and the erosion
// leaves it no core of its own: one part of two clays, split by colour (found as one sherd
// before: 3 of 4, precision 0.886).
TEST(TwoClays, ASteppedSherdAgainstAnotherClayIsFoundOnItsOwn) {
  const sim::Tray tray = sim::make_tray(sim::bench_tray_spec(69, sim::Background::Black));
  // The cut between the two clays goes halfway along the surface between their largest regions,
  // not exactly along the contact: ≈ 11 % of one part's points are its neighbour's (precision
  // 0.89).
  expect_each_sherd_found_once(tray, seg::segment(tray.cloud, tray_params(tray.spec.background)),
                               0.85, 0.85);
}

// Trays of `bench_segmentation --seed 1` in which two sherds of different clays came out as one
// part — a small sherd against a larger one, or a contact wider than the erosion cuts (truth
// sherds 2 and 6 of tray 34, 1 and 5 of 38, 1 and 9 of 54, 3 and 5 of 77) — and the colour split
// by two groups (2-means) took the fracture faces for the second clay.
class TwoClaysTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(TwoClaysTray, EachClayIsASherdOfItsOwn) { expect_bench_tray_found(1, GetParam(), 0.9, 0.9); }

INSTANTIATE_TEST_SUITE_P(BenchTrays, TwoClaysTray, ::testing::Values(34u, 38u, 54u, 77u));

// Trays of `bench_segmentation --seed 1` in which the watershed handed a strip of one sherd,
// mostly its fracture face behind a step, to the sherd it touches (truth sherd 14 of tray 2:
// 17 % of it in sherd 2's part; sherd 19 of tray 97: 32 % in sherd 3's): the strip, no face of
// its part's clay but one of its own sherd's, goes back by colour. In tray 74 (sherd 16: 11.5 %
// in sherd 14's part) the two clays lie so close that the strip is a face of both: it goes back
// to the part it touches most.
class FaceStripTray : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(FaceStripTray, TheStripGoesBackToItsSherd) {
  expect_bench_tray_found(1, GetParam(), 0.9, 0.9);
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, FaceStripTray, ::testing::Values(2u, 74u, 97u));

struct TrayOfRun {
  const char* what;
  std::uint64_t first;
  std::uint64_t tray;
};

// How GoogleTest names a case in its output (instead of the struct's bytes).
void PrintTo(const TrayOfRun& tray, std::ostream* out) {
  *out << tray.what << ": tray " << tray.tray << " of the run from seed " << tray.first;
}

std::string case_name(const ::testing::TestParamInfo<TrayOfRun>& info) {
  return std::string(info.param.what) + "_" + std::to_string(info.param.tray);
}

// Trays of bench_segmentation (first seed of the run, tray) that failed before, each sherd found
// once and whole now. Two sherds came out as one where a sherd was taken for its neighbour's
// fracture face or level:
// * by the colour split, whose face peaks lie near the line from their clay to grey: one sherd's
//   clay 0.005 off that line of its neighbour's (seed 5001's tray 5021, precision 0.85; a region
//   32 mm wide is no face), or a small sherd's 0.028 off (seed 9001's tray 9097, precision 0.977;
//   one sherd's faces lie within 0.01);
// * by the no-neck test's face rule, a part on its neighbour's line to grey but 16.8 and 16.5 mm
//   wide (seed 17001's tray 17011, precision 0.955; seed 19001's tray 19070, 0.945), where one
//   sherd's face parts are at most 15.7 mm wide;
// * by the levels' test: two sherds of one vessel, one leaning on the other, with an even step
//   where they overlap, but along a border 0.28 and 0.37 × the narrower one's width (seed 23001's
//   trays 23012, precision 0.808, and 23050, 0.913), where one sherd's levels meet along 1.4 ×
//   or more;
// * by the colour split, a sherd 11.8–13.1 mm wide in a clay on its neighbour's line to grey,
//   touching it briefly (along 0.08–0.17 × its length, where a fracture face runs along its sherd
//   for all its length): seed 135001's tray 135093 (precision 0.969), seed 145001's tray 145097
//   (0.977), seed 147001's tray 147088 (0.963).
// Two sherds came out as one where the erosion left one of them no core 5 mm deep, its boundary
// found inside it too (steep ridges and lips), so that the touching sherd's core took it: a shallow
// core now stands for it (seed 25001's tray 25085, precision 0.956; seed 105001's tray 105017,
// 0.968), and the join across unseen walls no longer hands such a part back to its neighbour (seed
// 55001's tray 55097, 0.974).
// One sherd came out as two parts:
// * a fracture face with a core of its own — along the edge of a sherd leaning on another (truth
//   sherd 4 of seed 1's tray 32: 21 % of it) or a level behind a step (sherd 5 of seed 1's tray
//   61: 44 %; sherd 3 of seed 7001's tray 7004: 25 %): narrow, greyer than the sherd's surface
//   and on its clay's line to grey, it joins the surface;
// * two levels of one sherd whose step varies along the border a little more than the levels'
//   test allowed (sherd 5 of seed 5001's tray 5075: 28 %, step q90 / q10 1.604, bound 1.6), or
//   is lower than it allowed (sherd 3 of seed 29001's tray 29046: 49 / 51 %, step q10 2.65 mm;
//   sherd 3 of seed 45001's tray 45006: 25 %, 2.83 mm; bound 3 mm);
// * a narrow sherd that the erosion cut into two small cores, each with a large part (sherd 6 of
//   seed 5001's tray 5041: 51 / 49 %; sherd 1 of seed 7001's tray 7072: 58 / 42 %), kept apart
//   as a narrow sherd touching another: beside a part whose core is as small, they are one;
// * one sherd's two parts with no neck between them, along a border 0.68 × the narrower part's
//   width (sherd 1 of seed 19001's tray 19012: 46 %; bound 0.7 before), or of hues 0.0081 apart
//   (a sherd of tray 19082, joined before as a fracture face 17 mm wide; hue bound 0.008);
// * a narrow level of a sherd in a cluster of its own, behind an even step but bordering the rest
//   of its sherd along less than a quarter of its voxels (sherd 1 of seed 23001's tray 23092: 20 %
//   of it; sherd 4 of seed 29001's tray 29059: 34 %);
// * a fracture face band with a core of its own, cut off from its sherd's surface by a step (sherd
//   4 of seed 1001's tray 1018: 29 % of it): it lies along its sherd in the top view, not joined
//   to it in 3-D, and goes to it by colour;
// * a narrow level showing the clay, in a cluster of its own, beside a part of its sherd that is
//   mostly fracture face (sherd 3 of seed 9001's tray 9012: 36 % of it): the level lies 0.020 off
//   that part's line to grey, the part 0.0001 off the level's, and the test runs both ways;
// * a strip of a sherd seen almost edge-on, under 9 mm wide in the top view where every sherd
//   shows 11 mm or more, on its sherd's line to grey: cut off by the erosion (the only sherd of
//   seed 79001's tray 79060: 5 % of it), by the colour split as a second clay (sherd 1 of seed
//   67001's tray 67089: 12 %), or handed to the touching sherd by the watershed and cut off from
//   it by the colour split (sherd 1 of seed 77001's tray 77003: 5 %).
// * a band of a sherd (a fracture face, a lip) behind a step higher than the clustering distance:
//   a cluster of its own with a sherd-sized core, meeting the rest of its sherd in the top view
//   across an even step, of its hue or its face's (sherd 1 of seed 5001's tray 5069: 22 % of it;
//   sherd 10 of seed 29001's tray 29088: 34 %; sherd 2 of seed 49001's tray 49086: about 12 %).
// * a sherd folded over itself (an everted rim, a carination seen from above): two levels with
//   the wall between them hidden under the fold, a band up to 20 mm wide beside the rest, of one
//   clay's line to grey, covering together 0.875 or more of their convex hull in the top view
//   (sherd 4 of seed 11001's tray 11095; sherd 2 of seed 47001's tray 47066; sherd 1 of seed
//   105001's tray 105018: its fracture face band, 10 mm wide, behind a step of 3.8–7.1 mm).
// * a ring-footed base sherd lying upside down: the foot's level sole beside the base or wall a
//   foot's height lower, covering together 0.82–0.875 of their convex hull (by voxels, the two
//   parts 46 / 54 % of the sherd in seed 143001's tray 143041, 39 / 61 % in 155001's tray 155084,
//   28 / 72 % in 165001's tray 165015).
// * two parts of one sherd (seed 241001's tray 241089) whose clays lie 0.037 apart, each with a
//   region along the other within 0.0014 of both clays' lines: the top view must not trade the
//   regions, or neither part is left whole to join the other (four sherds found as six).
// A piece of one sherd lay in its neighbour's part, off that part's clay, on its own sherd's:
// * along its own sherd in the top view, hardly joined to the neighbour's part in 3-D
//   (sherd 4 of seed 1001's tray 1027: 43 %; sherd 18 of seed 5001's tray 5094: 20 %; sherd 5
//   of seed 27001's tray 27091: 25 %);
// * not greyer than the neighbour's clay but 0.05 or more off it in hue, handed to it by the
//   watershed (sherd 2 of seed 133001's tray 133025: 18 % of it) or as a small core's part
//   (sherd 8 of seed 161001's tray 161048: 41 %; sherd 2 of seed 165001's tray 165096: 44 %).
// * handed to the neighbour by the watershed and cut off from it again by the colour split, but
//   left a part of its own: it joins the part of its clay it borders most in 3-D (sherd 2 of seed
//   159001's tray 159041: 29 % of it; sherd 8 of seed 189001's tray 189044: 36 %; sherd 10 of seed
//   231001's tray 231039: 38 %).
// * a fracture face of neither part's clay, hanging under its sherd's edge with a gap in 3-D,
//   lying along its own sherd in the top view 5.0 and 8.3 × as much as along the neighbour's part
//   (sherd 11 of seed 13001's tray 13099: 16 % of it; sherd 4 of seed 249001's tray 249030: 15 %).
// * a fracture face of no face of the part's clay but of its own sherd's, whose colour sum the
//   band it shares with the rest of the part (the part's voxels whose neighbourhood hue straddles
//   the crease) pulled off its own clay's line, 0.019 and 0.017 across where faces lie within
//   0.015: its inside decides (sherd 8 of seed 215001's tray 215016: 22 % of it; sherd 12 of seed
//   225001's tray 225054: 23 %; sherd 5 of seed 273001's tray 273030, in another cluster than the
//   rest of its sherd: 19 %).
// * a fracture face on both clays' lines to grey, falling steeply away from its own sherd, whose
//   uphill side it lies on: the slope tells whose material lies behind it (seed 139001's tray
//   139033, seed 213001's 213014 and seed 249001's 249025: a sherd's recall 0.83, 0.87 and 0.88
//   before).
// * the same with a gap in 3-D all along it, hardly within the clustering distance of its sherd,
//   its hue nearer its own clay's line than the part's (sherd 1 of seed 165001's tray 165091 and
//   sherd 9 of seed 173001's tray 173008: their recall 0.80 and 0.76 before).
// A narrow sherd touching a wider one, with no core of its own (its region 3 mm deep reaches into
// the wider sherd, or is too small) but a lobe of the depth that falls 3.6–4.6 mm to the contact,
// of a clay 0.014–0.018 off the other's line (sherd 4 of seed 133001's tray 133062; sherd 4 of
// seed 137001's tray 137014; sherd 1 of seed 195001's tray 195091: each merged before). A
// sherd's own lobe behind a narrow neck lies on the line of the rest of its sherd (within
// 0.0001–0.0011) and joins it: else sherd 2 of seed 1's tray 33, sherd 1 of seed 1001's tray 1025
// and sherd 8 of seed 5001's tray 5056 are each found as two.
// A single sherd whose surface falls away so steeply that the scan leaves a gap: two clusters,
// 62 and 22 mm wide in the top view, side by side along an even step of 4–5 mm, their hues 0.0006
// apart (seed 255001's tray 255060: found as two before, the recall 0.857).
// Two sherds of one hue (0.0055 and 0.0073 apart) touching along a short stretch, where the
// watershed had handed a strip of one to the other's basin: the border along the strip made the
// contact look as long as a narrowing of one sherd (sherds 1 and 6 of seed 137001's tray 137096,
// 4 and 8 of seed 199001's tray 199091: each pair merged before).
// The far side of a step inside a sherd, too small for a core of its own, touching another sherd
// at its own height longer than its own sherd across the unseen wall: it went to the other sherd,
// though its colour lies on its own sherd's clay line (within 0.0006–0.0010) and off the other's
// (0.008–0.042) (sherd 8 of seed 143001's tray 143048, sherd 12 of seed 153001's tray 153056,
// sherd 2 of seed 163001's tray 163056: each found as two before).
// A band of a sherd behind a step inside it, 6–10 mm wide, too narrow for a core erosion deep or a
// shallow one: the watershed handed it to a neighbour it touches at one end. A band core now
// stands for it, and its part joins the part across the step whose clay it shows (sherd 7 of seed
// 13001's tray 13065, its recall 0.887 before: the band 0.0016 off its own sherd's line and 0.016
// off the neighbour's) or the part it touches most in 3-D (seed 245001's tray 245013: a sherd
// found as one with its neighbour before, 11 of 12; seed 267001's tray 267004: 10 of 9).
// A sherd standing steeply on the plate, 38–49 mm high, shows from above only strips of itself at
// heights far apart, each 4–8 mm wide, and no part as wide as a sherd for them to join: strips of
// one clay beside each other in the top view join one another (sherd 2 of seed 221001's tray
// 221032 and sherd 3 of seed 273001's tray 273081: each found as two; sherd 9 of seed 275001's
// tray 275044: found as two, a sixth of it set aside as too small).
// Two sherds on one clay's line to grey, the narrower showing a band 18–20 mm wide beside the other
// across a step of q90 9–15 mm, were joined as one sherd folded over itself: a band that wide now
// joins only behind a level's wall (sherds 14 and 16 of seed 163001's tray 163011, 7 and 13 of
// seed 185001's tray 185022, 2 and 7 of seed 225001's tray 225031: each pair found as one before).
// A sherd's own fracture face between its surface and a sherd whose clay's line to grey runs close
// to its own touches that sherd more in 3-D than its own surface where the crease above it is not
// seen: it stays with the sherd uphill of it, its face falling away from its surface (seed 135001's
// tray 135057, 145001's 145025, 211001's 211071, 229001's 229024 and 229045: a piece of a sherd in
// its neighbour before, the sherd's recall 0.52–0.84).
// The two levels of one sherd, of one hue (0.0016 apart), along an even step of q10 3.5 mm and q90
// 5.5 mm, touching in 3-D beside it a little more than levels had been let: 86 neighbour pairs
// beside 1,563 step pairs, 0.055 (sherd 4 of seed 161001's tray 161055: found as two before).
// A narrow sherd touching a wider one, its core too small to be a sherd's, whose end past a neck
// inside it the watershed reached from the wider sherd's core: its basin, 645 voxels, fell short
// of a sherd's area (648) and it joined the other; with the 61 voxels nearer its own core given
// back it stays apart (sherds 2 and 1 of seed 161001's tray 161019: found as one before).
// A whole small sherd, 462 voxels (320 mm²) and its core too small to be a sherd's, touching a
// wider one through a neck and lying beside no other part across a step (sherds 2 and 1 of seed
// 243001's tray 243089: found as one before).
// A sherd's fracture face strip of 174 voxels left in its neighbour's part by the watershed, apart
// from that part in 3-D and joined all along to its own sherd's part (7.5 neighbour pairs per
// voxel), its hue nearer that sherd's clay line (sherd 2 of seed 247001's tray 247008: its recall
// 0.85 before).
// A whole small sherd, 410 mm² with no core of its own, beside a sherd of a clay whose line to grey
// runs 0.0104 from its colour, behind an even step: taken for a strip of that sherd's edge before
// (sherds 11 and 18 of seed 159001's tray 159037: found as one).
// A whole small sherd of its neighbour's clay whose surface rises to a lobe of its own (575–627
// voxels, 400–435 mm²), touching a wider sherd at a point (a border of 0.3–0.4 mm beside a width of
// 10–11 mm) and beside no part across a step (13–26 voxels): taken for a lobe of that sherd before
// (sherds 4 and 2 of seed 193001's tray 193051, 5 and 2 of seed 271001's tray 271022: found as
// one). One sherd whose surface runs on across the border where the erosion cut it: its two parts
// meet in 3-D along a border 0.57 × the narrower's width, with 17 step pairs beside 199 neighbour
// pairs, hues 0.0023 apart (sherd 1 of seed 207001's tray 207049: found as two before).
// One sherd's far side, a small core's basin large enough to stand as a narrow sherd (691 and 696
// voxels beside wide cores), of its sherd's hue (0.0022 and 0.0029 apart): in tray 187007 (sherd 6
// of seed 187001) it meets the rest in 3-D along a border longer than its width, in tray 243029
// (sherd 2 of seed 243001) behind an even step (q10 2.6, q90 3.4 mm; 12 3-D pairs beside 546 step
// pairs). Found as two before: such basins were not judged for levels and necks.
// A narrow sherd (a basin 12.3 mm wide) leaning on a wider one of a hue 0.013 apart, 6.4 mm above
// it behind an even step (sherds 17 and 2 of seed 787001's tray 787094): joined to it as its far
// side when such basins were first judged for levels; a sherd's far side is its lower level.
// Two sherds' fracture faces meeting where they touch, one grey region in the part the watershed
// gave both (their top creases unseen): 13 % of sherd 4 of seed 185001's tray 185053 in sherd 8's
// part, 22 % of sherd 2 of 187001's 187076 in sherd 7's, 31 % of sherd 1 of 199001's 199033 in
// sherd 9's. The region as a whole is held by the 3-D pairs of the part's own face; split by the
// part each voxel hangs from, the other sherd's piece goes back to it.
// The far side of a step inside a sherd, a basin too small to stand as a sherd (a band core's, 483
// voxels, in sherd 5 of seed 11001's tray 11019; a small core's, 457 voxels, in sherd 4 of seed
// 243001's tray 243017), touching another sherd of a close clay in 3-D at its end (127 and 74
// neighbour pairs; 11019's touches its own sherd by 13) and lying along its own sherd across the
// step (1,092 and 837 step pairs), its colour nearer its own sherd's clay line (0.0025 against
// 0.0055, 0.0011 against 0.0029): it joined the sherd it touched before.
// A sherd leaning on another of a close clay (0.0038–0.0077 off its line), its lower level a small
// or band core's basin (413–537 voxels) lying along the other across a step (1,163–1,979 step
// pairs beside 3–14 3-D pairs), its raised end flooded from the other's core through their contact
// (505, 229 and 540 voxels with 123, 149 and 84 3-D pairs to the rest of that basin): sherds 3 and
// 7 of seed 159001's tray 159065, 3 and 1 of 177001's 177017, 6 and 3 of 197001's 197057, found as
// one before.
// A whole sherd whose colour lies near another's clay line (greyer, within 0.008 of it) touching
// that one briefly, taken for its fracture face across a border without a neck: sherds 13 and 4
// of seed 145001's tray 145031, 3 and 6 of 11001's 11057, 8 and 10 of 151001's 151027, 2 and 1 of
// 925001's 925082 (3.0–10 × as long, area over width, as its longer border with the other).
// The two levels of one sherd of one hue (0.0013 and 0.0012 apart) behind a step too uneven for a
// level's wall (q10 3.5 and 3.0 mm, q90 7.2 and 6.1 mm: 2.04 and 2.07 ×), its surface bending down
// across the border: the lower level falling away at a slope of −0.56 (sherd 7 of seed 133001's
// tray 133065), or sloping 0.97 below the upper one (sherd 3 of seed 187001's tray 187069). Each
// found as two before, as was the sherd of seed 253001's tray 253070 whose lower level falls away
// at −0.59 behind a step of q90 8.7 mm.
// Two sherds that a first form of that rule joined: one whose edge rises (slope 1.6) to a step of
// q90 12.2 mm over a flat one (sloping −0.1 away; seed 195001's tray 195088), and one lying on
// another that sloped −0.41 away from their border (seed 969001's tray 969017).
// Two sherds of close clays (their cores 0.0065, 0.0088 and 0.0123 off each other's clay line)
// joined as one sherd's levels behind an even wall, the lower running on flat beside it (slopes
// −0.03, 0.10 and 0.33): seed 159001's tray 159051, 157001's 157056, 175001's 175087, each found
// as one before; a fracture face that far off its sherd's line falls away from it.
// The two levels of one sherd of one clay (0.0003 off each other's line) touching in 3-D beside
// the step at 7.3 % of its pairs, behind a step too uneven for a level's wall (q90 7.1 mm, 2.44 ×
// its q10), the surface bending 0.76 down across the border: sherd 3 of seed 199001's tray 199089,
// found as two before. Two sherds of close clays touching each other beside a step, which that
// rule joined with looser bounds: 0.0040 off with a bend of 0.19 at 6.4 % of the pairs (seed
// 981001's tray 981042), 0.0041 off running on flat (bend −0.10) at 8.3 % (223001's 223095), and
// 0.0046 off with a bend of 0.38 at 13.5 % (261001's 261022).
// A strip of one sherd without a core of its own (a face below its edge, its end on the neighbour)
// that the watershed handed to the neighbour's part, lying along its own sherd's part (sherds 3
// and 2 of seed 209001's tray 209056: 266 and 1,127 neighbour pairs with it against 104 and 140
// with the rest of the neighbour's) or showing its sherd's clay and not the neighbour's (sherd 10
// of seed 257001's tray 257093, 11 of 267001's 267011, 7 of 223001's 223099: 0.0026, 0.0003 and
// 0.0010 off its clay's line, 0.0205, 0.0132 and 0.0057 off the neighbour's), found split before.
// A strip of a sherd nearer its neighbour's core, lying along the neighbour's part (398 neighbour
// pairs against 21) but showing its own part's clay alone (0.0007 off its line, 0.0091 off the
// neighbour's): sherd 8 of seed 139001's tray 139065, merged when the 3-D rule alone judged it.
// A strip of a sherd's own clay, given back to its part from the neighbour's by that rule, barely
// joined to its part in 3-D (5 and 9 neighbour pairs, 25 and 188 with the neighbour), which the
// face rule then moved back to the neighbour by the slope of the whole strip (0.106 and 0.130 of it
// with the neighbour uphill), where the piece hanging from the neighbour does not fall away from
// it (0.13 and 0.21): sherd 4 of seed 165001's tray 165013, 2 of 1067001's 1067013, found split.
// A strip of a sherd that the watershed handed to the neighbour, of both parts' clay (within 0.005
// of both lines), joined in 3-D to neither part much (2–12 neighbour pairs with its sherd's part,
// 13–49 with the rest of the neighbour's), lying in the top view along its sherd's part for its
// whole length and along the rest of the neighbour's for 0.18–0.59 of it: sherd 8 of seed
// 983001's tray 983033, 1 of 137001's 137009, 2 of 975001's 975076, found split before.
// The two levels of one sherd in two Euclidean clusters (the wall between them unseen, the gap
// wider than the clustering distance), 12.8–36.7 mm wide, their colours on one clay's line
// (0.0001–0.0008 off, hues 0.007–0.025 apart), the lower falling away across the border (slopes
// −0.24 to −0.50) and the upper not rising to it (−0.34 to 0.02): sherd 4 of seed 223001's tray
// 223032, 1 of 261001's 261066 and 5 of 269001's 269041, found as two before.
// A whole sherd 15.6 mm wide in a cluster of its own, greyer than its neighbour and 0.0013 off
// its line, behind a step of spread 1.84 (90th / 10th percentile), taken for the neighbour's
// fracture-face band: sherds 3 and 7 of seed 147001's tray 147094, found as one before.
// The two levels of one sherd behind an even wall (q10 3.4 mm, q90 4.7 mm), 0.0011 off each
// other's clay line, the lower one greyer (hues 0.11 apart) and 16.1 mm wide, too wide for a face
// by the usual bound, falling away from the upper at a slope of −0.53: sherd 1 of seed 145001's
// tray 145052, found as two before. (The band of TwoAsOne_WideBandBehindAHighStep's tray 185022,
// 16.3 mm wide and 0.0015 off its neighbour's line, runs on flat beside it, slope 0.01: joined as
// a face without that test.)
// A whole sherd whose colour lies near another's clay line (greyer), lying beside it at about its
// height, both running level across their border (slopes within ±0.26) along 0.71–3.48 × the
// narrower one's width, taken for its fracture face: sherds 2 and 9 of seed 13001's tray 13034, 2
// and 17 of 195001's 195011, 3 and 7 of 231001's 231041, each found as one before.
// A whole sherd 7 mm wide, too narrow to keep more than a band core, touching a wider sherd in 3-D
// at its end (4 neighbour pairs, a border 0.10 × its width) and lying beside it across a step for
// only 60 of its 1,034 voxels: joined to it as the far side of that sherd's step (sherds 12 and
// 14 of seed 227001's tray 227048, found as one before).
// A sherd that a leaning one lies across, showing two pieces of one hue under it that meet only
// under it (sherd 1 of seed 153001's tray 153023, of 1385001's 1385026 and of 1427001's 1427098,
// each found as two before); and one whose two pieces lay under a sherd of a greyer clay and had
// joined it as its fracture face's strips across an unseen wall (sherds 1 and 2 of 1409001's tray
// 1409066).
class FormerlyFailingTray : public ::testing::TestWithParam<TrayOfRun> {};

TEST_P(FormerlyFailingTray, EachSherdIsFoundOnceAndWhole) {
  expect_bench_tray_found(GetParam().first, GetParam().tray, 0.9, 0.9);
}

INSTANTIATE_TEST_SUITE_P(
    BenchTrays, FormerlyFailingTray,
    ::testing::Values(TrayOfRun{"TwoAsOne_WideRegionNearTheLine", 5001, 5021},
                      TrayOfRun{"TwoAsOne_NoDeepCore", 25001, 25085},
                      TrayOfRun{"TwoAsOne_NoDeepCore", 105001, 105017},
                      TrayOfRun{"TwoAsOne_ShallowCoredPartAcrossAWall", 55001, 55097},
                      TrayOfRun{"TwoAsOne_PeakOffTheLine", 9001, 9097},
                      TrayOfRun{"TwoAsOne_PartWiderThanAFace", 17001, 17011},
                      TrayOfRun{"TwoAsOne_PartWiderThanAFace", 19001, 19070},
                      TrayOfRun{"TwoAsOne_ShortStepOfALeaningSherd", 23001, 23012},
                      TrayOfRun{"TwoAsOne_ShortStepOfALeaningSherd", 23001, 23050},
                      TrayOfRun{"TwoAsOne_NarrowSherdTouchingBriefly", 135001, 135093},
                      TrayOfRun{"TwoAsOne_NarrowSherdTouchingBriefly", 145001, 145097},
                      TrayOfRun{"TwoAsOne_NarrowSherdTouchingBriefly", 147001, 147088},
                      TrayOfRun{"OneAsTwo_FractureFaceOfALeaningSherd", 1, 32},
                      TrayOfRun{"OneAsTwo_FractureFaceLevel", 1, 61},
                      TrayOfRun{"OneAsTwo_FractureFaceLevel", 7001, 7004},
                      TrayOfRun{"OneAsTwo_LevelsOfAnUnevenStep", 5001, 5075},
                      TrayOfRun{"OneAsTwo_LevelsOfALowStep", 29001, 29046},
                      TrayOfRun{"OneAsTwo_LevelsOfALowStep", 45001, 45006},
                      TrayOfRun{"OneAsTwo_NarrowSherdCutInTwo", 5001, 5041},
                      TrayOfRun{"OneAsTwo_NarrowSherdCutInTwo", 7001, 7072},
                      TrayOfRun{"OneAsTwo_NoNeckAlongAShorterBorder", 19001, 19012},
                      TrayOfRun{"OneAsTwo_NoNeckAtTheHueNoise", 19001, 19082},
                      TrayOfRun{"OneAsTwo_NarrowLevelOfItsOwn", 23001, 23092},
                      TrayOfRun{"OneAsTwo_NarrowLevelOfItsOwn", 29001, 29059},
                      TrayOfRun{"OneAsTwo_FaceBandBehindAStep", 1001, 1018},
                      TrayOfRun{"OneAsTwo_ClayLevelBesideItsFace", 9001, 9012},
                      TrayOfRun{"OneAsTwo_StripSeenEdgeOn_CutByTheErosion", 79001, 79060},
                      TrayOfRun{"OneAsTwo_StripSeenEdgeOn_CutByColour", 67001, 67089},
                      TrayOfRun{"OneAsTwo_StripSeenEdgeOn_InTheNeighbour", 77001, 77003},
                      TrayOfRun{"OneAsTwo_BandInAClusterOfItsOwn", 5001, 5069},
                      TrayOfRun{"OneAsTwo_BandInAClusterOfItsOwn", 29001, 29088},
                      TrayOfRun{"OneAsTwo_BandInAClusterOfItsOwn", 49001, 49086},
                      TrayOfRun{"OneAsTwo_FoldedOverItself", 11001, 11095},
                      TrayOfRun{"OneAsTwo_FoldedOverItself", 47001, 47066},
                      TrayOfRun{"OneAsTwo_FoldedOverItself", 105001, 105018},
                      TrayOfRun{"OneAsTwo_RingFootUpsideDown", 143001, 143041},
                      TrayOfRun{"OneAsTwo_RingFootUpsideDown", 155001, 155084},
                      TrayOfRun{"OneAsTwo_RingFootUpsideDown", 165001, 165015},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsOwnSherd", 1001, 1027},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsOwnSherd", 5001, 5094},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsOwnSherd", 27001, 27091},
                      TrayOfRun{"PieceInTheNeighbour_FarOffItsClay", 133001, 133025},
                      TrayOfRun{"PieceInTheNeighbour_FarOffItsClay", 161001, 161048},
                      TrayOfRun{"PieceInTheNeighbour_FarOffItsClay", 165001, 165096},
                      TrayOfRun{"PieceInTheNeighbour_CutOffByColour", 159001, 159041},
                      TrayOfRun{"PieceInTheNeighbour_CutOffByColour", 189001, 189044},
                      TrayOfRun{"PieceInTheNeighbour_CutOffByColour", 231001, 231039},
                      TrayOfRun{"PieceInTheNeighbour_FaceOfNeitherClay", 13001, 13099},
                      TrayOfRun{"PieceInTheNeighbour_FaceOfNeitherClay", 249001, 249030},
                      TrayOfRun{"PieceInTheNeighbour_SumPulledOffTheLine", 215001, 215016},
                      TrayOfRun{"PieceInTheNeighbour_SumPulledOffTheLine", 225001, 225054},
                      TrayOfRun{"PieceInTheNeighbour_SumPulledOffTheLine", 273001, 273030},
                      TrayOfRun{"PieceInTheNeighbour_FaceFallingAwayFromItsSherd", 139001, 139033},
                      TrayOfRun{"PieceInTheNeighbour_FaceFallingAwayFromItsSherd", 213001, 213014},
                      TrayOfRun{"PieceInTheNeighbour_FaceFallingAwayFromItsSherd", 249001, 249025},
                      TrayOfRun{"PieceInTheNeighbour_FaceFallingAwayAcrossAGap", 165001, 165091},
                      TrayOfRun{"PieceInTheNeighbour_FaceFallingAwayAcrossAGap", 173001, 173008},
                      TrayOfRun{"OneAsTwo_HalvesOnEachOthersLine", 241001, 241089},
                      TrayOfRun{"TwoAsOne_NarrowSherdWithALobe", 133001, 133062},
                      TrayOfRun{"TwoAsOne_NarrowSherdWithALobe", 137001, 137014},
                      TrayOfRun{"TwoAsOne_NarrowSherdWithALobe", 195001, 195091},
                      TrayOfRun{"OneAsTwo_LobeOfItsOwnClay", 1, 33},
                      TrayOfRun{"OneAsTwo_LobeOfItsOwnClay", 1001, 1025},
                      TrayOfRun{"OneAsTwo_LobeOfItsOwnClay", 5001, 5056},
                      TrayOfRun{"OneAsTwo_WideLevelsOfOneHue", 255001, 255060},
                      TrayOfRun{"TwoAsOne_BorderAlongALeakedStrip", 137001, 137096},
                      TrayOfRun{"TwoAsOne_BorderAlongALeakedStrip", 199001, 199091},
                      TrayOfRun{"OneAsTwo_StepSideTouchingAnother", 143001, 143048},
                      TrayOfRun{"OneAsTwo_StepSideTouchingAnother", 153001, 153056},
                      TrayOfRun{"OneAsTwo_StepSideTouchingAnother", 163001, 163056},
                      TrayOfRun{"OneAsTwo_BandWithoutACore", 13001, 13065},
                      TrayOfRun{"TwoAsOne_BandWithoutACore", 245001, 245013},
                      TrayOfRun{"OneAsTwo_BandWithoutACore", 267001, 267004},
                      TrayOfRun{"OneAsTwo_StripsOfASteepSherd", 221001, 221032},
                      TrayOfRun{"OneAsTwo_StripsOfASteepSherd", 275001, 275044},
                      TrayOfRun{"OneAsTwo_StripsOfASteepSherd", 273001, 273081},
                      TrayOfRun{"TwoAsOne_WideBandBehindAHighStep", 163001, 163011},
                      TrayOfRun{"TwoAsOne_WideBandBehindAHighStep", 185001, 185022},
                      TrayOfRun{"TwoAsOne_WideBandBehindAHighStep", 225001, 225031},
                      TrayOfRun{"OneAsTwo_OwnFaceTouchingACloseClay", 135001, 135057},
                      TrayOfRun{"OneAsTwo_OwnFaceTouchingACloseClay", 145001, 145025},
                      TrayOfRun{"OneAsTwo_OwnFaceTouchingACloseClay", 211001, 211071},
                      TrayOfRun{"OneAsTwo_OwnFaceTouchingACloseClay", 229001, 229024},
                      TrayOfRun{"OneAsTwo_OwnFaceTouchingACloseClay", 229001, 229045},
                      TrayOfRun{"OneAsTwo_LevelsTouchingALittle", 161001, 161055},
                      TrayOfRun{"TwoAsOne_NarrowSherdTrimmedByTheWatershed", 161001, 161019},
                      TrayOfRun{"TwoAsOne_SmallSherdBesideAWideOne", 243001, 243089},
                      TrayOfRun{"OneAsTwo_SurfaceRunningOnAcrossAShortBorder", 207001, 207049},
                      TrayOfRun{"PieceInTheNeighbour_ApartThereJoinedToItsSherd", 247001, 247008},
                      TrayOfRun{"TwoAsOne_SmallSherdOffTheClayLineBehindAStep", 159001, 159037},
                      TrayOfRun{"TwoAsOne_SmallSherdTakenForALobe", 193001, 193051},
                      TrayOfRun{"TwoAsOne_SmallSherdTakenForALobe", 271001, 271022},
                      TrayOfRun{"OneAsTwo_FarSideKeptAsANarrowSherd", 187001, 187007},
                      TrayOfRun{"OneAsTwo_FarSideKeptAsANarrowSherd", 243001, 243029},
                      TrayOfRun{"TwoAsOne_NarrowSherdLeaningAsAFarSide", 787001, 787094},
                      TrayOfRun{"OneAsTwo_FacesMeetingAtTheContact", 185001, 185053},
                      TrayOfRun{"OneAsTwo_FacesMeetingAtTheContact", 187001, 187076},
                      TrayOfRun{"OneAsTwo_FacesMeetingAtTheContact", 199001, 199033},
                      TrayOfRun{"OneAsTwo_FarSideTouchingAnotherAtItsEnd", 11001, 11019},
                      TrayOfRun{"TwoAsOne_FarSideTouchingAnotherAtItsEnd", 243001, 243017},
                      TrayOfRun{"TwoAsOne_LevelLeaningOnAnotherWithItsRaisedEnd", 159001, 159065},
                      TrayOfRun{"TwoAsOne_LevelLeaningOnAnotherWithItsRaisedEnd", 177001, 177017},
                      TrayOfRun{"TwoAsOne_LevelLeaningOnAnotherWithItsRaisedEnd", 197001, 197057},
                      TrayOfRun{"TwoAsOne_WholeSherdTakenForAFace", 145001, 145031},
                      TrayOfRun{"TwoAsOne_WholeSherdTakenForAFace", 11001, 11057},
                      TrayOfRun{"TwoAsOne_WholeSherdTakenForAFace", 151001, 151027},
                      TrayOfRun{"TwoAsOne_WholeSherdTakenForAFace", 925001, 925082},
                      TrayOfRun{"OneAsTwo_SurfaceBendingDownAcrossAStep", 133001, 133065},
                      TrayOfRun{"OneAsTwo_SurfaceBendingDownAcrossAStep", 187001, 187069},
                      TrayOfRun{"OneAsTwo_SurfaceBendingDownAcrossAStep", 253001, 253070},
                      TrayOfRun{"TwoAsOne_EdgeRisingToAHighStep", 195001, 195088},
                      TrayOfRun{"TwoAsOne_LevelSlopingGentlyAway", 969001, 969017},
                      TrayOfRun{"TwoAsOne_CloseClayLevelRunningOnFlat", 159001, 159051},
                      TrayOfRun{"TwoAsOne_CloseClayLevelRunningOnFlat", 157001, 157056},
                      TrayOfRun{"TwoAsOne_CloseClayLevelRunningOnFlat", 175001, 175087},
                      TrayOfRun{"OneAsTwo_LevelsTouchingAndBendingDown", 199001, 199089},
                      TrayOfRun{"TwoAsOne_CloseClaysTouching", 981001, 981042},
                      TrayOfRun{"TwoAsOne_CloseClaysTouching", 223001, 223095},
                      TrayOfRun{"TwoAsOne_CloseClaysTouching", 261001, 261022},
                      TrayOfRun{"PieceInTheNeighbour_StripAlongItsSherd", 209001, 209056},
                      TrayOfRun{"PieceInTheNeighbour_StripOfItsClay", 257001, 257093},
                      TrayOfRun{"PieceInTheNeighbour_StripOfItsClay", 267001, 267011},
                      TrayOfRun{"PieceInTheNeighbour_StripOfItsClay", 223001, 223099},
                      TrayOfRun{"TwoAsOne_StripOfItsOwnClayAlongTheNeighbour", 139001, 139065},
                      TrayOfRun{"OneAsTwo_OwnStripNotFallingFromTheNeighbour", 165001, 165013},
                      TrayOfRun{"OneAsTwo_OwnStripNotFallingFromTheNeighbour", 1067001, 1067013},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsSherdInTheTopView", 983001, 983033},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsSherdInTheTopView", 137001, 137009},
                      TrayOfRun{"PieceInTheNeighbour_AlongItsSherdInTheTopView", 975001, 975076},
                      TrayOfRun{"OneAsTwo_OwnFaceBesideTheNeighboursFace", 153001, 153054},
                      TrayOfRun{"TwoAsOne_SmallBasinOfAnotherClay", 221001, 221011},
                      TrayOfRun{"TwoAsOne_SmallBasinOfAnotherClay", 223001, 223030},
                      TrayOfRun{"TwoAsOne_SmallSherdRisingFromTheStep", 193001, 193058},
                      TrayOfRun{"TwoAsOne_SmallSherdRisingFromTheStep", 243001, 243062},
                      TrayOfRun{"TwoAsOne_SmallSherdRisingFromTheStep", 253001, 253085},
                      TrayOfRun{"OneAsTwo_LevelsInTwoClustersBendingDown", 223001, 223032},
                      TrayOfRun{"OneAsTwo_LevelsInTwoClustersBendingDown", 261001, 261066},
                      TrayOfRun{"OneAsTwo_LevelsInTwoClustersBendingDown", 269001, 269041},
                      TrayOfRun{"TwoAsOne_BandInAnotherClusterBehindAnUnevenStep", 147001, 147094},
                      TrayOfRun{"OneAsTwo_WideFaceFallingAway", 145001, 145052},
                      TrayOfRun{"TwoAsOne_WholeSherdRunningLevelBesideIt", 13001, 13034},
                      TrayOfRun{"TwoAsOne_WholeSherdRunningLevelBesideIt", 195001, 195011},
                      TrayOfRun{"TwoAsOne_WholeSherdRunningLevelBesideIt", 231001, 231041},
                      TrayOfRun{"TwoAsOne_NarrowBandSherdTouchingAtItsEnd", 227001, 227048},
                      TrayOfRun{"OneAsTwo_PiecesUnderALeaningSherd", 153001, 153023},
                      TrayOfRun{"OneAsTwo_PiecesUnderALeaningSherd", 1385001, 1385026},
                      TrayOfRun{"OneAsTwo_PiecesUnderALeaningSherd", 1427001, 1427098},
                      TrayOfRun{"TwoAsOne_PiecesUnderASherdOfAGreyerClay", 1409001, 1409066}),
    case_name);

// A whole small sherd (348 mm²) lying under another along 118 voxels of its border, beside a
// larger sherd of its hue that the covering sherd only reaches (35 voxels): two parts under one
// part, of one hue, the smaller less than a sherd's area, but not cut across by it alike, so no
// pieces of one sherd (sherds 3 and 14 of seed 1457001's tray 1457034, found as one when
// join_pieces_under_one_sherd had no border ratio).
TEST(SmallSherdUnderAnother, StaysApartFromASherdOfItsHueBesideIt) {
  expect_bench_tray_found(1457001, 1457034, 0.9, 0.9);
}

// Whole narrow sherds kept apart beside a wider sherd of another hue (0.11 and 0.22 apart) whose
// colours lie on that sherd's line to grey, along 3-D borders 1.5–2.3 × their width (sherds 13 and
// 14 of seed 9001's tray 9034, 8 and 6 of seed 171001's tray 171079): taken for its fracture face,
// each joined its neighbour when such basins were first judged for levels and necks.
TEST(NarrowSherdKeptApart, IsNoFractureFaceOfItsNeighbour) {
  expect_bench_tray_found(9001, 9034, 0.9, 0.9);
  // The watershed left a quarter of one sherd there in its neighbour's part (recall 0.74, the
  // neighbour's precision 0.87) until faces meeting at a contact were split
  // (OneAsTwo_FacesMeeting…).
  expect_bench_tray_found(171001, 171079, 0.9, 0.9);
}

// A sherd's fracture face, greyer than its surface (hues 0.06–0.18 apart), bordering it without a
// neck along only 1.47–2.29 × the face's width, but not level with it across the border: the face
// falls away from the surface (slope −1.18 beside 0.19: sherd 3 of seed 221001's tray 221038;
// −3.36 beside −0.45: sherd 13 of 275001's 275042) or the surface rises from the face (1.04
// beside −0.12: sherd 1 of 273001's 273095). A build without the slope test, refusing every face
// along a border shorter than kFlatFaceMinBorderShare × its width, split all three.
TEST(FaceSlopingOffItsSherd, JoinsItAlongAShortBorder) {
  expect_bench_tray_found(221001, 221038, 0.9, 0.9);
  expect_bench_tray_found(273001, 273095, 0.9, 0.9);
  expect_bench_tray_found(275001, 275042, 0.9, 0.9);
}

// Strips of a sherd's fracture face that the watershed left in the neighbour's part, apart from it
// in 3-D and joined all along to their own sherd's part, of another clay than that part by the
// pieces' test: each meets its own sherd where that sherd lies higher, the face hanging from its
// surface. 188 voxels of sherd 10 of seed 203001's tray 203076, 161 of sherd 14 of 179001's 179051,
// 111 of sherd 6 of 9001's 9098, 102 of sherd 9 of 155001's 155034: their recall 0.946, 0.912,
// 0.978 and 0.960 left there, 0.992 or more moved. Sherd 14 of 179051 has a second piece, 78
// voxels in sherd 17's part, of which a roundabout way through the later steps moved all but 17;
// since strips go back to their sherd's part (kStripMinAlongPairs) 52 go there and 26 stay:
// recall 0.986.
struct PieceOfTray {
  std::uint64_t first, tray;
  int sherd;          // truth label
  double min_recall;  // of the found sherd holding most of it
};

// The found sherd holding most points of truth sherd `sherd`, and its recall of that sherd.
struct HoldingMost {
  const seg::Part* found = nullptr;
  double recall = 0.0;
};
HoldingMost found_holding_most(const SegmentedTray& segmented, int sherd) {
  const auto& labels = segmented.tray.labels;
  HoldingMost best;
  std::size_t most = 0;
  for (const auto& found : segmented.result.sherds) {
    const auto n = static_cast<std::size_t>(std::count_if(
        found.indices.begin(), found.indices.end(), [&](auto i) { return labels[i] == sherd; }));
    if (n > most) most = n, best.found = &found;
  }
  const auto total = std::count(labels.begin(), labels.end(), sherd);
  if (total > 0) best.recall = static_cast<double>(most) / static_cast<double>(total);
  return best;
}

void expect_piece_with_its_sherd(const PieceOfTray& piece) {
  const SegmentedTray segmented = segmented_bench_tray(piece.first, piece.tray);
  EXPECT_GE(found_holding_most(segmented, piece.sherd).recall, piece.min_recall);
}

class HangingPieceTray : public ::testing::TestWithParam<PieceOfTray> {};

TEST_P(HangingPieceTray, GoesToTheSherdItHangsFrom) { expect_piece_with_its_sherd(GetParam()); }

INSTANTIATE_TEST_SUITE_P(BenchTrays, HangingPieceTray,
                         ::testing::Values(PieceOfTray{203001, 203076, 10, 0.99},
                                           PieceOfTray{179001, 179051, 14, 0.98},
                                           PieceOfTray{9001, 9098, 6, 0.99},
                                           PieceOfTray{155001, 155034, 9, 0.99}));

// A strip going by its colour to its sherd's part leaves a piece of its old part's clay there
// only where that piece borders the rest of the old part more than the new one (own_clay_pieces):
// the strips of sherd 5 of seed 177001's tray 177024 (325 voxels) and of sherd 1 of 143001's
// 143036 (89) hold pieces of 52 + 37 and 46 voxels nearer the old part's clay by their colour,
// all of the strip's sherd, bordering the new part 118–249 times and the old part 0–20 times (voxel
// neighbour pairs). Kept back, the sherds' recall was 0.975 and 0.968; now 0.995 and 0.985.
class StripPieceTray : public ::testing::TestWithParam<PieceOfTray> {};

TEST_P(StripPieceTray, GoesWithItsStripWhereItBordersTheNewPart) {
  expect_piece_with_its_sherd(GetParam());
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, StripPieceTray,
                         ::testing::Values(PieceOfTray{177001, 177024, 5, 0.99},
                                           PieceOfTray{143001, 143036, 1, 0.98}));

// Pieces as large as a small sherd, with no core of their own, lying beside a sherd of another
// clay in the top view, their colours 0.0136 and 0.0117 off that clay's line to grey (within the
// strips' bound, kWallMaxOffClayLine): 279 mm², 60 % of sherd 12 of seed 137001's tray 137045, and
// 283 mm², 57 % of sherd 1 of seed 143001's tray 143093, were joined to that sherd, which then
// stood for both. Now the found sherd holding most of each stands for it.
class LargePieceTray : public ::testing::TestWithParam<PieceOfTray> {};

TEST_P(LargePieceTray, IsNoStripOfTheNeighbourOffItsClay) {
  const PieceOfTray& piece = GetParam();
  const SegmentedTray segmented = segmented_bench_tray(piece.first, piece.tray);
  const HoldingMost holding = found_holding_most(segmented, piece.sherd);
  ASSERT_NE(holding.found, nullptr);
  std::map<int, std::size_t> by_label;
  for (auto i : holding.found->indices) ++by_label[segmented.tray.labels[i]];
  const auto stands_for = std::max_element(by_label.begin(), by_label.end(), [](auto& a, auto& b) {
                            return a.second < b.second;
                          })->first;
  EXPECT_EQ(stands_for, piece.sherd);
  EXPECT_GE(holding.recall, piece.min_recall);
}

INSTANTIATE_TEST_SUITE_P(BenchTrays, LargePieceTray,
                         ::testing::Values(PieceOfTray{137001, 137045, 12, 0.55},
                                           PieceOfTray{143001, 143093, 1, 0.55}));

// A black plate seen from above every 0.5 mm, x from −50 to 30 mm, y from −40 to 40 mm, with
// what `cell` puts at (x, y): truth label (0 plate), height and colour.
struct PlateScene {
  sherd::Mesh cloud;
  std::vector<int> truth;
};

struct Cell {
  int label = 0;
  float z = 0.0f;
  sherd::Rgb8 colour{12, 12, 12};
};

template <typename CellAt>
PlateScene plate_scene(CellAt&& cell_at) {
  PlateScene scene;
  for (int j = -80; j <= 80; ++j) {
    for (int i = -100; i <= 60; ++i) {
      const float x = 0.5f * i, y = 0.5f * j;
      const Cell cell = cell_at(x, y);
      scene.cloud.vertices.points.emplace_back(x, y, cell.z);
      scene.cloud.vertices.colours.push_back(cell.colour);
      scene.truth.push_back(cell.label);
    }
  }
  return scene;
}

// A 40 × 50 mm sherd at 5 mm and, right beside it, a 6.5 mm wide strip 9 mm higher along its
// 50 mm edge (x from 0.5 to 7 mm): the wall between them is never sampled, so the strip is a
// cluster of its own, and too narrow for the erosion to leave it a core. Truth: 1 the sherd, 2
// the strip.
PlateScene sherd_and_strip(sherd::Rgb8 strip_colour) {
  return plate_scene([&](float x, float y) {
    if (std::abs(y) > 25 || x < -40 || x > 7 || (x > 0 && x < 0.5f)) return Cell{};
    return x <= 0 ? Cell{1, 5.0f, {180, 120, 80}} : Cell{2, 14.0f, strip_colour};
  });
}

std::vector<seg::Part> segment_scene(const PlateScene& scene) {
  seg::Params params;
  params.contact_erosion_mm = 5.0;
  params.plane_min_extent_mm = 70.0;  // the 80 mm plate is the support
  return seg::segment(scene.cloud, params).sherds;
}

// Two sherds found, each standing for another truth sherd, of whose points it holds at least
// `min_share`.
void expect_two_sherds(const PlateScene& scene, double min_share) {
  const auto sherds = segment_scene(scene);
  ASSERT_EQ(sherds.size(), 2u);
  std::set<int> stands_for;
  for (const auto& part : sherds) {
    std::map<int, std::size_t> counts;
    for (auto i : part.indices) ++counts[scene.truth[i]];
    const auto best = std::max_element(counts.begin(), counts.end(),
                                       [](auto& a, auto& b) { return a.second < b.second; });
    stands_for.insert(best->first);
    EXPECT_GE(static_cast<double>(best->second) / part.indices.size(), min_share) << part.id;
  }
  EXPECT_EQ(stands_for, (std::set<int>{1, 2}));
}

// One sherd found, holding every point of the scene's truth sherds.
void expect_one_sherd(const PlateScene& scene) {
  const auto sherds = segment_scene(scene);
  ASSERT_EQ(sherds.size(), 1u);
  EXPECT_EQ(sherds[0].indices.size(),
            static_cast<std::size_t>(scene.truth.size() -
                                     std::count(scene.truth.begin(), scene.truth.end(), 0)));
}

// The strip in the clay's colour mixed with grey, as a fracture face shows the fired core: 0.85 ×
// (0.6 × clay + 0.4 × grey 100) of the sherd's (180, 120, 80): one sherd of all their points.
TEST(UnseenWall, AStripOfTheClayMixedWithGreyIsPartOfTheSherd) {
  expect_one_sherd(sherd_and_strip(sherd::Rgb8{126, 95, 75}));
}

// The same strip in another clay's colour (hue (g/r, b/r) (0.93, 0.40), 0.25 off the sherd's
// clay-to-grey line): a sherd of its own beside it.
TEST(UnseenWall, AStripOfAnotherClayStaysApart) {
  expect_two_sherds(sherd_and_strip(sherd::Rgb8{150, 140, 60}), 1.0);
}

// A sherd standing steeply, alone on the plate, as the top view shows it: two strips 5 mm wide
// and 40 mm long, side by side along 10 mm of them — its top edge at 30 mm in the clay (180, 120,
// 80), x from 0 to 5 mm and y from −35 to 5 mm, and a band of its side 22 mm lower in
// `lower_colour`, x from 5.5 to 10.5 mm and y from −5 to 35 mm: clusters of their own, each
// narrower than any sherd lying down, no wider part beside them, and too far from covering their
// hull in the top view for a fold (about 0.7). Truth: 1 the upper strip, `lower_label` the lower.
PlateScene strips_of_a_steep_sherd(sherd::Rgb8 lower_colour, int lower_label) {
  return plate_scene([&](float x, float y) {
    if (x >= 0 && x <= 5 && y >= -35 && y <= 5) return Cell{1, 30.0f, {180, 120, 80}};
    if (x >= 5.5f && x <= 10.5f && y >= -5 && y <= 35) return Cell{lower_label, 8.0f, lower_colour};
    return Cell{};
  });
}

// The lower strip in the same clay, in shade (0.8 ×): one sherd of all their points.
TEST(SteepSherd, StripsOfOneClayAloneOnThePlateAreOneSherd) {
  expect_one_sherd(strips_of_a_steep_sherd(sherd::Rgb8{144, 96, 64}, 1));
}

// The lower strip in another clay (see AStripOfAnotherClayStaysApart): two sherds.
TEST(SteepSherd, StripsOfTwoClaysStayApart) {
  expect_two_sherds(strips_of_a_steep_sherd(sherd::Rgb8{150, 140, 60}, 2), 1.0);
}

// A 40 × 50 mm sherd at 10 mm and, beside its 50 mm edge, a 14 mm wide band 5 mm lower, as a lip
// or a foot ring shows (x from 0.5 to 14.5 mm): the wall between them is never sampled and the
// step is higher than the clustering distance, so the band is a cluster of its own, wide enough
// for the erosion to leave it a core. Truth: 1 the sherd, 2 the band.
PlateScene sherd_and_band(sherd::Rgb8 band_colour) {
  return plate_scene([&](float x, float y) {
    if (std::abs(y) > 25 || x < -40 || x > 14.5f || (x > 0 && x < 0.5f)) return Cell{};
    return x <= 0 ? Cell{1, 10.0f, {180, 120, 80}} : Cell{2, 5.0f, band_colour};
  });
}

// The band in the sherd's clay, or in its fracture face's colour (the clay mixed with grey, as in
// AStripOfTheClayMixedWithGreyIsPartOfTheSherd): one sherd of all their points.
TEST(LevelApart, ABandOfTheClayBehindAHighStepIsPartOfTheSherd) {
  for (const sherd::Rgb8 colour : {sherd::Rgb8{180, 120, 80}, sherd::Rgb8{126, 95, 75}}) {
    SCOPED_TRACE(int(colour.r));
    expect_one_sherd(sherd_and_band(colour));
  }
}

// The band in the second clay of TwoSherdsAlongAWideContactAreSplitByClay (hue 0.056 along the
// sherd's clay-to-grey line, 0.019 across it): a sherd of its own, as two sherds side by side.
TEST(LevelApart, ABandOfAnotherClayBehindAHighStepStaysApart) {
  expect_two_sherds(sherd_and_band(sherd::Rgb8{170, 121, 82}), 1.0);
}

// A 35 × 38 mm sherd of clay (180, 120, 80) at 5 mm (x from −50 to −15 mm, y from −38 to 0 mm)
// and a 13 mm wide band beside its upper edge at the same height (y from 0.5 to 13.5 mm, x from
// `band_from` to `band_to`) in that clay's fracture face colour (see
// AStripOfTheClayMixedWithGreyIsPartOfTheSherd). Truth: 1 the sherd, 2 the band.
PlateScene band_beside_a_sherd(float band_from, float band_to) {
  return plate_scene([&](float x, float y) {
    if (x >= -50 && x <= -15 && y >= -38 && y <= 0) return Cell{1, 5.0f, {180, 120, 80}};
    if (x >= band_from && x <= band_to && y >= 0.5f && y <= 13.5f)
      return Cell{2, 5.0f, {126, 95, 75}};
    return Cell{};
  });
}

// A band 57 mm long touching the sherd along 12 mm of its edge (x from −27 to 30 mm): too wide a
// contact for the erosion to part them, and in a colour on the sherd's line to grey, narrower
// than kFaceMaxWidthMm; but it borders the sherd along a fifth of its length, as no fracture face
// does: another clay's sherd (its hue on the first's line by chance).
TEST(TwoClays, ANarrowSherdOnItsNeighboursLineToGreyTouchingItBrieflyIsASherd) {
  expect_two_sherds(band_beside_a_sherd(-27.0f, 30.0f), 0.97);
}

// The band along the sherd's whole edge (x from −50 to −15 mm): the sherd's fracture face.
TEST(TwoClays, AFaceColouredBandAlongTheWholeEdgeIsPartOfTheSherd) {
  EXPECT_EQ(segment_scene(band_beside_a_sherd(-50.0f, -15.0f)).size(), 1u);
}

// A 22 × 30 mm sherd at 5 mm (x from 0.5 to 22.5 mm, y from −4 to 26 mm) with a ridge 3 mm wide
// and 2 mm high along its length (x from 10 to 13 mm), as a flange or a cordon: the ridge's sides
// are steps the boundary test takes for edges, so the erosion finds the sherd two strips 9.5 mm
// wide, 4.75 mm deep at the most: no core 5 mm deep, one 3 mm deep in each strip. In the clay of
// `with_neighbour`'s 40 × 38 mm sherd (x from −40 to 0 mm, y from −38 to 0 mm), which touches it
// along 4 mm of its edge. Truth: 1 the neighbour, 2 the ridged sherd.
PlateScene ridged_sherd(bool with_neighbour) {
  return plate_scene([&](float x, float y) {
    const sherd::Rgb8 clay{180, 120, 80};
    if (with_neighbour && x >= -40 && x <= 0 && y >= -38 && y <= 0) return Cell{1, 5.0f, clay};
    if (x < 0.5f || x > 22.5f || y < -4 || y > 26) return Cell{};
    return Cell{2, x >= 10 && x <= 13 ? 7.0f : 5.0f, clay};
  });
}

// Alone, the ridged sherd stays one sherd: its two strips' shallow cores are one sherd's.
TEST(ShallowCores, ARidgedSherdIsOneSherd) {
  const auto scene = ridged_sherd(false);
  const auto sherds = segment_scene(scene);
  ASSERT_EQ(sherds.size(), 1u);
  EXPECT_EQ(sherds[0].indices.size(),
            static_cast<std::size_t>(std::count(scene.truth.begin(), scene.truth.end(), 2)));
}

// Beside a wider sherd of the same clay, the ridged sherd (the two strips' shallow cores together,
// 660 mm²) is a sherd of its own: without the shallow cores the wider sherd's core takes it all.
TEST(ShallowCores, ARidgedSherdTouchingAWiderOneOfItsClayIsASherdOfItsOwn) {
  expect_two_sherds(ridged_sherd(true), 0.97);
}

// A 30 × 40 mm sherd at 12 mm (x from −30 to 0 mm) and, beside its 40 mm edge, a 14 mm wide band
// (x from 0.5 to 14.5 mm) lower by a step that grows from 3 to 7 mm along that edge: a sherd folded
// over itself (an everted rim seen from above) whose fold hides the wall between its levels. The
// band shows the other skin of the clay, 0.9 × the sherd's (180, 120, 80): the same hue. Its step
// varies more than the levels' tests allow (q90 / q10 about 1.9), and it is higher than the
// clustering distance. The arguments set how far the sherd and the band reach along y, and how
// much the sherd falls per mm away from the band (0: level). Truth: 1 the sherd, 2 the band.
PlateScene sherd_and_folded_band(float sherd_from_y, float sherd_to_y, float band_from_y,
                                 float band_to_y, float sherd_fall = 0.0f) {
  return plate_scene([=](float x, float y) {
    if (x >= -30 && x <= 0 && y >= sherd_from_y && y <= sherd_to_y)
      return Cell{1, 12.0f + sherd_fall * x, {180, 120, 80}};
    if (x < 0.5f || x > 14.5f || y < band_from_y || y > band_to_y) return Cell{};
    const float along = std::clamp((y - sherd_from_y) / (sherd_to_y - sherd_from_y), 0.0f, 1.0f);
    return Cell{2, 12.0f - (3.0f + 4.0f * along), {162, 108, 72}};
  });
}

// Band and sherd side by side along the whole band fill their convex hull together: one sherd.
TEST(Folds, ABandAlongTheWholeSherdOfItsClayIsPartOfIt) {
  expect_one_sherd(sherd_and_folded_band(-20, 20, -20, 20));
}

// The same band 76 mm long beside a 40 mm sherd (y from −38 mm), reaching 36 mm past its end:
// together they cover about 0.8 of their convex hull (2,264 of 2,833 mm², by hand; 0.8155 by the
// voxels' cells), as a narrow sherd lying against another does. Two sherds, though the sherd lies
// level a foot's height above the band as a ring foot's sole does: that rule wants 0.82.
TEST(Folds, ABandReachingFarPastTheSherdStaysApart) {
  expect_two_sherds(sherd_and_folded_band(-38, 2, -38, 38), 1.0);
}

// A ring-footed base lying upside down, as a level sole beside a band a foot's height (3–7 mm)
// lower that reaches 24 mm past it: together they cover about 0.84 of their convex hull (2,096 of
// 2,482 mm², by hand), under the fold's 0.875, over the sole's 0.82. One sherd.
TEST(Folds, ALevelSoleBesideABandAFootLowerIsOneSherd) {
  expect_one_sherd(sherd_and_folded_band(-38, 2, -38, 26));
}

// The same scene with the sherd falling 0.3 mm per mm away from the band (17°): within 4.5 mm of
// the band its heights spread over 1.35 mm, an interquartile range of about 0.68 mm, no sole's.
// A sherd lying tilted beside another: two sherds.
TEST(Folds, ATiltedSherdBesideTheSameBandStaysApart) {
  expect_two_sherds(sherd_and_folded_band(-38, 2, -38, 26, 0.3f), 1.0);
}

// Two sherds at 5 mm side by side, 40 × 40 mm and 28 × 40 mm, along a 40 mm contact, far wider
// than the erosion cuts (one core over both). Sherd 1's clay (180, 120, 80), hue (g/r, b/r)
// (0.667, 0.444); sherd 2's (170, 121, 82), hue (0.712, 0.482): 0.056 along sherd 1's
// clay-to-grey line and 0.019 across it (computed by hand), as the second clays of
// bench_segmentation's trays 34, 38, 54, 77. Too far across the line for a fracture face of
// sherd 1: two sherds. (The earlier rule, one clay within 0.03 of the other's line, left one.)
TEST(TwoClays, TwoSherdsAlongAWideContactAreSplitByClay) {
  // The cut follows the contact to within one voxel (0.83 mm): up to 40 × 0.83 mm² of the
  // other's 1120 mm², 3 %.
  expect_two_sherds(plate_scene([&](float x, float y) {
                      if (std::abs(y) > 20 || x < -40 || x > 28) return Cell{};
                      return x <= 0 ? Cell{1, 5.0f, {180, 120, 80}} : Cell{2, 5.0f, {170, 121, 82}};
                    }),
                    0.97);
}

// A clay sherd against a blue object along a wide contact: the blue's hue (g/r, b/r) is
// (20, 100) against the clay's (0.67, 0.44), far beyond the hue histogram's bounded span
// (kHueMaxBins). Its voxels still go with the histogram peak nearest them, which is no face of
// the clay: two sherds.
TEST(TwoClays, ASherdAndABlueObjectTouchingAreTwo) {
  const PlateScene scene = plate_scene([&](float x, float y) {
    if (std::abs(y) > 20 || x < -40 || x > 28) return Cell{};
    return x <= 0 ? Cell{1, 5.0f, {180, 120, 80}} : Cell{2, 5.0f, {2, 40, 200}};
  });
  expect_two_sherds(scene, 0.97);
}

// PNG header: width and height are the big-endian words at bytes 16 and 20.
std::pair<int, int> png_size(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  unsigned char h[24] = {};
  in.read(reinterpret_cast<char*>(h), sizeof h);
  auto word = [&](int at) { return h[at] << 24 | h[at + 1] << 16 | h[at + 2] << 8 | h[at + 3]; };
  return {word(16), word(20)};
}

TEST(SegmentationOverview, TopViewAtFourPixelsPerMillimetre) {
  // One 40 × 20 mm patch: the view spans it plus 10 mm each side, 60 × 40 mm at 4 px/mm.
  seg::Result result;
  sherd::Mesh mesh;
  seg::Part part;
  part.id = "s01";
  for (int y = 0; y <= 40; ++y) {
    for (int x = 0; x <= 80; ++x) {
      part.indices.push_back(static_cast<std::uint32_t>(mesh.vertices.points.size()));
      mesh.vertices.points.emplace_back(0.5f * x, 0.5f * y, 5.0f);
    }
  }
  result.sherds.push_back(part);
  const auto file = std::filesystem::temp_directory_path() / "sherd_overview_test.png";
  seg::write_overview_png(mesh, result, file);
  EXPECT_EQ(png_size(file), std::make_pair(240, 160));
  std::filesystem::remove(file);
}

}  // namespace
