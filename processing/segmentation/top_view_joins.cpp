#include "processing/segmentation/top_view_joins.h"

#include <boost/geometry/algorithms/append.hpp>
#include <boost/geometry/algorithms/area.hpp>
#include <boost/geometry/algorithms/convex_hull.hpp>
#include <boost/geometry/geometries/multi_point.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/geometry/geometries/polygon.hpp>
#include <boost/geometry/strategies/strategies.hpp>

#include <algorithm>
#include <limits>
#include <map>

#include "processing/segmentation/clay.h"
#include "processing/segmentation/contacts.h"

namespace sherd::segmentation::detail {

namespace {

// How wide `region` is in the top view (mm): its voxels' cells on a grid of side `leaf`, flattened
// onto the plate, and twice the largest distance of a cell from an empty one. The distances are a
// two-pass 3-4 chamfer transform, written out here as neither PCL nor Eigen has a 2-D one.
double top_view_width(const std::vector<std::uint32_t>& region, const std::vector<Vec3f>& centres,
                      double leaf) {
  auto cell = [&](float v) { return static_cast<int>(std::floor(v / leaf)); };
  int i_lo = std::numeric_limits<int>::max(), j_lo = i_lo;
  int i_hi = std::numeric_limits<int>::min(), j_hi = i_hi;
  for (auto v : region) {
    i_lo = std::min(i_lo, cell(centres[v].x())), i_hi = std::max(i_hi, cell(centres[v].x()));
    j_lo = std::min(j_lo, cell(centres[v].y())), j_hi = std::max(j_hi, cell(centres[v].y()));
  }
  // A frame of empty cells around the region, so that the passes need no bounds checks.
  const int w = i_hi - i_lo + 3, h = j_hi - j_lo + 3;
  std::vector<int> distance(static_cast<std::size_t>(w) * h, 0);
  auto at = [&](int i, int j) -> int& { return distance[static_cast<std::size_t>(j) * w + i]; };
  for (auto v : region)
    at(cell(centres[v].x()) - i_lo + 1, cell(centres[v].y()) - j_lo + 1) = w * h * 4;
  for (int j = 1; j < h - 1; ++j) {
    for (int i = 1; i < w - 1; ++i) {
      if (at(i, j) > 0)
        at(i, j) = std::min({at(i, j), at(i - 1, j) + 3, at(i - 1, j - 1) + 4, at(i, j - 1) + 3,
                             at(i + 1, j - 1) + 4});
    }
  }
  int deepest = 0;
  for (int j = h - 2; j >= 1; --j) {
    for (int i = w - 2; i >= 1; --i) {
      if (at(i, j) == 0) continue;
      at(i, j) = std::min({at(i, j), at(i + 1, j) + 3, at(i + 1, j + 1) + 4, at(i, j + 1) + 3,
                           at(i - 1, j + 1) + 4});
      deepest = std::max(deepest, at(i, j));
    }
  }
  return 2.0 * leaf * deepest / 3.0;
}

// A part left narrower than kSherdMinTopViewWidthMm in the top view is no sherd: a sherd lying on
// the plate or leaning on another shows a face wider than that from above. It is a strip of one —
// a fracture face or a band of the surface seen almost edge-on (the raised edge of a leaning
// sherd, the steep side of a deep one) — that the erosion, the colour split or a gap in 3-D cut
// off. It joins the part beside it (in 3-D or in the top view; not itself so narrow) of whose
// clay it is, or of whose clay mixed with grey (a fracture face) it is, within
// kWallMaxOffClayLine (both ways, as in join_across_unseen_walls); of several, the nearest in
// colour. Measured on bench_segmentation, the width as here: the largest parts of 2,726 sherds
// (260 trays of seeds 2001, 3001 and 4001) were 11.1 mm wide or more, 13.3 mm but for two; the
// pieces found as sherds of their own in 60 failing trays of 44 runs (1 / 1001 / … / 87001) were
// 3.9–27 mm wide, 17 of them under 9 mm, each 0.0001–0.0091 off its sherd's line, the other parts
// beside them 0.017 or more off but one (0.0017, tray 51042, against its own sherd's 0.0008). The
// sherds that showed only narrow strips of themselves (trays 79021, 87038: a leaning sherd, a
// sherd under another) bordered parts 0.034 and more off: they stay apart. Over 38 runs (1 /
// 1001 / … / 75001) the exact count 97.24 → 97.82 % (22 trays made right, none wrong); on four
// runs looked at only afterwards (89001 / … / 95001) one tray made right, none wrong.
constexpr double kSherdMinTopViewWidthMm = 9.0;

// A sherd standing steeply on the plate (a deep, narrow piece) shows from above only strips of
// itself far apart in height — its top edge, bands of its faces — each narrower than a sherd, and
// no wide part for join_narrow_parts to join them to. So the narrow parts left alone (`strip`)
// that lie beside each other in the top view (within `radius`) and of one clay, a face or the
// other skin included (off_either_line within kWallMaxOffClayLine), join one another: joins[p]
// set to one strip of each such group. Measured with a debug build on the 80 runs (1, 1001, 5001,
// …, 15001; 133001, …, 275001), pairs of such strips against the truth: 46 pairs in 6 trays, every
// one of one sherd (0.0001–0.0070 off each other's line), strips 1.7–8.3 mm wide (the four sherds
// found split because of them stood 38–50 mm high); no pair of two sherds.
void join_strips_of_one_clay(const std::vector<std::vector<std::uint32_t>>& parts,
                             const std::vector<Vec3f>& centres, const std::vector<Vec3f>& colour,
                             const std::vector<std::uint8_t>& strip, double radius,
                             std::vector<int>& joins) {
  const int n_parts = static_cast<int>(parts.size());
  if (std::count(strip.begin(), strip.end(), 1) < 2) return;
  TopView top(parts, centres, strip);
  Groups group(n_parts);
  std::vector<int> found, beside;
  for (int p = 0; p < n_parts; ++p) {
    if (!strip[p]) continue;
    beside.clear();
    for (auto v : parts[p]) {
      top.search(centres[v], radius, found);
      for (auto f : found) add_once(beside, top.part_of[top.voxel_at[f]]);
    }
    for (int q : beside) {
      if (q > p && off_either_line(colour[p], colour[q]) < kWallMaxOffClayLine) group.join(p, q);
    }
  }
  for (int p = 0; p < n_parts; ++p) {
    if (strip[p] && group.root(p) != p) joins[p] = group.root(p);
  }
}

// The voxels of `judged` in or beside a top-view cell (`radius` wide) that holds a voxel of
// another owner (`owner_of`: a cluster or part per voxel): only they can have one within `radius`
// in the top view, so the radius searches skip the rest.
std::vector<std::uint32_t> beside_other_owners(const std::vector<Vec3f>& centres,
                                               const std::vector<std::uint32_t>& judged,
                                               const std::vector<int>& owner_of, double radius) {
  if (judged.empty()) return {};
  Eigen::Vector2f lo = Eigen::Vector2f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (auto v : judged) {
    lo = lo.cwiseMin(centres[v].head<2>()), hi = hi.cwiseMax(centres[v].head<2>());
  }
  const auto cell = [&](const auto& at, int axis) {
    return static_cast<int>((at[axis] - lo[axis]) / radius);
  };
  const int nx = cell(hi, 0) + 1, ny = cell(hi, 1) + 1;
  constexpr int kEmpty = -1, kSeveral = -2;
  std::vector<int> cell_owner(static_cast<std::size_t>(nx) * ny, kEmpty);
  for (auto v : judged) {
    int& c = cell_owner[static_cast<std::size_t>(cell(centres[v], 1)) * nx + cell(centres[v], 0)];
    c = c == kEmpty || c == owner_of[v] ? owner_of[v] : kSeveral;
  }
  std::vector<std::uint32_t> beside;
  for (auto v : judged) {
    const int i = cell(centres[v], 0), j = cell(centres[v], 1);
    bool other = false;
    for (int b = std::max(0, j - 1); b <= std::min(ny - 1, j + 1) && !other; ++b) {
      for (int a = std::max(0, i - 1); a <= std::min(nx - 1, i + 1) && !other; ++a) {
        const int c = cell_owner[static_cast<std::size_t>(b) * nx + a];
        other = c != kEmpty && c != owner_of[v];
      }
    }
    if (other) beside.push_back(v);
  }
  return beside;
}

// Where parts (of kWallPartMinMm2 or more; smaller ones are crumbs) meet in the top view: per pair
// (a, b), the heights between their voxels within `radius` of each other there (a < b), and a's
// voxels along the border with b; where `under` is given, also the pairs of those voxels where b
// lies above a, apart in 3-D, into it. Only voxels of different owners count: of different
// clusters (`cluster_of`, each voxel's) — apart in 3-D —, or of different parts where that is null.
struct TopViewBorders {
  std::map<std::pair<int, int>, std::vector<float>> steps;
  std::map<std::pair<int, int>, std::size_t> band;
};

TopViewBorders top_view_borders(const std::vector<std::vector<std::uint32_t>>& parts,
                                const std::vector<Vec3f>& centres,
                                const std::vector<int>* cluster_of, double radius, double leaf,
                                std::map<std::pair<int, int>, std::size_t>* under = nullptr) {
  const auto min_voxels = static_cast<std::size_t>(kWallPartMinMm2 / (leaf * leaf));
  std::vector<int> part_of(centres.size(), -1);  // of the parts judged: large enough
  std::vector<std::uint32_t> judged;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (parts[p].size() < min_voxels) continue;
    for (auto v : parts[p]) part_of[v] = static_cast<int>(p), judged.push_back(v);
  }
  const std::vector<int>& owner_of = cluster_of != nullptr ? *cluster_of : part_of;
  const std::vector<std::uint32_t> at_borders =
      beside_other_owners(centres, judged, owner_of, radius);
  TopViewBorders borders;
  if (at_borders.empty()) return borders;
  TopView top(centres, at_borders);
  std::vector<int> found;
  std::vector<int> beside;
  const auto radius2 = static_cast<float>(radius * radius);
  for (auto v : at_borders) {
    const int p = part_of[v];
    top.search(centres[v], radius, found);
    beside.clear();
    for (auto f : found) {
      const auto n = top.voxel_at[f];
      if (owner_of[n] == owner_of[v]) continue;
      const int q = part_of[n];
      add_once(beside, q);
      if (q > p) borders.steps[{p, q}].push_back(std::abs(centres[n].z() - centres[v].z()));
      if (under != nullptr && centres[n].z() > centres[v].z() &&
          (centres[n] - centres[v]).squaredNorm() > radius2)
        ++(*under)[{p, q}];
    }
    for (int q : beside) ++borders.band[{p, q}];
  }
  return borders;
}

// Two parts of different Euclidean clusters that meet in the top view across an even step — the
// wall between one sherd's levels (level_wall) — along a border at least kLevelMinBorderShare of
// the narrower one's top-view width are that sherd's levels when the narrower one is a band no
// wider than kLevelApartMaxWidthMm (a lip, a foot ring, a fracture face) and both show one clay:
// hues closer than kLevelApartMaxHueDifference, or the band greyer and within
// kLevelApartFaceMaxOffClayLine of the other's line to grey (of_one_clay). A step higher than the
// clustering distance leaves such a level a cluster of its own, which levels_of_one_sherd never
// sees. Parts of one cluster are not judged here: the erosion's tests have judged them by their
// cores, and the colour split may have parted them. Measured on bench_segmentation (100 trays
// each of sixteen runs, 1001 / 5001 / … / 61001; part pairs of different clusters passing the
// step and border tests, against the truth): 3 pairs of one sherd (5069, 29088, 49086; and 93009
// of a later run) with a narrower part 9.4–15.6 mm wide, hues 0.0026–0.0032 apart or a face
// 0.0005–0.0016 off its clay's line; 110 pairs of two sherds, touching where one's edge stands
// higher than the other's. Of those, the ones with a narrower part over 16 mm came as close in
// hue as one sherd's levels (25011: 0.0058 apart, 25 and 28 mm wide); the 7 up to 16 mm lay
// 0.038 or more off each other's line. The bounds of the levels inside a cluster (hues 0.03,
// faces 0.02 off) merged three pairs on other runs, bands 13–15 mm wide 0.0082–0.0104 off
// (trays 74, 7045, 23054), hence the tighter ones. The wall's spread (90th / 10th percentile) is
// held to kLevelApartMaxSpread, a little under the levels' inside a cluster (kLevelStepMaxSpread):
// with a debug build on the 80 runs (1, 1001, 5001, …, 15001; 133001, …, 275001; every pair these
// rules joined, against the truth), the 212 pairs of one sherd had spreads of 1.10–1.76 and the one
// pair of two sherds 1.84 (147094: a whole sherd 15.6 mm wide taken for its neighbour's face band).
constexpr double kLevelApartMaxWidthMm = 16.0;
constexpr double kLevelApartMaxHueDifference = 0.01;
constexpr double kLevelApartFaceMaxOffClayLine = 0.004;
constexpr double kLevelApartMaxSpread = 1.8;
// Wider levels join too when their hues agree within kWideLevelApartMaxHueDifference: a sherd
// whose surface falls away so steeply that the scan leaves a gap along the fall. Measured with a
// debug build on the 80 runs (1, 1001, 5001, …, 15001; 133001, …, 275001; part pairs of different
// clusters passing the step and border tests, against the truth): of one sherd, three pairs whose
// narrower part was 18.9–21.7 mm wide, hues 0.0006–0.0025 apart (135040, 253066, 255060); of two
// sherds, 548 pairs, the nearest 0.0064 apart (20 mm wide; 25011, of an earlier run, 0.0058).
// Against the band rule alone, in the same session: over the 80 runs one tray made right (255060:
// one sherd found as two, the recall 0.857), no other tray's figures moved; on four runs never run
// before (313001, …, 319001) none moved.
constexpr double kWideLevelApartMaxHueDifference = 0.004;
// Levels of one clay join as well where the surface bends down across the border, as over
// a carination whose wall the top view does not show, though their hues differ (a skin and a
// greyer one): colours on one clay's line (off_either_line below kBendingLevelApartMaxOffClayLine,
// hues within kBendingLevelApartMaxHueDifference), a step within the bounds of falling levels
// (kFallingLevelStepMaxMm, kFallingLevelStepMaxSpread in contacts.h), the lower level falling
// away across the border (its slope, see slopes_across, kBendingLevelApartMaxLowerSlope or
// steeper) and the upper not rising to it (kBendingLevelApartMaxUpperSlope at most). A sherd
// leaning on another rises to where it rests on it, and the one under it lies flat. Measured with
// a debug build on the 80 runs (1, 1001, 5001, …, 15001; 133001, …, 275001; part pairs of
// different clusters with 100 step pairs or more, against the truth, with both levels' slopes):
// of the pairs not joined by the rules above with parts at least 80 % pure, both 10 mm wide or
// more, within 0.0055 of each other's line, a step within those bounds and a long border, 13 were
// one sherd's and 351 two sherds'. Over all pairs, these bounds join 22 of one sherd (223032,
// 261066 and 269041 were left split) and none of two; the nearest two sherds' pairs were 0.0006
// off with hues 0.018 apart but the upper rising at 0.26 and the lower at −0.19 (217002), 0.0011
// off with hues 0.049 apart (169045), and 0.0026 off (271021, the lower at −0.19). 233069, one
// sherd's levels 0.0004 off, stays split: its lower level runs on flat (−0.04).
constexpr double kBendingLevelApartMaxOffClayLine = 0.001;
constexpr double kBendingLevelApartMaxHueDifference = 0.03;
constexpr double kBendingLevelApartMaxLowerSlope = -0.2;
constexpr double kBendingLevelApartMaxUpperSlope = 0.1;

// A sherd folded over itself — an everted or flanged rim, a carination, seen from above — shows
// two levels: the fold's top hides the wall under it, so they meet in the top view along a step
// and hardly at all in 3-D. Where that step varies more along the border than a level's wall
// (level_wall), or the upper level shows the other skin or a fracture face, every rule above may
// leave them two parts. Two parts side by side in the top view (kLevelMinStepPairs neighbour pairs
// at least) are such a sherd when, together: the narrower is a band no wider than
// kFoldMaxNarrowerWidthMm in the top view (top_view_width: a rim band, a fracture face); their
// border is at least as long as that band is wide (kFoldMinBorderShare, its length as for
// parts_without_neck); their colours lie on one clay's line to grey (off_either_line below
// kFoldMaxOffClayLine: the simulated skins are one clay at two brightnesses, a face that clay
// mixed with grey); and together they cover kFoldMinSolidity of their convex hull in the top view,
// as one sherd's outline does, where a sherd lying against or on another leaves notches where
// their outlines meet. Measured on bench_segmentation, pairs of parts left after the narrow join
// against the truth, in 991 trays (those failing at 92ff4cc in 60 runs, 1 / 1001 / 5001 / … /
// 119001, and all of runs 1 / 1001 / 5001 / … / 15001): 90 pairs of one sherd, 4,135 of two.
// One sherd's parts lay 0–0.0054 off each other's line, half of them covering 0.89 or more of
// their hull; of the two sherds' pairs, 10 % lay within 0.0068 of the line. With bands up to
// 18 mm and 0.87 of the hull, 59 pairs of one sherd and none of two; but over 54 runs (1 / 1001 /
// 5001 / … / 107001) that made 48 trays right and 3 wrong (83088, 85014, 93001: bands of 13–16 mm
// beside a sherd of their clay, covering 0.873–0.877), and on six runs after them (121001 / … /
// 131001) four pairs of one sherd stayed apart with bands 19.4–21.7 mm wide. 20 mm and 0.875 take
// 65 pairs of one sherd and none of two; the nearest pairs of two: bands 18.9 and 20 mm wide
// covering 0.874 and 0.870 (49072, 115014), bands 15.6–17.8 mm covering 0.842–0.854 (101093,
// 89004, 55053: a narrow sherd against or on another), 0.0068 off the line covering 0.888
// (111054). Over the 54 runs the exact count went 97.83 → 98.70 %: 53 trays made right, 6 wrong
// (35057, 67077, 83088, 93001, 95065, 97047: two sherds of one clay joined); on six runs never run
// before (133001 / … / 143001) 96.0 → 97.33 %: 9 made right, none wrong.
constexpr double kFoldMinBorderShare = 1.0;
constexpr double kFoldMaxOffClayLine = 0.005;
constexpr double kFoldMinSolidity = 0.875;
constexpr double kFoldMaxNarrowerWidthMm = 20.0;
// A band wider than kFoldWideBandMm joins only behind a step no higher than a level's wall (90th
// percentile at most kLevelStepMaxMm): a wide band of one sherd is a flange or a foot's sole a few
// mm above the rest, while a sherd as wide lying beside another and on its line to grey meets it
// where one's edge stands higher by its curve. Measured with a debug build on the 80 runs (1,
// 1001, 5001, …, 15001; 133001, …, 275001), the pairs passing every other fold test, against the
// truth: with a band of 17.8–20 mm, 13 pairs of one sherd behind steps of q90 3.0–7.1 mm, and 10
// of two sherds, 9 of them behind 9.0–15.1 mm (one 6.8 mm); with a band up to 17.2 mm, 71 pairs
// of one sherd, behind steps up to 41.5 mm (a narrow band of a steep sherd), and 2 of two.
constexpr double kFoldWideBandMm = 17.5;

// A base sherd with a ring foot lying upside down shows two levels that the hull test can miss
// (its outline notched where foot and body meet): the foot's sole, flat and level, and a foot's
// height (3–7 mm) below it the base inside the ring or the wall falling away outside it. So a pair
// passing the fold tests but the hull's is one sherd, covering kFootMinSolidity of the hull at
// least, when the higher part is level along the border — its heights within kFootSoleBandMm of
// the other part in the top view have an interquartile range of at most kFootSoleMaxIqrMm — and
// the step is no higher than a level's wall (90th percentile at most kLevelStepMaxMm): a sherd
// lying on another is tilted by it. Measured on bench_segmentation, the pairs passing the fold
// tests but the hull's in 44 runs (1 / 1001 / 5001 / … / 51001 and 133001 / … / 167001), against
// the truth: 12 pairs of one sherd covering 0.802–0.873 of their hull had a sole's IQR of
// 0.06–0.30 mm and steps up to 7.81 mm, and every tray holding one has a ring-footed base sherd
// lying upside down (the simulator's truth); of the pairs of two sherds, the levellest were
// 0.08 mm covering 0.774 (31094), 0.25 mm with a 23 mm step (159096: a flat sherd on another)
// and 0.65 mm (137073). The hull bound is 0.82, not lower, for a level sherd with a narrow one
// lying beside it a foot lower and reaching far past it (0.8155 in the Folds tests); it leaves
// two of the twelve pairs apart (41084 at 0.802, 145052 at 0.818).
constexpr double kFootMinSolidity = 0.82;
constexpr double kFootSoleBandMm = 4.5;
constexpr double kFootSoleMaxIqrMm = 0.4;

// How much of their convex hull in the top view two parts cover together: their cells on a grid of
// side `leaf`, flattened onto the plate, against the hull of those cells' corners.
double top_view_solidity(const std::vector<std::uint32_t>& a, const std::vector<std::uint32_t>& b,
                         const std::vector<Vec3f>& centres, double leaf) {
  namespace bg = boost::geometry;
  using Point = bg::model::d2::point_xy<double>;
  std::vector<std::pair<int, int>> cells;
  for (const auto* part : {&a, &b}) {
    for (auto v : *part) {
      cells.emplace_back(static_cast<int>(std::floor(centres[v].x() / leaf)),
                         static_cast<int>(std::floor(centres[v].y() / leaf)));
    }
  }
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  bg::model::multi_point<Point> corners;  // each cell's four corners: the hull covers whole cells
  for (auto [i, j] : cells) {
    for (int di : {0, 1}) {
      for (int dj : {0, 1}) bg::append(corners, Point((i + di) * leaf, (j + dj) * leaf));
    }
  }
  bg::model::polygon<Point> hull;
  bg::convex_hull(corners, hull);
  return static_cast<double>(cells.size()) * leaf * leaf / bg::area(hull);
}

// Whether the higher of parts `a` and `b` is a ring foot's sole beside the other across the
// border step `heights` (reordered; see kFootMinSolidity).
bool ring_foot_sole(const std::vector<std::uint32_t>& a, const std::vector<std::uint32_t>& b,
                    const std::vector<Vec3f>& centres, std::vector<float>& heights) {
  if (quantile_of(heights, 0.9) > kLevelStepMaxMm) return false;
  // Heights of each part's voxels within kFootSoleBandMm of the other in the top view.
  auto near_border = [&](const std::vector<std::uint32_t>& part,
                         const std::vector<std::uint32_t>& other) {
    TopView top(centres, other);
    std::vector<int> found;
    std::vector<float> z;
    for (auto v : part) {
      top.search(centres[v], kFootSoleBandMm, found);
      if (!found.empty()) z.push_back(centres[v].z());
    }
    return z;
  };
  std::vector<float> za = near_border(a, b), zb = near_border(b, a);
  if (za.empty() || zb.empty()) return false;
  std::vector<float>& sole = quantile_of(za, 0.5) >= quantile_of(zb, 0.5) ? za : zb;
  return quantile_of(sole, 0.75) - quantile_of(sole, 0.25) <= kFootSoleMaxIqrMm;
}

}  // namespace

