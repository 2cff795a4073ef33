// Gray-code decoding against independent truths: the reference pattern images (each projector
// pixel must decode to its own column/row) and the real captures of a chessboard.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "core/errors.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/phase_shift.h"

namespace sl = sherd::structured_light;

namespace {
const std::filesystem::path kSample =
    std::filesystem::path(SHERD_SHARED_DATA) / "procam-graycode-calib/sample_data";
}

TEST(GrayCode, ThePatternSetHasTenPlusTenBitsAndInversesFor1024x768) {
  const sl::GrayCodePatterns patterns{1024, 768};
  EXPECT_EQ(patterns.column_bits(), 10);
  EXPECT_EQ(patterns.row_bits(), 10);
  EXPECT_EQ(patterns.frame_count(), 42);
}

// The reference's own pattern images (made by OpenCV's GrayCodePattern) are the truth for frame
// order, bit order and code: ours must equal them pixel for pixel.
TEST(GrayCode, GeneratedFramesEqualTheReferencePatternImages) {
  const sl::GrayCodePatterns patterns{1024, 768};
  const auto reference = sl::read_sequence(kSample / "graycode_pattern", "pattern_", 40);
  for (int i = 0; i < 40; ++i) {
    const sl::GreyImage ours = patterns.frame(i);
    ASSERT_EQ(reference[i].width, 1024);
    ASSERT_EQ(reference[i].height, 768);
    EXPECT_EQ(ours.pixels, reference[i].pixels) << "frame " << i;
  }
}

// Decoding the pattern images themselves: every projector pixel decodes to its own column and row.
TEST(GrayCode, EveryProjectorPixelOfThePatternImagesDecodesToItself) {
  const sl::GrayCodePatterns patterns{1024, 768};
  auto frames = sl::read_sequence(kSample / "graycode_pattern", "pattern_", 40);
  frames.push_back(patterns.frame(patterns.white_frame()));
  frames.push_back(patterns.frame(patterns.black_frame()));
  const sl::DecodedMap map = sl::decode(patterns, frames, {});
  ASSERT_EQ(map.decoded_count(), 1024u * 768u);
  for (int y = 0; y < 768; ++y)
    for (int x = 0; x < 1024; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * 1024 + x;
      ASSERT_EQ(map.column[i], x) << "at " << x << "," << y;
      ASSERT_EQ(map.row[i], y) << "at " << x << "," << y;
    }
}

// Real captures: the projector lights the wall and board over the upper ~80 % of the frame (the
// bottom is in shadow; see graycode_40.png). Loose bounds from looking at the images, not the
// code's own output: most lit pixels decode (the 1-pixel least significant stripes are at the
// camera's resolution limit, so a share of pixels falls under white_thr there, as in the
// reference).
TEST(GrayCode, RealCapturesDecodeTheLitBoardAndMaskTheShadow) {
  const sl::GrayCodePatterns patterns{1024, 768};
  const auto frames = sl::read_sequence(kSample / "capture_0", "graycode_", 42);
  ASSERT_EQ(frames[0].width, 1280);
  ASSERT_EQ(frames[0].height, 1024);
  const sl::DecodedMap map = sl::decode(patterns, frames, {40, 5});
  std::size_t lit = 0;
  for (std::size_t i = 0; i < map.state.size(); ++i) lit += map.state[i] != sl::PixelState::kShadow;
  const double lit_share = double(lit) / map.state.size();
  const double decoded_of_lit = double(map.decoded_count()) / lit;
  EXPECT_GT(lit_share, 0.6);
  EXPECT_LT(lit_share, 0.95);
  EXPECT_GT(decoded_of_lit, 0.7);
  // Neighbouring decoded pixels lie on neighbouring projector columns: a smoothness check that
  // catches bit-order or Gray-conversion mistakes on real data.
  std::size_t pairs = 0, close = 0;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x + 1 < map.width; ++x)
      if (map.decoded(x, y) && map.decoded(x + 1, y)) {
        const std::size_t i = static_cast<std::size_t>(y) * map.width + x;
        ++pairs;
        close += std::abs(map.column[i + 1] - map.column[i]) <= 3 &&
                 std::abs(map.row[i + 1] - map.row[i]) <= 3;
      }
  EXPECT_GT(double(close) / pairs, 0.97);
}

