#include "processing/segmentation/clay_split.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>

#include "processing/segmentation/clay.h"
#include "processing/segmentation/contacts.h"

namespace sherd::segmentation::detail {

namespace {

// A piece that the colour split cut off from a part — a lobe or a level of one sherd that the
// watershed handed to the sherd it touches — joins the rest of its sherd: the part it borders
// most in 3-D (neighbour pairs), when that is no other piece of the same split, the border has
// kPieceMinPairsPerVoxel pairs per voxel of the piece or more (not a corner), and the two show one
// clay (of_one_clay: hues closer than kNoNeckMaxHueDifference, or one the other's fracture face,
// no wider than a face and within kPieceMaxOffClayLine of its clay's line).
// Measured on bench_segmentation (a debug build printing every piece with the parts it borders and
// their truth, 26 runs: 1, 1001, 5001, …, 15001 and 133001, …, 167001): of the pieces whose
// longest border was with another part, the two of that part's sherd lay 0.0001 and 0.0003 off
// its clay's line (tray 159041: a sherd left split), with 0.29 and 0.79 pairs per voxel; another
// sherd's 0.0079 off, and two sherds touching at a corner 0.0034 and 0.0041 off with 0.001 and
// 0.009 pairs per voxel. A first draft judged by the line alone merged tray 239054's sherds: a
// whole sherd cut from the one it had been merged with, 0.0015 off the line of a third sherd it
// bordered, both wider than a face. With of_one_clay, over 74 runs (those 26, 169001, …, 239001
// and 241001, …, 263001, never run before): 4 trays made right (159041, 189044, 231039, 247002),
// none wrong.
constexpr double kPieceMaxOffClayLine = 0.005;
constexpr double kPieceMinPairsPerVoxel = 0.1;

// A fracture face strip of one sherd that the watershed handed to the sherd it touches (a level
// behind a step, reached through the contact before its own sherd) goes back to its sherd by
// colour. In each part, a connected region of voxels that is no face of the part's clay (its
// largest hue peak, see face_offset_of), covers kWallPartMinMm2 and is greyer than that clay (or
// far off it, see below) goes to the part, bordering it in the top view, of whose clay it is a
// face (the nearest to that clay's line). Only greyer regions, or regions far off the part's clay
// (kFarFromClayHue): a fracture face is greyer than the clays around it, and a small sherd's own
// hue scatters beyond kSameHue the other way (tray 5093 of seed 5001 lost a piece of its sherd to a
// neighbour that way). Measured on bench_segmentation (100 trays each, seeds 1 / 1001 / 5001 /
// 7001), split sherds 5 / 6 / 10 / 10 → 3 / 4 / 8 / 5 (trays 2 and 97 of seed 1), merged 0 / 0 / 1
// / 0 unchanged; exact count 98 / 99 / 93 / 97 % unchanged; the least precision of seed 1 0.989 →
// 0.995.
// The region's hue is that of its colour sum; where that is no face of a clay beside it, the hue
// of the region's inside (its voxels whose neighbours in the part all lie in the region) decides.
// The region is found by neighbourhood hues, so it takes in a band of the part's own voxels along
// its border, whose neighbourhoods straddle the crease; their colours pull the sum towards the
// part's clay. With a debug build: two sherds' fracture faces left in a neighbour's part (trays
// 215016, 225054) had sums 0.019 and 0.017 off their clay's line (faces: within kFaceMaxAcross),
// insides 0.004 and 0.002. The sum is kept first: the voxels' median hue instead, in every rule
// below, made 11 trays right and 21 wrong over 80 runs — single voxels' hues scatter, and where
// the sum had moved a region rightly the median lay off the line. Over the 80 runs of 100 trays
// (1, 1001, 5001, …, 15001; 133001, …, 275001), against the sum alone in the same session: 8 trays
// made right (167002, 201051, 215016, 225054, 233051, 267002, 269016, 273030), one wrong (237008:
// a sherd's strip went back to it and took 13 % of the neighbour along); split sherds 93 → 87,
// merged 69 → 68. Four runs never run before (289001, …, 295001): one made right (293031), one
// wrong (293037, a region whose inside held 7 voxels).
// A region kFarFromClayHue or more off the part's clay is no scatter of it, greyer or not: it is
// the other sherd's surface, or its fracture face beside a clay greyer than its own. The contact
// split hands such a strip (a level behind a step, a narrow lobe without a core) to a touching
// sherd when the watershed reaches it through the contact before its own sherd does, or when it
// has a small core of its own whose part borders the touching sherd most. Measured with
// a debug build on 26 runs (1, 1001, 5001, …, 15001 and 133001, 135001, …, 167001) before the
// change: of 66 regions held back only by the greyer test, the 57 of the sherd they were to go to
// lay 0.018–0.24 off the part's clay (42 of them 0.05 or more), the 8 of the part's own sherd
// 0.009–0.047, one of a third sherd 0.020.
// With the bound at 0.05 (and at 0.035 alike) 14 trays became right and none wrong; split sherds
// 48 → 32, merged 26 and the exact counts unchanged.
// Where the two sherds' clays lie so close that the strip is a face of both (tray 74 of seed 1:
// clays 0.016 apart, the strip 0.004 off either's line), contact decides: a region of the part's
// own faces (greyer than its clay beyond kSameHue) goes to another part of whose clay it is a
// face too when it has more 3-D neighbour pairs with that part than with the rest of its own (tray
// 74's strip: 772 against 563). Measured (100 trays each, seeds 1 / 1001 / 5001 / 7001 and the
// held-out 9001 / 11001): 74 no longer split, counts otherwise unchanged; 14 trays gained
// 0.15–0.4 % of precision and recall, one (11010) lost 0.17 %.
// Last, a region off the part's clay (beyond kSameHue, face or not) of kWallPartMinMm2 or more goes
// to another part when, together: it lies along that part in the top view more than along the
// rest of its own (more of its voxels have a top-view neighbour there); its hue lies nearer that
// part's clay or line to grey than its own part's (face_offset_of); and it is hardly joined to
// the rest of its own part in 3-D, fewer than kRegionMaxPairsPerVoxel neighbour pairs with it per
// voxel of the region. So go back a piece of a sherd that the watershed handed to its neighbour
// through a corner (a raised edge behind an unseen wall) and a sherd's fracture face band that the
// erosion left a core of its own, cut off from the sherd's surface by a step. A sherd's own face
// strip between its surface and a touching sherd lies along both about equally in the top view,
// along a crease of its surface in 3-D, and nearer its own clay's line. Measured on
// bench_segmentation (seeds 1, 1001, 5001, …, 51001, 100 trays each; every region so moved in the
// trays it made right or wrong, with a debug build, before either test): the 28 regions rightly
// moved had 0.02–1.8 pairs per voxel (but a 57-voxel rest of one, 3.0) and, but for two (trays
// 41074, 45050), a hue nearer the part they went to; of the 20 wrongly moved, 14 had 1.96–4.5
// pairs per voxel and 5 of the other 6 a hue nearer their own part's line (43027's still goes).
// Where the hue cannot tell — the region a face of neither clay (face_offset_of infinite for
// both) — the top view decides alone, when the region lies along the other part kTopViewDecides ×
// as much as along the rest of its own, or more. So goes back a sherd's fracture face that the
// watershed left in the neighbour it touches, hanging under the sherd's edge with a gap in 3-D
// where the crease was not seen: it lies along its sherd's outline for its whole length, along
// the neighbour only where it touches it. Measured with a debug build on the trays of 74 runs
// (1, 1001, 5001, …, 15001 and 133001, 135001, …, 263001) that left a piece of one sherd in
// another: of the 40 pieces this test sees, 15 were held by the 3-D pairs; 5 others lay along
// their own sherd 1.95–8.3 × as much as along their part but were held by the hue, a face of
// neither clay. Another 4 were within 0.008 of both clays' lines, 1.1–7.7 ×; letting the top view
// decide those as well moved the two halves of a sherd into each other (241089: two parts of one
// sherd, clays 0.037 apart, each region within 0.0014 of both lines).
// Over those 74 runs: 5 trays made right (13099, 163008, 179051, 225034, 249030), none wrong; of
// the 39 trays changed, 38 gained 0.1–0.7 % of precision and recall, one (137014) lost 0.02 %. On
// six runs never run before (265001, …, 275001): no count changed, two trays gained 0.1 %.
// The contact rule (tray 74's strip, above) also moved a sherd's own face strip into the sherd it
// touches, where the two clays' lines to grey lie close (within 0.012) and the strip touches the
// other sherd more in 3-D than its own, whose crease above it is not seen. Which sherd's face a
// strip is, the slope tells: a fracture face falls away from its sherd's surface, so the part
// uphill of it (uphill_parts) is its own sherd. So the strip goes only when enough of it has the
// other part uphill, at first 0.1 of its voxels. Measured with a debug build on the 83 trays of the
// 80 runs (1, 1001, 5001, …, 15001; 133001, …, 275001) where the rule moved a region: the 72
// regions moved rightly had 0.047 (one, 64 voxels of tray 193022), then 0.15–0.98 of their voxels
// with the other part uphill (all but six 0.35 or more); of the 9 moved wrongly, whole of their own
// sherd, six had 0–0.07 (135057, 145025, 211071, 229024, 229045, 229088: five of them left their
// sherd split), three 0.29–0.44.
// Read over the whole strip, that share moved a strip of the part's own sherd barely joined to it
// in 3-D (5 and 9 neighbour pairs) whose far end lay below the other part (0.106 and 0.130 of it;
// trays 165013, 1067013: split). So the share is read on the piece of the strip that hangs from
// the other part (pieces_hanging_from_others): where a strip is that part's face, that piece falls
// away from it. Measured with a debug build over 96 runs (the 80 above and 961001, 963001, …,
// 991001): of the 40 regions moved rightly between two sherds' parts, the piece hanging from the
// part they went to had 0.43–1.0 of its voxels with that part uphill (all but one 0.56 or more);
// of the 3 moved wrongly, each all of its own part's sherd, 0.13 and 0.20 (165013, 171079) and
// 0.88 (253051).
// The rest of the region, hanging from the part itself, goes along only when it has the other part
// uphill on that share of its voxels too. Where two sherds' faces meet as one region on both clays'
// lines (tray 153054: 350 voxels, 192 of the part's own sherd), the piece hanging from the other
// part is that part's face and the rest is the part's own (0.22 of it with the other part uphill).
// Of the 38 moves that the last round's debug build printed with their pieces, the rests of the
// regions moved rightly between two sherds' parts had 0.36–1.0 of their voxels with the other
// part uphill, but for two small regions (989091, 143032: 57 and 70 voxels, 0.17 and 0.15) whose
// rests hold their own part's sherd about half. The other rests now held back had 0.16–0.22 and
// were mostly of their own part's sherd: 153054's, 22 of 25 voxels in 979057, and all of 253051's
// strip, moved wrongly.
constexpr double kFaceMinUphillShare = 0.3;
constexpr double kRegionMaxPairsPerVoxel = 1.9;
constexpr double kTopViewDecides = 1.5;
constexpr float kFarFromClayHue = 0.05f;

// A surface seen from above has its material below it: on a slope, on the uphill side. A steep
// strip of a part with its own part downhill and another part uphill is either the part's surface
// rising to its edge or the other part's fracture face falling away from it, which the watershed
// reached through the contact before its own sherd (the crease at the face's top is not seen, so
// 3-D leaves a gap there). The strip goes to the other part when it is greyer than its part's clay
// by kSlopeFaceMinGreyer or more (no scatter of that clay), a face of the other's clay, and within
// the clustering distance of the other part for kSlopeFaceMinNearShare of its voxels or more — or,
// where a gap in 3-D runs all along it (its whole top edge unseen), when it lies nearer the other
// clay's line than its own part's. The hue alone cannot place such a strip when it lies on both
// clays' lines to grey (the rules above leave it; the top view moved a sherd's own halves into each
// other, 241089).
// Measured on the voxels of bench trays (the 177 trays of 86 runs left with a sherd merged or
// split at 5a60ffd, and the 100 of run 1001; strips of 40 voxels or more, 2.5 mm or less from the
// part uphill at their 10th percentile): of the 30 strips of the uphill part's sherd, 26 pass the
// colour tests, 4 do not; of the 13 of their own part's sherd, none passes (they lie within
// 0.01 of their part's clay, or are less grey); of the 9 holding both, one. Over the 80 runs of
// 100 trays (1, 1001, 5001, …, 15001; 133001, …, 275001), against the binary before in the same
// session: 7 trays made right (135007, 139033, 147039, 175085, 213014, 219097, 249025), none wrong;
// split sherds 86 → 79, merged 68; 120 trays gained precision or recall, 7 lost (up to 0.8 %, in
// 205052, a tray already failing). Eight runs never run before (321001, …, 335001): no count
// changed, 12 trays gained precision or recall, none lost. The 1 M-point tray (ten rounds taking
// turns): fastest 534 ms before, 554 ms after.
// The gap: with a debug build on 44 of those 80 runs, of the strips passing the colour tests but
// held back by the near share, 14 were of the uphill part's sherd (each a piece of a sherd left in
// its neighbour, 62–205 voxels) and 7 of their own part's (59–105 voxels). Dropping the near share
// moved them all: of the trays checked one by one, 11074, 165091 and 173008 came right, 137032 and
// 173061 lost 0.24 and 0.29 % of precision, and two trays of the suite failed; the hue lets 8 of
// the 14 go (0.0002–0.0027 off the other's line, 0.0025 or more or no face off their part's) and
// one of the 7 (137009: 0.0005 against 0.0011). Over the 80 runs, against the binary before in the
// same session: 6 trays made right (165091, 173008, 187094, 215066, 241021, 257048), none wrong;
// split sherds 61 → 55, merged 52; 18 trays gained precision or recall, 2 lost (137009 0.44 %,
// 275042 0.25 %). 16 runs never run before (609001, …, 639001): 5 trays made right, none wrong; 8
// gained, one lost 0.28 %.
constexpr double kSteepSlope = 0.6;        // height per run, ≈ 31°
constexpr double kSlopeRadiusMm = 1.5;     // plane fit, in the top view
constexpr double kSlopeMaxHeightMm = 6.0;  // of the part's voxels in the plane fit
constexpr double kSideRadiusMm = 6.0;      // the parts uphill and downhill of a voxel
constexpr float kSlopeFaceMinGreyer = 0.04f;
constexpr double kSlopeFaceMinNearShare = 0.1;

// For each voxel (−1 for those not in `top`): the part of `top` whose voxels within kSideRadiusMm
// lie uphill of it on average, the nearest such, when the voxel lies on a slope of kSteepSlope
// or more and its own part lies downhill of it; −1 otherwise.
std::vector<int> uphill_parts(TopView& top, const std::vector<Vec3f>& centres) {
  // The parts in each kSideRadiusMm square of the top view: only voxels with another part in the
  // squares around theirs are searched (most of a part lies farther from any other).
  auto cell_of = [](const Vec3f& c, int dx, int dy) {
    return (static_cast<std::int64_t>(std::floor(c.x() / kSideRadiusMm)) + dx) * 1000003 +
           static_cast<std::int64_t>(std::floor(c.y() / kSideRadiusMm)) + dy;
  };
  std::unordered_map<std::int64_t, std::vector<int>> parts_in;
  for (auto v : top.voxel_at) add_once(parts_in[cell_of(centres[v], 0, 0)], top.part_of[v]);
  std::vector<int> uphill(centres.size(), -1), found;
  // Per part within kSideRadiusMm (a few): its voxels' summed offsets downhill and its nearest
  // voxel's squared top-view distance.
  struct Side {
    int part;
    double offsets, nearest;
  };
  std::vector<Side> sides;
  for (auto v : top.voxel_at) {
    const int p = top.part_of[v];
    const Vec3f& c = centres[v];
    bool other = false;
    for (int dx = -1; dx <= 1 && !other; ++dx) {
      for (int dy = -1; dy <= 1 && !other; ++dy) {
        const auto at = parts_in.find(cell_of(c, dx, dy));
        if (at != parts_in.end())
          other = std::any_of(at->second.begin(), at->second.end(), [&](int q) { return q != p; });
      }
    }
    if (!other) continue;
    top.search(c, kSlopeRadiusMm, found);
    // z = a x + b y + h over the part's voxels close by, relative to this one.
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int fitted = 0;
    for (auto f : found) {
      const auto n = top.voxel_at[f];
      if (top.part_of[n] != p) continue;
      const Vec3f d = centres[n] - c;
      if (std::abs(d.z()) > kSlopeMaxHeightMm) continue;
      const Eigen::Vector3d row(d.x(), d.y(), 1.0);
      normal += row * row.transpose();
      rhs += row * d.z();
      ++fitted;
    }
    if (fitted < 5) continue;
    const Eigen::Vector2d gradient = normal.ldlt().solve(rhs).head<2>();
    if (!gradient.allFinite() || gradient.norm() < kSteepSlope) continue;
    const Eigen::Vector2d downhill = -gradient.normalized();
    top.search(c, kSideRadiusMm, found);  // only on slopes: most voxels lie on flatter surface
    sides.clear();
    for (auto f : found) {
      const auto n = top.voxel_at[f];
      const int q = top.part_of[n];
      const Eigen::Vector2d d = (centres[n] - c).head<2>().cast<double>();
      auto at =
          std::find_if(sides.begin(), sides.end(), [&](const Side& s) { return s.part == q; });
      if (at == sides.end()) at = sides.insert(at, {q, 0.0, d.squaredNorm()});
      at->offsets += d.dot(downhill);
      at->nearest = std::min(at->nearest, d.squaredNorm());
    }
    const auto own =
        std::find_if(sides.begin(), sides.end(), [&](const Side& s) { return s.part == p; });
    if (own == sides.end() || own->offsets <= 0.0) continue;
    double best = std::numeric_limits<double>::infinity();
    for (const Side& s : sides) {
      if (s.part != p && s.offsets < 0.0 && s.nearest < best) uphill[v] = s.part, best = s.nearest;
    }
  }
  return uphill;
}

// The part of each voxel of `parts`, -1 for the other voxels.
std::vector<int> part_index(const std::vector<std::vector<std::uint32_t>>& parts,
                            std::size_t n_voxels) {
  std::vector<int> part_of(n_voxels, -1);
  for (std::size_t p = 0; p < parts.size(); ++p) {
    for (auto v : parts[p]) part_of[v] = static_cast<int>(p);
  }
  return part_of;
}

// The part other than `own` with which `voxels` share the most neighbour pairs, and how many
// (-1 and 0 when they touch none).
std::pair<int, std::size_t> most_touched_part(const std::vector<std::uint32_t>& voxels, int own,
                                              const std::vector<int>& part_of, const Graph& near) {
  std::map<int, std::size_t> pairs;
  for (auto v : voxels) {
    for (auto n : near[v]) {
      if (part_of[n] >= 0 && part_of[n] != own) ++pairs[part_of[n]];
    }
  }
  const auto most = std::max_element(
      pairs.begin(), pairs.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  if (most == pairs.end()) return {-1, 0};
  return {most->first, most->second};
}

// `parts` with each voxel v where moved_to[v] >= 0 moved to that part, the emptied parts dropped.
std::vector<std::vector<std::uint32_t>> with_moved(
    const std::vector<std::vector<std::uint32_t>>& parts, const std::vector<int>& moved_to) {
  std::vector<std::vector<std::uint32_t>> result(parts.size());
  for (std::size_t p = 0; p < parts.size(); ++p) {
    for (auto v : parts[p]) result[moved_to[v] >= 0 ? moved_to[v] : p].push_back(v);
  }
  std::erase_if(result, [](const auto& r) { return r.empty(); });
  return result;
}

}  // namespace

std::vector<std::vector<std::uint32_t>> split_by_clay(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf, std::vector<float>& distance, std::vector<int>& tag,
    std::vector<int>& split_from) {
  const auto min_group = static_cast<std::size_t>(kClayMinMm2 / (leaf * leaf));
  std::vector<std::vector<std::uint32_t>> result;
  split_from.clear();
  std::vector<std::uint8_t> mark(near.size(), 0);
  for (std::size_t index = 0; index < parts.size(); ++index) {
    auto& part = parts[index];
    if (part.size() < 2 * min_group) {
      result.push_back(std::move(part));
      split_from.push_back(-1);
      continue;
    }
    const std::vector<Eigen::Vector2f> h = neighbourhood_hues(part, near, voxel_rgb, mark);
    std::vector<int> clay_of;
    const int clays = clays_of(h, part, near, centres, radius, voxel_rgb, min_group, clay_of);
    std::vector<std::pair<std::uint32_t, int>> seeds;
    int seeded = 0;
    for (int g = 0; g < clays && clays > 1; ++g) {
      for (std::size_t k = 0; k < h.size(); ++k) mark[part[k]] = clay_of[k] == g;
      std::vector<std::uint32_t> largest;
      for (auto& region : components(near, part, mark)) {
        if (region.size() > largest.size()) largest = std::move(region);
      }
      if (largest.size() < min_group) continue;
      for (auto v : largest) seeds.emplace_back(v, seeded);
      ++seeded;
    }
    for (auto v : part) mark[v] = 0;
    if (seeded < 2) {
      result.push_back(std::move(part));
      split_from.push_back(-1);
      continue;
    }
    geodesic_from(near, centres, part, seeds, distance, tag, mark);
    // A part can lie apart in 3-D (two levels joined across their unseen wall): what no seed
    // reaches is a piece of its own.
    std::vector<std::vector<std::uint32_t>> pieces(seeded + 1);
    for (auto v : part) pieces[tag[v] >= 0 ? tag[v] : seeded].push_back(v);
    if (pieces.back().empty()) pieces.pop_back();
    for (auto& piece : pieces) {
      result.push_back(std::move(piece));
      split_from.push_back(static_cast<int>(index));
    }
  }
  return result;
}

std::vector<std::vector<std::uint32_t>> pieces_to_their_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<int>& split_from,
    const Graph& near, const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb,
    double radius) {
  const std::vector<int> part_of = part_index(parts, near.size());
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  Groups group(static_cast<int>(parts.size()));
  std::vector<std::uint8_t> inside(near.size(), 0);
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (split_from[p] < 0) continue;
    const auto [q, pairs] = most_touched_part(parts[p], static_cast<int>(p), part_of, near);
    if (q < 0) continue;
    if (split_from[q] == split_from[p] ||
        static_cast<double>(pairs) < kPieceMinPairsPerVoxel * parts[p].size())
      continue;
    if (of_one_clay(colour[p], width_of(near, centres, parts[p], radius, inside), colour[q],
                    width_of(near, centres, parts[q], radius, inside), kNoNeckMaxHueDifference,
                    kPieceMaxOffClayLine))
      group.join(static_cast<int>(p), q);
  }
  return with_joined(std::move(parts), group);
}

