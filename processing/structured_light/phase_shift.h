// Phase shifting along projector columns, unwrapped by the Gray code: N sinusoidal fringe frames
// of period P pixels give each camera pixel a sub-pixel projector column; the Gray-code column
// picks the fringe (period index), so no spatial unwrapping is needed.
#pragma once

#include <span>

#include "processing/structured_light/gray_code.h"

namespace sherd::structured_light {

struct PhaseShiftPatterns {
  int projector_width = 1024, projector_height = 768;
  int period_px = 16;  // fringe period in projector pixels
  int steps = 4;       // frames, each shifted by 2π/steps

  // Frame k: 127.5 · (1 + cos(2π·x/P + 2π·k/N)), rounded.
  GreyImage frame(int k) const;
  // The intensity frame k shows at a (fractional) projector column x, before rounding.
  double intensity(double x, int k) const;
};

// Refines `map` in place: sets map.column_fine for decoded pixels whose fringe modulation (the
// sinusoid's amplitude, grey levels) reaches `min_modulation`; other decoded pixels become
// kLowContrast, and those with a fringe frame at or above `saturation` kSaturated (a clipped
// sinusoid shifts the phase) — unless map.column_fine already holds their column from the stripe
// edges (refine_columns_at_edges run first), which they then keep: dim surfaces at grazing
// incidence decode in the Gray code but have too little fringe amplitude for a phase. Throws
// InputError when the frame count or sizes do not match.
void refine_columns(const PhaseShiftPatterns& patterns, std::span<const GreyImage> frames,
                    double min_modulation, DecodedMap& map, int saturation = 255);

}  // namespace sherd::structured_light
