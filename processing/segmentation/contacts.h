// Splitting clusters at the contacts of touching sherds (erosion and watershed) and joining the
// pieces of one sherd that lie apart in 3-D across an unseen wall. Internal to
// processing/segmentation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/types.h"
#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation::detail {

// Two parts of a cluster that meet only across a step — side by side in the top view, apart in
// 3-D — are the two levels of one sherd (a ring foot's recess, a lip: the wall between them is
// never seen from above) when, together: the step is a real one (its 10th percentile height at
// least kLevelStepMinMm), no higher than such a wall (90th percentile at most kLevelStepMaxMm) and
// about equally high all along the border (90th / 10th percentile at most kLevelStepMaxSpread);
// the parts hardly touch in 3-D beside it (3-D neighbour pairs at most kLevelMaxContactShare of
// the step pairs); and their cores have the same clay colour (hue, see below, closer than
// kLevelMaxHueDifference). A sherd leaning on another shows a step that grows along its edge (it
// rests on one end), two sherds laid side by side touch in 3-D, and two different vessels rarely
// share a hue. Measured on bench_segmentation (seed 1, trays 1–40 and the failing ones; seed 1001
// all): the two levels of one sherd left split had step heights q10 / q90 of 4.2 / 5.5 and
// 4.3 / 6.7 mm with 7 and 9 3-D pairs beside 1200 and 766 step pairs and core hues 0.011 and 0.18
// apart (the second a fracture face: its own hue); different sherds passing the step tests had
// core hues 0.06–0.15 apart. Without the hue test, 2 more trays of seed 1 and 3 of seed 1001
// merged two sherds; joining across clusters as well (by whole parts' hues) found none of seed
// 1001's unconnected levels (their gap is wider than the clustering distance) and merged 1 + 3
// more trays. The spread was 1.6 from those; over six seeds (100 trays each of 1 / 1001 / 5001 /
// 7001 / 9001 / 11001), pairs passing the other tests (step, contact, clay) had spreads of
// 1.31–1.98 for one sherd's levels (tray 5075 split at 1.604) and 2.11 and more for different
// sherds (5014): 1.85 joins 5075 and changes nothing else. The border must also be as long as a
// wall across the sherd, at least kLevelMinBorderShare of the narrower part's width (its length
// as for parts_without_neck): a sherd leaning on another of the same vessel shows an even step
// only where it overlaps the other. Over fourteen seeds (1 / 1001 / 5001 / … / 27001), pairs
// passing all other tests had borders of 1.4–3.3 × when they were one sherd's levels (20 pairs),
// 0.27–0.37 × when they were two sherds (23012 and 23050 merged, both one vessel's).
// The least step was 3 mm until 21 seeds (1 / 1001 / 5001 / … / 51001, part pairs of sherd-sized
// cores with their truth): two sherds' level pairs (29046, 45006, each left split) had steps of
// q10 2.65 and 2.83 mm and passed every other test; of the pairs of different sherds passing the
// tests but the step's and the clay's, the four with q10 of 1.5–3 mm had hues 0.07–0.14 apart.
// With 2.5 mm, over 38 runs (1 / 1001 / … / 75001): 7 trays made right (five on runs 53001–75001,
// not used for the figure), one made wrong (55048: two sherds merged).
// The contact share was 0.05 until a debug build (each pair printed with its truth) on 20 runs (1 /
// 1001 / 5001 / … / 15001, 133001 / 135001 / … / 155001) and tray 161055: the pairs failing the
// contact test alone were one sherd's levels, all at 0.055–0.056 (7, 139097, 147018, joined by a
// later step; 161055, left split); two sherds' pairs failing it and one other test, 0.056–0.076.
// With 0.06, over 80 runs (1 / 1001 / 5001 / … / 15001, 133001 / 135001 / … / 275001), beside the
// binary before: 161055 made right, no other tray's figures moved; on 24 runs never run before
// (465001 / 467001 / … / 511001) none moved. The narrow pieces' join keeps 0.05
// (kWallMaxContactShare): with 0.06 it joined a third sherd to a merged pair (tray 147045).
inline constexpr double kLevelStepMinMm = 2.5;
inline constexpr double kLevelStepMaxMm = 8.0;
inline constexpr double kLevelStepMaxSpread = 1.85;
inline constexpr double kLevelMaxContactShare = 0.06;
inline constexpr double kLevelMaxHueDifference = 0.03;
inline constexpr std::size_t kLevelMinStepPairs = 100;  // a border, not a corner
inline constexpr double kLevelMinBorderShare = 0.7;

