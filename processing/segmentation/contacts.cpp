#include "processing/segmentation/contacts.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <unordered_map>

#include "processing/segmentation/clay.h"

namespace sherd::segmentation::detail {

namespace {

// Calls step(n) for each step pair (v, n) of voxel v: n a voxel of `top` within `radius` of v in
// the top view (flattened onto the plate) but not in 3-D, and of another part (by `tag`).
template <class Step>
void for_each_step_pair(TopView& top, const std::vector<Vec3f>& centres,
                        const std::vector<int>& tag, std::uint32_t v, double radius,
                        std::vector<int>& found, Step&& step) {
  const float radius2 = static_cast<float>(radius * radius);
  top.search(centres[v], radius, found);
  for (auto f : found) {
    const auto n = top.voxel_at[f];
    if (tag[n] != tag[v] && (centres[n] - centres[v]).squaredNorm() > radius2) step(n);
  }
}

// The borders between the parts (by `tag`; `parts` of them) among the voxels `among`, by pair
// (a, b) with a < b: how many 3-D neighbour pairs join them, and the heights of their step pairs —
// neighbours in the top view (flattened onto the plate) that are not neighbours in 3-D — with how
// many of those rise from a to b (b's voxel the higher). band[a][b] counts the voxels of part a
// with a step pair to part b, for any a and b. `top` is the top view of `among`.
struct StepBorders {
  std::vector<std::vector<std::size_t>> contacts;
  std::vector<std::vector<std::vector<float>>> heights;
  std::vector<std::vector<std::size_t>> rises;
  std::vector<std::vector<std::size_t>> band;
  // Whether b is the upper level of a and b: most of a's step pairs with it rise to b.
  bool b_upper(int a, int b) const { return 2 * rises[a][b] > heights[a][b].size(); }
};
StepBorders step_borders(const Graph& near, TopView& top, const std::vector<Vec3f>& centres,
                         const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
                         int parts, double radius) {
  const std::vector<std::vector<std::size_t>> zeros(parts, std::vector<std::size_t>(parts, 0));
  StepBorders borders{
      zeros,
      std::vector<std::vector<std::vector<float>>>(parts, std::vector<std::vector<float>>(parts)),
      zeros, zeros};
  for (auto v : among) {
    for (auto n : near[v]) borders.contacts[tag[v]][tag[n]] += tag[n] > tag[v];
  }
  std::vector<int> found;
  std::vector<int> beside;
  for (auto v : among) {
    beside.clear();
    for_each_step_pair(top, centres, tag, v, radius, found, [&](std::uint32_t n) {
      add_once(beside, tag[n]);
      if (tag[n] > tag[v]) {
        const float rise = centres[n].z() - centres[v].z();
        borders.heights[tag[v]][tag[n]].push_back(std::abs(rise));
        borders.rises[tag[v]][tag[n]] += rise > 0.0f;
      }
    });
    for (int b : beside) ++borders.band[tag[v]][b];
  }
  return borders;
}

// Pairs (a, b) of parts (by the `borders` among them; core_rgb.size() of them) that are one
// sherd's levels, judged by their borders and by the colours of their cores (`core_rgb`, sums) and
// their widths (`width`, mm; `face_width` as a fracture face: infinite for a part that is none, a
// small core's basin kept apart, judged only as the lower level beside a wider part and the
// upper beside a narrower one: see split_at_contacts in contacts.h), and behind an uneven step,
// between cores off each other's clay line or where the levels touch a little by the levels'
// slopes across the border (see kFallingLevelMaxSlope, kLevelCloseClayMaxOffClayLine and
// kTouchingLevelMaxContactShare). The parts' voxels are `among` (by `tag`), whose top view is
// `top`.
std::vector<std::pair<int, int>> levels_of_one_sherd(
    StepBorders& borders, TopView& top, const std::vector<Vec3f>& centres,
    const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
    const std::vector<double>& width, const std::vector<double>& face_width,
    const std::vector<Vec3f>& core_rgb, double radius) {
  const int parts = static_cast<int>(core_rgb.size());
  std::vector<std::pair<int, int>> levels;
  for (int a = 0; a < parts; ++a) {
    for (int b = a + 1; b < parts; ++b) {
      auto& heights = borders.heights[a][b];
      const double border_mm = border_length_mm(borders.band[a][b], borders.band[b][a], radius);
      const double contacts = static_cast<double>(borders.contacts[a][b]);
      const bool apart = contacts <= kLevelMaxContactShare * heights.size();
      const bool touching = !apart && contacts <= kTouchingLevelMaxContactShare * heights.size();
      const bool long_border = border_mm >= kLevelMinBorderShare * std::min(width[a], width[b]);
      const bool one_clay = of_one_clay(core_rgb[a], face_width[a], core_rgb[b], face_width[b],
                                        kLevelMaxHueDifference, kLevelFaceMaxOffClayLine);
      const bool wide_face =
          !one_clay &&
          of_one_clay(core_rgb[a], face_width[a], core_rgb[b], face_width[b],
                      kLevelMaxHueDifference, kLevelFaceMaxOffClayLine, kLevelWideFaceMaxWidthMm);
      const bool kept_basin = std::isinf(face_width[a]) || std::isinf(face_width[b]);
      const bool b_upper = borders.b_upper(a, b);
      const bool wider_upper = b_upper == (width[b] > width[a]);
      if (!(apart || touching) || !long_border || !(one_clay || wide_face) ||
          (kept_basin && !wider_upper))
        continue;
      if (!level_wall(heights, kFallingLevelStepMaxMm, kFallingLevelStepMaxSpread)) continue;
      const float off_line = off_either_line(core_rgb[a], core_rgb[b]);
      const bool close_clay = off_line < kLevelCloseClayMaxOffClayLine;
      const bool even_wall = level_wall(heights);
      const bool behind_level_wall = apart && even_wall && close_clay;
      if (behind_level_wall && !wide_face) {  // the common case: no slopes needed
        levels.emplace_back(a, b);
        continue;
      }
      if (touching && off_line >= kTouchingLevelMaxOffClayLine) continue;
      // Comparisons with NaN are false: a level without a slope shows neither.
      const auto slopes = slopes_across(top, centres, among, tag, a, b, b_upper, radius);
      if (wide_face && !(slopes.lower <= kOffClayLevelMaxSlope)) continue;
      if (behind_level_wall) {
        levels.emplace_back(a, b);
        continue;
      }
      if (touching) {
        if (slopes.upper - slopes.lower >= kTouchingLevelMinBend) levels.emplace_back(a, b);
        continue;
      }
      const bool falls_away =
          slopes.lower <= (even_wall ? kOffClayLevelMaxSlope : kFallingLevelMaxSlope);
      const bool bends_down = close_clay && slopes.upper - slopes.lower >= kFallingLevelMinBend &&
                              level_wall(heights, kLevelStepMaxMm, kFallingLevelStepMaxSpread);
      if (falls_away || bends_down) levels.emplace_back(a, b);
    }
  }
  return levels;
}

// For each voxel of `among` that the watershed handed to another basin (by `tag`) than its
// sherd's, that basin; −1 for the others and for voxels not in `among`. Such a voxel lies nearer
// to another basin's core than to its own basin's, by more than `slack` (mm, along the surface; to
// its own along paths within the basin). The cores are the `seeds` of the basins marked in
// `judged`.
std::vector<int> leaked_to(const Graph& near, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& among,
                           const std::vector<std::pair<std::uint32_t, int>>& seeds,
                           const std::vector<int>& tag, const std::vector<std::uint8_t>& judged,
                           double slack) {
  std::vector<std::pair<std::uint32_t, int>> cores;  // by basin
  for (auto [v, c] : seeds) {
    if (judged[tag[v]]) cores.emplace_back(v, tag[v]);
  }
  std::vector<float> to_any(near.size()), to_own(near.size());
  std::vector<int> nearest(near.size()), own(near.size()), leaked(near.size(), -1);
  std::vector<std::uint8_t> inside(near.size(), 0);
  geodesic_from(near, centres, among, cores, to_any, nearest, inside);
  geodesic_from(near, centres, among, cores, to_own, own, inside, &tag);
  for (auto v : among) {
    if (nearest[v] != tag[v] && to_own[v] - to_any[v] > slack) leaked[v] = nearest[v];
  }
  return leaked;
}

// The voxels of `strip`, in part `own` by `tag`, that stay there when the strip goes to part
// `to` of another clay (see kStripMinOwnPieceMm2): the pieces, connected and `min_piece` voxels or
// more, whose colour — each voxel's summed with its neighbours' in the strip, against the noise of
// a few points — lies nearer the clay line of their own part (colour `own_rgb`, less the strip)
// than of the new one (`new_rgb`), and that border the rest of their own part in 3-D more than
// the new part. `mark` is scratch space, all zero (sized here for all voxels when empty).
std::vector<std::uint32_t> own_clay_pieces(const Graph& near,
                                           const std::vector<std::uint32_t>& strip,
                                           const std::vector<int>& tag, int own, int to,
                                           const std::vector<Vec3f>& voxel_rgb,
                                           const Vec3f& new_rgb, const Vec3f& own_rgb,
                                           std::size_t min_piece, std::vector<std::uint8_t>& mark) {
  mark.resize(near.size(), 0);
  for (auto v : strip) mark[v] = 1;
  std::vector<std::uint32_t> own_clay;
  for (auto v : strip) {
    Vec3f around = voxel_rgb[v];
    for (auto n : near[v]) {
      if (mark[n]) around += voxel_rgb[n];
    }
    if (off_either_line(around, own_rgb) < off_either_line(around, new_rgb)) own_clay.push_back(v);
  }
  for (auto v : strip) mark[v] = 0;
  for (auto v : own_clay) mark[v] = 1;
  const auto pieces = components(near, own_clay, mark);
  for (auto v : strip) mark[v] = 1;  // the neighbours outside the strip are what a piece borders
  std::vector<std::uint32_t> staying;
  for (const auto& piece : pieces) {
    if (piece.size() < min_piece) continue;
    std::size_t along_own = 0, along_new = 0;
    for (auto v : piece) {
      for (auto n : near[v]) {
        if (!mark[n]) along_own += tag[n] == own, along_new += tag[n] == to;
      }
    }
    if (along_own > along_new) staying.insert(staying.end(), piece.begin(), piece.end());
  }
  for (auto v : strip) mark[v] = 0;
  return staying;
}

// Whether `strip` (strip number `id` in `strip_of`, in part `from` by `tag`) lies along part `to`
// in the top view and hardly along the rest of its own part: its voxels with a top-view neighbour
// within `radius` in each (see kStripMaxTopViewFromShare).
bool lies_along_in_top_view(TopView& top, const std::vector<Vec3f>& centres,
                            const std::vector<std::uint32_t>& strip,
                            const std::vector<int>& strip_of, int id, const std::vector<int>& tag,
                            int to, int from, double radius) {
  std::size_t along_to = 0, along_from = 0;
  std::vector<int> found;
  for (auto v : strip) {
    top.search(centres[v], radius, found);
    bool by_to = false, by_from = false;
    for (auto f : found) {
      const auto n = top.voxel_at[f];
      by_to = by_to || tag[n] == to;
      by_from = by_from || (tag[n] == from && strip_of[n] != id);
    }
    along_to += by_to, along_from += by_from;
  }
  const auto size = static_cast<double>(strip.size());
  return along_to >= kStripMinTopViewToShare * size &&
         along_from <= kStripMaxTopViewFromShare * size;
}

// Gives the strips of `cluster` that the watershed handed to another part (by `tag`, `parts` of
// them; cores `seeds`) than their sherd's back to that one (see kStripMinAlongPairs): the voxels
// nearer another part's core than their own part's by more than `slack` (leaked_to) flood the
// cluster again as cores of the part they are nearer; the voxels that then change part make the
// strips, less the pieces of their old part's clay (own_clay_pieces).
void reclaim_leaked_strips(const Graph& near, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& cluster,
                           std::vector<std::pair<std::uint32_t, int>> seeds,
                           const std::vector<Vec3f>& voxel_rgb, const std::vector<float>& depth,
                           int parts, double slack, const CoreSizes& sizes, std::vector<int>& tag) {
  std::vector<std::uint8_t> judged(parts, 0);
  for (auto v : cluster) judged[tag[v]] = 1;
  if (std::count(judged.begin(), judged.end(), 1) < 2) return;
  for (auto& [v, part] : seeds) part = tag[v];
  const auto leaked = leaked_to(near, centres, cluster, seeds, tag, judged, slack);
  std::vector<std::uint8_t> leaks(static_cast<std::size_t>(parts) * parts, 0);  // [from][to]
  for (auto v : cluster) {
    if (leaked[v] < 0) continue;
    leaks[tag[v] * parts + leaked[v]] = 1;
    seeds.emplace_back(v, leaked[v]);
  }
  if (std::find(leaks.begin(), leaks.end(), 1) == leaks.end()) return;
  // The parts after the flood, where a voxel moves only from a part it leaked from to that part.
  std::vector<int> after(near.size(), -1);
  flood_from_cores(near, cluster, seeds, depth, after);
  for (auto v : cluster) {
    if (!leaks[tag[v] * parts + after[v]]) after[v] = tag[v];
  }
  // Each strip (moving voxels connected within their part, going to one part) goes over when it
  // shows that part's clay alone, or shows neither part's alone and lies along that part far longer
  // than along the rest of its own.
  std::vector<Vec3f> part_rgb(parts, Vec3f::Zero());  // before any strip goes over
  if (!voxel_rgb.empty())
    for (auto v : cluster) part_rgb[tag[v]] += voxel_rgb[v];
  std::vector<int> strip_of(near.size(), -1);
  std::unique_ptr<TopView> top;    // of the cluster, built when a strip needs it
  std::vector<std::uint8_t> mark;  // own_clay_pieces' scratch space
  std::vector<std::uint32_t> strip;
  int strips = 0;
  for (auto first : cluster) {
    if (after[first] == tag[first] || strip_of[first] >= 0) continue;
    const int from = tag[first], to = after[first];
    strip.assign(1, first);
    strip_of[first] = strips;
    for (std::size_t k = 0; k < strip.size(); ++k) {
      for (auto n : near[strip[k]]) {
        if (strip_of[n] < 0 && tag[n] == from && after[n] == to)
          strip_of[n] = strips, strip.push_back(n);
      }
    }
    std::size_t along_to = 0, along_from = 0;
    for (auto v : strip) {
      for (auto n : near[v]) {
        along_to += after[n] == to && strip_of[n] != strips;
        along_from += after[n] == from;
      }
    }
    bool goes = along_to >= kStripMinAlongPairs && along_to >= kStripMinAlongShare * along_from;
    bool of_other_clay = false;       // goes by colour, to a part of a clay apart from its own
    bool of_own_clay = false;         // stays by colour
    Vec3f from_rgb = part_rgb[from];  // less the strip
    if (!voxel_rgb.empty()) {
      Vec3f strip_rgb = Vec3f::Zero();
      for (auto v : strip) strip_rgb += voxel_rgb[v];
      from_rgb -= strip_rgb;
      const bool to_clay = off_either_line(strip_rgb, part_rgb[to]) < kStripMaxOffClayLine;
      const bool from_clay = off_either_line(strip_rgb, from_rgb) < kStripMaxOffClayLine;
      if (to_clay != from_clay) goes = to_clay;
      of_other_clay = to_clay && !from_clay &&
                      off_either_line(part_rgb[to], from_rgb) >= kStripTrimMinClaysApart;
      of_own_clay = from_clay && !to_clay;
    }
    if (!goes && !of_own_clay) {
      if (top == nullptr) top = std::make_unique<TopView>(centres, cluster);
      goes = lies_along_in_top_view(*top, centres, strip, strip_of, strips, tag, to, from, slack);
    }
    ++strips;
    if (!goes) continue;
    std::vector<std::uint32_t> staying;
    if (of_other_clay) {
      staying = own_clay_pieces(near, strip, tag, from, to, voxel_rgb, part_rgb[to], from_rgb,
                                sizes.min_own_clay_piece_voxels, mark);
    }
    for (auto v : strip) tag[v] = to;
    for (auto v : staying) tag[v] = from;
  }
}

// The bands of the borders between the parts (by `tag`; `parts` of them) in 3-D: band[a][b] is
// how many voxels of `among` in part a have a neighbour in part b. Voxels `leaked` to another
// basin (leaked_to, when given) are no part of a band.
std::vector<std::vector<std::size_t>> border_bands(const Graph& near,
                                                   const std::vector<std::uint32_t>& among,
                                                   const std::vector<int>& tag, int parts,
                                                   const std::vector<int>* leaked) {
  std::vector<std::vector<std::size_t>> band(parts, std::vector<std::size_t>(parts, 0));
  std::vector<int> beside;
  for (auto v : among) {
    if (leaked != nullptr && (*leaked)[v] >= 0) continue;
    beside.clear();
    for (auto n : near[v]) {
      if (tag[n] != tag[v]) add_once(beside, tag[n]);
    }
    for (int b : beside) ++band[tag[v]][b];
  }
  return band;
}

// A fracture face lies along its sherd's surface over its whole length: beside it in 3-D (the
// crease) or across a step (the face above or below the surface in the top view). A whole sherd
// whose colour happens to lie near another's clay line meets that one along a contact, short for
// its size. So a part stands as the other's face, across a border without a neck, only where its
// length — its area over its width — is at most kFaceMaxLengthPerBorder × the longer of its two
// borders with the other (in 3-D, across the step). Measured with a debug build (the pairs joined
// as a face and its surface over 80 runs of 100 trays — 1 / 1001 / 5001 / … / 15001, 133001 /
// 135001 / … / 275001 — and held-out tray 925082, with their truth): 30 faces of their own sherd
// were 0.33–1.90 × as long as that border; whole sherds taken for a face 2.55–10.2 × (273095,
// 145031, 151027, 11057, 925082), five more 0.95–1.85 × (195011, 257008, 205008, 231041, 13034:
// they lie along the other across a step). Over the 80 runs, beside the binary without it: 5
// trays made right (those four and 227023), none wrong; on 16 runs never run before (929001 /
// 931001 / … / 959001) 2 made right (939071, 945071), none wrong.
constexpr double kFaceMaxLengthPerBorder = 2.5;

// A fracture face meets its sherd's surface at a crease: across the border the face stands steep
// or the surface falls away to it. A whole sherd whose colour lies near another's clay line, lying
// beside it at about its height, runs on level with it. So where both parts run within
// kFlatFaceMaxSlope of level across the border (their slopes as the levels' rule measures them,
// see kFallingLevelMaxSlope), a part stands as the other's face only along a border
// kFlatFaceMinBorderShare × the narrower part's width or longer. Measured with a debug build
// (every pair joined as a face, with its truth and both slopes, over the 80 runs named above):
// the faces of their own sherd that ran level (both slopes within ±0.27) bordered it along
// 4.9–18.7 × their width; the whole sherds taken for a face that ran level, 0.71–3.48 × (231041,
// 195011, 13034; slopes up to 0.26). One sherd's faces along shorter borders had a slope of 0.34 or
// steeper (211086, 167015). Over the 80 runs, beside the binary without it: those three trays made
// right, no other tray's figures moved; on 16 runs never run before (1353001 / 1355001 / … /
// 1383001) no tray moved. Refusing every face along so short a border, whatever its slopes, made
// 205008 right too but split 221038, 273095 and 275042 (faces sloping off along 1.47–2.29 ×).
constexpr double kFlatFaceMaxSlope = 0.3;
constexpr double kFlatFaceMinBorderShare = 4.0;

// Pairs (a, b) of parts (by `tag`, widths `width` and `face_width` as for levels_of_one_sherd) with
// no neck between them, among the voxels `among` of the parts marked in `judged` (whose top view
// is `top`); voxels `leaked` to another basin (leaked_to, when given) are no part of a border. A
// pair whose surface runs on across the border (by its step `borders`, see kSmoothMaxStepShare)
// needs a shorter one.
std::vector<std::pair<int, int>> parts_without_neck(
    const Graph& near, TopView& top, const std::vector<Vec3f>& centres,
    const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
    const std::vector<double>& width, const std::vector<double>& face_width,
    const std::vector<std::uint8_t>& judged, const std::vector<int>* leaked,
    const std::vector<Vec3f>& core_rgb, const StepBorders& borders, double radius) {
  const int parts = static_cast<int>(core_rgb.size());
  const auto band = border_bands(near, among, tag, parts, leaked);
  const double leaf = radius / kVoxelsPerTolerance;
  std::vector<double> area_mm2(parts, 0.0);
  for (auto v : among) area_mm2[tag[v]] += leaf * leaf;
  std::vector<std::pair<int, int>> pairs;
  for (int a = 0; a < parts; ++a) {
    for (int b = a + 1; b < parts; ++b) {
      if (!judged[a] || !judged[b] || band[a][b] == 0) continue;
      const double border_mm = border_length_mm(band[a][b], band[b][a], radius);
      const double narrower_mm = std::min(width[a], width[b]);
      const double along_mm =
          std::max(border_mm, border_length_mm(borders.band[a][b], borders.band[b][a], radius));
      auto as_face = [&](int p) {  // p's width as the other's face (see kFaceMaxLengthPerBorder)
        return area_mm2[p] <= kFaceMaxLengthPerBorder * along_mm * face_width[p]
                   ? face_width[p]
                   : std::numeric_limits<double>::infinity();
      };
      const bool one_clay = of_one_clay(core_rgb[a], as_face(a), core_rgb[b], as_face(b),
                                        kNoNeckMaxHueDifference, kFaceMaxOffClayLine);
      const auto& heights = borders.heights[a][b];
      const bool one_hue = (hue(core_rgb[a]) - hue(core_rgb[b])).norm() < kNoNeckMaxHueDifference;
      const bool smooth = heights.size() <= kSmoothMaxStepShare * borders.contacts[a][b] && one_hue;
      const double least_share = smooth ? kSmoothMinBorderShare : kNoNeckMinBorderShare;
      if (border_mm < least_share * narrower_mm || !one_clay) continue;
      if (!one_hue && border_mm < kFlatFaceMinBorderShare * narrower_mm) {  // joined as a face
        const auto slopes =
            slopes_across(top, centres, among, tag, a, b, borders.b_upper(a, b), radius);
        if (std::abs(slopes.upper) < kFlatFaceMaxSlope &&
            std::abs(slopes.lower) < kFlatFaceMaxSlope)
          continue;
      }
      pairs.emplace_back(a, b);
    }
  }
  return pairs;
}

// A narrow sherd touching a wider one may keep no core `erosion` deep, nor a shallow one of its
// own: the region kShallowCoreShare × erosion deep around its deepest point reaches into the
// wider sherd across the contact, or is too small. Its surface still rises to a depth maximum of
// its own, and the depth falls far from that top to the contact: a lobe with a high dynamic (the
// fall from a regional maximum to the saddle where it meets a deeper one, as in a component
// tree). So a lobe whose top lies kLobeMinTopShare × erosion deep or more, that falls
// kLobeMinDynamicShare × erosion to its saddle, and whose voxels above the saddle hold
// kLobeMinCoreShare × min_own_core_voxels or more is a core when no core lies in it. A sherd's own
// lobe behind a narrow neck (a protruding corner, a level reached round the end of an unseen
// wall) looks the same, but shows the same clay as the rest of its sherd — its colour, or that
// colour mixed with grey, within kFaceMaxOffClayLine of that line: such a lobe's basin joins the
// basin it borders most, before any other join — unless it covers a sherd's area
// (min_own_basin_voxels) beside a wide core, as a shallow core's part stays. Measured with a
// debug build on 10 runs (1, 1001, 5001, 7001, 133001, 137001, 147001, 149001, 175001, 195001):
// the narrow sherds merged for want of a core had lobes 3.98–4.95 mm deep falling 3.1–4.6 mm to
// the contact; the three first made right (trays 133062, 137014, 195091) lay 0.014–0.018 off the
// line of the part they had joined, three sherds' own lobes (trays 33, 1025, 5056) 0.0001–0.0011
// off their sherd's. Over 80 runs of 100 trays (those 10 and 70 more), beside the binary
// without lobes in the same session: 17 trays made right, 7 wrong; merged sherds 72 → 69, split
// 100 → 93, exact count 7,896 → 7,899. Six runs never run before (277001, …, 287001): 2 made
// right, 1 wrong, exact count 588 of 600 both. Without the sherd's-area exception, over the 80
// runs: 17 made right, 9 wrong.
// A whole small sherd of its neighbour's clay rises to a lobe too; like a small core's basin (see
// kSmallSherdMaxStepBandMm2) a lobe's basin of half a sherd's area beside a wide core, not without
// a neck and not behind a step unless rising away from it, stays apart. Measured with a debug build
// (every lobe joined on 12 runs, 159001 / 177001 / … / 253001, with its truth): the 178 lobes of
// their own sherd had 49 or more voxels beside a step; two whole small sherds (193051, 271022) 13
// and 26. Over the 80 runs, beside the binary without it: 193051, 271022 and 263064 made right,
// none wrong.
constexpr double kLobeMinTopShare = 0.8;
constexpr double kLobeMinDynamicShare = 0.6;
constexpr double kLobeMinCoreShare = 2.0;

// A small core's basin is mostly the far side of a step inside its sherd, and joins the basin it
// touches most in 3-D. Where that far side also touches another sherd at its own height, the 3-D
// border can be longer there than across the (unseen) wall to its own sherd, and it went to the
// wrong one. So a small core's basin whose colour lies kSmallCoreAcrossStep or more off the clay
// line of the basin it touches most, and within it of the line of the basin it borders most
// across a step (top-view neighbours apart in 3-D), joins that basin. Measured with a debug build
// on six runs of 100 trays (133001, 141001, 143001, 145001, 147001, 149001): of 81 small cores'
// basins joined, 13 joined another sherd than their own; seven of those lay 0.0004–0.0016 off the
// line of the basin across the step, their own sherd, and 0.021–0.11 off the one they touched
// (the others fit both or neither); of those joined rightly, the three with more step pairs to
// another basin than 3-D pairs to their own lay 0.0004–0.0008 off their own and 0.024–0.059 off
// the other. Over 80 runs (1 / 1001 / … / 15001, 133001 / 135001 / … / 275001), beside the binary
// without it: 4 trays made right (143048, 153056, 163056, 173013), none wrong; on eight runs never
// run before (353001 / 355001 / … / 367001) 1 made right (359017), none wrong.
constexpr double kSmallCoreAcrossStep = 0.008;
// A band's or small core's basin is the far side of a step inside its sherd or that sherd's
// fracture face (its clay mixed with grey, on the clay's line to grey) — or a small sherd of its
// own, which the colour split parts off again later only where its clay covers kClayMinMm2. So such
// a basin joins no basin whose clay line its colour lies kSmallBasinMinOffClayLine or more off.
// Measured with a debug build (every band's and small core's basin joined over 12 runs: 1, 1001,
// 5001, …, 15001, 133001, …, 139001; 608 joins with their truth): of the 598 joined rightly, one
// lay 0.027 off the line (a band holding 146 voxels of the other sherd) and the rest at most
// 0.014; of the 10 joined wrongly, 5 lay 0.032–0.066 off, two of them left merged (221011,
// 223030), the others parted by the colour split. Such a basin joins instead the basin it touches
// most among those whose clay line it lies within kSmallCoreAcrossStep of, or stays apart: in
// 231039 a far side of one sherd touched the other sherd a little more than its own (496 against
// 445 neighbour pairs), and 221011's band touched a third sherd 0.027 off its line at 10 pairs.
constexpr double kSmallBasinMinOffClayLine = 0.03;
// The far side of a step inside a sherd lies along the rest of it across the step over its whole
// length, and may touch it in 3-D only round the wall's ends. Where its end also touches another
// sherd in 3-D, that contact can be the longer border, and the clay bound above does not part
// them when the two clays are close. So a band's or small core's basin with kAlongStepMinPairs ×
// or more step pairs with the basin it borders most across a step than 3-D pairs with the one it
// touches most joins across the step when its colour lies within kSmallCoreAcrossStep of that
// basin's clay line and no farther off it than off the touched one's. Measured with a debug build
// (every band's and small core's basin joined over 80 runs of 100 trays, 1 / 1001 / 5001 / … /
// 15001, 133001 / 135001 / … / 275001, 4,167 joins, with its truth): it changes 19 joins, all to
// the basin's own sherd, 8 of them joined to another before (trays 1022, 7008, 11019, 11074,
// 13045, 181047, 195093, 243017: 8.6–217 × as many step pairs, 0.0006–0.0040 off the line
// across, 0.0019–0.0066 off the touched one's); at 6.3 × a band whose colour fits both (0.0007,
// 0.0009 off; tray 137009) would go across to another sherd. Beside the binary without it, over
// those 80 runs: 11019 and 243017 made right, none wrong, 8 trays gained precision or recall, none
// lost; on 16 runs never run before (865001 / 867001 / … / 895001) no tray's count moved, one lost
// 0.21 % (893098: its band now goes to its own sherd, a corner of that sherd to the neighbour).
constexpr double kAlongStepMinPairs = 8.0;

// A band's or small core's basin that lies along another across a step may be a level of its own
// sherd cut off from the rest: the watershed flooded the rest from the other sherd's core through
// their contact (a sherd leaning on another, its raised end on it). That rest is the part of the
// basin across the step nearer c's step partners than the cores inside it (part_across_step): a
// lobe that meets the rest of its basin along a contact, short for its size, and holds little of
// it; the far side of a step inside a sherd instead meets the rest of its own basin along the
// whole wall, or is most of its basin. So where the basin across the step has kAlongStepMinPairs
// × as many step pairs as the joining one's longest 3-D border, and that part of it has fewer
// than kLeakedLevelMaxBorderShare × its voxels 3-D pairs with the rest and under
// kLeakedLevelMaxShare × the basin, the part goes to the joining basin, which joins neither.
// Measured with a debug build (every band's and small core's basin joined across a step over 16
// runs of 100 trays holding such joins made wrongly — 11001, 139001, 143001, 147001, 159001,
// 173001, 177001, 189001, 197001, 205001, 227001, 233001, 243001, 247001, 253001, 255001 —
// 861 joins, with truth): that part's border was 0.055–0.72 × its voxels for 10 joins to another
// sherd whose part was the joining basin's own sherd (0.90–1.0 of its step partners), 1.0–11 ×
// (median 3.5) for the 120 right joins with as many step pairs, and for the 10 right joins below
// 1.0 × the part was 0.5–0.96 of its basin (two halves of one sherd), the 10 wrong 0.14–0.35.
constexpr double kLeakedLevelMaxBorderShare = 1.0;
constexpr double kLeakedLevelMaxShare = 0.5;

// A narrow sherd beside a wider one, its core too small to be a sherd's by itself, stays apart
// when its basin covers min_own_basin_voxels. Where the sherd narrows inside (a neck between its
// core and an end of it), the watershed reached that end from the wider sherd's core across the
// contact, the basin fell short, and the narrow sherd joined the wider one. So a small core's
// basin beside a wide core gets back, before it is judged, the voxels leaked_to it — nearer its
// core than their own basin's by more than the erosion, along the surface — when it then covers
// min_own_basin_voxels and they are no more than kSmallCoreMaxReclaimShare × its size: they seed
// the watershed again with its core, so that it now meets the wider sherd at their contact. The
// far side of a step inside a sherd, behind the unseen wall from the rest, is nearer its own small
// core than the rest's in the same way, but its basin holds little of that (the flood from the
// deep core reaches round the wall's end first). Measured with a debug build (every small core's
// basin judged over 80 runs of 100 trays, 1 / 1001 / 5001 / … / 15001, 133001 / 135001 / … /
// 275001, with its truth): of those beside a wide core that the voxels leaked to them would bring
// to min_own_basin_voxels, six were narrow sherds (trays 147088, 161019, 167053, 171079, 255039,
// 259088; leaked voxels 0.09–0.51 × the basin, all of the basin's sherd) and one a sherd's far
// side (161015: 4.6 ×). Beside the binary without it, over those 80 runs: 161019 made right,
// 171079 left split (a sixth of it still in its neighbour) where it was merged, no other count
// moved.
constexpr double kSmallCoreMaxReclaimShare = 1.0;

// The voxels above the saddle of each regional maximum of `depth` over `cluster` whose top is
// `min_top` deep or more, that falls `min_dynamic` or more to that saddle and holds `min_voxels`
// or more, deepest top first. One sweep in order of decreasing depth joins each voxel to the
// components of its neighbours already swept (union-find); where two meet, the one with the lower
// top ends at that saddle. The cluster's deepest maximum has no saddle. `cluster` is a whole
// component of `near`; `local` is scratch space sized for all voxels.
std::vector<std::vector<std::uint32_t>> prominent_lobes(
    const Graph& near, const std::vector<std::uint32_t>& cluster, const std::vector<float>& depth,
    double min_top, double min_dynamic, std::size_t min_voxels, std::vector<int>& local) {
  const auto n = static_cast<std::uint32_t>(cluster.size());
  for (std::uint32_t k = 0; k < n; ++k) local[cluster[k]] = static_cast<int>(k);
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return depth[cluster[a]] > depth[cluster[b]];
  });
  std::vector<int> parent(n, -1);  // −1: not swept yet
  std::vector<float> top(n);       // per component root
  // Each component's voxels as a linked list (first, last, count per root; next per voxel): a
  // merge splices the smaller list after the larger in constant time, with no allocation per
  // voxel.
  constexpr std::uint32_t kEnd = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> first(n), last(n), next(n, kEnd), count(n);
  auto root = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<std::pair<float, std::vector<std::uint32_t>>> lobes;  // (top, voxels)
  for (auto k : order) {
    const float level = depth[cluster[k]];
    parent[k] = static_cast<int>(k), top[k] = level, first[k] = last[k] = k, count[k] = 1;
    for (auto neighbour : near[cluster[k]]) {
      const int j = local[neighbour];
      if (parent[j] < 0) continue;  // not swept yet
      int a = root(static_cast<int>(k)), b = root(j);
      if (a == b) continue;
      if (top[a] < top[b]) std::swap(a, b);  // b ends here
      if (top[b] >= min_top && top[b] - level >= min_dynamic && count[b] >= min_voxels) {
        std::vector<std::uint32_t> lobe;
        lobe.reserve(count[b]);
        for (auto i = first[b]; i != kEnd; i = next[i]) lobe.push_back(cluster[i]);
        lobes.emplace_back(top[b], std::move(lobe));
      }
      if (count[a] >= count[b]) {
        next[last[a]] = first[b], last[a] = last[b];
      } else {
        next[last[b]] = first[a], first[a] = first[b];
      }
      count[a] += count[b];
      parent[b] = a;
    }
  }
  std::sort(lobes.begin(), lobes.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<std::vector<std::uint32_t>> voxels;
  for (auto& [depth_of_top, lobe] : lobes) voxels.push_back(std::move(lobe));
  return voxels;
}

// The step pairs of the basins (by `tag`; asked.size() of them) marked in `asked`: top-view
// neighbours within `radius` that are not 3-D neighbours.
struct StepPairs {
  std::vector<int> most_across;  // by basin: the basin it has most pairs with; −1 for none
  std::vector<std::size_t> most_across_pairs;  // by basin: how many pairs with most_across
  std::vector<std::uint8_t> beside_step;       // by voxel: whether it is in one
};
StepPairs step_pairs(TopView& top, const std::vector<Vec3f>& centres,
                     const std::vector<std::uint32_t>& cluster, const std::vector<int>& tag,
                     const std::vector<std::uint8_t>& asked, double radius) {
  const int basins = static_cast<int>(asked.size());
  StepPairs steps{std::vector<int>(basins, -1), std::vector<std::size_t>(basins, 0),
                  std::vector<std::uint8_t>(centres.size(), 0)};
  std::vector<std::vector<std::size_t>> pairs(basins);
  std::vector<int> found;
  for (auto v : cluster) {
    if (!asked[tag[v]]) continue;
    auto& counts = pairs[tag[v]];
    counts.resize(basins, 0);
    for_each_step_pair(top, centres, tag, v, radius, found, [&](std::uint32_t n) {
      ++counts[tag[n]];
      steps.beside_step[v] = 1;
    });
  }
  for (int c = 0; c < basins; ++c) {
    const auto& counts = pairs[c];
    if (counts.empty()) continue;
    const auto most = std::max_element(counts.begin(), counts.end());
    if (*most == 0) continue;
    steps.most_across[c] = static_cast<int>(most - counts.begin());
    steps.most_across_pairs[c] = *most;
  }
  return steps;
}

// The part of basin `across` across a step from basin c: its voxels nearer, in steps along `near`
// inside it, to those of its voxels that c's voxels have step pairs with than to the cores' seeds
// inside it; with how many 3-D neighbour pairs join that part to the rest of the basin, and the
// basin's size. Hop counts sit in hash maps: the basin is a few thousand of the scene's voxels.
struct PartAcrossStep {
  std::vector<std::uint32_t> voxels;
  std::size_t border = 0;
  std::size_t basin_size = 0;
};
PartAcrossStep part_across_step(const Graph& near, TopView& top, const std::vector<Vec3f>& centres,
                                const std::vector<std::uint32_t>& cluster,
                                const std::vector<int>& tag,
                                const std::vector<std::pair<std::uint32_t, int>>& seeds, int c,
                                int across, double radius) {
  using Hops = std::unordered_map<std::uint32_t, int>;
  auto hops_from = [&](std::vector<std::uint32_t> queue) {
    Hops hops;
    for (auto v : queue) hops.emplace(v, 0);
    for (std::size_t i = 0; i < queue.size(); ++i) {
      const int next = hops[queue[i]] + 1;
      for (auto n : near[queue[i]])
        if (tag[n] == across && hops.emplace(n, next).second) queue.push_back(n);
    }
    return hops;
  };
  std::vector<std::uint32_t> start;
  for (auto [v, core] : seeds)
    if (core == across && tag[v] == across) start.push_back(v);
  const Hops from_seeds = hops_from(start);
  start.clear();
  std::vector<int> found;
  for (auto v : cluster) {
    if (tag[v] != c) continue;
    for_each_step_pair(top, centres, tag, v, radius, found, [&](std::uint32_t n) {
      if (tag[n] == across) start.push_back(n);
    });
  }
  std::sort(start.begin(), start.end());
  start.erase(std::unique(start.begin(), start.end()), start.end());
  const Hops from_step = hops_from(start);
  auto in_part = [&](std::uint32_t v) {
    const auto step = from_step.find(v);
    if (step == from_step.end()) return false;
    const auto seed = from_seeds.find(v);
    return seed == from_seeds.end() || step->second < seed->second;
  };
  PartAcrossStep part;
  for (auto v : cluster) {
    if (tag[v] != across) continue;
    ++part.basin_size;
    if (!in_part(v)) continue;
    part.voxels.push_back(v);
    for (auto n : near[v]) part.border += tag[n] == across && !in_part(n);
  }
  return part;
}

// The voxels of `cluster` as parts by the group of their basin (`tag`), appended to `parts`.
void append_parts(const std::vector<std::uint32_t>& cluster, const std::vector<int>& tag,
                  Groups& group, int groups, std::vector<std::vector<std::uint32_t>>& parts) {
  std::vector<int> part_of(groups, -1);
  for (auto v : cluster) {
    const int g = group.root(tag[v]);
    if (part_of[g] < 0) part_of[g] = static_cast<int>(parts.size()), parts.emplace_back();
    parts[part_of[g]].push_back(v);
  }
}

// Whether part b lies above part a (by `tag` among `among`, whose top view is `top`): most of a's
// step pairs with b rise to b.
bool lies_above(TopView& top, const std::vector<Vec3f>& centres,
                const std::vector<std::uint32_t>& among, const std::vector<int>& tag, int a, int b,
                double radius) {
  std::size_t pairs = 0, rises = 0;
  std::vector<int> found;
  for (auto v : among) {
    if (tag[v] != a) continue;
    for_each_step_pair(top, centres, tag, v, radius, found, [&](std::uint32_t n) {
      if (tag[n] != b) return;
      ++pairs;
      rises += centres[n].z() > centres[v].z();
    });
  }
  return 2 * rises > pairs;
}

}  // namespace

