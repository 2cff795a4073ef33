#include "processing/structured_light/phase_shift.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "core/errors.h"

namespace sherd::structured_light {

double PhaseShiftPatterns::intensity(double x, int k) const {
  const double two_pi = 2 * std::numbers::pi;
  return 127.5 * (1 + std::cos(two_pi * x / period_px + two_pi * k / steps));
}

GreyImage PhaseShiftPatterns::frame(int k) const {
  if (k < 0 || k >= steps)
    throw InputError(fmt::format("phase shift: frame {} out of range 0..{}", k, steps - 1));
  GreyImage image{projector_width, projector_height, {}};
  image.pixels.resize(static_cast<std::size_t>(projector_width) * projector_height);
  for (int x = 0; x < projector_width; ++x) {
    const auto value = static_cast<std::uint8_t>(std::lround(intensity(x, k)));
    for (int y = 0; y < projector_height; ++y)
      image.pixels[static_cast<std::size_t>(y) * projector_width + x] = value;
  }
  return image;
}

void refine_columns(const PhaseShiftPatterns& patterns, std::span<const GreyImage> frames,
                    double min_modulation, DecodedMap& map, int saturation) {
  if (static_cast<int>(frames.size()) != patterns.steps)
    throw InputError(fmt::format("phase shift: {} frames given, the pattern set has {}",
                                 frames.size(), patterns.steps));
  for (const GreyImage& f : frames)
    if (f.width != map.width || f.height != map.height)
      throw InputError(fmt::format("phase shift: a {}x{} frame for a {}x{} decoded map", f.width,
                                   f.height, map.width, map.height));
  const double two_pi = 2 * std::numbers::pi;
  std::vector<double> cosines(patterns.steps), sines(patterns.steps);
  for (int k = 0; k < patterns.steps; ++k) {
    cosines[k] = std::cos(two_pi * k / patterns.steps);
    sines[k] = std::sin(two_pi * k / patterns.steps);
  }
  const double period = patterns.period_px;
  if (map.column_fine.empty())
    map.column_fine.assign(map.state.size(), std::numeric_limits<float>::quiet_NaN());
  // A pixel whose fringes cannot be read keeps the stripe edges' column where it has one.
  auto unreadable = [&](std::size_t i, PixelState state) {
    if (std::isnan(map.column_fine[i])) map.state[i] = state;
  };
  for (std::size_t i = 0; i < map.state.size(); ++i) {
    if (map.state[i] != PixelState::kDecoded) continue;
    // I_k = A + B·cos(θ + δ_k)  ⇒  Σ I_k cos δ_k = (N/2)·B·cos θ, Σ I_k sin δ_k = −(N/2)·B·sin θ.
    double c = 0, s = 0;
    bool clipped = false;
    for (int k = 0; k < patterns.steps; ++k) {
      c += frames[k].pixels[i] * cosines[k];
      s += frames[k].pixels[i] * sines[k];
      clipped |= frames[k].pixels[i] >= saturation;
    }
    if (clipped) {
      unreadable(i, PixelState::kSaturated);
      continue;
    }
    if (2.0 / patterns.steps * std::hypot(c, s) < min_modulation) {
      unreadable(i, PixelState::kLowContrast);
      continue;
    }
    double theta = std::atan2(-s, c);
    if (theta < 0) theta += two_pi;
    const double within = theta / two_pi * period;  // column modulo the period
    // The Gray-code column chooses the fringe: the period index that puts us nearest to it.
    const double fringe = std::round((map.column[i] - within) / period);
    map.column_fine[i] = static_cast<float>(fringe * period + within);
  }
}

}  // namespace sherd::structured_light