std::vector<std::vector<std::uint32_t>> join_narrow_parts(
    std::vector<std::vector<std::uint32_t>> parts, const Graph& near,
    const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb, double radius,
    double leaf) {
  const int n_parts = static_cast<int>(parts.size());
  const auto min_voxels = static_cast<std::size_t>(kWallPartMinMm2 / (leaf * leaf));
  std::vector<std::uint8_t> narrow(n_parts, 0), wide(n_parts, 0), strip(n_parts, 0);
  for (int p = 0; p < n_parts; ++p) {
    if (parts[p].size() < min_voxels) continue;  // crumbs: the size filter reports them
    narrow[p] = top_view_width(parts[p], centres, leaf) < kSherdMinTopViewWidthMm;
    wide[p] = !narrow[p];
  }
  if (std::find(narrow.begin(), narrow.end(), 1) == narrow.end()) return parts;
  TopView top(parts, centres, wide);  // among the wide parts' voxels
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  std::vector<int> found;
  std::vector<int> joins(n_parts, -1);
  std::vector<int> beside;  // the wide parts a narrow one borders
  for (int p = 0; p < n_parts; ++p) {
    if (!narrow[p] || top.empty()) continue;
    beside.clear();
    for (auto v : parts[p]) {
      for (auto n : near[v]) {
        if (top.part_of[n] >= 0) add_once(beside, top.part_of[n]);
      }
      top.search(centres[v], radius, found);
      for (auto f : found) add_once(beside, top.part_of[top.voxel_at[f]]);
    }
    float best = kWallMaxOffClayLine;
    for (int q : beside) {
      const float off = off_either_line(colour[p], colour[q]);
      if (off < best) best = off, joins[p] = q;
    }
  }
  for (int p = 0; p < n_parts; ++p) strip[p] = narrow[p] && joins[p] < 0;
  join_strips_of_one_clay(parts, centres, colour, strip, radius, joins);
  return with_joined(std::move(parts), joins);
}

