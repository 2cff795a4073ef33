// The vector part of a plate: axis, black section, exterior outline, rim and base lines, in
// drawing coordinates (mm; u to the right with the axis at u = 0, v up = height along the axis).
// Computed once, drawn by cairo into plate.png and written by hand as profile.svg.
#pragma once

#include "processing/profile/profile.h"

#include <filesystem>
#include <optional>
#include <string>

namespace sherd::render {

struct DrawingBounds {
  double u_min = 0.0, u_max = 0.0, v_min = 0.0, v_max = 0.0;
  void include(double u, double v);
  void include(const DrawingBounds& other);
};

struct HorizontalLine {
  double v = 0.0, u_from = 0.0, u_to = 0.0;
};

struct ProfileDrawing {
  double axis_v_min = 0.0, axis_v_max = 0.0;  // the dash-dot axis line at u = 0
  profile::Polyline2 section;                 // closed polygon: outer profile, then inner reversed
  profile::Polyline2 exterior_outline;        // the outer profile mirrored onto the exterior side
  std::optional<HorizontalLine> rim_line, base_line;  // across both halves
  DrawingBounds bounds;                               // of everything above
};

// Section at +r when `section_on_right`, else at −r (mirrored); the exterior on the other side.
// Throws sherd::InputError when the profile has fewer than two outer or inner points or
// non-finite values.
ProfileDrawing make_profile_drawing(const profile::Analysis& analysis, bool section_on_right);

// profile.svg: 1 user unit = 1 mm (width/height in mm, viewBox in mm), y down as SVG has it,
// i.e. svg y = −v. `margin_mm` of white around the bounds. Throws sherd::ProcessingError when
// the file cannot be written.
void write_profile_svg(const std::filesystem::path& file, const ProfileDrawing& drawing,
                       double margin_mm);

// profile.svg for a sherd without an axis: no section can be drawn; the file says why, so that
// every sherd still has the artefact DESIGN.md promises.
void write_no_section_svg(const std::filesystem::path& file, const std::string& reason);

}  // namespace sherd::render