// A part can hold pieces apart in 3-D: the watershed cuts along the top view, the joins across
// unseen walls, of levels and of folds join parts that only meet in the top view, and the face
// rules move regions along it. A piece (a 3-D component of its part, not the largest, of
// kDetachedMinMm2 or more) that shares kDetachedMinPairsPerVoxel neighbour pairs per voxel or more
// with one other part may be that part's: a sherd's fracture face strip, greyer than its surface
// and so nearer the line of the neighbour's clay, left in that neighbour (seed 231001's tray
// 231005: a face part of 487 voxels joined across a step, 1,445 neighbour pairs with its own
// sherd's part and none with the one it joined). Or it is its own part's, leaning on the
// neighbour, and colour cannot tell: the two clays' lines to grey often lie close. A face strip
// hangs from its sherd's surface, so where it meets that sherd, the sherd lies higher; a piece
// leaning on a neighbour meets it at its foot. So the piece goes when the other part's voxels
// touching it lie higher on average than its own voxels touching that part, or when it is of one
// clay with that part (of_one_clay, as for the pieces above) and its hue lies nearer that part's
// clay line than the rest of its own part's (face_offset_of).
// Measured with a debug build on the final parts of the 80 runs (1, 1001, 5001, …, 15001; 133001,
// …, 275001; 497d495's logic), pieces of 50 voxels or more with 2 pairs per voxel or more with one
// part: of the 17 of their own part's sherd, every one meets that part lower (0.15–3.2 mm on
// average), and the 2 of one clay with it (137009, 137096) lie nearer their own part's line; of
// the 39 of that part's sherd, 29 meet it higher and 3 more are of one clay with it and nearer its
// line. The 7 held back meet it 0.23–1.9 mm lower, and none lies nearer its line than its own
// part's.
constexpr double kDetachedMinMm2 = 35.0;
constexpr double kDetachedMinPairsPerVoxel = 2.0;