// Levels whose step is higher or less even than that (90th percentile at most
// kFallingLevelStepMaxMm, 90th / 10th at most kFallingLevelStepMaxSpread) but pass every other
// test are one sherd's still where its surface bends down across the border, as over a rim or a
// carination that hides the wall between them: each level's slope is that of the plane through its
// voxels within kFallingLevelNearMm of the border (top view), going from the upper level across
// the border. The lower level falls away at kFallingLevelMaxSlope or steeper; or, behind a step no
// higher than one sherd's wall (kLevelStepMaxMm), its slope lies kFallingLevelMinBend or more
// below the upper's. A sherd resting on another lies along the other's surface, which runs on
// under the border; one whose edge rises to a high step over a flat sherd bends too. Measured with
// a debug build (each pair the levels' tests judge, with its truth and a plane fitted to each
// level's voxels within 10 mm of the border) over 40 runs of 100 trays (1 / 1001 / 5001 / … /
// 15001, 133001 / 135001 / … / 197001): of the pairs at least 80 % pure, of one clay, passing step
// count, contact and border but refused for the step's shape alone (spread 1.85–2.6, 90th
// percentile 8–12.4 mm), 21 were one sherd's levels and 53 two sherds. The lower level's slope:
// one sherd's −2.16…0.03 (median −0.54), two sherds' −0.35…0.89; the upper's minus the lower's:
// one sherd's 0.20–4.78, two sherds' −0.61…0.74. At −0.4 and 0.9 with any step, 16 of the 21
// joined and none of the 53; but over the 80 runs of the round's bench and 16 held out (961001 /
// 963001 / … / 991001) that rule joined two sherds three times: a bend of 1.7 behind a step of
// 11.9 and 12.2 mm (two sherds of 80 % purity there, one leaning over the other) and a lower slope
// of −0.41. At −0.5 and 0.9 behind a wall-high step, 14 of the 21 join and none of the 53; over the
// 96 runs that makes 133065, 187069 and 253070 right and none wrong, and on 16 runs never run
// before (501001 / 503001 / … / 531001) it changed no tray. The angle between the planes, unsigned,
// and the step's trend along the border overlapped between the two kinds. A plane of fewer than
// kFallingLevelMinPlaneVoxels voxels or steeper than a normal z of kFallingLevelMinNormalZ (84°)
// has no slope to judge.
inline constexpr double kFallingLevelStepMaxMm = 12.4;
inline constexpr double kFallingLevelStepMaxSpread = 2.6;
inline constexpr double kFallingLevelNearMm = 10.0;
inline constexpr double kFallingLevelMaxSlope = -0.5;
inline constexpr double kFallingLevelMinBend = 0.9;
inline constexpr std::size_t kFallingLevelMinPlaneVoxels = 10;
inline constexpr double kFallingLevelMinNormalZ = 0.1;

// Levels behind an even wall whose cores lie kLevelCloseClayMaxOffClayLine or more off each other's
// clay line (a fracture face, or another sherd of a close clay) are one sherd's only where the
// lower level falls away at kOffClayLevelMaxSlope or steeper (a face slopes off its sherd's
// surface; a sherd lying under another runs on flat). Bends (above) count only between levels of a
// close clay. Measured with a debug build (every pair of judged parts with kLevelMinStepPairs step
// pairs, with its truth and both levels' slopes) over 41 runs (1 / 1001 / 5001 / … / 15001, 133001
// / 135001 / … / 197001): of the 147 pairs the levels' tests joined, 13 were two sherds (5 of them
// left merged at the end), their cores 0.0016–0.0184 off each other's line (10 at 0.0065 or more),
// their lower level's slope −0.12…0.33; the 6 one sherd's pairs 0.0055 or more apart (fracture
// faces, 0.0062–0.0147) fell away at −2.17…−0.52, and one sherd's levels with a lower slope above
// −0.5 lay within 0.0046 of each other's line. The bound on the slope lies midway between the two
// kinds. Beside the binary before: 157056, 159051 and 175087 (80 runs), 985033 (961001 / … /
// 991001) and 531065 (501001 / … / 531001, not looked at) made right, none wrong.
inline constexpr double kLevelCloseClayMaxOffClayLine = 0.0055;
inline constexpr double kOffClayLevelMaxSlope = -0.3;
// A level up to kLevelWideFaceMaxWidthMm wide (rather than kFacePartMaxWidthMm, clay.h) is its
// sherd's fracture face where it falls away from the other level at kOffClayLevelMaxSlope or
// steeper: a face slopes off its sherd's surface, and a sherd lying beside or on another runs on
// flat or rises. Measured with a debug build (every pair of parts judged as levels, with its truth
// and both levels' slopes) over 80 runs of 100 trays (1 / 1001 / 5001 / … / 15001, 133001 /
// 135001 / … / 275001): of the pairs refused by their colours alone, their cores within
// kLevelFaceMaxOffClayLine of one line, 22 were one sherd's levels and 21 two sherds'. Of one
// sherd's with the narrower part 16–18.2 mm wide (13 pairs), 9 fell away at −0.69…−0.31 (145052
// left split), the rest at −0.22…−0.14; two sherds' falling at −0.3 or steeper had narrower parts
// 19.6 mm wide or wider, and the four whose narrower part was 16.3–18.5 mm wide ran on or rose
// (−0.06…0.63; 185022's, 16.3 mm, joined without the slope test). Beside the binary before:
// 145052 made right, no other tray moved over the 80 runs; on 16 runs never run before (1321001 /
// 1323001 / … / 1351001) none moved.
inline constexpr double kLevelWideFaceMaxWidthMm = 18.0;

