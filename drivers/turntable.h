// The rotational plate as the station sees it. Angles in radians inside the code, measured
// counter-clockwise about the world z axis (the calibrated turntable axis, pointing up).
#pragma once

#include <string>

namespace sherd::drivers {

enum class TurntableState { Idle, Homing, Moving, Fault, Disconnected };

const char* to_string(TurntableState state);

class Turntable {
 public:
  virtual ~Turntable() = default;
  virtual std::string describe() const = 0;
  // Finds the index position and defines it as angle 0. Throws DeviceError on failure.
  virtual void home() = 0;
  // Moves to `angle_rad` (any real number; taken modulo 2π, shortest way not required) and blocks
  // until the plate stands still. Returns the angle the encoder reports after the move, which the
  // caller must record (it differs from the command by the encoder resolution). Throws DeviceError
  // on stall, timeout or disconnect.
  virtual double move_to(double angle_rad) = 0;
  // The encoder position (radians, [0, 2π)). Throws DeviceError when the device is gone.
  virtual double position() const = 0;
  virtual TurntableState state() const = 0;
  // The smallest angle step the encoder resolves (radians).
  virtual double resolution() const = 0;
};

}  // namespace sherd::drivers
