// The clay colour of parts: hue, fracture faces (the clay mixed with grey) and the clays a part
// shows. Internal to processing/segmentation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/types.h"
#include "processing/segmentation/voxel_graph.h"

namespace sherd::segmentation::detail {

// Hue of a colour sum as (g/r, b/r): shading scales all three channels alike, so the two levels
// of one sherd, lit differently, keep it.
Eigen::Vector2f hue(const Vec3f& rgb);

// Hue `h` lies from hue `clay` towards grey's (1, 1): the clay mixed with grey, as a fracture
// face shows it.
bool greyer(const Eigen::Vector2f& h, const Eigen::Vector2f& clay);

// How far the hue of `face` (a colour sum) lies from the hues of `clay` mixed with grey: the
// segment from hue(clay) to grey's (1, 1), a little beyond clay's end for noise.
float off_clay_line(const Vec3f& clay, const Vec3f& face);

// How far two parts' colours (sums) lie off each other's clay line: the lesser of the two ways,
// as either may be the clay and the other its fracture face.
float off_either_line(const Vec3f& a, const Vec3f& b);

// Each part's colour: the sum over its voxels' sums.
std::vector<Vec3f> colour_sums(const std::vector<std::vector<std::uint32_t>>& parts,
                               const std::vector<Vec3f>& voxel_rgb);

// A part that shows a sherd's fracture face — the fired core, greyer than the surfaces, cut off
// from them by the erosion where the wall's edge meets a surface at a sharp crease — joins the
// part of its sherd's surface, levels or no neck between them, though their hues differ: when
// it is no wider than a wall is thick (kFacePartMaxWidthMm, twice its deepest voxel's distance from
// the boundary), greyer than that surface's clay and within kFaceMaxOffClayLine of the clay's
// line to grey (kLevelFaceMaxOffClayLine for levels, whose even step without contact already
// tells much). Measured on bench_segmentation (100 trays each, seeds 1 / 1001 / 5001 / 7001;
// parts passing the levels' or the no-neck border tests): the faces (trays 32, 5042, 7004, 7010)
// were 14.4–15.7 mm wide and 0.0000–0.0025 off their clay's line; different sherds within 0.008
// of the line were 23.6 mm wide or more (7045, 1082 at 0.002 and 0.005: merged by the line
// alone), different sherds 18 mm wide or less 0.016 off or more. Split sherds 3 / 4 / 8 / 5 →
// 2 / 4 / 7 / 3, exact counts 98 / 99 / 93 / 97 → 99 / 99 / 94 / 99 %, no more merges. The
// simulated walls are 3–10 mm thick; the measured width runs wider, as the crease is only
// partly taken for boundary. Of the level pairs (passing the step tests), the face level of tray
// 61 lay 0.0147 off its clay's line and 15.5 mm wide; different sherds 0.024 off and more, or
// 19.7 mm wide and more (1028 at 0.011; 65 at 0.006 is 26 mm wide): 0.02 for levels joins 61
// (seed 1: no sherd split any more) and changes nothing on the other five seeds (9001 / 11001
// held out). That figure was fitted to the one tray.
// A part's width bound was kFaceMaxWidthMm (18 mm, as for the hue regions in clays_of) until
// ten seeds (100 trays each of 1 / 1001 / 5001 / … / 19001): of the part pairs passing the
// levels' or the no-neck border tests by the face rule, one sherd's faces were 13.4–15.7 mm
// wide (14 pairs), two different sherds merged as faces 16.5 and 16.8 mm (19070, 17011). On
// runs looked at after that (21001, 37001), 16 mm against 18 kept one more pair of sherds apart
// (37068) and left two sherds split (21098, a part 17.2 mm wide 0.010 from its clay; 37024).
inline constexpr double kFaceMaxWidthMm = 18.0;
inline constexpr double kFacePartMaxWidthMm = 16.0;
inline constexpr double kFaceMaxOffClayLine = 0.008;
inline constexpr double kLevelFaceMaxOffClayLine = 0.02;

// Two parts (colour sums, widths in mm) show one sherd's clay: their hues closer than
// `same_hue`, or one is the other's fracture face (within `face_off_clay_line` of the line).
// A face may be up to `max_face_width_mm` wide.
bool of_one_clay(const Vec3f& a_rgb, double a_width_mm, const Vec3f& b_rgb, double b_width_mm,
                 double same_hue, double face_off_clay_line,
                 double max_face_width_mm = kFacePartMaxWidthMm);

// A part holding sherds of different clays is split by colour: a narrow or stepped sherd against
// a larger one that the erosion left no core of its own, or two sherds touching along a contact
// wider than the erosion cuts. Every sherd shows one clay on its surfaces (shading and firing
// clouds change brightness, not the hue (g/r, b/r)) and that clay mixed with grey on its fracture
// faces (the fired core). So the part's clays are the peaks of its voxels' hue histogram (each
// voxel's hue over its neighbourhood within the part, to average out the 8-bit noise) that are
// not the face of another peak; a peak is a face of another when it lies within kSameHue of it
// (one clay's noise) or greyer than it, within kFaceCone (as a ratio of the distance along that
// line) and kFaceMaxAcross of the line from its hue to grey. Each clay whose largest connected
// region covers kClayMinMm2 seeds a sherd, and every voxel of the part goes to the nearest seed
// along the surface. Measured on bench_segmentation (100 trays each of seeds 1 / 1001 / 5001,
// peaks holding at least a quarter of that area): one sherd's face peaks lay 0.000–0.013 across
// its clay's line, at most 0.07 × their distance along it; the second clays of the parts that
// merged two sherds (trays 34, 38, 54, 77 of seed 1) 0.016–0.050 across, 0.28–0.68 × along. The
// earlier rule (two groups by 2-means, off each other's line by 0.03) split the fracture faces
// from the clays and left all four merged. Merged sherds 4 / 2 / 2 → 0 / 0 / 1.
// kFaceMaxAcross was 0.03 until the six seeds (1 / 1001 / 5001 / 7001 / 9001 / 11001): of the
// face peaks whose largest region covers 300 voxels or more, one sherd's faces lay at most
// 0.0097 across, other sherds taken for faces 0.018–0.028 (9097 merged; 9062, 11098). At 0.015
// 9097 is no longer merged and 4 strips (7065, 9048, 11039, 11098) no longer split; 48 trays
// moved by 0.1–0.3 % of precision and recall, either way.
inline constexpr double kClayMinMm2 = 300.0;
// See clays_of: a face peak's region this wide (mm) and bordering the rest of its part along less
// than this share of its length is a sherd. Measured on bench_segmentation (a debug build, the
// regions of 300 mm² or more of face peaks up to kFaceMaxWidthMm wide, over 20 runs of 100 trays:
// 1, 1001, 5001, …, 15001 and 133001, 135001, …, 155001): of those wider than 10 mm, three were
// another sherd than their part's (trays 135093, 145097, 147088, each merged), with borders of
// 0.08–0.17 × their length; 24 one sherd's faces, 0.29–8.6 × (1.1 and 2.1 × for two other sherds
// on one clay's line). Narrower face strips border their part down to 0.01 × (a level apart).
// Those 20 runs: 1,965 → 1,968 trays of exact count, no tray made wrong, no other tray's parts
// changed; six runs never run before (157001, 159001, …, 167001): 588 → 589 of 600, none wrong.
inline constexpr double kTouchingMinWidthMm = 10.0;
inline constexpr double kFaceMinBorderShare = 0.23;
// Hue histogram bin and smoothing (Gaussian sigma, in bins): a voxel's hue, averaged over its
// neighbourhood, scatters by about 0.004 within one clay.
inline constexpr float kHueBin = 0.004f;
inline constexpr float kHueSmoothBins = 1.5f;
inline constexpr float kSameHue = 0.015f;
inline constexpr float kFaceCone = 0.15f;
inline constexpr float kFaceMaxAcross = 0.015f;

// How far hue `h` lies from being a face of the clay of hue `clay`: its distance from the clay's
// hue when that is below kSameHue, else its distance across the clay's clay-to-grey line when it
// lies greyer than the clay, within kFaceCone of the line and kFaceMaxAcross of it; infinite when
// it is no face of that clay.
float face_offset_of(const Eigen::Vector2f& clay, const Eigen::Vector2f& h);

// Groups the voxels of a part (hues `h`, colour sums voxel_rgb[part[k]]) by clay: every voxel to
// its nearest hue peak (peaks holding fewer than a quarter of `min_region` voxels dropped, the
// smallest first), and each peak that is the face of another (see kFaceCone) to the clay whose
// line it lies nearest — unless its largest region, `min_region` or more, is too wide for a face
// or borders the rest of the part along too short a stretch for one.
// Returns the number of clays; clay_of[k] is voxel k's, −1 for a mixture of two (see below).
int clays_of(const std::vector<Eigen::Vector2f>& h, const std::vector<std::uint32_t>& part,
             const Graph& near, const std::vector<Vec3f>& centres, double radius,
             const std::vector<Vec3f>& voxel_rgb, std::size_t min_region, std::vector<int>& clay_of,
             Eigen::Vector2f* main_clay = nullptr);

// Each voxel's hue over its neighbourhood within `part` (to average out the 8-bit noise); `mark`
// is scratch space, all zero, sized for all voxels.
std::vector<Eigen::Vector2f> neighbourhood_hues(const std::vector<std::uint32_t>& part,
                                                const Graph& near,
                                                const std::vector<Vec3f>& voxel_rgb,
                                                std::vector<std::uint8_t>& mark);

}  // namespace sherd::segmentation::detail