// Levels that touch in 3-D beside the step more than kLevelMaxContactShare allows, up to
// kTouchingLevelMaxContactShare (a step fading out along the border, the wall seen where it is
// low), are one sherd's only where their cores lie within kTouchingLevelMaxOffClayLine of each
// other's clay line and the surface bends down across the step: the upper level's slope lies
// kTouchingLevelMinBend or more above the lower's, whatever the step's shape within the loose
// bounds (kFallingLevelStepMaxMm, kFallingLevelStepMaxSpread). A sherd lying on another of a close
// clay runs on flat beside it. Measured with a debug build (every pair of judged parts with
// kLevelMinStepPairs step pairs, with its truth and both levels' slopes) over 80 runs (1 / 1001 /
// 5001 / … / 15001, 133001 / 135001 / … / 275001): of the pairs at least 80 % pure, of one clay,
// with a long border and a loose wall, touching at a share of 0.06–0.4 and within 0.0055 of each
// other's line, 7 were one sherd's (share 0.068–0.119, cores 0.0003–0.0021 off each other's line,
// bends 0.55–1.40 but one of 0.17; 199089 left split) and 4 two sherds' (0.0030–0.0046 off at
// shares 0.062–0.135 with bends −0.10…0.38, 0.0024 off at 0.180). A first form (0.0055 and a bend
// of 0.1) joined two sherds 0.0040 off with a bend of 0.19 (981042, of 16 runs held out: 961001 /
// 963001 / … / 991001); the bounds lie between the two kinds. Beside the binary before: 199089
// made right, none wrong over those 96 runs; on 16 runs never run before (1001001 / 1003001 / … /
// 1031001) no tray moved.
inline constexpr double kTouchingLevelMaxContactShare = 0.125;
inline constexpr double kTouchingLevelMaxOffClayLine = 0.0025;
inline constexpr double kTouchingLevelMinBend = 0.4;

// The step heights along a border (reordered) are those of a wall between one sherd's levels:
// enough of them, a real step, no higher than such a wall (`max_mm`) and about equally high all
// along (90th / 10th percentile at most `max_spread`).
bool level_wall(std::vector<float>& heights, double max_mm = kLevelStepMaxMm,
                double max_spread = kLevelStepMaxSpread);

// Slopes (rise over run) of two levels across the border between them, going from the upper.
struct SlopesAcross {
  double upper, lower;
};

// The slopes of two levels a and b (parts by `tag` among `among`, whose top view is `top`; b the
// upper when `b_upper`) across the border between them (see kFallingLevelMaxSlope): each level's
// is that of the plane through its voxels within kFallingLevelNearMm of the border (in the top
// view), along the direction from the upper level's side of the border to the lower's (the
// centres of the step pairs' voxels on either side). NaN for a level without one.
SlopesAcross slopes_across(TopView& top, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
                           int a, int b, bool b_upper, double radius);

// The same, the upper level being the one that most of the other's step pairs with it rise to.
SlopesAcross slopes_across(TopView& top, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
                           int a, int b, double radius);

// Two parts of sherd-sized cores that meet along a border about as long as the narrower of them
// is wide — no neck between them — are one sherd that the erosion cut where it narrows a little (a
// long rim strip, a lip band along a rim), when their cores share the clay's hue (closer than
// kNoNeckMaxHueDifference). Where two sherds touch, the contact is a neck shorter than either is
// wide. The border's length is the area of the bands along it (voxels of either part within
// `radius` of the other, about `radius` wide each) over 2 × radius; a part's width is twice its
// deepest voxel's distance from the cluster's boundary. Measured on bench_segmentation
// (100 trays each of seeds 1, 2, 1001, pairs of parts left apart by the rules above): one
// sherd's parts (trays 1026, 1059, 1088; 92 of seeds 1 and 2) had borders 0.87–2.06 × the
// narrower's width and core hues 0.001–0.005 apart; different sherds of hues closer than 0.02,
// 0.30–0.44 ×; different sherds with borders over 0.7 × had hues 0.025–0.047 apart. On seed
// 5001, two sherds 0.0108 apart (tray 5096) merged with 0.012, hence 0.008; seeds 5001 and 7001
// (not used for choosing the other figures): exact count 91 → 92 % and 92 → 94 %, no merges.
// Over ten seeds (1 / 1001 / 5001 / … / 19001), different sherds of hues closer than 0.0085
// had borders of at most 0.30 × (0.53 and 0.58 × at 0.0091–0.0092), and one sherd's parts
// 0.68 × (19012, split at 0.7) and 0.0081 apart (19082, joined until then as a face); pairs
// joined by the face rule went down to 0.61 × for different sherds (61, 1022): 0.65 and
// 0.0085 join both and change nothing else.
// The border leaves out the voxels the watershed handed to the wrong basin (see leaked_to in
// contacts.cpp): those nearer another basin's core than their own basin's (along paths within it)
// by more than the erosion. A strip of one sherd along the other's edge, flooded from the other's
// core, makes the contact look long: trays 137096 and 199091, two sherds each, hues 0.0055 and
// 0.0073 apart, borders 13.9 and 12.1 mm beside narrower parts 19.3 and 15.1 mm wide, 12.1 and 7.6
// mm without the strip. Over 80 runs of 100 trays (1 / 1001 / … / 15001, 133001 / 135001 / … /
// 275001), beside the binary without it: those 2 trays made right, no other tray's figures moved;
// on eight runs never run before (337001 / 339001 / … / 351001) no tray's figures moved.
inline constexpr double kNoNeckMinBorderShare = 0.65;
inline constexpr double kNoNeckMaxHueDifference = 0.0085;

