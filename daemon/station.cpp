#include "daemon/station.h"

#include "core/errors.h"
#include "drivers/libusb_transport.h"
#include "drivers/aravis_camera.h"
#include "drivers/drm_projector.h"
#include "drivers/usb_turntable.h"
#include "processing/structured_light/scanner.h"
#include "simulators/sim_scanner.h"
#include "simulators/structured_light_world.h"
#include "simulators/sim_turntable.h"
#include "simulators/turntable_firmware.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>

namespace sherd::station {
namespace {

sim::TurntableFault turntable_fault(const std::string& name) {
  if (name == "stall") return sim::TurntableFault::Stall;
  if (name == "timeout") return sim::TurntableFault::Timeout;
  if (name == "disconnect") return sim::TurntableFault::Disconnect;
  return sim::TurntableFault::None;  // the config parser has already rejected anything else
}

// The turntable named by [turntable] driver, and where its plate physically stands.
std::unique_ptr<drivers::Turntable> make_turntable(const config::StationConfig& config,
                                                   std::function<double()>& plate_angle) {
  const auto& t = config.turntable;
  const bool usb_only_fault =
      t.fault == "no_reply" || t.fault == "garbled" || t.fault == "unplug" || t.fault == "homing";
  if (t.driver == "simulated") {
    if (usb_only_fault) {
      throw InputError(
          fmt::format("{}: turntable.fault = \"{}\" needs turntable.driver = "
                      "\"usb-simulated\" (the simulated firmware)",
                      config.source.string(), t.fault));
    }
    auto table = std::make_unique<sim::SimulatedTurntable>(
        sim::TurntableModel{t.steps_per_revolution, t.speed_deg_s, t.acceleration_deg_s2,
                            t.time_scale, turntable_fault(t.fault), t.fault_at_move});
    const sim::SimulatedTurntable* plate = table.get();
    plate_angle = [plate] { return plate->physical_angle(); };
    return table;
  }
  drivers::UsbTurntableSettings settings;
  settings.steps_per_revolution = t.steps_per_revolution;
  settings.speed_deg_s = t.speed_deg_s;
  settings.acceleration_deg_s2 = t.acceleration_deg_s2;
  settings.reply_timeout = std::chrono::milliseconds(t.reply_timeout_ms);
  settings.move_attempts = t.move_attempts;
  settings.reconnect_timeout =
      std::chrono::milliseconds(static_cast<long>(t.reconnect_timeout_s * 1000));
  if (t.driver == "usb") {
    auto transport = std::make_unique<drivers::LibusbTransport>(drivers::UsbDeviceId{
        static_cast<std::uint16_t>(t.usb_vendor_id), static_cast<std::uint16_t>(t.usb_product_id),
        t.usb_serial, t.usb_interface});
    auto table = std::make_unique<drivers::UsbTurntable>(std::move(transport), settings);
    const drivers::UsbTurntable* plate = table.get();
    plate_angle = [plate] { return plate->position(); };  // a real plate: its encoder
    return table;
  }
  if (t.fault == "timeout") {
    throw InputError(
        fmt::format("{}: turntable.fault = \"timeout\" is the \"simulated\" "
                    "driver's; with \"usb-simulated\" use \"no_reply\"",
                    config.source.string()));
  }
  sim::FirmwareModel firmware_model;
  firmware_model.steps_per_revolution = t.steps_per_revolution;
  firmware_model.max_speed_deg_s = t.speed_deg_s;
  firmware_model.acceleration_deg_s2 = t.acceleration_deg_s2;
  firmware_model.fault = sim::firmware_fault_from_string(t.fault);
  firmware_model.fault_at = t.fault_at_move;
  firmware_model.fault_count = t.fault_count;
  firmware_model.seed = config.simulation.seed;
  auto firmware = std::make_shared<sim::TurntableFirmware>(firmware_model);
  auto transport = std::make_unique<sim::FirmwareTransport>(firmware, t.time_scale);
  // The transport lives as long as the turntable, which the Station holds longer than the scanner.
  const sim::FirmwareTransport* bus = transport.get();
  plate_angle = [firmware, bus] { return firmware->plate_angle_rad(bus->now_s()); };
  return std::make_unique<drivers::UsbTurntable>(std::move(transport), settings);
}

namespace sl = structured_light;

sl::ScannerOptions structured_light_options(const config::ScannerSettings& c) {
  sl::ScannerOptions options;
  options.patterns = c.patterns == "phase" ? sl::PatternSet::kPhase : sl::PatternSet::kGray;
  options.thresholds = {c.black_threshold, c.white_threshold, c.edge_bits};
  options.phase_period_px = c.phase_period_px;
  options.phase_steps = c.phase_steps;
  options.min_modulation = c.min_modulation;
  options.max_ray_gap_mm = c.max_ray_gap_mm;
  return options;
}

// The structured-light scanner on a real camera and projector, which it owns.
class CameraProjectorScanner : public drivers::Scanner {
 public:
  CameraProjectorScanner(std::unique_ptr<drivers::Camera> camera, std::unique_ptr<drivers::Projector> projector,
                         const sl::ProCamCalibration& calibration, const sl::ScannerOptions& options)
      : camera_(std::move(camera)),
        projector_(std::move(projector)),
        scanner_(*camera_, *projector_, calibration, options) {}
  std::string describe() const override { return scanner_.describe(); }
  OrganisedView capture() override { return scanner_.capture(); }

