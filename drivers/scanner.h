// The 3D scanner as the station sees it: one call captures one organised view.
// Implementations: the simulated scanner (simulators/), the structured-light scanner (later).
#pragma once

#include "core/types.h"

#include <string>

namespace sherd::drivers {

class Scanner {
 public:
  virtual ~Scanner() = default;
  // A short human-readable identification (model, serial, or "simulated").
  virtual std::string describe() const = 0;
  // Captures one view in the scanner frame (millimetres; x right, y down, z along the optical
  // axis, OpenCV convention). Normals point towards the scanner. Throws DeviceError on failure;
  // never returns a partial or stale view.
  virtual OrganisedView capture() = 0;
};

}  // namespace sherd::drivers