// Where the erosion cut one sherd whose surface runs on across the border, the two parts meet in
// 3-D all along it and hardly a voxel of one lies above or below the other in the top view; two
// sherds side by side meet at their broken edges, whose faces and heights stand as steps beside
// the contact. So a pair of one hue (closer than kNoNeckMaxHueDifference; no fracture face, which
// would stand as a step) with step pairs at most kSmoothMaxStepShare of its 3-D neighbour pairs
// has no neck when its border is kSmoothMinBorderShare of the narrower part's width. Measured with
// a debug build (pairs of sherd-sized cores' parts, with their truth, over 80 runs of 100 trays: 1
// / 1001 / 5001 / … / 15001, 133001 / 135001 / … / 275001; 21,934 pairs): of the pairs of one
// hue with step pairs at most 0.2 × their 3-D pairs, 35 were one sherd's and one two sherds'
// touching at a single neighbour pair (269099, border 0.014 ×); two sherds' pairs came next at
// 0.22–0.30 × (159007, 271037, 215065, 145076; borders 0.24–0.47 ×). Two of one sherd's pairs
// were left split, at 0.012 and 0.085 × with borders 0.35 and 0.57 × (143086, 207049). Two flat
// sherds of one clay at one height meet without a step too: where they touch briefly (4 mm,
// test ARidgedSherdTouchingAWiderOneOfItsClayIsASherdOfItsOwn) the border is 0.46 × the narrower
// part's width, so the border must be half of it (143086 stays split).
inline constexpr double kSmoothMaxStepShare = 0.1;
inline constexpr double kSmoothMinBorderShare = 0.5;

// The watershed's depth is the distance from the cluster's boundary, and the boundary test takes a
// crease for an edge: where a sherd's fracture face meets its surface, or where it rests on
// another. A strip of a sherd between two such lines (a face below its edge, its end lying on the
// neighbour) rises to a ridge with no core of its own and goes to whichever basin reaches the ridge
// highest: often the neighbour's, across the contact. Its voxels lie nearer their own sherd's core
// than the core of the part they are in, along the surface, by more than the erosion (leaked_to in
// contacts.cpp). So, after the joins, the cluster is flooded again with those voxels as cores of
// the parts they are nearer, and each strip (voxels moving from one part to one other, connected)
// goes over when its colour is that part's clay (within kStripMaxOffClayLine of its clay line) and
// not its own part's (as far off its line or more); it stays when its colour is its own part's
// clay alone; otherwise (no colours, or both clays or neither) it goes over when it lies along that
// part in 3-D: kStripMinAlongPairs neighbour pairs or more, and kStripMinAlongShare × its pairs
// with the rest of its own part. Being nearer another core is not enough: near a contact, a part's
// own voxels lie nearer a neighbour's core when their own core is far. Measured with a debug build
// (every strip of 20 voxels or more moving between parts that stand for different sherds, with its
// truth): over 20 runs of 100 trays (1 / 1001 / 5001 / … / 15001, 133001, 135001, 197001 / 199001 /
// … / 215001), 305 strips were of their new part's sherd and 143 of their own part's; of those
// lying along the new part as above, 167 of its sherd (16,469 voxels), none of their own part's (2
// mixed). Over 9 more (259001 / 261001 / … / 275001), 140 and 55; of those of the new part's clay
// and not their own part's, 79 of the new part's sherd (8,490 voxels), one of their own part's (23
// voxels). A first form that let a strip go by the 3-D rule whatever its colour merged 139065 (a
// strip of its own part's clay alone along the neighbour). Beside the binary before, with the
// pieces below kept back: over the 80 runs (1 / 1001 / … / 15001, 133001 / … / 275001) 7 trays
// made right (143093, 187002, 209056, 219041, 223099, 257093, 267011), 2 wrong (165013: a strip
// gone rightly, the sherd split by a later step; 179062: a third sherd's piece along the
// neighbour); on 961001 / … / 991001 3 made right, none wrong; on 16 runs never run before
// (1065001 / 1067001 / … / 1095001) 3 made right (1069073, 1081034, 1083028), 1 wrong (1067013).
inline constexpr std::size_t kStripMinAlongPairs = 100;
inline constexpr double kStripMinAlongShare = 2.0;
inline constexpr double kStripMaxOffClayLine = 0.005;
// A strip that goes by its colour to a part of another clay (the clay lines
// kStripTrimMinClaysApart or more apart) may carry a piece of its old part's sherd, where the new
// cores' flood ran past its sherd's edge (189044: 48 of 297 voxels, with which the sherd's two
// parts were no longer joined later). Pieces of the strip whose colour — each voxel's summed with
// its neighbours' in the strip; one voxel's few points are noise — lies nearer the old part's clay
// line than the new part's stay there when they are kStripMinOwnPieceMm2 or more (28 voxels on
// the trays) and border the rest of the old part in 3-D more than the new part (own_clay_pieces
// in contacts.cpp). Measured with a debug build over 10 runs (1 / 1001 / 5001 / … / 15001, 133001,
// 135001): 158 strips went by colour to a part of another clay, with 7,416 voxels of the new
// part's sherd and 236 of the old part's. Every voxel nearer the old clay by its smoothed colour
// would have kept back 175 of the old part's sherd and 387 of the new part's; connected pieces
// as large as above, 62 and 57 (a piece of 36 voxels of the new part's sherd, bordering the new
// part only: 15077); bordering the old part more, 62 and 21 (two strips: 7037 26 and 19, 15077 36
// and 2). In 189044 a piece of 45 voxels, all of the old part's sherd, stays.
// A strip joined in 3-D to neither part much — a level of its sherd behind an unseen wall, its end
// lying on the neighbour — still lies along its sherd's part in the top view for its whole length,
// and along the rest of the part it is in only where it touches it. So a strip that would stay but
// is not of its own part's clay alone goes over when kStripMinTopViewToShare of its voxels or more
// have a top-view neighbour within the erosion in the new part and kStripMaxTopViewFromShare or
// fewer one in the rest of their own part (lies_along_in_top_view in contacts.cpp). Measured with
// a debug build over 20 runs (1 / 1001 / 5001 / … / 15001, 133001 / 135001 / … / 155001; every
// strip of 20 voxels or more that stayed, not of its own part's clay alone, with its truth): of
// those that would go so, 29 were mostly of the new part's sherd (2,035 of their 2,179 voxels) and
// 2 lay between two parts of one sherd; none was of its own part's sherd, the nearest such lying
// along the rest of its part for 0.67 of its voxels (139087), the new part's sherd's for 0.20–0.60
// (all with 0.83 or more along the new part).
inline constexpr double kStripMinTopViewToShare = 0.8;
inline constexpr double kStripMaxTopViewFromShare = 0.6;
inline constexpr double kStripTrimMinClaysApart = 2.0 * kStripMaxOffClayLine;
inline constexpr double kStripMinOwnPieceMm2 = 20.0;

