#include "render/png_writer.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <png.h>

#include <bit>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstring>

namespace sherd::render {
namespace {

// libpng reports errors by longjmp; each call into it goes through a function that holds only
// trivially destructible locals, so that jumping out is well defined. Returns false on error.
template <typename F>
bool guarded(png_structp png, F&& call) {
  if (setjmp(png_jmpbuf(png))) return false;
  call();
  return true;
}

}  // namespace

PngStream::PngStream(const std::filesystem::path& file, int width, int height, int dpi,
                     PngFormat format)
    : file_(file), height_(height) {
  if (width <= 0 || height <= 0 || dpi <= 0)
    throw ProcessingError(
        fmt::format("{}: bad PNG request {}×{} px at {} dpi", file.string(), width, height, dpi));
  out_ = std::fopen(file.c_str(), "wb");
  if (!out_)
    throw ProcessingError(fmt::format("{}: cannot write ({}); check the output directory",
                                      file.string(), std::strerror(errno)));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  png_ = png;
  info_ = info;
  if (!info) {
    close();
    throw ProcessingError(fmt::format("{}: libpng could not be initialised", file.string()));
  }
  const auto pixels_per_metre = static_cast<png_uint_32>(std::lround(dpi / 0.0254));
  const bool ok = guarded(png, [&] {
    png_init_io(png, out_);
    const bool grey = format == PngFormat::kGrey16;
    png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
                 grey ? 16 : 8, grey ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_pHYs(png, info, pixels_per_metre, pixels_per_metre, PNG_RESOLUTION_METER);
    // Plates are mostly white: zlib's fastest level compresses them nearly as well as its
    // default and several times faster (bench/render's encode stage).
    png_set_compression_level(png, 1);
    // Sub and Up only: files as small as with libpng's five-way adaptive choice (Paeth and
    // Average buy nothing on paper-white and smooth shading) at about 2/3 of the encode time.
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB | PNG_FILTER_UP);
    png_write_info(png, info);
    if (grey && std::endian::native == std::endian::little) png_set_swap(png);
  });
  if (!ok) {
    close();
    throw ProcessingError(fmt::format("{}: libpng failed writing the header", file.string()));
  }
}

PngStream::~PngStream() { close(); }

void PngStream::close() {
  if (png_) {
    auto png = static_cast<png_structp>(png_);
    auto info = static_cast<png_infop>(info_);
    png_destroy_write_struct(&png, &info);
    png_ = info_ = nullptr;
  }
  if (out_) {
    std::fclose(out_);
    out_ = nullptr;
  }
  if (!finished_) {
    std::error_code ignored;
    std::filesystem::remove(file_, ignored);
  }
}

void PngStream::write_row(const void* row) {
  if (rows_written_ >= height_)
    throw ProcessingError(fmt::format("{}: more than {} rows written", file_.string(), height_));
  auto png = static_cast<png_structp>(png_);
  if (!guarded(png, [&] { png_write_row(png, static_cast<png_const_bytep>(row)); }))
    throw ProcessingError(
        fmt::format("{}: libpng failed while writing (disk full?)", file_.string()));
  ++rows_written_;
}

void PngStream::finish() {
  if (rows_written_ != height_)
    throw ProcessingError(
        fmt::format("{}: {} of {} rows written", file_.string(), rows_written_, height_));
  auto png = static_cast<png_structp>(png_);
  const bool ok = guarded(png, [&] { png_write_end(png, nullptr); });
  const bool closed = std::fclose(out_) == 0;
  out_ = nullptr;
  if (!ok || !closed)
    throw ProcessingError(fmt::format("{}: writing the PNG failed (disk full?)", file_.string()));
  finished_ = true;
}

}  // namespace sherd::render