TEST(GrayCode, AShortSequenceIsRefusedWithAClearMessage) {
  const sl::GrayCodePatterns patterns{1024, 768};
  std::vector<sl::GreyImage> frames(3, sl::GreyImage{4, 4, std::vector<std::uint8_t>(16, 0)});
  try {
    sl::decode(patterns, frames, {});
    FAIL() << "no error";
  } catch (const sherd::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("3 frames given"), std::string::npos) << e.what();
  }
}

namespace {

// A camera of 400 × 4 pixels whose rows see the projector along the line p(x) = 100.3 + 0.55·x
// (about 1.8 camera pixels per projector column), each pixel's grey linear between the projector
// pixels on either side of p (a blur-free projector), dark 20 and lit 200 grey levels: the frames
// it films of `patterns`.
constexpr int kLineWidth = 400, kLineHeight = 4;
double line_seen(int x) { return 100.3 + 0.55 * x; }
std::vector<sl::GreyImage> film_line(const std::vector<sl::GreyImage>& patterns) {
  std::vector<sl::GreyImage> frames;
  for (const sl::GreyImage& shown : patterns) {
    sl::GreyImage image{kLineWidth, kLineHeight,
                        std::vector<std::uint8_t>(kLineWidth * kLineHeight)};
    for (int y = 0; y < kLineHeight; ++y)
      for (int x = 0; x < kLineWidth; ++x) {
        const double p = line_seen(x), w = p - std::floor(p);
        const int left = static_cast<int>(p), projector_row = 300 + y;
        const double lit = (1 - w) * shown.at(left, projector_row) / 255.0 +
                           w * shown.at(left + 1, projector_row) / 255.0;
        image.pixels[y * kLineWidth + x] = static_cast<std::uint8_t>(std::lround(20 + 180 * lit));
      }
    frames.push_back(std::move(image));
  }
  return frames;
}

// The Gray-code frames filmed, decoded and refined at the stripe edges.
sl::DecodedMap decode_line(const sl::GrayCodePatterns& patterns) {
  std::vector<sl::GreyImage> shown;
  for (int f = 0; f < patterns.frame_count(); ++f) shown.push_back(patterns.frame(f));
  const auto frames = film_line(shown);
  sl::DecodedMap map = sl::decode(patterns, frames, {.edge_bits = 1});
  EXPECT_EQ(map.decoded_count(), static_cast<std::size_t>(kLineWidth * kLineHeight));
  sl::refine_columns_at_edges(patterns, frames, map);
  return map;
}

// The largest |column − p(x)| over the pixels with a boundary on both sides.
template <typename Column>
double worst_column_error(const sl::DecodedMap& map, Column column) {
  double worst = 0;
  for (int y = 0; y < kLineHeight; ++y)
    for (int x = 2; x < kLineWidth - 2; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * kLineWidth + x;
      if (map.state[i] != sl::PixelState::kDecoded) return std::numeric_limits<double>::infinity();
      worst = std::max(worst, std::abs(column(i) - line_seen(x)));
    }
  return worst;
}

}  // namespace

// Truth: p(x). The decoded whole column is up to half a column off; the stripe edges place every
// pixel between two boundaries to a small fraction of a column.
TEST(GrayCode, StripeEdgesPlaceColumnsBetweenProjectorPixels) {
  const sl::DecodedMap map = decode_line({1024, 768});
  EXPECT_GT(worst_column_error(map, [&](std::size_t i) { return double(map.column[i]); }), 0.4);
  EXPECT_LT(worst_column_error(map, [&](std::size_t i) { return double(map.column_fine[i]); }),
            0.05);
}

// Fringes too faint to read (a projector showing flat grey): the pixels keep the stripe edges'
// columns instead of being dropped.
TEST(GrayCode, StripeEdgesStandWhereFringesAreTooFaint) {
  sl::DecodedMap map = decode_line({1024, 768});
  const sl::PhaseShiftPatterns phase{1024, 768};
  const sl::GreyImage grey{1024, 768, std::vector<std::uint8_t>(1024 * 768, 128)};
  const auto frames = film_line(std::vector<sl::GreyImage>(phase.steps, grey));
  sl::refine_columns(phase, frames, 8, map);
  EXPECT_LT(worst_column_error(map, [&](std::size_t i) { return double(map.column_fine[i]); }),
            0.05);
}