// Splits one Euclidean cluster where sherds touch or lean on each other. A sherd's surface is
// a patch that stays wide everywhere, while two sherds meet at a point or along a short stretch
// of their edges: eroding the cluster (voxels within `erosion` of its boundary, measured along
// the surface) leaves one core per sherd, and every voxel then goes to the core nearest along the
// surface (a geodesic watershed). Boundary voxels are those whose neighbourhood lies to one side
// (its mean is off the centre by more than a quarter of the radius; a half-disk gives 0.42).
// A core counts only when it could be a sherd by itself (`min_core_voxels`); one smaller than
// `min_own_core_voxels` is taken for the far side of a step inside a sherd (see
// Params::contact_min_core_mm2) and its part joins a neighbour — unless that part covers
// `min_own_basin_voxels` (Params::contact_own_basin_mm2) and borders no other small core's part
// of its own (see kWideCoreMm2): then it is a narrow sherd touching a wider one (what the
// watershed handed the wider one first counting, see kSmallCoreMaxReclaimShare), or it is half as
// large and neither behind a step nor without a neck (kSmallSherdMaxStepBandMm2). Where no core
// lies, a shallower one may stand for a sherd (see kShallowCoreShare), and a shallower still for
// a band of one, whose part joins a neighbour (see kBandCoreShare) unless it is a narrow sherd's
// (kBandSherdMaxStepBandShare); with fewer than two cores the cluster stays whole. Two parts
// standing as sherds — sherd-sized cores' and the small cores'
// basins kept apart — that are one sherd's levels (levels_of_one_sherd) or have no neck between
// them (parts_without_neck) are joined; both need colours (`voxel_rgb` sums per voxel, empty when
// none). A small core's basin kept apart is judged by its hue alone, never as a fracture face of
// its neighbour: it covers a sherd's area, and its own sherd's far side shows its clay. Measured
// with a debug build (every pair of parts meeting in a cluster, with their truth) on the sherds
// left split by the watershed over 80 runs of 100 trays (1 / 1001 / 5001 / … / 15001, 133001 /
// 135001 / … / 275001): in 5 of the 16 split into parts of their own, one part was such a basin,
// three of them passing the tests with a part of their sherd (187007: no neck, border 1.07 × its
// width; 243029: an even step; 269046, whose third part stays apart), hues 0.0015–0.0029 apart.
// Judged with the face test too, two whole narrow sherds joined a wider sherd of another hue (0.11,
// 0.22) whose line to grey they lie on (9034, 171079). Beside the binary before, over the 80 runs:
// 187007 and 243029 made right, none wrong; on 16 runs never run before (737001 / 739001 / … /
// 767001) 755098, 757033 and 763038 made right, none wrong; on 16 more (769001 / … / 799001)
// none right, two wrong: narrow sherds joined to a wider one they lie under (783065: no neck, a
// border 0.85 × its width) or lean on (787094: an even step).
// As a level, such a basin is the lower one beside a wider part and the upper beside a narrower
// one: the far side of a step inside a sherd lies below the wide face the wall falls from, a
// fracture face hangs from its sherd; a narrow sherd leaning on a wider one lies above it. Measured
// with a debug build (every level join of such a basin, with the median rise of its step pairs)
// over those 112 runs (the 80 and both sets of 16): 14 beside wider parts (18–37 mm wide), all one
// sherd's, the basin 3.1–6.1 mm lower; 5 beside narrower parts (8–11 mm, its fracture face), one
// sherd's, 3.6–6.2 mm higher; one narrow sherd 6.4 mm above the wider one it leans on (787094). So
// such a basin joins as a level only with its wider level upper. The no-neck joins show no such
// order (one sherd's basins from 4.6 mm lower to 4.2 mm higher at their steps; 783065 5.9 mm lower)
// and are left as they are. Beside the binary before: 787094 made right, no other tray moved on the
// 112 runs; on 16 runs never run before (801001 / 803001 / … / 831001) none moved.
// Last, strips that the watershed handed to another part than their sherd's go back to their
// sherd's part (see kStripMinAlongPairs).
struct CoreSizes {
  std::size_t min_core_voxels;       // smaller cores are ignored
  std::size_t min_own_core_voxels;   // smaller cores' parts join a neighbour …
  std::size_t min_own_basin_voxels;  // … unless the part is at least this large …
  std::size_t min_wide_core_voxels;  // … beside a part of its own with a core this large
  std::size_t max_small_sherd_step_band_voxels;  // see kSmallSherdMaxStepBandMm2 below
  std::size_t min_own_clay_piece_voxels;         // see kStripMinOwnPieceMm2
};