 private:
  std::unique_ptr<drivers::Camera> camera_;
  std::unique_ptr<drivers::Projector> projector_;
  sl::StructuredLightScanner scanner_;
};

// [scanner] driver = "structured-light": the calibration file, the Aravis camera at the calibrated
// size, the projector as a DRM/KMS display.
std::unique_ptr<drivers::Scanner> make_structured_light_scanner(const config::StationConfig& config) {
  const auto& c = config.scanner;
  std::error_code error;
  if (!std::filesystem::exists(c.calibration_file, error)) {
    throw InputError(fmt::format("{}: scanner.calibration_file: no scanner calibration at {}; run "
                                 "`sherdctl calibrate scanner --captures DIR…` or set calibration_file",
                                 config.source.string(), c.calibration_file.string()));
  }
  sl::ProCamCalibration calibration = sl::read_calibration(c.calibration_file);
  if (calibration.camera.width <= 0) {
    throw InputError(fmt::format("{}: the scanner calibration has no camera image size (img_shape); "
                                 "calibrate again with `sherdctl calibrate scanner`",
                                 c.calibration_file.string()));
  }
  drivers::AravisCameraSettings camera;
  camera.id = c.camera_id;
  camera.width = calibration.camera.width;
  camera.height = calibration.camera.height;
  if (c.trigger == "line") camera.trigger = drivers::AravisCameraSettings::Trigger::kLine;
  camera.trigger_line = c.trigger_line;
  auto opened = std::make_unique<drivers::AravisCamera>(camera);  // DeviceError: not found
  auto projector = std::make_unique<drivers::DrmProjector>(
      drivers::DrmProjectorSettings{c.projector_device, c.projector_connector});  // DeviceError
  return std::make_unique<CameraProjectorScanner>(std::move(opened), std::move(projector), calibration,
                                                  structured_light_options(c));
}

// Uncalibrated, the nominal pose may be off by a mounting error of this order.
constexpr double kUncalibratedTiltSdDeg = 0.5;
constexpr double kUncalibratedTranslationSdMm = 2.0;
// Floors under a calibration's σ: a fit of 12 views says nothing of the drift of the mount since
// (temperature, a bump) nor of the printed object's tolerances.
constexpr double kMinTiltSdDeg = 0.01;
constexpr double kMinTranslationSdMm = 0.05;

// A simulated scanner (any kind with set_scene) as the station's scanner; placing the
// calibration object swaps its scene for the calibration scene and back.
template <typename SimulatedScannerKind>
void attach_simulated_scanner(Station& station, std::unique_ptr<SimulatedScannerKind> scanner,
                              const sim::SceneSpec& spec) {
  SimulatedScannerKind* simulated = scanner.get();
  station.place_calibration_object = [simulated, spec](bool on_plate) {
    sim::SceneSpec now = spec;
    if (on_plate) now.kind = sim::SceneKind::Calibration;
    simulated->set_scene(sim::make_scene(now));
  };
  station.scanner = std::move(scanner);
}

}  // namespace

Pose calibrated_scanner_pose(const config::ScannerSettings& scanner) {
  return sim::look_at_pose(scanner.position_mm, scanner.look_at_mm);
}

Pose simulated_scanner_pose(const config::StationConfig& config) {
  return sim::mounted_pose(calibrated_scanner_pose(config.scanner),
                           {config.simulation.scanner_tilt_error_deg,
                            config.simulation.scanner_offset_error_mm, config.simulation.seed});
}

registration::PriorUncertainty prior_uncertainty(
    const std::optional<calibration::TurntableCalibration>& calibration,
    const config::TurntableSettings& turntable) {
  registration::PriorUncertainty prior;
  prior.angle_sd_deg = turntable.angle_sd_deg;
  if (!calibration) {
    prior.tilt_sd_deg = kUncalibratedTiltSdDeg;
    prior.translation_sd_mm = kUncalibratedTranslationSdMm;
    return prior;
  }
  prior.tilt_sd_deg = std::max(calibration->direction_sd_deg, kMinTiltSdDeg);
  prior.translation_sd_mm =
      std::max(std::hypot(calibration->point_sd_mm, calibration->height_sd_mm), kMinTranslationSdMm);
  return prior;
}

void apply_turntable_calibration(Station& station, const calibration::TurntableCalibration& calibration,
                                 const config::StationConfig& config) {
  station.scanner_to_world = calibration.scanner_to_world();
  station.turntable_calibration = calibration;
  station.prior_uncertainty = prior_uncertainty(calibration, config.turntable);
  station.calibration_note.clear();
}

sim::SceneSpec scene_spec(const config::SimulationSettings& simulation) {
  sim::SceneSpec spec;
  spec.seed = simulation.seed;
  spec.kind = sim::scene_kind_from_string(simulation.scene);
  spec.sherds = simulation.sherds;
  spec.background = simulation.background == "white" ? sim::Background::White : sim::Background::Black;
  return spec;
}

Station make_station(const config::StationConfig& config) {
  if (config.scanner.driver != "simulated" && config.scanner.driver != "structured-light-simulated" &&
      config.scanner.driver != "structured-light") {
    throw InputError(fmt::format("{}: scanner.driver = \"{}\": no such driver in this build; use \"simulated\"",
                                 config.source.string(), config.scanner.driver));
  }
  Station station;
  station.scanner_to_world = calibrated_scanner_pose(config.scanner);
  station.prior_uncertainty = prior_uncertainty(std::nullopt, config.turntable);
  const auto& file = config.calibration.turntable_file;
  std::error_code error;
  if (!std::filesystem::exists(file, error)) {
    station.calibration_note = fmt::format(
        "turntable not calibrated — run sherdctl calibrate turntable (no {})", file.string());
  } else {
    try {
      apply_turntable_calibration(station, calibration::read_turntable_calibration(file), config);
    } catch (const InputError& e) {
      station.calibration_note = e.what();
    }
  }

  // The angle the simulated scanner images the plate at: the plate's physical angle, which after
  // a stall differs from the commanded one (that is what the station must notice).
  std::function<double()> plate_angle;
  std::unique_ptr<drivers::Turntable> turntable = make_turntable(config, plate_angle);

  const auto& c = config.scanner;
  sim::ScannerModel model;
  model.width = c.width;
  model.height = c.height;
  model.fx = c.fx;
  model.fy = c.fy;
  model.cx = c.cx;
  model.cy = c.cy;
  model.scanner_to_world = simulated_scanner_pose(config);  // the physical pose, not the believed one
  model.projector_offset_mm = c.projector_offset_mm;
  model.depth_noise_mm = c.depth_noise_mm;
  model.grazing_limit_deg = c.grazing_limit_deg;
  model.dropout_fraction = c.dropout_fraction;
  model.seed = config.simulation.seed;

  const sim::SceneSpec spec = scene_spec(config.simulation);
  if (c.driver == "structured-light") {
    station.scanner = make_structured_light_scanner(config);
    station.turntable = std::move(turntable);
    return station;
  }
  if (c.driver == "structured-light-simulated") {
    // Its camera is the [scanner] camera at its physical pose; its projector sits at
    // projector_offset_mm aimed at look_at_mm. Both are also its calibration (the simulated truth).
    sl::Intrinsics camera;
    camera.width = c.width;
    camera.height = c.height;
    camera.matrix << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1;
    const Vec3d target = calibrated_scanner_pose(c).inverse() * c.look_at_mm;
    const sl::ProCamCalibration calibration =
        sim::procam_aimed_at(camera, c.projector_offset_mm, target, c.projector_width, c.projector_height);
    attach_simulated_scanner(
        station,
        std::make_unique<sim::SimulatedStructuredLightScanner>(
            sim::make_scene(spec), model.scanner_to_world, calibration,
            structured_light_options(c), sim::StructuredLightOptics{.seed = config.simulation.seed},
            std::move(plate_angle)),
        spec);
    station.turntable = std::move(turntable);
    return station;
  }
  attach_simulated_scanner(
      station,
      std::make_unique<sim::SimulatedScanner>(sim::make_scene(spec), model, std::move(plate_angle)),
      spec);
  station.turntable = std::move(turntable);
  return station;
}

}  // namespace sherd::station
