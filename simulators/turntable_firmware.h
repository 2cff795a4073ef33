// The turntable controller's firmware, simulated: the line protocol of drivers/README.md parsed
// and executed by a state machine with a stepper (trapezoidal motion in simulated time), an
// encoder on the plate and an index sensor, plus the faults real hardware has, on command.
// FirmwareTransport puts it on the "bus" beneath the driver in place of libusb.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/usb_transport.h"
#include "simulators/random.h"

namespace sherd::sim {

enum class FirmwareFault {
  None,
  Stall,       // missed steps: the plate stops short, the motor believes it arrived
  NoReply,     // replies are lost
  Garbled,     // replies arrive corrupted
  Disconnect,  // off the bus half way through a move, back (restarted, not homed) replug_after_s
               // later
  Unplug,      // off the bus half way through a move, for good
  Homing,      // the index sensor does not trigger: G28 fails
};

// "none" | "stall" | "no_reply" | "garbled" | "disconnect" | "unplug" | "homing"; InputError
// otherwise.
FirmwareFault firmware_fault_from_string(const std::string& name);

struct FirmwareModel {
  int steps_per_revolution = 3200;  // 1/16 microstepping of a 200-step motor
  double max_speed_deg_s = 90.0;    // a G1's F is capped to this; also the homing speed
  double acceleration_deg_s2 = 360.0;
  double power_up_angle_deg = 0.0;  // where the plate stands at power-up (the index is at 0°)
  FirmwareFault fault = FirmwareFault::None;
  // The fault strikes first at the `fault_at`-th G1 (G28 for Homing) since the simulation began
  // (replugs do not reset the count). Stall, Disconnect, Unplug and Homing then strike
  // `fault_count` consecutive such commands; NoReply and Garbled lose or corrupt the replies to
  // `fault_count` consecutive commands of any kind, starting with that G1's.
  int fault_at = 1;
  int fault_count = 1;
  double replug_after_s = 0.5;  // Disconnect: off the bus this long
  std::uint64_t seed = 7;       // where a stall stops
};

class TurntableFirmware {
 public:
  // Throws InputError for non-positive steps, speed, acceleration, fault_at or fault_count.
  explicit TurntableFirmware(FirmwareModel model);

  // The USB side. `now_s` is simulated time in seconds, never decreasing across calls.
  void receive(std::string_view bytes, double now_s);  // bulk OUT
  std::string transmit(double now_s);                  // bulk IN: what is ready to send
  bool on_bus(double now_s);
  int boot_count(double now_s);  // +1 at every re-enumeration after a disconnect

  // Ground truth for tests and the simulated scanner.
  double plate_angle_rad(double now_s);             // the plate's physical angle, [0, 2π)
  std::vector<std::string> received_lines() const;  // every command line, in order
  double last_motion_seconds() const;               // duration of the last G1 or G28 motion

 private:
  struct Motion {
    double from_rad = 0, distance_rad = 0, speed_rad_s = 0, start_s = 0, seconds = 0;
    bool homing = false, homing_finds_index = false;
    std::optional<double> unplug_at_s;  // Disconnect/Unplug: leaves the bus at this time
  };
  void advance(double now_s);
  void process(const std::string& line, double now_s);
  void start_move(const std::string& line, double now_s);
  void start_homing(double now_s);
  void reply(std::vector<std::string> lines, double ready_s);
  double angle_at(double now_s) const;
  int encoder_count(double angle_rad) const;
  double step_rad() const;
  void power_cycle();

  mutable std::mutex mutex_;
  FirmwareModel model_;
  Rng rng_;
  double now_ = 0;
  double plate_rad_ = 0;  // resting angle when no motion runs
  std::optional<Motion> motion_;
  bool enabled_ = false, homed_ = false;
  int motor_count_ = 0;  // where the motor believes it is (steps from the index)
  std::string partial_;
  std::deque<std::string> pending_;                    // complete lines not yet executed
  double blocked_until_ = 0;                           // a G28 in progress holds back later lines
  std::deque<std::pair<double, std::string>> outbox_;  // (ready at, bytes)
  std::optional<double> gone_since_;
  double back_at_ = std::numeric_limits<double>::infinity();
  int boot_ = 1;
  int g1_seen_ = 0, g28_seen_ = 0;
  int silent_replies_ = 0, garbled_replies_ = 0;
  std::vector<std::string> received_;
  double last_motion_seconds_ = 0;
};

// The simulated firmware on the "bus": the UsbTransport the driver gets instead of libusb.
// Simulated time runs 1/time_scale as fast as the wall clock (time_scale 0: a million times).
class FirmwareTransport : public drivers::UsbTransport {
 public:
  FirmwareTransport(std::shared_ptr<TurntableFirmware> firmware, double time_scale);
  void open() override;
  void close() override;
  bool is_open() const override;
  void write(std::string_view bytes, std::chrono::milliseconds timeout) override;
  std::string read(std::chrono::milliseconds timeout) override;
  std::string describe() const override;
  double now_s() const;  // the simulated clock

 private:
  void throw_if_gone() const;
  std::shared_ptr<TurntableFirmware> firmware_;
  double seconds_per_real_second_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  bool open_ = false;
  int boot_ = 0;
};

}  // namespace sherd::sim
