// PNG output with the physical pixel size recorded (pHYs), written row by row with libpng
// directly (cairo's PNG writer records no pHYs and wants the whole image in memory).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>

namespace sherd::render {

enum class PngFormat {
  kRgb8,    // 3 bytes per pixel
  kGrey16,  // one std::uint16_t per pixel (native byte order; written big-endian as PNG wants)
};

// Streams rows from the top into `file`, pHYs = dpi / 0.0254 pixels per metre (rounded), so a
// plate never has to be held whole. Throws sherd::ProcessingError when the file cannot be
// written; an unfinished file is removed.
class PngStream {
 public:
  PngStream(const std::filesystem::path& file, int width, int height, int dpi, PngFormat format);
  ~PngStream();
  PngStream(const PngStream&) = delete;
  PngStream& operator=(const PngStream&) = delete;

  void write_row(const void* row);  // width pixels in `format`
  void finish();                    // after exactly `height` rows

 private:
  void close();  // frees libpng, closes the file and removes it unless finished

  std::filesystem::path file_;
  int height_ = 0, rows_written_ = 0;
  std::FILE* out_ = nullptr;
  void* png_ = nullptr;   // png_structp (libpng's types stay in the .cpp)
  void* info_ = nullptr;  // png_infop
  bool finished_ = false;
};

}  // namespace sherd::render