std::vector<std::vector<std::uint32_t>> detached_pieces_to_their_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf) {
  const auto min_piece = static_cast<std::size_t>(kDetachedMinMm2 / (leaf * leaf));
  const std::vector<int> part_of = part_index(parts, near.size());
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  std::vector<int> moved_to(near.size(), -1);
  std::vector<std::uint8_t> mark(near.size(), 0);
  // Whether part q's voxels touching `piece` lie higher on average than the piece's touching q.
  std::vector<std::uint8_t> counted(near.size(), 0);
  auto hangs_from = [&](const std::vector<std::uint32_t>& piece, int q) {
    double piece_z = 0.0, q_z = 0.0;
    std::size_t n_piece = 0, n_q = 0;
    for (auto v : piece) {
      bool touches = false;
      for (auto n : near[v]) {
        if (part_of[n] != q) continue;
        touches = true;
        if (counted[n] == 0) counted[n] = 1, q_z += centres[n].z(), ++n_q;
      }
      if (touches) piece_z += centres[v].z(), ++n_piece;
    }
    for (auto v : piece) {
      for (auto n : near[v]) counted[n] = 0;
    }
    return q_z / static_cast<double>(n_q) > piece_z / static_cast<double>(n_piece);
  };
  for (std::size_t p = 0; p < parts.size(); ++p) {
    for (auto v : parts[p]) mark[v] = 1;
    auto pieces = components(near, parts[p], mark);
    for (auto v : parts[p]) mark[v] = 0;
    if (pieces.size() < 2) continue;
    const auto largest =
        std::max_element(pieces.begin(), pieces.end(),
                         [](const auto& a, const auto& b) { return a.size() < b.size(); }) -
        pieces.begin();
    for (std::size_t k = 0; k < pieces.size(); ++k) {
      const auto& piece = pieces[k];
      if (static_cast<std::ptrdiff_t>(k) == largest || piece.size() < min_piece) continue;
      const auto [q, pairs] = most_touched_part(piece, static_cast<int>(p), part_of, near);
      if (q < 0 || static_cast<double>(pairs) < kDetachedMinPairsPerVoxel * piece.size()) continue;
      Vec3f piece_rgb = Vec3f::Zero();
      for (auto v : piece) piece_rgb += voxel_rgb[v];
      const Eigen::Vector2f h = hue(piece_rgb);
      if (hangs_from(piece, q) ||
          (of_one_clay(piece_rgb, width_of(near, centres, piece, radius, mark), colour[q],
                       width_of(near, centres, parts[q], radius, mark), kNoNeckMaxHueDifference,
                       kPieceMaxOffClayLine) &&
           face_offset_of(hue(colour[q]), h) < face_offset_of(hue(colour[p] - piece_rgb), h))) {
        for (auto v : piece) moved_to[v] = q;
      }
    }
  }
  return with_moved(parts, moved_to);
}

