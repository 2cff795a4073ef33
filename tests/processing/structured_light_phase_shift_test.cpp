// Phase shifting unwrapped by the Gray code, against analytic truth: sinusoidal fringes sampled
// at known (fractional) projector columns must decode to those columns.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "processing/structured_light/phase_shift.h"

namespace sl = sherd::structured_light;

namespace {

// A camera row of `width` pixels where pixel u sees projector column x(u) = x0 + scale·u and row
// 5, with the Gray-code frames (the projector pixel nearest x) and the fringe frames (the sinusoid
// at x itself, rounded to 8 bits).
struct SyntheticCapture {
  std::vector<sl::GreyImage> gray, fringes;
};

SyntheticCapture capture(const sl::GrayCodePatterns& gray, const sl::PhaseShiftPatterns& fringes,
                         int width, double x0, double scale) {
  SyntheticCapture out;
  for (int f = 0; f < gray.frame_count(); ++f) {
    const sl::GreyImage projected = gray.frame(f);
    sl::GreyImage image{width, 1, std::vector<std::uint8_t>(width)};
    for (int u = 0; u < width; ++u)
      image.pixels[u] = projected.at(static_cast<int>(std::lround(x0 + scale * u)), 5);
    out.gray.push_back(image);
  }
  for (int k = 0; k < fringes.steps; ++k) {
    sl::GreyImage image{width, 1, std::vector<std::uint8_t>(width)};
    for (int u = 0; u < width; ++u)
      image.pixels[u] =
          static_cast<std::uint8_t>(std::lround(fringes.intensity(x0 + scale * u, k)));
    out.fringes.push_back(image);
  }
  return out;
}

}  // namespace

TEST(PhaseShift, ProjectorPixelsDecodeToTheirOwnColumns) {
  const sl::GrayCodePatterns gray{1024, 768};
  const sl::PhaseShiftPatterns fringes{1024, 768, 16, 4};
  const SyntheticCapture c = capture(gray, fringes, 1024, 0.0, 1.0);
  sl::DecodedMap map = sl::decode(gray, c.gray, {});
  sl::refine_columns(fringes, c.fringes, 10, map, 256);  // fringes peak at 255: no clipping here
  ASSERT_EQ(map.decoded_count(), 1024u);
  for (int x = 0; x < 1024; ++x) EXPECT_NEAR(map.column_fine[x], x, 0.05) << x;
}

// Fractional columns: 8-bit rounding of a 127.5-amplitude sinusoid moves the phase by at most
// ~0.5/127.5 rad per frame, i.e. < 0.02 px at a 16-px period; 0.05 px is the bound held.
TEST(PhaseShift, FractionalColumnsDecodeToSubPixelAccuracy) {
  const sl::GrayCodePatterns gray{1024, 768};
  for (int steps : {3, 4, 8}) {
    const sl::PhaseShiftPatterns fringes{1024, 768, 16, steps};
    const double x0 = 3.3, scale = 0.731;
    const SyntheticCapture c = capture(gray, fringes, 1300, x0, scale);
    sl::DecodedMap map = sl::decode(gray, c.gray, {});
    sl::refine_columns(fringes, c.fringes, 10, map, 256);
    ASSERT_EQ(map.decoded_count(), 1300u) << steps;
    double worst = 0;
    for (int u = 0; u < 1300; ++u)
      worst = std::max(worst, std::abs(map.column_fine[u] - (x0 + scale * u)));
    EXPECT_LT(worst, 0.05) << steps << " steps";
  }
}

// The synthetic fringes span 0..255, so their peaks reach 255: with the default saturation level
// (255) exactly the pixels whose sinusoid rounds to 255 in some frame are masked; with 256 none.
TEST(PhaseShift, ClippedFringesAreMaskedAsSaturated) {
  const sl::GrayCodePatterns gray{1024, 768};
  const sl::PhaseShiftPatterns fringes{1024, 768, 16, 4};
  const SyntheticCapture c = capture(gray, fringes, 1024, 0.0, 1.0);
  std::size_t peaks = 0;  // truth: pixels with a 255 in some fringe frame
  for (int x = 0; x < 1024; ++x) {
    bool peak = false;
    for (const auto& f : c.fringes) peak |= f.pixels[x] == 255;
    peaks += peak;
  }
  ASSERT_GT(peaks, 0u);
  sl::DecodedMap map = sl::decode(gray, c.gray, {});
  sl::refine_columns(fringes, c.fringes, 10, map);
  EXPECT_EQ(std::count(map.state.begin(), map.state.end(), sl::PixelState::kSaturated),
            static_cast<std::ptrdiff_t>(peaks));
  sl::DecodedMap unclipped = sl::decode(gray, c.gray, {});
  sl::refine_columns(fringes, c.fringes, 10, unclipped, 256);
  EXPECT_EQ(unclipped.decoded_count(), 1024u);
}

TEST(PhaseShift, FlatLightIsLowModulationNotAColumn) {
  const sl::GrayCodePatterns gray{1024, 768};
  const sl::PhaseShiftPatterns fringes{1024, 768, 16, 4};
  SyntheticCapture c = capture(gray, fringes, 64, 10.0, 1.0);
  for (auto& f : c.fringes) std::fill(f.pixels.begin(), f.pixels.end(), 128);  // no fringes seen
  sl::DecodedMap map = sl::decode(gray, c.gray, {});
  sl::refine_columns(fringes, c.fringes, 10, map);
  EXPECT_EQ(map.decoded_count(), 0u);
}
