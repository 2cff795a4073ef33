// The station's hardware, assembled from the configuration: a scanner, a turntable and the
// calibrated scanner pose in the world (= turntable) frame.
#pragma once

#include "config/station_config.h"
#include "core/types.h"
#include "drivers/scanner.h"
#include "drivers/turntable.h"
#include "processing/calibration/turntable_calibration.h"
#include "processing/registration/registration.h"
#include "simulators/pottery.h"

#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace sherd::station {

struct Station {
  std::unique_ptr<drivers::Turntable> turntable;
  std::unique_ptr<drivers::Scanner> scanner;
  Pose scanner_to_world = Pose::Identity();  // calibrated
  // How well scanner_to_world and the encoder place each view: the weight of the turntable prior.
  registration::PriorUncertainty prior_uncertainty;
  // The turntable calibration in force; none: scanner_to_world is the configured nominal pose
  // and `calibration_note` says why (never calibrated, or the file is unreadable).
  std::optional<calibration::TurntableCalibration> turntable_calibration;
  std::string calibration_note;
  // What the operator does by hand around a calibration scan: put the calibration object on the
  // plate (true), take it off again (false). The simulated station swaps its scene.
  std::function<void(bool on_plate)> place_calibration_object;
};

// The configured (nominal) scanner pose (optical centre and look-at point): what the station
// believes until the turntable is calibrated.
Pose calibrated_scanner_pose(const config::ScannerSettings& scanner);

// The simulated scanner's physical pose: the nominal pose moved by [simulation]'s mounting error
// (scanner_tilt_error_deg, scanner_offset_error_mm, directions from the seed). The truth that a
// turntable calibration of the simulated station must find.
Pose simulated_scanner_pose(const config::StationConfig& config);

// The prior's uncertainty: from the calibration's σ (with floors: the fit's σ says nothing of
// drift since, or of the printed object's tolerances), or generous defaults when uncalibrated;
// the angle from [turntable] angle_sd_deg.
registration::PriorUncertainty prior_uncertainty(
    const std::optional<calibration::TurntableCalibration>& calibration,
    const config::TurntableSettings& turntable);

// Puts `calibration` in force: scanner_to_world and prior_uncertainty follow it.
void apply_turntable_calibration(Station& station, const calibration::TurntableCalibration& calibration,
                                 const config::StationConfig& config);

// The synthetic scene the simulated station holds (shared with tests, which rebuild its truth).
sim::SceneSpec scene_spec(const config::SimulationSettings& simulation);

// Builds the drivers named in the configuration and puts the turntable calibration found in
// [calibration] turntable_file in force (a missing or unreadable file leaves the nominal pose,
// with the reason in calibration_note: the station must still start, to be calibrated again).
// Throws InputError for an unknown driver and DeviceError when the hardware cannot be opened.
Station make_station(const config::StationConfig& config);

}  // namespace sherd::station