std::vector<std::vector<std::uint32_t>> join_levels_across_clusters(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, const std::vector<int>& cluster_of, double radius,
    double leaf) {
  const int n_parts = static_cast<int>(parts.size());
  auto [steps, band] = top_view_borders(parts, centres, &cluster_of, radius, leaf);
  if (steps.empty()) return parts;
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  std::vector<double> width(n_parts, 0.0);
  Groups group(n_parts);
  std::vector<int> tag;  // the two levels' voxels by part, for their slopes; -1 elsewhere
  auto bends_down_across = [&](int a, int b) {
    if (tag.empty()) tag.assign(centres.size(), -1);
    std::vector<std::uint32_t> among = parts[a];
    among.insert(among.end(), parts[b].begin(), parts[b].end());
    for (int p : {a, b}) {
      for (auto v : parts[p]) tag[v] = p;
    }
    TopView top(centres, among);
    const SlopesAcross slopes = slopes_across(top, centres, among, tag, a, b, radius);
    for (auto v : among) tag[v] = -1;
    // Comparisons with NaN are false: a level without a slope shows no bend.
    return slopes.lower <= kBendingLevelApartMaxLowerSlope &&
           slopes.upper <= kBendingLevelApartMaxUpperSlope;
  };
  for (auto& [pair, heights] : steps) {
    const auto [a, b] = pair;
    if (!level_wall(heights, kFallingLevelStepMaxMm, kFallingLevelStepMaxSpread)) continue;
    for (int p : {a, b}) {
      if (width[p] == 0.0) width[p] = top_view_width(parts[p], centres, leaf);
    }
    const double narrower_mm = std::min(width[a], width[b]);
    const double border_mm = border_length_mm(band[{a, b}], band[{b, a}], radius);
    if (border_mm < kLevelMinBorderShare * narrower_mm) continue;
    const bool band = narrower_mm <= kLevelApartMaxWidthMm &&
                      of_one_clay(colour[a], width[a], colour[b], width[b],
                                  kLevelApartMaxHueDifference, kLevelApartFaceMaxOffClayLine);
    const float hue_apart = (hue(colour[a]) - hue(colour[b])).norm();
    const bool one_hue = hue_apart < kWideLevelApartMaxHueDifference;
    if (level_wall(heights, kLevelStepMaxMm, kLevelApartMaxSpread) && (band || one_hue)) {
      group.join(a, b);
      continue;
    }
    const bool one_clay =
        off_either_line(colour[a], colour[b]) < kBendingLevelApartMaxOffClayLine &&
        hue_apart < kBendingLevelApartMaxHueDifference;
    if (one_clay && bends_down_across(a, b)) group.join(a, b);
  }
  return with_joined(std::move(parts), group);
}

