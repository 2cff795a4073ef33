#include "processing/structured_light/gray_code.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "core/errors.h"

namespace sherd::structured_light {
namespace {

int bits_for(int size) { return size <= 1 ? 1 : std::bit_width(static_cast<unsigned>(size - 1)); }

std::uint32_t gray_to_binary(std::uint32_t gray) {
  for (std::uint32_t shift = gray >> 1; shift != 0; shift >>= 1) gray ^= shift;
  return gray;
}

}  // namespace

GreyImage read_grey_image(const std::filesystem::path& file) {
  // Checked first: OpenCV would also print its own warning for a missing file.
  const cv::Mat image = std::filesystem::is_regular_file(file)
                            ? cv::imread(file.string(), cv::IMREAD_GRAYSCALE)
                            : cv::Mat();
  if (image.empty())
    throw InputError(
        fmt::format("structured light: cannot read image {} (missing or not an "
                    "image); check the capture folder",
                    file.string()));
  GreyImage grey{image.cols, image.rows, {}};
  grey.pixels.resize(static_cast<std::size_t>(image.cols) * image.rows);
  for (int y = 0; y < image.rows; ++y)
    std::copy_n(image.ptr<std::uint8_t>(y), image.cols, grey.pixels.begin() + y * image.cols);
  return grey;
}

std::vector<GreyImage> read_sequence(const std::filesystem::path& dir, std::string_view prefix,
                                     int count) {
  std::vector<GreyImage> frames;
  frames.reserve(count);
  for (int i = 0; i < count; ++i)
    frames.push_back(read_grey_image(dir / fmt::format("{}{:02d}.png", prefix, i)));
  return frames;
}

int GrayCodePatterns::column_bits() const { return bits_for(projector_width); }
int GrayCodePatterns::row_bits() const { return bits_for(projector_height); }

GreyImage GrayCodePatterns::frame(int index) const {
  if (index < 0 || index >= frame_count())
    throw InputError(fmt::format("structured light: pattern frame {} out of range 0..{}", index,
                                 frame_count() - 1));
  GreyImage image{projector_width, projector_height, {}};
  image.pixels.assign(static_cast<std::size_t>(projector_width) * projector_height, 0);
  if (index == white_frame()) {
    std::fill(image.pixels.begin(), image.pixels.end(), 255);
    return image;
  }
  if (index == black_frame()) return image;
  const bool columns = index < 2 * column_bits();
  const int pair = columns ? index / 2 : (index - 2 * column_bits()) / 2;
  const int bits = columns ? column_bits() : row_bits();
  const int bit = bits - 1 - pair;  // most significant first
  const bool inverse = index % 2 == 1;
  for (int y = 0; y < projector_height; ++y)
    for (int x = 0; x < projector_width; ++x) {
      const unsigned coordinate = columns ? x : y;
      const bool lit = (((coordinate ^ (coordinate >> 1)) >> bit) & 1u) != inverse;
      image.pixels[static_cast<std::size_t>(y) * projector_width + x] = lit ? 255 : 0;
    }
  return image;
}

std::size_t DecodedMap::decoded_count() const {
  return static_cast<std::size_t>(std::count(state.begin(), state.end(), PixelState::kDecoded));
}

DecodedMap decode(const GrayCodePatterns& patterns, std::span<const GreyImage> frames,
                  const DecodeThresholds& thresholds, int threads) {
  if (static_cast<int>(frames.size()) != patterns.frame_count())
    throw InputError(
        fmt::format("structured light: {} frames given, the Gray-code set for a "
                    "{}x{} projector has {}; capture the whole sequence",
                    frames.size(), patterns.projector_width, patterns.projector_height,
                    patterns.frame_count()));
  const int width = frames[0].width, height = frames[0].height;
  for (std::size_t i = 0; i < frames.size(); ++i)
    if (frames[i].width != width || frames[i].height != height)
      throw InputError(
          fmt::format("structured light: frame {} is {}x{}, frame 0 is {}x{}; all "
                      "frames of a sequence must come from the same camera region",
                      i, frames[i].width, frames[i].height, width, height));

  const std::size_t cells = static_cast<std::size_t>(width) * height;
  DecodedMap map;
  map.width = width;
  map.height = height;
  map.column.assign(cells, -1);
  map.row.assign(cells, -1);
  map.state.assign(cells, PixelState::kShadow);

  const int column_bits = patterns.column_bits(), row_bits = patterns.row_bits();
  const auto& white = frames[patterns.white_frame()].pixels;
  const auto& black = frames[patterns.black_frame()].pixels;
  // One pass over rows [begin, end); frames are read pixel-major so each thread streams through
  // its own band of every frame.
  auto decode_rows = [&](int begin, int end) {
    for (std::size_t i = static_cast<std::size_t>(begin) * width;
         i < static_cast<std::size_t>(end) * width; ++i) {
      if (static_cast<int>(white[i]) - static_cast<int>(black[i]) <= thresholds.black) continue;
      bool ambiguous = false;
      auto read_bits = [&](int first_frame, int bits) {
        std::uint32_t gray = 0;
        int unclear = 0;
        for (int b = 0; b < bits; ++b) {
          const int lit = frames[first_frame + 2 * b].pixels[i];
          const int unlit = frames[first_frame + 2 * b + 1].pixels[i];
          unclear += std::abs(lit - unlit) < thresholds.white;
          gray = (gray << 1) | (lit > unlit ? 1u : 0u);
        }
        ambiguous |= unclear > thresholds.edge_bits;
        return static_cast<std::int32_t>(gray_to_binary(gray));
      };
      const std::int32_t column = read_bits(0, column_bits);
      const std::int32_t row = read_bits(2 * column_bits, row_bits);
      if (ambiguous) {
        map.state[i] = PixelState::kLowContrast;
      } else if (column >= patterns.projector_width || row >= patterns.projector_height) {
        map.state[i] = PixelState::kOutOfRange;
      } else {
        map.state[i] = PixelState::kDecoded;
        map.column[i] = column;
        map.row[i] = row;
      }
    }
  };

  threads = std::clamp(threads, 1, height);
  std::vector<std::jthread> workers;
  for (int t = 1; t < threads; ++t)
    workers.emplace_back(decode_rows, height * t / threads, height * (t + 1) / threads);
  decode_rows(0, height / threads);
  workers.clear();  // joins
  return map;
}

void refine_columns_at_edges(const GrayCodePatterns& patterns, std::span<const GreyImage> frames,
                             DecodedMap& map, double max_gap_px) {
  if (static_cast<int>(frames.size()) != patterns.frame_count())
    throw InputError(fmt::format(
        "structured light: {} frames given to locate stripe edges, the Gray-code set has {}; "
        "pass the sequence that was decoded",
        frames.size(), patterns.frame_count()));
  for (const GreyImage& f : frames)
    if (f.width != map.width || f.height != map.height)
      throw InputError(fmt::format(
          "structured light: a {}x{} frame for a {}x{} decoded map; pass the sequence that was "
          "decoded",
          f.width, f.height, map.width, map.height));
  const int bits = patterns.column_bits();
  const auto& white = frames[patterns.white_frame()].pixels;
  const auto& black = frames[patterns.black_frame()].pixels;
  // The bit's (pattern − inverse) as a share of the pixel's full modulation (albedo cancels).
  auto contrast = [&](int bit, std::size_t i) {
    const int pair = bits - 1 - bit;  // frames run most significant bit first
    const double difference = static_cast<double>(frames[2 * pair].pixels[i]) -
                              static_cast<double>(frames[2 * pair + 1].pixels[i]);
    return difference / (static_cast<double>(white[i]) - static_cast<double>(black[i]));
  };
  struct Boundary {
    double x;       // camera column where the boundary lies
    double column;  // projector column there (c + 0.5)
  };
  // Neighbouring pixels further apart in columns lie across a depth edge or a misdecoded bit.
  constexpr int kMaxColumnsBetweenPixels = 3;
  map.column_fine.assign(map.state.size(), std::numeric_limits<float>::quiet_NaN());
  std::vector<Boundary> boundaries;
  for (int y = 0; y < map.height; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * map.width;
    boundaries.clear();
    for (int x = 0; x + 1 < map.width; ++x) {
      const std::size_t i = row + x, j = i + 1;
      if (map.state[i] != PixelState::kDecoded || map.state[j] != PixelState::kDecoded) continue;
      const std::int32_t low = std::min(map.column[i], map.column[j]);
      const int steps = std::abs(map.column[i] - map.column[j]);
      if (steps == 0 || steps > kMaxColumnsBetweenPixels) continue;
      // Each boundary between the two pixels' columns has its own bit (consecutive Gray
      // boundaries never flip the same one), read at both pixels. They are taken in the order
      // the row meets them and kept in that order (noise may swap two crossings in one pixel).
      const bool ascending = map.column[j] > map.column[i];
      double after = 0;  // the previous boundary's place between the two pixels
      for (int k = 0; k < steps; ++k) {
        const std::int32_t c = ascending ? low + k : low + steps - 1 - k;  // boundary c | c+1
        const auto flipped =
            static_cast<std::uint32_t>((c ^ (c >> 1)) ^ ((c + 1) ^ ((c + 1) >> 1)));
        const int bit = std::countr_zero(flipped);
        const double ci = contrast(bit, i), cj = contrast(bit, j);
        if (!(ci != cj)) continue;  // no crossing between them (both read 0)
        after = std::max(after, std::clamp(ci / (ci - cj), 0.0, 1.0));
        boundaries.push_back({x + after, c + 0.5});
      }
    }
    std::size_t next = 0;  // first boundary right of x
    for (int x = 0; x < map.width; ++x) {
      const std::size_t i = row + x;
      if (map.state[i] != PixelState::kDecoded) continue;
      map.column_fine[i] = static_cast<float>(map.column[i]);
      while (next < boundaries.size() && boundaries[next].x <= x) ++next;
      if (next == 0 || next == boundaries.size()) continue;
      const Boundary& left = boundaries[next - 1];
      const Boundary& right = boundaries[next];
      if (right.x - left.x > max_gap_px || right.column == left.column ||
          std::abs(right.column - left.column) > kMaxColumnsBetweenPixels)
        continue;
      bool holes = false;
      for (int k = static_cast<int>(std::ceil(left.x)); k <= static_cast<int>(right.x); ++k)
        holes |= map.state[row + k] != PixelState::kDecoded;
      if (holes) continue;
      const double fine =
          left.column + (x - left.x) / (right.x - left.x) * (right.column - left.column);
      if (std::abs(fine - map.column[i]) <= 1) map.column_fine[i] = static_cast<float>(fine);
    }
  }
}

}  // namespace sherd::structured_light
