// The station's hardware, assembled from the configuration: a scanner, a turntable and the
// calibrated scanner pose in the world (= turntable) frame.
#pragma once

#include "config/station_config.h"
#include "core/types.h"
#include "drivers/scanner.h"
#include "drivers/turntable.h"
#include "simulators/pottery.h"

#include <memory>

namespace sherd::station {

struct Station {
  std::unique_ptr<drivers::Turntable> turntable;
  std::unique_ptr<drivers::Scanner> scanner;
  Pose scanner_to_world = Pose::Identity();  // calibrated
};

// The calibrated scanner pose from the configuration (optical centre and look-at point).
Pose calibrated_scanner_pose(const config::ScannerSettings& scanner);

// The synthetic scene the simulated station holds (shared with tests, which rebuild its truth).
sim::SceneSpec scene_spec(const config::SimulationSettings& simulation);

// Builds the drivers named in the configuration. Throws InputError for an unknown driver and
// DeviceError when the hardware cannot be opened.
Station make_station(const config::StationConfig& config);

}  // namespace sherd::station
