// The structured-light scanner as the station sees it (drivers::Scanner): the projector shows the
// pattern sequence (Gray code, optionally followed by phase-shifted fringes), the camera captures
// each pattern, the frames are decoded and triangulated into one organised view in the camera frame
// (mm), grey colour from the white frame.
#pragma once

#include <memory>

#include "drivers/camera.h"
#include "drivers/projector.h"
#include "drivers/scanner.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/phase_shift.h"
#include "processing/structured_light/triangulation.h"

namespace sherd::structured_light {

enum class PatternSet {
  kGray,   // Gray code alone: sub-pixel columns from the stripe edges (refine_columns_at_edges)
  kPhase,  // Gray code, then phase-shifted fringes refining the column to a fraction of a pixel
};

struct ScannerOptions {
  PatternSet patterns = PatternSet::kGray;
  DecodeThresholds thresholds{.edge_bits = 1};
  int phase_period_px = 16;   // fringe period (kPhase)
  int phase_steps = 4;        // fringe frames (kPhase)
  double min_modulation = 8;  // fringe amplitude (grey levels) below which the edge column stands
  // Points whose camera and projector rays pass further apart than this are dropped: the decoded
  // column and row disagree (a pixel straddling a depth edge, a misdecoded bit). 0 = keep all.
  double max_ray_gap_mm = 0;
  int threads = 2;
};

class StructuredLightScanner : public drivers::Scanner {
 public:
  // Camera and projector must outlive the scanner. Throws InputError when the projector's size
  // is not the calibrated one.
  StructuredLightScanner(drivers::Camera& camera, drivers::Projector& projector,
                         const ProCamCalibration& calibration, const ScannerOptions& options = {});

  std::string describe() const override;
  // Throws DeviceError when the camera fails or delivers frames of another size than calibrated.
  OrganisedView capture() override;

  // Frames one capture shows and films.
  int frame_count() const { return static_cast<int>(pattern_frames_.size()); }

 private:
  drivers::Camera& camera_;
  drivers::Projector& projector_;
  ScannerOptions options_;
  GrayCodePatterns gray_;
  PhaseShiftPatterns phase_;
  std::vector<GreyImage> pattern_frames_;  // made once: the same sequence every capture
  Triangulator triangulator_;
  int camera_width_, camera_height_;
};

}  // namespace sherd::structured_light
