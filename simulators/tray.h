// Trays for the segmentation benchmark: 1 to 20 sherds lying on the plate, some touching a
// neighbour, some leaning on one, on a black or white background with shading, scanner noise,
// dust and stray points, as the point cloud a scanner above the tray sees — one point per grid
// cell of the plate, the topmost surface there — with a ground-truth label per point.
// Deterministic from the seed; millimetres, world = turntable frame (plate top at z = 0).
#pragma once

#include <cstdint>
#include <vector>

#include "core/types.h"
#include "simulators/pottery.h"

namespace sherd::sim {

inline constexpr int kMaxTraySherds = 20;

struct TraySpec {
  std::uint64_t seed = 1;
  int sherds = 8;  // 1 … kMaxTraySherds
  Background background = Background::Black;
  double grid_mm = 0.5;         // point spacing on the plate (0.265 mm gives ≈ 1 M points)
  double touching_share = 0.3;  // of the sherds after the first: laid against a neighbour
  double leaning_share = 0.15;  // of the sherds after the first: tilted onto a neighbour's edge
  int dust_specks = 40;         // crumbs of clay and grit on the plate (background)
  int stray_points = 300;       // isolated points in the air (scanner outliers, background)
};

struct Tray {
  TraySpec spec;
  Mesh cloud;               // points + colours, no triangles
  std::vector<int> labels;  // per point: 0 = background (plate, dust, strays), k = sherd k
  int sherds = 0;
  int touching = 0;  // sherds laid so that their footprint touches another's
  int leaning = 0;   // sherds resting partly on another
};

// The tray bench_segmentation lays for `seed`: its sherd count (1…kMaxTraySherds) spread over the
// seeds. Tests rebuild the bench's failing trays from it by seed.
inline TraySpec bench_tray_spec(std::uint64_t seed, Background background) {
  TraySpec spec;
  spec.seed = seed;
  spec.sherds = 1 + static_cast<int>(seed * 7 % kMaxTraySherds);
  spec.background = background;
  return spec;
}

// InputError for a sherd count outside 1…kMaxTraySherds or a grid step outside [0.1, 2] mm.
Tray make_tray(const TraySpec& spec);

}  // namespace sherd::sim