// A small core's basin smaller than min_own_basin_voxels is mostly the far side of a step inside
// a sherd: it lies along the rest of its sherd across the step (top-view neighbours apart in 3-D),
// or borders it in 3-D without a neck. A whole small sherd touching a wider one does neither. So
// a small core's basin of half min_own_basin_voxels or more, beside a wide core
// (min_wide_core_voxels), stays apart when less than kSmallSherdMaxStepBandMm2 of it lies beside
// another basin across a step and its 3-D border with the basin it borders most (as
// parts_without_neck measures it) is shorter than kNoNeckMinBorderShare × its width. Measured with
// a debug build (every small core's basin joined over 80 runs of 100 trays, 1 / 1001 / 5001 / … /
// 15001, 133001 / 135001 / … / 275001, 1,157 joins, with its truth): the basins of 324 voxels or
// more beside a wide core with fewer than 30 voxels (21 mm²) across a step and such a neck were
// all whole small sherds joined wrongly (8: 473–616 voxels; trays 141042, 177068, 179008, 181097,
// 239054, 243089, 259071, 9097); the far sides of steps that joined rightly had 80 or more such
// voxels, or borders of 0.87 × their width or longer (one with 49 voxels: 263012).
inline constexpr double kSmallSherdMaxStepBandMm2 = 20.0;
// A whole small sherd leaning on a wider one, or lying under it, does lie beside it across a step;
// but unlike the far side of a step inside a sherd (its fracture face, or its surface falling away
// from the wall) the lower of the two then rises away from the wall, following its own curve. So
// a lobe's basin (see kLobeMinTopShare in contacts.cpp) with such a neck also stays apart when the
// lower level's slope across the border (as the levels rule measures it, see
// kFallingLevelMaxSlope) is kSmallSherdMinLowerRise or more. Measured with a debug build (every
// such basin asked over 20 runs: 1, 1001, 5001, …, 15001, 133001, …, 155001, with its truth): of
// the lobes beside a step with such a neck, the 66 far sides joined rightly had lower slopes up
// to −0.04, and of the 5 whole sherds joined wrongly one had 0.84; the three left merged on the
// 80 runs had 0.19–0.24 (193058, 243062, 253085). Not so for small cores' basins: such a basin
// rising from the step is as often a piece of a sherd whose core lies in another basin (in 7008
// and 1201071 kept apart, it left its sherd split).
inline constexpr double kSmallSherdMinLowerRise = 0.1;