std::vector<std::vector<std::uint32_t>> join_folded_parts(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, double radius, double leaf) {
  const int n_parts = static_cast<int>(parts.size());
  auto [steps, band] = top_view_borders(parts, centres, nullptr, radius, leaf);
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  std::vector<double> width(n_parts, 0.0);
  Groups group(n_parts);
  for (auto& [pair, heights] : steps) {
    const auto [a, b] = pair;
    if (heights.size() < kLevelMinStepPairs) continue;
    for (int p : {a, b}) {
      if (width[p] == 0.0) width[p] = top_view_width(parts[p], centres, leaf);
    }
    const double border_mm = border_length_mm(band[{a, b}], band[{b, a}], radius);
    const float off = off_either_line(colour[a], colour[b]);
    const double narrower_mm = std::min(width[a], width[b]);
    if (narrower_mm > kFoldMaxNarrowerWidthMm || border_mm < kFoldMinBorderShare * narrower_mm ||
        off >= kFoldMaxOffClayLine ||
        (narrower_mm > kFoldWideBandMm && quantile_of(heights, 0.9) > kLevelStepMaxMm))
      continue;
    const double solidity = top_view_solidity(parts[a], parts[b], centres, leaf);
    if (solidity >= kFoldMinSolidity ||
        (solidity >= kFootMinSolidity && ring_foot_sole(parts[a], parts[b], centres, heights)))
      group.join(a, b);
  }
  return with_joined(std::move(parts), group);
}

