#include "render/png_writer.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <png.h>

#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>

namespace sherd::render {
namespace {

// libpng reports errors by longjmp; this function holds only trivially destructible locals so
// that jumping out of it is well defined. Returns an empty string on success.
const char* write_rows(std::FILE* out, int width, int height, const std::uint8_t* rgb,
                       png_uint_32 pixels_per_metre) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!png) return "libpng could not be initialised";
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return "libpng could not be initialised";
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return "libpng failed while writing (disk full?)";
  }
  png_init_io(png, out);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_pHYs(png, info, pixels_per_metre, pixels_per_metre, PNG_RESOLUTION_METER);
  png_write_info(png, info);
  for (int row = 0; row < height; ++row)
    png_write_row(png, rgb + static_cast<std::size_t>(row) * width * 3);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return "";
}

}  // namespace

void write_png_rgb8(const std::filesystem::path& file, int width, int height,
                    const std::vector<std::uint8_t>& rgb, int dpi) {
  if (width <= 0 || height <= 0 || dpi <= 0 ||
      rgb.size() != static_cast<std::size_t>(width) * height * 3)
    throw ProcessingError(fmt::format("{}: bad PNG request {}×{} px at {} dpi ({} bytes)",
                                      file.string(), width, height, dpi, rgb.size()));
  std::FILE* out = std::fopen(file.c_str(), "wb");
  if (!out)
    throw ProcessingError(fmt::format("{}: cannot write ({}); check the output directory",
                                      file.string(), std::strerror(errno)));
  const auto pixels_per_metre = static_cast<png_uint_32>(std::lround(dpi / 0.0254));
  const char* error = write_rows(out, width, height, rgb.data(), pixels_per_metre);
  const bool closed = std::fclose(out) == 0;
  if (*error || !closed)
    throw ProcessingError(fmt::format("{}: {}", file.string(),
                                      *error ? error : "closing the file failed (disk full?)"));
}

}  // namespace sherd::render