namespace {

struct HangingScratch {
  std::vector<float> distance;
  std::vector<int> tag;
  std::vector<std::uint8_t> inside;
};

// Two sherds touching at their broken edges show both fracture faces there, greyer than either clay
// and joined in 3-D at the contact, their top creases often unseen: the watershed hands both to one
// sherd, and the rule for regions off a part's clay (along_other_part in faces_to_their_clay) sees
// one region, which the part's own face holds by its 3-D pairs with the part. So each voxel of a
// region left there (`region`, flagged in `in_region`, of part p) goes with the part it hangs from
// nearest along the surface — the part of its 3-D neighbours outside the region, p first — and the
// pieces hanging from other parts are returned, by part, to be judged alone, the rest of the region
// counted as the part's. Such a piece goes to the part it hangs from when it is a face of that
// part's clay at all: a face lies on both clays' lines to grey, and which it lies nearer tells
// little (the regions' hue comparison would hold 9 of the 17 that went below). Measured with a
// debug build on the 80 runs of 100 trays (1, 1001, 5001, …, 15001; 133001, …, 275001): of the 19
// trays left split with a piece of a sherd (11–44 % of it) in its neighbour's part, 14 had it in
// such a region, held by its 3-D pairs (10: 2.0–4.9 per voxel) or by the hue (4: 0.85–1.6 pairs per
// voxel, both clays' lines close by). Split so, in 26 trays (those and the ones the split changed),
// 22 of 31 pieces hung from their own sherd's part: 16 went back (0.38–1.88 pairs per voxel;
// 0.0000–0.0128 off that clay's line), 6 stayed (5 at 2.2–3.9 pairs per voxel, one along its part
// in the top view); of the 9 hanging from another sherd's part, 8 are no face of its clay and one
// went (68 voxels of tray 229088). The pieces move only where the steep strips' rule, measured on
// whole regions, moves nothing: before it, 173008's strip, split, stayed half in its neighbour.
// Beside the binary before over the 80 runs: 13 trays made right (7008,
// 11074, 171079, 185053, 187076, 199033, 199069, 229088, 241077, 247079, 253051, 255061, 265065),
// one wrong (137009: the piece went back, and with a bit of its sherd left apart, one clay with the
// neighbour, the detached pieces' rule took 10 % of the sherd over); split sherds 53 → 43, merged
// 45; 90 trays gained precision or recall, 7 lost (137009 0.6 %, the others 0.03–0.23 %). On 16
// runs never run before (833001, 835001, …, 863001): no tray made right or wrong (exact count 1,582
// of 1,600, merged 13, split 8, both); 9 trays gained, one lost (855033, 0.47 %: a piece of its own
// part's sherd went to the part it hangs from, 0.0124 off that clay's line).
// The rule for faces of the part's own clay reads its slope on such a piece (kFaceMinUphillShare).
std::map<int, std::vector<std::uint32_t>> pieces_hanging_from_others(
    const Graph& near, const std::vector<Vec3f>& centres, const std::vector<std::uint32_t>& region,
    int p, const std::vector<int>& part_of, const std::vector<std::uint8_t>& in_region,
    HangingScratch& scratch) {
  std::vector<std::pair<std::uint32_t, int>> hanging;
  for (auto v : region) {
    int from = -1;
    for (auto n : near[v]) {
      const int q = part_of[n];
      if (q >= 0 && !in_region[n] && (from < 0 || q == p)) from = q;
    }
    if (from >= 0) hanging.emplace_back(v, from);
  }
  std::map<int, std::vector<std::uint32_t>> pieces;
  if (std::all_of(hanging.begin(), hanging.end(), [&](const auto& h) { return h.second == p; }))
    return pieces;
  scratch.distance.resize(centres.size()), scratch.tag.resize(centres.size());
  scratch.inside.resize(centres.size(), 0);
  geodesic_from(near, centres, region, hanging, scratch.distance, scratch.tag, scratch.inside);
  for (auto v : region) {
    if (scratch.tag[v] >= 0 && scratch.tag[v] != p) pieces[scratch.tag[v]].push_back(v);
  }
  return pieces;
}

}  // namespace

