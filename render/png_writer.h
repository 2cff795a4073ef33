// PNG output with the physical pixel size recorded (pHYs), written with libpng directly because
// cairo's PNG writer records none.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace sherd::render {

// Writes 8-bit RGB (`rgb`: rows from the top, 3 bytes per pixel) with pHYs = dpi / 0.0254 pixels
// per metre, rounded. Throws sherd::ProcessingError when the file cannot be written.
void write_png_rgb8(const std::filesystem::path& file, int width, int height,
                    const std::vector<std::uint8_t>& rgb, int dpi);

}  // namespace sherd::render