// A small core's large part beside another part of its own with a small core is one narrow
// sherd that the erosion cut into two small cores (where it narrows, or across a bend), not a
// narrow sherd touching a wider one. Measured on bench_segmentation (100 trays each, seeds 1 /
// 1001 / 5001 / 7001): of the parts the own-basin rule kept apart, the narrow sherds beside
// other sherds had neighbours' cores of 133 mm² or more (12 cases); one sherd's two parts (trays
// 5041, 7072: one sherd too many) 42–49 mm². Split sherds 2 / 4 / 7 / 3 → 2 / 4 / 6 / 2, no
// merges. Held out (seeds 9001 / 11001, not used for the figure): exact counts 97 / 93 % →
// 97 / 96 %, merges 2 / 1 unchanged. A neighbour that is no part of its own (a smaller core and
// part, which joins a neighbour itself) does not count: joining it chained tray 11086's narrow
// sherd to the next sherd.
inline constexpr double kWideCoreMm2 = 80.0;
// A sherd whose boundary the erosion also finds inside it (the sides of a flange, a cordon or a
// steep lip are steps the boundary test takes for edges) can keep no core `erosion` deep; it then
// went wholly to a touching sherd's core (tray 105017; tray 105002: a 26 × 31 mm rim sherd with a
// ridge, 4.35 mm deep at the most). So where no deep core lies, a region kShallowCoreShare ×
// `erosion` deep and as large as a sherd's own core (min_own_core_voxels) is a shallow core. Its
// part joins the part it borders most, as a small core's does, unless it covers
// min_own_basin_voxels beside a wide core (min_wide_core_voxels); beside a part that is no sherd
// of its own it joins too (tray 9067: one sherd's shallow and small deep core). Shallow cores are
// judged first, then the small deep cores by the parts they have after that: in tray 21030 one
// sherd's shallow and small deep core had half of its area each, and the small core's part, too
// small to stay apart, joined the next sherd. Measured on bench_segmentation (54 runs of 100
// trays, first seeds 1, 1001, 5001, 7001, …, 107001), against no shallow cores: trays with every
// sherd found once and whole 5,200 → 5,212 (14 made right, 2 wrong: 51074, where the colour split
// no longer parts a merged pair, and 89095, a sherd's level behind an uneven step kept apart),
// merged sherds 55 → 46; at 0.7 × 5,208. A first draft (shallow cores from min_core_voxels up,
// judged together with the small deep cores by their rule) made 6 trays right and 16 wrong on
// the first 13 runs, splitting sherds.
inline constexpr double kShallowCoreShare = 0.6;
// A band of a sherd behind a step inside it (a rim band, a lip, the far side of a carination), 6–10
// mm wide in the top view (3.1–4.9 mm deep at the most), keeps no core erosion deep nor
// kShallowCoreShare × erosion deep, and went to whichever basin the watershed reached it from
// first: where the band also touches another sherd in 3-D (its end against that sherd's corner),
// often that sherd's, though it touches its own far longer or lies along it across the step. So a
// region kBandCoreShare × erosion deep that holds no other core and covers min_own_core_voxels is a
// band core, and its basin joins at once (before the shallow cores are judged by the basins they
// then have) the basin it touches most in 3-D, or the one across the step that its colour shows, as
// a small core's does (kSmallCoreAcrossStep, kAlongStepMinPairs in contacts.cpp). Measured with a
// debug build on the 46 sherds left split by the watershed over 80 runs of 100 trays (1 / 1001 / …
// / 15001, 133001 / 135001 / … / 275001): 23 had a piece without a core in a neighbour's part: 14
// touching the neighbour in 3-D more than the rest of their sherd (6–169 neighbour pairs against
// 3–32), 9 touching their own sherd more (32–1132 against 12–102). Over those 80 runs, beside the
// binary without band cores: 8 trays made right (13065, 147011, 271094 by colour across the step;
// 233097, 245013, 267004, where the piece touched its own sherd by 490–744 pairs and the neighbour
// by 60–125; 151075, 189050), 1 wrong (205008: a band 0.0090 off its own sherd's clay line and
// 0.0014 off its neighbour's went across to the neighbour); on eight runs never run before (369001
// / 371001 / … / 383001), 1 made right (373073), none wrong. A first draft judged the band cores
// with the small ones, after the shallow ones, and made 5 trays wrong: the bands' basins had taken
// area from shallow cores' basins, which fell under min_own_basin_voxels and joined a neighbour
// (11010, 199056).
inline constexpr double kBandCoreShare = 0.4;
// A band core's basin of a sherd's area (min_own_basin_voxels) beside a wide core can also be a
// whole narrow sherd touching a wider one at its end. The far side of a step lies along its sherd
// across the step for much of its length; such a sherd does not. So the basin stays apart when
// less than kBandSherdMaxStepBandShare of it lies beside another basin across a step and it
// borders the basin it touches most with a neck (as small sherds do, kSmallSherdMaxStepBandMm2).
// Measured with a debug build (every band core's basin over 80 runs of 100 trays, 1 / 1001 /
// 5001 / … / 15001, 133001 / 135001 / … / 275001, with its truth and where it joined): of the 50
// such basins, the 31 far sides of steps that joined their own sherd lay beside a step for
// 0.24–0.86 of their area. The 15 that did so for less than 0.2 (0.016–0.187) were all whole
// sherds: 12 stayed apart by their colour, 2 were parted by later rules, and 227048's, bordering
// its neighbour along 0.10 × its width, was left merged with it. (One more whole sherd, 0.25,
// stayed apart by its colour.) Beside the binary before, 227048 came right on the 80 runs and no
// other tray's count moved, nor any on 16 runs never run before (1385001 / 1387001 / … / 1415001).
inline constexpr double kBandSherdMaxStepBandShare = 0.2;

// The parts of the clusters after the first stages of split_at_contacts, for the benchmark's
// steps (segment()'s ClusteringStep): each core's basin, then the basins after the band, shallow
// and small cores' basins joined their neighbours.
struct ContactStages {
  std::vector<std::vector<std::uint32_t>> basins, small_cores;
};

// `cluster` (voxels, a whole component of `near`) split at the contacts of touching sherds, as
// described above; `distance` and `tag` are scratch space sized for all voxels, `stages` (may be
// null) receives the parts after the first stages.
std::vector<std::vector<std::uint32_t>> split_at_contacts(
    const Graph& near, const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb,
    const std::vector<std::uint32_t>& cluster, double radius, double erosion,
    const CoreSizes& sizes, std::vector<float>& distance, std::vector<int>& tag,
    ContactStages* stages);

