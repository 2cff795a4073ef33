// A simulated turntable: a stepper plate that takes realistic time to move (trapezoidal speed
// profile), reports its angle through a finite-resolution encoder, and can be told to fail.
#pragma once

#include "drivers/turntable.h"

#include <mutex>
#include <string>

namespace sherd::sim {

enum class TurntableFault { None, Stall, Timeout, Disconnect };

struct TurntableModel {
  int steps_per_revolution = 3200;
  double speed_deg_s = 90.0;
  double acceleration_deg_s2 = 360.0;
  double time_scale = 1.0;  // multiplies every simulated motion time; 0 = no waiting
  TurntableFault fault = TurntableFault::None;
  int fault_at_move = 1;    // 1-based index of the move that fails
};

class SimulatedTurntable : public drivers::Turntable {
 public:
  explicit SimulatedTurntable(TurntableModel model);
  std::string describe() const override;
  void home() override;
  double move_to(double angle_rad) override;
  double position() const override;
  drivers::TurntableState state() const override;
  double resolution() const override;

  // The plate's true physical angle (radians) — what the simulated scanner sees. After a stall it
  // differs from what the caller asked for.
  double physical_angle() const;

 private:
  // (the helper that implements this class adds its private state here)
  mutable std::mutex mutex_;
  TurntableModel model_;
};

}  // namespace sherd::sim