// A sherd leaning on another lies across it; where it covers the middle of a narrow one, the sherd
// under it shows two pieces that meet only under it, or not at all, each at the covering sherd's
// foot: that sherd lies above them across their top-view border, apart in 3-D. No rule above joins
// them. Two parts lying under one part (along kLevelMinStepPairs such pairs, a border and not a
// corner) are one sherd's pieces when they show one hue (closer than kSameHue, one clay's noise)
// on one clay's line (kFoldMaxOffClayLine), the smaller covers less than a sherd's area
// (contact_own_basin_mm2: sherds of one hue lying whole around another are common), and they lie
// under it along borders within kUnderMinBorderRatio of each other: the covering sherd's edge
// cuts both pieces across the sherd's width. Measured with a debug build over the 80 runs and 16
// never run before (1385001 … 1415001), every pair of final parts lying under one part (5 voxels
// or more beside it), against the truth: 11 pairs of one sherd, 10,024 of two. Of one hue and
// line: 5 of one sherd, 85 of two; of those, with the smaller under a sherd's area, 3 of one sherd
// (153023, 1385026, 1409066: pieces of 170–320 mm² beside 213–816 mm², under it along borders
// 0.67–0.86 of each other) and none of two, whose smaller parts covered 459 mm² and more (662
// voxels: 1405077, 1415011, 1415014). Two pairs of one sherd stay apart: 143086 (its smaller
// piece 459 mm²) and 233069 (two large pieces). Over all pairs of one sherd the hues lay
// 0.0007–0.25 apart, so a looser hue takes in more pairs of two sherds (1397084's 0.025 beside
// two pairs of two at 0.021 and 0.028, 0.0026 and 0.0016 off the line, pieces of 389–405 mm²).
// Without the border ratio, on 48 runs never run before (1417001 … 1511001) the rule made 1427098
// right and 1457034 wrong: a whole small sherd (348 mm²) lying under a sherd along 118 voxels,
// beside a larger one of its hue that sherd only reaches (35 voxels, 0.30 of it); with it both
// are right.
constexpr double kUnderMinBorderRatio = 0.5;

