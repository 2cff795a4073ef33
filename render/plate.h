// The publication plate of one sherd: the exterior rendered headlessly (EGL, Lafortune BRDF) at
// real scale next to the black profile section, axis line, scale bar and key measurements.
// Writes plate.png (pHYs = dpi; 8-bit RGB or 16-bit grey) and profile.svg (1 user unit = 1 mm).
// The plate is composed and written in bands of rows, so memory stays bounded at any dpi.
#pragma once

#include "core/types.h"
#include "processing/profile/profile.h"

#include <filesystem>
#include <string>

namespace sherd::render {

struct PlateSettings {
  int dpi = 600;
  std::string material = "clay";
  std::filesystem::path materials_file;  // config/materials.xml
  bool section_on_right = true;          // German/Austrian convention; false = British
  bool grey16 = false;  // plate.png as 16-bit grey (the view read back from GL in float)
  int band_rows = 0;    // rows composed at a time (0: about 128 MiB worth); bounds memory
  bool rim_percent_diagram = true;  // the preserved rim share as an arc, where it is known
};

struct PlateInput {
  std::string scan_id;
  std::string sherd_id;
  const Mesh* mesh = nullptr;                   // the sherd in the world frame
  const profile::Analysis* analysis = nullptr;  // nullptr or !axis.found: body sherd without axis
};

struct PlateFiles {
  std::filesystem::path png;
  std::filesystem::path svg;
  int width_px = 0, height_px = 0;
};

// Renders into `dir` (created if missing). Throws sherd::InputError for a bad materials file or an
// unknown preset, sherd::ProcessingError when no EGL context can be made (the message names what
// is missing).
PlateFiles render_plate(const PlateInput& input, const PlateSettings& settings,
                        const std::filesystem::path& dir);

}  // namespace sherd::render
