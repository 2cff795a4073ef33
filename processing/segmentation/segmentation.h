// Splitting a fused scan into sherds: background removed by colour, plane and scanning volume,
// then Euclidean clustering, splitting of touching sherds and size filters.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"

namespace sherd::segmentation {

enum class BackgroundColour { Black, White, None };

struct Params {
  BackgroundColour background = BackgroundColour::Black;
  // Euclidean clustering distance; raised to 4 point spacings where the data are sparser.
  double cluster_tolerance_mm = 2.5;
  // Touching sherds are split where the cluster, eroded by this depth from its boundary
  // (measured along the surface), falls apart into sherd-sized cores: contacts shorter than
  // about twice this are cut, so a sherd must be wider than that everywhere, or hold a lobe of
  // its own: a depth 0.8 × this that falls by 0.6 × this to the contact (contacts.cpp,
  // kLobeMinTopShare). 0: no splitting.
  // Off by default: on a tray seen from above (bench_segmentation) 5 mm splits touching sherds,
  // but on the station's fused frame scans, which show both faces of a standing sherd, each face
  // erodes to a core of its own and sherds come out split in two. With it, a narrow piece the
  // erosion leaves no core, cut off from its sherd by a wall too steep to be seen from above (the
  // raised edge of a leaning sherd), joins the sherd it borders in the top view in its clay; two
  // parts of one hue with no neck between them are one sherd; a part of several clays is split
  // by colour; a level of a sherd behind a step higher than the clustering distance joins it by
  // the step and colour (a narrow band of its clay, a wider level of its very hue, or of its clay
  // where the surface bends down across the border); a sherd's
  // fracture face strip, or a piece of it lying along it in the top view, that went to the sherd
  // it touches goes back by colour (and, where the colour fits both, by the side its slope
  // faces); and a part left narrower in the top view than any sherd lying on the plate shows (a
  // strip seen almost edge-on) joins the part of its clay beside it (the steps in contacts.h,
  // clay_split.h and top_view_joins.h, their measurements beside their constants).
  double contact_erosion_mm = 0.0;
  // A core left by that erosion stands for a sherd of its own only when it covers at least this
  // much of the plate; a smaller one (but at least what a sherd of min_extent_mm keeps) is mostly
  // the far side of a step inside one sherd — a ring foot's recess, a lip — cut off by the unseen
  // vertical wall between them, and its part joins the part it shares the longest border with.
  // Measured on bench_segmentation (100 trays; seeds 1, 2, 1001), exact counts: every core a sherd
  // (the bound ≈ 6 mm²) 84/85/83 %; cores under 30 mm² dropped 90/90/87 %, joined 91/91/87 %;
  // under 80 mm² dropped 79 % (seed 1: small sherds touching others lost, merges 5 → 20).
  double contact_min_core_mm2 = 30.0;
  // … except when the part the watershed gives that small core covers at least this much: then
  // it is a narrow sherd (a rim strip, a thin wall piece) that the erosion left little of,
  // touching another, and stays a sherd of its own; the far side of a step is a small part of its
  // sherd. Measured on bench_segmentation (100 trays, seeds 1 / 2 / 1001), exact counts
  // 91 / 91 / 87 % without this, 92 / 92 / 91 % with 450 mm² (merged sherds 8 / 8 / 6 →
  // 5 / 5 / 2); 300 mm² 86 / 86 / 87 %, 400 and 500 mm² as 450 within one tray. Parts rightly
  // joined covered up to 390 mm², narrow sherds wrongly joined from 440 mm². Only beside a
  // wider sherd (a neighbouring core of 80 mm² or more): beside another small core, the two
  // are one narrow sherd the erosion cut in two.
  double contact_own_basin_mm2 = 450.0;
  int min_points = 400;
  double min_extent_mm = 12.0;
  double max_extent_mm = 450.0;
  // The holding frame, by its known geometry: plinths whose flat tops lie this high above the
  // plate, the sherds standing sunk into them (simulators/pottery.h: 8 mm). Nothing of a sherd
  // shows below that height, and on the plinths' top plane what faces up is the frame (a standing
  // sherd's faces there are steep), so the frame goes whatever its colour. 0: no frame (sherds
  // lying on the plate, whose lower parts are below any plinth height).
  double frame_height_mm = 0.0;
  double volume_radius_mm = 160.0;  // cylinder about the world z axis; <= 0: no volume cut
  double volume_min_z_mm = 0.5;
  double volume_max_z_mm = 400.0;
  // Colour background test (HSV, channels in 0–1): grey means saturation below
  // background_max_saturation or chroma (max − min) below background_max_chroma; black means
  // grey with value below black_max_value; white, grey with value above white_min_value.
  // Saturation does not change with shading, so shaded clay stays clay; the chroma bound catches
  // the near-black cells whose saturation is only 8-bit noise. On a black background with a
  // support plane found, black is further held to what that plate shows (1.2 × its points'
  // 99th-percentile value): clay in deep shade is darker than black_max_value but brighter than
  // the plate.
  double background_max_saturation = 0.25;
  double background_max_chroma = 0.06;
  double black_max_value = 0.35;
  double white_min_value = 0.55;
  // Support plane: the dominant RANSAC plane is removed (with the points within
  // plane_distance_mm of it) only when its inliers span at least plane_min_extent_mm, so that
  // a large flat sherd is never taken for the support.
  double plane_distance_mm = 1.5;
  double plane_min_extent_mm = 250.0;
};

struct Part {
  std::string id;                      // "s01", "s02", … ordered by centroid (x, then y)
  std::vector<std::uint32_t> indices;  // into the input mesh's vertices
  Mesh mesh;                           // the sub-mesh
  Box3 bbox;
};

struct Rejected {
  std::vector<std::uint32_t> indices;
  std::string reason;  // "too small: 120 points < 400", "too large: extent 612 mm > 450 mm"
};

struct Result {
  std::vector<Part> sherds;
  std::vector<Rejected> rejected;
  std::size_t background_points = 0;
};

// The parts (point indices, sorted, as in Part::indices) after one step of the clustering, before
// the size filters: what the tray benchmark reads to tell which step left a sherd split or merged.
struct ClusteringStep {
  // "clusters"; with contact splitting "basins" (each core's watershed part), "small cores" (the
  // shallow and small cores' parts joined to their neighbours), "contacts" (one sherd's levels
  // and parts without a neck joined), with colours then "clay", "levels", "walls", "faces",
  // "narrow", "folds", "detached", "under"
  std::string name;
  std::vector<std::vector<std::uint32_t>> parts;
};

// Steps, in order: non-finite points out; the support plane (fitted on the whole scene, where it
// is certainly the dominant plane); the holding frame (frame_height_mm); the scanning volume;
// background colour (needs colours); Euclidean clustering; touching sherds split (see
// contact_erosion_mm); size filters. Every point removed by the first four counts in
// background_points. An empty input gives an empty result. With `steps`, the parts after each
// step of the clustering and splitting are kept there (for the benchmark; it costs a copy each).
Result segment(const Mesh& fused, const Params& params,
               std::vector<ClusteringStep>* steps = nullptr);

}  // namespace sherd::segmentation