std::vector<std::vector<std::uint32_t>> join_pieces_under_one_sherd(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, double radius, double leaf, std::size_t max_piece_voxels) {
  const int n_parts = static_cast<int>(parts.size());
  std::map<std::pair<int, int>, std::size_t> under;  // step pairs, per (lower, upper) part
  top_view_borders(parts, centres, nullptr, radius, leaf, &under);
  // Per part, the parts it lies across, with the step pairs along each one's border with it.
  std::vector<std::vector<std::pair<int, std::size_t>>> lying_under(n_parts);
  for (const auto& [pair, step_pairs] : under) {
    if (step_pairs >= kLevelMinStepPairs)
      lying_under[pair.second].emplace_back(pair.first, step_pairs);
  }
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  Groups group(n_parts);
  for (const auto& pieces : lying_under) {
    for (std::size_t i = 0; i < pieces.size(); ++i) {
      for (std::size_t j = i + 1; j < pieces.size(); ++j) {
        const auto [a, a_pairs] = pieces[i];
        const auto [b, b_pairs] = pieces[j];
        if (std::min(parts[a].size(), parts[b].size()) < max_piece_voxels &&
            std::min(a_pairs, b_pairs) >= kUnderMinBorderRatio * std::max(a_pairs, b_pairs) &&
            (hue(colour[a]) - hue(colour[b])).norm() < kSameHue &&
            off_either_line(colour[a], colour[b]) < kFoldMaxOffClayLine)
          group.join(a, b);
      }
    }
  }
  return with_joined(std::move(parts), group);
}

}  // namespace sherd::segmentation::detail
