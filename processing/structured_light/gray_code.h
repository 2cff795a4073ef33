// Gray-code structured light: the projected pattern set (columns and rows, each bit with its
// inverse, then a white and a black frame) and the per-pixel decoding of a captured sequence into
// projector column/row, with shadow and low-contrast masks. No OpenCV in this header.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

namespace sherd::structured_light {

// An 8-bit grey image, row-major.
struct GreyImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;
  std::uint8_t at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
};

// Reads an 8-bit PNG (or any format OpenCV's imgcodecs reads) as grey; throws InputError naming
// the file when it cannot be read.
GreyImage read_grey_image(const std::filesystem::path& file);
// Reads `count` frames named <prefix>NN.png (two digits) from `dir`.
std::vector<GreyImage> read_sequence(const std::filesystem::path& dir, std::string_view prefix,
                                     int count);

// The pattern set for a projector of width × height pixels. Frame order (the same as OpenCV's
// structured_light::GrayCodePattern, which produced the reference captures): for each column bit,
// most significant first, the pattern then its inverse; then the row bits likewise; then a white
// frame and a black frame.
struct GrayCodePatterns {
  int projector_width = 1024, projector_height = 768;

  int column_bits() const;
  int row_bits() const;
  int frame_count() const { return 2 * (column_bits() + row_bits()) + 2; }
  int white_frame() const { return frame_count() - 2; }
  int black_frame() const { return frame_count() - 1; }
  // The projector image of frame `index` (255 lit, 0 dark).
  GreyImage frame(int index) const;
};

// Thresholds in grey levels, named as in the reference implementation.
struct DecodeThresholds {
  int black = 40;  // white − black frame must exceed this, or the pixel is in shadow
  int white = 5;   // |pattern − inverse| must reach this for every bit, or the pixel is ambiguous
  // Bits per axis allowed below `white`. A pixel on a stripe edge sees its bit half lit; Gray code
  // changes one bit from each column to the next, so either reading of that one bit is a column
  // beside the edge (which phase shifting refines anyway). 0 = the reference's rule.
  int edge_bits = 0;
};

// kSaturated: a phase-shift frame clipped at the sensor's top (set by refine_columns).
enum class PixelState : std::uint8_t {
  kDecoded = 0,
  kShadow,
  kLowContrast,
  kOutOfRange,
  kSaturated
};

// Per camera pixel: the projector column and row that lit it (valid where state is kDecoded).
struct DecodedMap {
  int width = 0, height = 0;
  std::vector<std::int32_t> column, row;
  std::vector<PixelState> state;
  // Sub-pixel projector columns where phase shifting refined them (refine_columns), else empty.
  std::vector<float> column_fine;

  std::size_t decoded_count() const;
  bool decoded(int x, int y) const {
    return state[static_cast<std::size_t>(y) * width + x] == PixelState::kDecoded;
  }
};

// Decodes a captured sequence (frame_count() images of equal size) on up to `threads` threads.
// Throws InputError when the frame count or sizes do not match the pattern set.
DecodedMap decode(const GrayCodePatterns& patterns, std::span<const GreyImage> frames,
                  const DecodeThresholds& thresholds, int threads = 2);

// Sub-pixel projector columns from Gray code alone (sets map.column_fine). Every boundary between
// neighbouring projector columns c | c+1 flips exactly one Gray bit; where two neighbouring camera
// pixels of a row decode to c and c+1, the boundary (projector column c + 0.5) lies where that
// bit's (pattern − inverse)/(white − black) crosses zero, linearly interpolated between the two
// pixels. Each decoded pixel's column then follows linearly between the boundaries on either side
// of it (at most `max_gap_px` camera pixels apart, the pixels between them all decoded, the result
// within one column of the decoded one: windows across a depth edge are rejected); a pixel without
// such boundaries keeps its whole column. Assumes camera rows run across the projector columns
// (a baseline along them), as the column-plane triangulation does. `frames` is the decoded
// sequence; throws InputError when its frame count or sizes do not match.
void refine_columns_at_edges(const GrayCodePatterns& patterns, std::span<const GreyImage> frames,
                             DecodedMap& map, double max_gap_px = 6);

}  // namespace sherd::structured_light