// A narrow piece of a sherd cut off from the rest by a wall too steep to be seen from above: the
// raised edge of a sherd leaning on another (its fracture face, seen from above as a strip as
// wide as the wall is thick) with the sherd's surface falling away steeply beside it. It comes out
// as a part of its own — a cluster, as the wall leaves a gap in 3-D — that the erosion leaves no
// sherd-sized core, lying in the top view right against the rest of its sherd; so does a narrow
// level of a sherd behind a step higher than the clustering distance. It joins the part (with a
// core) that, together: borders it in the top view along at least kWallMinBorderShare of its
// voxels (top-view neighbours, apart in 3-D), or less behind a level's wall (level_wall: an even
// step, 2.5–8 mm high); hardly touches it in 3-D beside that
// (kWallMaxContactShare, the levels' bound before it grew: at 0.06 this join merged another sherd,
// see kLevelMaxContactShare); and has its clay's colour, or that colour mixed with
// grey — the fired core a fracture face shows is greyer than the surfaces — within
// kWallMaxOffClayLine of that line in hue. Of several, the one nearest in colour: a leaning sherd's
// strip borders the sherd it rests on as well. Smaller pieces than kWallPartMinMm2 are crumbs on
// the plate. Measured on bench_segmentation (100 trays each of seeds 1, 2, 1001): the five strips
// (trays 94 of seeds 1 and 2; 1014, 1062, 1068, 1099) cover 80–245 mm², lie 3–5 mm from their
// boundary at the deepest, border their sherd along 28–86 % of their voxels and lie 0.002–0.012 off
// its clay line; the other sherds bordering them 0.018–0.065 off. Seed 1001's exact count 91 → 94
// %. Over eighteen seeds (1 / 1001 / 5001 / … / 35001), four narrow levels in clusters of their own
// (trays 13026, 23092, 29059, 33056) bordered their sherd along 22–24 % of their voxels, 0.0001–
// 0.0011 off its clay line, behind steps of q90 / q10 1.1–1.2; a narrow sherd beside another
// (9025, merged when the share alone was lowered to 0.2) 23 %, 0.0026 off, behind a step of
// 6–14 mm (a leaning neighbour). With the level's wall as an alternative the four join and no tray
// changes otherwise. The colour test runs both ways, as of_one_clay's: the narrow piece may be the
// level that shows the clay and the cored part mostly fracture face (tray 9012: the piece 0.020
// off the cored part's line, the cored part 0.0001 off the piece's). Over ten seeds (1001 / 5001
// / 7001 / … / 37001) that joins 9012 and changes no other tray; over 38 runs (1 / 1001 / … /
// 75001) it makes 9012 and 15033 right, and on four runs looked at only afterwards (77001 / 79001 /
// 81001 / 83001) three trays (79091, 81028, 83004), none wrong. The cored part counts as the
// face only where it is no wider than a face (kFacePartMaxWidthMm, clay.h; twice its deepest
// voxel's distance from the boundary): a wide part is mostly surface, and a sherd lying under one
// of a greyer clay took it for its face (1409066, never run before: two pieces 0.29–0.31 in hue
// less grey than the 5,894-voxel sherd over them, 0.0087 off its line). Measured with a debug
// build, every join of this rule over 40 of the 80 runs against the truth (135 of 137 to the
// piece's own sherd): the piece lay less grey than the cored part by more than a clay's noise
// only beside parts 9.4–13.1 mm wide (237072, 249048, 259076: by 0.071, 0.043 and 0.048), beside
// wider ones (up to 55 mm) by 0.017 at most, within the line's end (off_clay_line). Over the 80
// runs no tray changed; on 16 runs never run before 1409066's merge became a split, which
// join_pieces_under_one_sherd (top_view_joins.cpp) then joins.
inline constexpr double kWallPartMinMm2 = 40.0;
inline constexpr double kWallMinBorderShare = 0.25;
inline constexpr double kWallMaxOffClayLine = 0.015;
inline constexpr double kWallMaxContactShare = 0.05;
// A piece as large as a small sherd (kWallLargePartMm2 or more) joins only within a face's bound of
// the clay line (kFaceMaxOffClayLine, clay.h): the colour of so many points lies close to its
// sherd's line, and whole small sherds without a core beside a sherd of a close clay came in under
// the strips' bound. Measured with a debug build (every join of this rule with its truth, 43 of the
// 80 runs: 1 / 1001 / 5001 / 7001 / 11001 / 13001 / 15001, 133001 / 135001 / … / 203001): 170
// joins of a piece to its own sherd, 6 to another. The own pieces of 250 mm² or more (13, up to 544
// mm²) lay 0.0000–0.0040 off the clay line, one of 217 mm² 0.0101 (161071); five of the six wrong
// joins were pieces of 279–410 mm², 0.0098–0.0136 off (137045, 143093, 159037, 195088, 201032: a
// whole small sherd, or 57–60 % of a sherd the watershed cut), the sixth a 45 mm² crumb (201025).
// A seventh seen since (243017: 344 mm² behind a level's wall, 0.0035 off) stayed joined until
// the far side of that step joined its own sherd across the step first (kAlongStepMinPairs,
// contacts.cpp).
inline constexpr double kWallLargePartMm2 = 250.0;

// `parts` (voxel lists) with the narrow pieces joined to their sherds; `depth` is each voxel's
// distance from its cluster's boundary. A part has a core with min_core_voxels beyond the
// erosion, or as a shallow core's sherd (see kShallowCoreShare) min_own_core_voxels beyond
// kShallowCoreShare × erosion and min_own_basin_voxels in all: the contact split kept that apart
// as a sherd, which this join would hand back to its neighbour (over 54 runs of 100 trays, with
// shallow cores: 4 trays more right, 1 more wrong than without this).
std::vector<std::vector<std::uint32_t>> join_across_unseen_walls(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, const std::vector<float>& depth, double radius,
    double erosion, const CoreSizes& sizes, double leaf);

}  // namespace sherd::segmentation::detail