SlopesAcross slopes_across(TopView& top, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
                           int a, int b, bool b_upper, double radius) {
  const int lower = b_upper ? a : b;
  constexpr std::uint8_t kInBand = 1, kNearBand = 2;
  std::vector<std::uint8_t> mark(centres.size(), 0);
  std::vector<std::uint32_t> band;  // voxels of either level in a step pair with the other
  std::vector<int> found;
  auto add_to_band = [&](std::uint32_t v) {
    if (!(mark[v] & kInBand)) mark[v] |= kInBand, band.push_back(v);
  };
  for (auto v : among) {
    if (tag[v] != a) continue;
    for_each_step_pair(top, centres, tag, v, radius, found, [&](std::uint32_t n) {
      if (tag[n] == b) add_to_band(v), add_to_band(n);
    });
  }
  // By side: [0] the upper level's, [1] the lower's.
  Eigen::Vector2d band_sum[2] = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  std::size_t band_count[2] = {0, 0};
  std::vector<std::uint32_t> near_band[2];
  for (auto v : band) {
    const int side = tag[v] == lower;
    band_sum[side] += centres[v].head<2>().cast<double>();
    ++band_count[side];
    top.search(centres[v], kFallingLevelNearMm, found);
    for (auto f : found) {
      const auto n = top.voxel_at[f];
      if ((tag[n] != a && tag[n] != b) || (mark[n] & kNearBand)) continue;
      mark[n] |= kNearBand;
      near_band[tag[n] == lower].push_back(n);
    }
  }
  if (band_count[0] == 0 || band_count[1] == 0) return {std::nan(""), std::nan("")};
  const Eigen::Vector2d across =
      (band_sum[1] / band_count[1] - band_sum[0] / band_count[0]).normalized();
  // A level's slope along `across`; none (NaN) for too few voxels or a plane about as steep as a
  // wall (normal.z near 0), which has no meaningful slope.
  auto slope_of = [&](const std::vector<std::uint32_t>& voxels) {
    if (voxels.size() < kFallingLevelMinPlaneVoxels) return std::nan("");
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (auto v : voxels) mean += centres[v].cast<double>();
    mean /= static_cast<double>(voxels.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (auto v : voxels) {
      const Eigen::Vector3d d = centres[v].cast<double>() - mean;
      scatter += d * d.transpose();
    }
    const Eigen::Vector3d normal =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
    if (std::abs(normal.z()) < kFallingLevelMinNormalZ) return std::nan("");
    return -normal.head<2>().dot(across) / normal.z();
  };
  return {slope_of(near_band[0]), slope_of(near_band[1])};
}

SlopesAcross slopes_across(TopView& top, const std::vector<Vec3f>& centres,
                           const std::vector<std::uint32_t>& among, const std::vector<int>& tag,
                           int a, int b, double radius) {
  return slopes_across(top, centres, among, tag, a, b,
                       lies_above(top, centres, among, tag, a, b, radius), radius);
}

bool level_wall(std::vector<float>& heights, double max_mm, double max_spread) {
  if (heights.size() < kLevelMinStepPairs) return false;
  const double q10 = quantile_of(heights, 0.1), q90 = quantile_of(heights, 0.9);
  return q10 >= kLevelStepMinMm && q90 <= max_mm && q90 <= max_spread * q10;
}

std::vector<std::vector<std::uint32_t>> split_at_contacts(
    const Graph& near, const std::vector<Vec3f>& centres, const std::vector<Vec3f>& voxel_rgb,
    const std::vector<std::uint32_t>& cluster, double radius, double erosion,
    const CoreSizes& sizes, std::vector<float>& distance, std::vector<int>& tag,
    ContactStages* stages) {
  std::vector<std::uint8_t> core(near.size(), 0);
  geodesic_from(near, centres, cluster, boundary_of(near, centres, cluster, radius, core), distance,
                tag, core);
  for (auto v : cluster) core[v] = distance[v] >= erosion;
  std::vector<std::pair<std::uint32_t, int>> seeds;
  std::vector<std::size_t> core_size;
  for (const auto& c : components(near, cluster, core)) {
    if (c.size() < sizes.min_core_voxels) continue;
    for (auto v : c) seeds.emplace_back(v, static_cast<int>(core_size.size()));
    core_size.push_back(c.size());
  }
  // Lobes (see kLobeMinTopShare), deepest top first, that hold no core's voxels nor another
  // lobe's: cores that count as deep ones.
  const int lobes_begin = static_cast<int>(core_size.size());
  for (auto v : cluster) core[v] = 0;
  for (auto [v, c] : seeds) core[v] = 1;
  for (auto& lobe : prominent_lobes(near, cluster, distance, kLobeMinTopShare * erosion,
                                    kLobeMinDynamicShare * erosion,
                                    kLobeMinCoreShare * sizes.min_own_core_voxels, tag)) {
    if (std::any_of(lobe.begin(), lobe.end(), [&](std::uint32_t v) { return core[v] != 0; }))
      continue;
    for (auto v : lobe) seeds.emplace_back(v, static_cast<int>(core_size.size())), core[v] = 1;
    core_size.push_back(lobe.size());
  }
  const int deep_cores = static_cast<int>(core_size.size());
  // Regions `depth` deep or more that hold no core yet and have min_own_core_voxels: cores.
  auto add_cores_at = [&](double depth) {
    for (auto v : cluster) core[v] = distance[v] >= depth;
    for (auto [v, c] : seeds) core[v] = 2;
    for (const auto& c : components(near, cluster, core)) {
      if (c.size() < sizes.min_own_core_voxels ||
          std::any_of(c.begin(), c.end(), [&](std::uint32_t v) { return core[v] == 2; }))
        continue;
      for (auto v : c) seeds.emplace_back(v, static_cast<int>(core_size.size()));
      core_size.push_back(c.size());
    }
  };
  add_cores_at(kShallowCoreShare * erosion);  // shallow cores (see kShallowCoreShare)
  const int shallow_end = static_cast<int>(core_size.size());
  add_cores_at(kBandCoreShare * erosion);  // band cores (see kBandCoreShare)
  for (auto v : cluster) core[v] = 0;      // `core` is sized for all voxels; leave it clean
  const int cores = static_cast<int>(core_size.size());
  if (cores < 2) {
    if (stages != nullptr) {
      stages->basins.push_back(cluster);
      stages->small_cores.push_back(cluster);
    }
    return {cluster};
  }
  flood_from_cores(near, cluster, seeds, distance, tag);
  Groups group(cores);
  if (stages != nullptr) append_parts(cluster, tag, group, cores, stages->basins);
  std::vector<std::vector<std::size_t>> border;  // neighbour pairs between basins
  std::vector<std::size_t> basin_size;
  auto measure_basins = [&] {
    border.assign(cores, std::vector<std::size_t>(cores, 0));
    basin_size.assign(cores, 0);
    for (auto v : cluster) {
      ++basin_size[tag[v]];
      for (auto n : near[v]) border[tag[v]][tag[n]] += tag[n] != tag[v];
    }
  };
  std::optional<TopView> cluster_top;  // built once, when the first step pairs are asked for
  auto top_view = [&]() -> TopView& {
    if (!cluster_top) cluster_top.emplace(centres, cluster);
    return *cluster_top;
  };
  auto longest_border = [&](int c) {
    return static_cast<int>(std::max_element(border[c].begin(), border[c].end()) -
                            border[c].begin());
  };
  // The basins marked in `asked` that are whole small sherds touching a wide core's basin (see
  // kSmallSherdMaxStepBandMm2): half min_own_basin_voxels or more, beside a wide core, not without
  // a neck, and not behind a step — for lobes, unless rising away from it
  // (kSmallSherdMinLowerRise); band cores' basins of a sherd's area, not along a step
  // (kBandSherdMaxStepBandShare).
  enum class Asked { kSmallCores, kLobes, kBands };
  auto small_sherds_among = [&](std::vector<std::uint8_t> asked, Asked kind) {
    bool any = false;
    for (int c = 0; c < cores; ++c) {
      const std::size_t area = kind == Asked::kBands ? basin_size[c] : 2 * basin_size[c];
      asked[c] = asked[c] && area >= sizes.min_own_basin_voxels &&
                 core_size[longest_border(c)] >= sizes.min_wide_core_voxels;
      any |= asked[c] != 0;
    }
    if (!any) return asked;
    const auto beside_step =
        step_pairs(top_view(), centres, cluster, tag, asked, radius).beside_step;
    const auto band = border_bands(near, cluster, tag, cores, nullptr);
    std::vector<std::size_t> step_band(cores, 0);
    std::vector<double> width(cores, 0.0);
    for (auto v : cluster) {
      if (!asked[tag[v]]) continue;
      step_band[tag[v]] += beside_step[v];
      width[tag[v]] = std::max(width[tag[v]], 2.0 * distance[v]);
    }
    for (int c = 0; c < cores; ++c) {
      if (!asked[c]) continue;
      const int longest = longest_border(c);
      const double border_mm = border_length_mm(band[c][longest], band[longest][c], radius);
      // Beside a step, the lower of the two rising away from it (see kSmallSherdMinLowerRise).
      auto lower_rises_away = [&] {
        return slopes_across(top_view(), centres, cluster, tag, c, longest, radius).lower >=
               kSmallSherdMinLowerRise;
      };
      const bool behind_step = kind == Asked::kBands
                                   ? step_band[c] >= kBandSherdMaxStepBandShare * basin_size[c]
                                   : step_band[c] >= sizes.max_small_sherd_step_band_voxels &&
                                         !(kind == Asked::kLobes && lower_rises_away());
      asked[c] = border_mm < kNoNeckMinBorderShare * width[c] && !behind_step;
    }
    return asked;
  };
  // Each basin marked in `joining` joins the basin it borders most (by `border`) or the one it
  // borders most across a step, when its colour shows that it is not the clay of the first but is
  // of the second (kSmallCoreAcrossStep), or when it lies along the second far longer than it
  // touches the first and is no nearer the first's clay (kAlongStepMinPairs).
  auto join_touched_or_across = [&](const std::vector<std::uint8_t>& joining) {
    std::vector<Vec3f> basin_rgb(cores, Vec3f::Zero());
    StepPairs steps;
    if (!voxel_rgb.empty() && std::find(joining.begin(), joining.end(), 1) != joining.end()) {
      for (auto v : cluster) basin_rgb[tag[v]] += voxel_rgb[v];
      steps = step_pairs(top_view(), centres, cluster, tag, joining, radius);
    }
    // No far side or face of a sherd lies far off its clay's line: c joins `to` unless its colour
    // lies kSmallBasinMinOffClayLine or more off it, else the basin it touches most among those
    // whose clay line it lies on (within kSmallCoreAcrossStep), if any.
    auto of_another_clay = [&](int c, int to) {
      return !voxel_rgb.empty() &&
             off_either_line(basin_rgb[c], basin_rgb[to]) >= kSmallBasinMinOffClayLine;
    };
    auto join_of_its_clay = [&](int c, int to) {
      if (of_another_clay(c, to)) {
        to = -1;
        for (int q = 0; q < cores; ++q) {
          if (q != c && border[c][q] > 0 &&
              off_either_line(basin_rgb[c], basin_rgb[q]) < kSmallCoreAcrossStep &&
              (to < 0 || border[c][q] > border[c][to]))
            to = q;
        }
      }
      if (to >= 0) group.join(c, to);
    };
    for (int c = 0; c < cores; ++c) {
      if (!joining[c]) continue;
      const int longest = longest_border(c);
      const int across = steps.most_across.empty() ? -1 : steps.most_across[c];
      if (across < 0) {
        join_of_its_clay(c, longest);
        continue;
      }
      const float off_touched = off_either_line(basin_rgb[c], basin_rgb[longest]);
      const float off_across = off_either_line(basin_rgb[c], basin_rgb[across]);
      const bool clay_across_step =
          off_touched >= kSmallCoreAcrossStep && off_across < kSmallCoreAcrossStep;
      const bool along_step =
          steps.most_across_pairs[c] >= kAlongStepMinPairs * border[c][longest] &&
          off_across < kSmallCoreAcrossStep && off_across <= off_touched;
      const int to = across == longest || clay_across_step || along_step ? across : longest;
      if (to == across && steps.most_across_pairs[c] >= kAlongStepMinPairs * border[c][longest]) {
        const auto part =
            part_across_step(near, top_view(), centres, cluster, tag, seeds, c, across, radius);
        if (part.border < kLeakedLevelMaxBorderShare * part.voxels.size() &&
            part.voxels.size() < kLeakedLevelMaxShare * part.basin_size) {
          for (auto v : part.voxels) tag[v] = c;  // a level of c's sherd: c and it stay apart
          continue;
        }
      }
      join_of_its_clay(c, to);
    }
  };
  // A lobe of its neighbour's clay is that sherd's own (see kLobeMinTopShare).
  if (deep_cores > lobes_begin) {
    measure_basins();
    std::vector<Vec3f> basin_rgb(cores, Vec3f::Zero());
    if (!voxel_rgb.empty())
      for (auto v : cluster) basin_rgb[tag[v]] += voxel_rgb[v];
    std::vector<std::uint8_t> lobe(cores, 0);
    for (int c = lobes_begin; c < deep_cores; ++c) lobe[c] = 1;
    const auto small_sherd = small_sherds_among(lobe, Asked::kLobes);
    for (int c = lobes_begin; c < deep_cores; ++c) {
      const int longest = longest_border(c);
      const bool own_clay = voxel_rgb.empty() ||
                            off_either_line(basin_rgb[c], basin_rgb[longest]) < kFaceMaxOffClayLine;
      const bool sherds_area = basin_size[c] >= sizes.min_own_basin_voxels &&
                               core_size[longest] >= sizes.min_wide_core_voxels;
      if (border[c][longest] > 0 && own_clay && !sherds_area && !small_sherd[c])
        group.join(c, longest);
    }
    for (auto v : cluster) tag[v] = group.root(tag[v]);
  }
  // Band cores' basins join next (see kBandCoreShare), so that the shallow cores are judged by
  // the basins they then have; a narrow sherd's stays apart (kBandSherdMaxStepBandShare).
  if (cores > shallow_end) {
    measure_basins();
    std::vector<std::uint8_t> joining(cores, 0);
    for (int c = shallow_end; c < cores; ++c) joining[c] = border[c][longest_border(c)] > 0;
    const auto band_sherd = small_sherds_among(joining, Asked::kBands);
    for (int c = shallow_end; c < cores; ++c) joining[c] = joining[c] && !band_sherd[c];
    join_touched_or_across(joining);
    for (auto v : cluster) tag[v] = group.root(tag[v]);
  }
  // Shallow cores' basins then, until none joins: one joins the basin it borders most unless
  // it is a sherd's (min_own_basin_voxels) beside a wide core. Its voxels go over, so that the
  // small deep cores below are judged by the basins they then have.
  for (bool joined = true; joined;) {
    measure_basins();
    joined = false;
    for (int c = deep_cores; c < shallow_end; ++c) {
      const int longest = longest_border(c);
      if (border[c][longest] == 0 || (basin_size[c] >= sizes.min_own_basin_voxels &&
                                      core_size[longest] >= sizes.min_wide_core_voxels))
        continue;
      group.join(c, longest);
      joined = true;
    }
    if (joined)
      for (auto v : cluster) tag[v] = group.root(tag[v]);
  }
  // A small core's basin joins the neighbouring basin it has most neighbour pairs with — for the
  // far side of a step, mostly the only one: the rest of its sherd — or the one across the step
  // that its colour shows (join_touched_or_across). A large basin around a small core is a sherd
  // too narrow for the erosion to leave much of it, touching a wider one.
  // Whether the basin small core c borders most leaves it a sherd of its own when it is large.
  auto beside_wide_or_none = [&](int c) {
    const int longest = longest_border(c);
    const bool own_neighbour = core_size[longest] >= sizes.min_own_core_voxels ||
                               basin_size[longest] >= sizes.min_own_basin_voxels;
    return border[c][longest] > 0 &&
           (!own_neighbour || core_size[longest] >= sizes.min_wide_core_voxels);
  };
  // A narrow sherd's basin that the watershed trimmed gets back what it lost first (see
  // kSmallCoreMaxReclaimShare).
  std::vector<int> trimmed;
  for (int c = 0; c < deep_cores; ++c) {
    if (core_size[c] < sizes.min_own_core_voxels && basin_size[c] < sizes.min_own_basin_voxels &&
        basin_size[c] * (1.0 + kSmallCoreMaxReclaimShare) >= sizes.min_own_basin_voxels &&
        beside_wide_or_none(c))
      trimmed.push_back(c);
  }
  if (!trimmed.empty()) {
    std::vector<std::uint8_t> judged(cores);
    for (int c = 0; c < cores; ++c) judged[c] = basin_size[c] > 0;
    const auto leaked = leaked_to(near, centres, cluster, seeds, tag, judged, erosion);
    std::vector<std::size_t> lost(cores, 0);
    for (auto v : cluster) lost[std::max(leaked[v], 0)] += leaked[v] >= 0;
    auto flood_seeds = seeds;
    for (int c : trimmed) {
      if (basin_size[c] + lost[c] < sizes.min_own_basin_voxels ||
          lost[c] > kSmallCoreMaxReclaimShare * basin_size[c])
        continue;
      for (auto v : cluster) {
        if (leaked[v] == c) flood_seeds.emplace_back(v, c);
      }
    }
    if (flood_seeds.size() > seeds.size()) {
      flood_from_cores(near, cluster, flood_seeds, distance, tag);
      for (auto v : cluster) tag[v] = group.root(tag[v]);
      measure_basins();
    }
  }
  std::vector<std::uint8_t> sherd_sized(cores), to_join(cores, 0);
  for (int c = 0; c < cores; ++c) {
    // A shallow core that still has a part stays apart (judged above); a band core's has none.
    sherd_sized[c] = c < deep_cores ? core_size[c] >= sizes.min_own_core_voxels : basin_size[c] > 0;
    if (sherd_sized[c] || c >= deep_cores) continue;
    const bool narrow_sherd = basin_size[c] >= sizes.min_own_basin_voxels && beside_wide_or_none(c);
    to_join[c] = border[c][longest_border(c)] > 0 && !narrow_sherd;
  }
  // A small sherd's basin beside a wide core stays apart (see kSmallSherdMaxStepBandMm2).
  const auto small_sherd = small_sherds_among(to_join, Asked::kSmallCores);
  for (int c = 0; c < cores; ++c) to_join[c] = to_join[c] && !small_sherd[c];
  join_touched_or_across(to_join);
  if (stages != nullptr) append_parts(cluster, tag, group, cores, stages->small_cores);
  // Levels are looked for among the parts that stand as sherds: those of sherd-sized cores and the
  // small cores' basins kept apart above, which are no fracture face (see split_at_contacts in
  // contacts.h).
  std::vector<std::uint8_t> judged_part = sherd_sized;
  for (int c = 0; c < deep_cores; ++c) judged_part[c] |= basin_size[c] > 0 && !to_join[c];
  if (!voxel_rgb.empty() && std::count(judged_part.begin(), judged_part.end(), 1) >= 2) {
    std::vector<Vec3f> core_rgb(cores, Vec3f::Zero());
    for (auto [v, c] : seeds) core_rgb[c] += voxel_rgb[v];
    std::vector<std::uint32_t> judged;
    std::vector<double> width(cores, 0.0);  // twice the deepest voxel's distance from the boundary
    for (auto v : cluster) {
      if (!judged_part[tag[v]]) continue;
      judged.push_back(v);
      width[tag[v]] = std::max(width[tag[v]], 2.0 * distance[v]);
    }
    std::vector<double> face_width = width;
    for (int c = 0; c < cores; ++c)
      if (!sherd_sized[c]) face_width[c] = std::numeric_limits<double>::infinity();
    TopView judged_top(centres, judged);
    auto borders = step_borders(near, judged_top, centres, judged, tag, cores, radius);
    for (auto [a, b] : levels_of_one_sherd(borders, judged_top, centres, judged, tag, width,
                                           face_width, core_rgb, radius))
      group.join(a, b);
    // Leaving out leaked voxels only shortens borders, so they are looked for (two searches over
    // the cluster) only where a pair would join without them.
    auto no_neck = parts_without_neck(near, judged_top, centres, judged, tag, width, face_width,
                                      judged_part, nullptr, core_rgb, borders, radius);
    if (!no_neck.empty()) {
      const auto leaked = leaked_to(near, centres, judged, seeds, tag, judged_part, erosion);
      no_neck = parts_without_neck(near, judged_top, centres, judged, tag, width, face_width,
                                   judged_part, &leaked, core_rgb, borders, radius);
    }
    for (auto [a, b] : no_neck) group.join(a, b);
  }
  for (auto v : cluster) tag[v] = group.root(tag[v]);
  reclaim_leaked_strips(near, centres, cluster, seeds, voxel_rgb, distance, cores, erosion, sizes,
                        tag);
  std::vector<std::vector<std::uint32_t>> parts;
  append_parts(cluster, tag, group, cores, parts);
  return parts;
}

std::vector<std::vector<std::uint32_t>> join_across_unseen_walls(
    std::vector<std::vector<std::uint32_t>> parts, const std::vector<Vec3f>& centres,
    const std::vector<Vec3f>& voxel_rgb, const std::vector<float>& depth, double radius,
    double erosion, const CoreSizes& sizes, double leaf) {
  const int n_parts = static_cast<int>(parts.size());
  const auto min_voxels = static_cast<std::size_t>(kWallPartMinMm2 / (leaf * leaf));
  const auto large_voxels = static_cast<std::size_t>(kWallLargePartMm2 / (leaf * leaf));
  std::vector<std::uint8_t> cored(n_parts, 0);
  std::vector<int> narrow;
  std::vector<double> width(n_parts, 0.0);  // twice the deepest voxel's distance from the boundary
  for (int p = 0; p < n_parts; ++p) {
    std::size_t core = 0, shallow_core = 0;
    for (auto v : parts[p]) {
      core += depth[v] >= erosion;
      shallow_core += depth[v] >= kShallowCoreShare * erosion;
      width[p] = std::max(width[p], 2.0 * depth[v]);
    }
    cored[p] = core >= sizes.min_core_voxels || (parts[p].size() >= sizes.min_own_basin_voxels &&
                                                 shallow_core >= sizes.min_own_core_voxels);
    if (!cored[p] && parts[p].size() >= min_voxels) narrow.push_back(p);
  }
  if (narrow.empty()) return parts;
  TopView top(parts, centres, cored);  // among the cored parts' voxels
  if (top.empty()) return parts;
  std::vector<int> found;
  const float radius2 = static_cast<float>(radius * radius);
  const std::vector<Vec3f> colour = colour_sums(parts, voxel_rgb);
  std::vector<int> joins(n_parts, -1);
  std::vector<int> beside;  // the cored parts a voxel borders across a step
  for (int p : narrow) {
    std::map<int, std::size_t> bordering, contacts;  // per cored part
    std::map<int, std::vector<float>> steps;         // step heights, per cored part
    for (auto v : parts[p]) {
      top.search(centres[v], radius, found);
      beside.clear();
      for (auto f : found) {
        const auto n = top.voxel_at[f];
        const int q = top.part_of[n];
        if ((centres[n] - centres[v]).squaredNorm() <= radius2) {
          ++contacts[q];
        } else {
          steps[q].push_back(std::abs(centres[n].z() - centres[v].z()));
          add_once(beside, q);
        }
      }
      for (int q : beside) ++bordering[q];
    }
    float best = parts[p].size() >= large_voxels ? static_cast<float>(kFaceMaxOffClayLine)
                                                 : kWallMaxOffClayLine;
    for (const auto& [q, n] : bordering) {
      const float off = width[q] <= kFacePartMaxWidthMm ? off_either_line(colour[p], colour[q])
                                                        : off_clay_line(colour[q], colour[p]);
      if ((n < kWallMinBorderShare * parts[p].size() && !level_wall(steps[q])) ||
          contacts[q] > kWallMaxContactShare * steps[q].size() || off >= best)
        continue;
      best = off;
      joins[p] = q;
    }
  }
  // Narrow parts join cored ones only, so one pass moves every voxel to its final part.
  return with_joined(std::move(parts), joins);
}

}  // namespace sherd::segmentation::detail
