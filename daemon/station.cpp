#include "daemon/station.h"

#include "core/errors.h"
#include "simulators/sim_scanner.h"
#include "simulators/sim_turntable.h"

#include <fmt/format.h>

namespace sherd::station {
namespace {

sim::TurntableFault turntable_fault(const std::string& name) {
  if (name == "stall") return sim::TurntableFault::Stall;
  if (name == "timeout") return sim::TurntableFault::Timeout;
  if (name == "disconnect") return sim::TurntableFault::Disconnect;
  return sim::TurntableFault::None;  // the config parser has already rejected anything else
}

sim::SceneKind scene_kind(const std::string& name) {
  if (name == "plate") return sim::SceneKind::Plate;
  if (name == "vessel") return sim::SceneKind::Vessel;
  if (name == "empty") return sim::SceneKind::Empty;
  return sim::SceneKind::Frame;
}

}  // namespace

Pose calibrated_scanner_pose(const config::ScannerSettings& scanner) {
  return sim::look_at_pose(scanner.position_mm, scanner.look_at_mm);
}

sim::SceneSpec scene_spec(const config::SimulationSettings& simulation) {
  sim::SceneSpec spec;
  spec.seed = simulation.seed;
  spec.kind = scene_kind(simulation.scene);
  spec.sherds = simulation.sherds;
  spec.background = simulation.background == "white" ? sim::Background::White : sim::Background::Black;
  return spec;
}

Station make_station(const config::StationConfig& config) {
  if (config.turntable.driver != "simulated") {
    throw InputError(fmt::format("{}: turntable.driver = \"{}\": no such driver in this build; use \"simulated\"",
                                 config.source.string(), config.turntable.driver));
  }
  if (config.scanner.driver != "simulated") {
    throw InputError(fmt::format("{}: scanner.driver = \"{}\": no such driver in this build; use \"simulated\"",
                                 config.source.string(), config.scanner.driver));
  }
  Station station;
  station.scanner_to_world = calibrated_scanner_pose(config.scanner);

  const auto& t = config.turntable;
  auto turntable = std::make_unique<sim::SimulatedTurntable>(sim::TurntableModel{
      t.steps_per_revolution, t.speed_deg_s, t.acceleration_deg_s2, t.time_scale,
      turntable_fault(t.fault), t.fault_at_move});

  const auto& c = config.scanner;
  sim::ScannerModel model;
  model.width = c.width;
  model.height = c.height;
  model.fx = c.fx;
  model.fy = c.fy;
  model.cx = c.cx;
  model.cy = c.cy;
  model.scanner_to_world = station.scanner_to_world;
  model.projector_offset_mm = c.projector_offset_mm;
  model.depth_noise_mm = c.depth_noise_mm;
  model.grazing_limit_deg = c.grazing_limit_deg;
  model.dropout_fraction = c.dropout_fraction;
  model.seed = config.simulation.seed;

  // The simulated scanner images the plate at the turntable's physical angle, which after a
  // stall differs from the commanded one: that is what the station must notice.
  const sim::SimulatedTurntable* plate = turntable.get();
  station.scanner = std::make_unique<sim::SimulatedScanner>(
      sim::make_scene(scene_spec(config.simulation)), model, [plate] { return plate->physical_angle(); });
  station.turntable = std::move(turntable);
  return station;
}

}  // namespace sherd::station