std::vector<std::vector<std::uint32_t>> faces_to_their_clay(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf) {
  const int n_parts = static_cast<int>(parts.size());
  const auto min_region = static_cast<std::size_t>(kWallPartMinMm2 / (leaf * leaf));
  const auto min_group = static_cast<std::size_t>(kClayMinMm2 / (leaf * leaf));
  std::vector<std::uint8_t> mark(near.size(), 0);
  std::vector<Eigen::Vector2f> clay(n_parts);
  std::vector<std::uint8_t> coloured(n_parts, 0);
  std::vector<std::vector<Eigen::Vector2f>> hues(n_parts);
  for (int p = 0; p < n_parts; ++p) {
    if (parts[p].size() < 2 * min_region) continue;
    hues[p] = neighbourhood_hues(parts[p], near, voxel_rgb, mark);
    std::vector<int> clay_of;
    clays_of(hues[p], parts[p], near, centres, radius, voxel_rgb, min_group, clay_of, &clay[p]);
    coloured[p] = 1;
  }
  TopView top(parts, centres, coloured);
  if (top.empty()) return parts;
  std::vector<int> found;
  std::vector<int> moved_to(centres.size(), -1);
  const std::vector<int> uphill_of = uphill_parts(top, centres);
  // The parts of the pieces split off regions where two faces meet, moved where the steep strips'
  // rule (the last) moves nothing: it was measured on the whole regions.
  std::vector<int> hung_to(centres.size(), -1);
  HangingScratch hanging_scratch;
  auto region_hue = [&](const std::vector<std::uint32_t>& region) {
    Vec3f sum = Vec3f::Zero();
    for (auto v : region) sum += voxel_rgb[v];
    return hue(sum);
  };
  for (int p = 0; p < n_parts; ++p) {
    if (!coloured[p]) continue;
    const auto& part = parts[p];
    for (std::size_t k = 0; k < part.size(); ++k)
      mark[part[k]] = std::isinf(face_offset_of(clay[p], hues[p][k]));
    for (const auto& region : components(near, part, mark)) {
      if (region.size() < min_region) continue;
      std::vector<int> beside;
      for (auto v : region) {
        top.search(centres[v], radius, found);
        for (auto f : found) {
          const int q = top.part_of[top.voxel_at[f]];
          if (q != p) add_once(beside, q);
        }
      }
      // The part beside the region of whose clay hue h is a face, when h is off the part's own.
      auto face_of_beside = [&](const Eigen::Vector2f& h) {
        int best = -1;
        float best_offset = std::numeric_limits<float>::infinity();
        for (int q : beside) {
          const float offset = face_offset_of(clay[q], h);
          if (offset < best_offset) best = q, best_offset = offset;
        }
        const bool off_clay = greyer(h, clay[p]) || (h - clay[p]).norm() >= kFarFromClayHue;
        return off_clay ? best : -1;
      };
      int best = face_of_beside(region_hue(region));
      if (best < 0) {  // the region's inside, without the band that mixes with the rest of the part
        Vec3f inside = Vec3f::Zero();
        std::size_t inside_voxels = 0;
        for (auto v : region) {
          const bool in = std::all_of(near[v].begin(), near[v].end(), [&](std::uint32_t n) {
            return top.part_of[n] != p || mark[n];
          });
          if (in) inside += voxel_rgb[v], ++inside_voxels;
        }
        if (inside_voxels > 0) best = face_of_beside(hue(inside));
      }
      if (best >= 0) {
        for (auto v : region) moved_to[v] = best;
      }
    }
    for (auto v : part) mark[v] = 0;
    // Faces of the part's own clay that touch another part more than the rest of their own, and
    // are a face of that part's clay as well: the two clays lie too close for the hue to tell.
    for (std::size_t k = 0; k < part.size(); ++k) {
      mark[part[k]] = (hues[p][k] - clay[p]).norm() >= kSameHue &&
                      std::isfinite(face_offset_of(clay[p], hues[p][k]));
    }
    for (const auto& region : components(near, part, mark)) {
      if (region.size() < min_region) continue;
      // Neighbour pairs with voxels outside the faces, by their part (−1: an uncoloured one).
      std::map<int, std::size_t> touching;
      for (auto v : region) {
        for (auto n : near[v]) touching[top.part_of[n]] += !mark[n];
      }
      const Eigen::Vector2f h = region_hue(region);
      int best = -1;
      std::size_t most = touching[p];
      for (auto [q, pairs] : touching) {
        if (q >= 0 && q != p && pairs > most && std::isfinite(face_offset_of(clay[q], h)))
          best = q, most = pairs;
      }
      if (best < 0) continue;
      // The slope is read where the region hangs from `best`: away from it, a strip of the part's
      // own sherd may lie on any slope.
      const auto pieces =
          pieces_hanging_from_others(near, centres, region, p, top.part_of, mark, hanging_scratch);
      const auto hanging = pieces.find(best);
      if (hanging == pieces.end()) continue;
      const auto& piece = hanging->second;
      const auto below_best = std::count_if(piece.begin(), piece.end(),
                                            [&](std::uint32_t v) { return uphill_of[v] == best; });
      if (static_cast<double>(below_best) < kFaceMinUphillShare * piece.size()) continue;
      // The rest of the region goes along when it falls away from `best` as well: else it is the
      // part's own face beside the other's (kFaceMinUphillShare).
      for (auto v : piece) moved_to[v] = best;
      std::size_t rest = 0, rest_below = 0;
      for (auto v : region) {
        if (moved_to[v] == best) continue;
        ++rest;
        rest_below += uphill_of[v] == best;
      }
      if (static_cast<double>(rest_below) >= kFaceMinUphillShare * rest) {
        for (auto v : region) moved_to[v] = best;
      }
    }
    for (auto v : part) mark[v] = 0;
    // Regions off the part's clay, not moved above, that lie along another part in the top view
    // more than along the rest of their own and are hardly joined to it in 3-D. `mark` flags the
    // region's voxels; the part it goes to, or −1. A piece hanging from part `hangs_from` goes to
    // it as a face of its clay, however near the part's own clay's line
    // (pieces_hanging_from_others).
    auto along_other_part = [&](const std::vector<std::uint32_t>& region, int hangs_from) {
      std::size_t joined = 0;  // 3-D neighbour pairs with the rest of the part
      for (auto v : region) {
        for (auto n : near[v]) joined += top.part_of[n] == p && !mark[n];
      }
      if (joined >= kRegionMaxPairsPerVoxel * region.size()) return -1;
      // Per part (p: the rest of it), the region's voxels that have a top-view neighbour in it.
      std::map<int, std::size_t> bordering;
      std::vector<int> beside;
      for (auto v : region) {
        top.search(centres[v], radius, found);
        beside.clear();
        for (auto f : found) {
          const auto n = top.voxel_at[f];
          const int q = top.part_of[n];
          if (q != p || !mark[n]) add_once(beside, q);
        }
        for (int q : beside) ++bordering[q];
      }
      const Eigen::Vector2f h = region_hue(region);
      const float own_offset = face_offset_of(clay[p], h);  // infinite when no face of its part
      int best = -1;
      std::size_t most = bordering[p];
      for (auto [q, count] : bordering) {
        if (q == p || count <= most) continue;
        const float offset = face_offset_of(clay[q], h);
        const bool hue_tells = std::isfinite(offset) || std::isfinite(own_offset);
        if (offset < own_offset || (!hue_tells && count >= kTopViewDecides * bordering[p]) ||
            (q == hangs_from && std::isfinite(offset)))
          best = q, most = count;
      }
      return best;
    };
    for (std::size_t k = 0; k < part.size(); ++k)
      mark[part[k]] = (hues[p][k] - clay[p]).norm() >= kSameHue && moved_to[part[k]] < 0;
    for (const auto& region : components(near, part, mark)) {
      if (region.size() < min_region) continue;
      const int best = along_other_part(region, -1);
      if (best >= 0) {
        for (auto v : region) moved_to[v] = best;
        continue;
      }
      // Perhaps two sherds' fracture faces meeting at their contact: its pieces hanging from
      // other parts are judged alone, each against the rest of the region as the part's.
      const auto pieces =
          pieces_hanging_from_others(near, centres, region, p, top.part_of, mark, hanging_scratch);
      for (const auto& [q, piece] : pieces) {
        if (piece.size() < min_region) continue;
        for (auto v : region) mark[v] = 0;
        for (auto v : piece) mark[v] = 1;
        if (along_other_part(piece, q) == q) {
          for (auto v : piece) hung_to[v] = q;
        }
        for (auto v : region) mark[v] = 1;
      }
    }
    for (auto v : part) mark[v] = 0;
    // Steep strips greyer than the part's clay, whose material lies towards another part.
    for (auto v : part) mark[v] = uphill_of[v] >= 0 && moved_to[v] < 0;
    for (const auto& region : components(near, part, mark)) {
      if (region.size() < min_region) continue;
      std::map<int, std::size_t> votes;
      for (auto v : region) ++votes[uphill_of[v]];
      const int q = std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) {
                      return a.second < b.second;
                    })->first;
      std::size_t near_q = 0;  // voxels within the clustering distance of q in 3-D
      for (auto v : region) {
        near_q += std::any_of(near[v].begin(), near[v].end(),
                              [&](std::uint32_t n) { return top.part_of[n] == q; });
      }
      const Eigen::Vector2f h = region_hue(region);
      const float offset_q = face_offset_of(clay[q], h);
      const bool near_in_3d = static_cast<double>(near_q) >= kSlopeFaceMinNearShare * region.size();
      if ((near_in_3d || offset_q < face_offset_of(clay[p], h)) && greyer(h, clay[p]) &&
          (h - clay[p]).norm() >= kSlopeFaceMinGreyer && std::isfinite(offset_q)) {
        for (auto v : region) moved_to[v] = q;
      }
    }
    for (auto v : part) mark[v] = 0;
    for (auto v : part) {
      if (moved_to[v] < 0) moved_to[v] = hung_to[v];
    }
  }
  return with_moved(parts, moved_to);
}

}  // namespace sherd::segmentation::detail
