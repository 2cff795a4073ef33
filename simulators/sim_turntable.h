// A simulated turntable: a stepper plate that takes realistic time to move (trapezoidal speed
// profile), reports its angle through a finite-resolution encoder, and can be told to fail.
#pragma once

#include "drivers/turntable.h"
#include "simulators/random.h"

#include <chrono>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>

namespace sherd::sim {

enum class TurntableFault { None, Stall, Timeout, Disconnect };

struct TurntableModel {
  int steps_per_revolution = 3200;
  double speed_deg_s = 90.0;
  double acceleration_deg_s2 = 360.0;
  double time_scale = 1.0;  // multiplies every simulated motion time; 0 = no waiting
  TurntableFault fault = TurntableFault::None;
  // 1-based index of the failing move, counted from the last home() (or power-up): the fault
  // recurs at the same move after every re-home, so a test can rely on it.
  int fault_at_move = 1;
  double timeout_s = 10.0;  // how long a Timeout move hangs before it throws (simulated seconds)
  std::uint64_t seed = 7;   // where a stall stops
};

// Parse "none"|"stall"|"timeout"|"disconnect"; InputError otherwise.
TurntableFault turntable_fault_from_string(const std::string& name);

class SimulatedTurntable : public drivers::Turntable {
 public:
  // Starts at the index position (angle 0), as after power-up homing. Throws InputError for a
  // model with non-positive steps, speed or acceleration, negative time_scale or fault_at_move < 1.
  explicit SimulatedTurntable(TurntableModel model);
  std::string describe() const override;
  void home() override;
  // Moves the shortest way. During the move state() is Moving and position()/physical_angle()
  // follow the speed profile.
  double move_to(double angle_rad) override;
  double position() const override;
  drivers::TurntableState state() const override;
  double resolution() const override;

  // The plate's true physical angle (radians) — what the simulated scanner sees. After a stall it
  // differs from what the caller asked for.
  double physical_angle() const;

  // Simulated duration (seconds, before time_scale) of the last move or homing, also of a failed
  // one: what the motion took on the station's clock.
  double last_move_seconds() const;

 private:
  using Clock = std::chrono::steady_clock;
  // A motion in progress, from `from_rad` by `distance_rad` (signed) along the speed profile.
  struct Motion {
    double from_rad = 0.0, distance_rad = 0.0, seconds = 0.0;
    Clock::time_point start;
  };
  // Runs a motion: publishes it, sleeps unlocked for its scaled duration, returns relocked with
  // the plate at its end.
  void run_motion(std::unique_lock<std::mutex>& lock, double distance_rad, double seconds,
                  drivers::TurntableState during);
  double physical_locked() const;
  double encoder_reading(double physical_rad) const;
  void throw_if_disconnected() const;

  mutable std::mutex mutex_;
  TurntableModel model_;
  Rng rng_;
  double physical_rad_ = 0.0;  // resting angle in [0, 2π)
  std::optional<Motion> motion_;
  drivers::TurntableState state_ = drivers::TurntableState::Idle;
  int moves_since_home_ = 0;
  double last_move_seconds_ = 0.0;
};

}  // namespace sherd::sim
