// Gray-code decoding against independent truths: the reference pattern images (each projector
// pixel must decode to its own column/row) and the real captures of a chessboard.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/errors.h"
#include "processing/structured_light/gray_code.h"

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

// Sub-column Gray code: a camera row that sees the projector along the line p(x) = 100.3 + 0.55·x
// (about 1.8 camera pixels per projector column), each pixel's grey linear between the projector
// pixels on either side of p (a blur-free projector), dark 20 and lit 200 grey levels. Truth: p(x).
// The decoded whole column is up to half a column off; the stripe edges place every pixel between
// two boundaries to a small fraction of a column.
TEST(GrayCode, StripeEdgesPlaceColumnsBetweenProjectorPixels) {
  const sl::GrayCodePatterns patterns{1024, 768};
  const int width = 400, height = 4;
  auto seen = [](int x) { return 100.3 + 0.55 * x; };
  std::vector<sl::GreyImage> frames;
  for (int f = 0; f < patterns.frame_count(); ++f) {
    const sl::GreyImage shown = patterns.frame(f);
    sl::GreyImage image{width, height, std::vector<std::uint8_t>(width * height)};
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        const double p = seen(x), w = p - std::floor(p);
        const int left = static_cast<int>(p), projector_row = 300 + y;
        const double lit = (1 - w) * shown.at(left, projector_row) / 255.0 +
                           w * shown.at(left + 1, projector_row) / 255.0;
        image.pixels[y * width + x] = static_cast<std::uint8_t>(std::lround(20 + 180 * lit));
      }
    frames.push_back(std::move(image));
  }
  sl::DecodedMap map = sl::decode(patterns, frames, {.edge_bits = 1});
  ASSERT_EQ(map.decoded_count(), static_cast<std::size_t>(width * height));
  sl::refine_columns_at_edges(patterns, frames, map);
  double worst_whole = 0, worst_fine = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 2; x < width - 2; ++x) {  // a boundary on both sides
      const std::size_t i = static_cast<std::size_t>(y) * width + x;
      worst_whole = std::max(worst_whole, std::abs(map.column[i] - seen(x)));
      worst_fine = std::max(worst_fine, std::abs(map.column_fine[i] - seen(x)));
    }
  EXPECT_GT(worst_whole, 0.4);
  EXPECT_LT(worst_fine, 0.05);
}
