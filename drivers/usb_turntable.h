// The rotational plate on its USB controller: the line protocol of drivers/README.md over a
// UsbTransport. Every move is verified against the encoder before it returns; a move that misses
// is re-homed and made again; queries (never moves) are re-sent when their reply is lost or
// garbled; an unplugged device is waited for and re-homed.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "drivers/turntable.h"
#include "drivers/usb_transport.h"

namespace sherd::drivers {

struct UsbTurntableSettings {
  int steps_per_revolution = 3200;  // must match the firmware's (M115)
  double speed_deg_s = 90.0;        // F of every move
  double acceleration_deg_s2 = 360.0;
  std::chrono::milliseconds reply_timeout{500};  // for a command's reply (G28: plus its motion)
  int query_attempts = 3;   // a query whose reply is lost or garbled is sent again this often
  int move_attempts = 3;    // a move that misses its target is re-homed and made again
  int homing_attempts = 2;  // G28 that does not find the index is tried again
  std::chrono::milliseconds reconnect_timeout{5000};  // how long an unplugged device is waited for
};

class UsbTurntable : public Turntable {
 public:
  // Opens the transport and reads the firmware's identity. Throws DeviceError when the device
  // cannot be opened or does not answer, InputError when its steps per revolution differ from
  // the settings'.
  UsbTurntable(std::unique_ptr<UsbTransport> transport, UsbTurntableSettings settings);
  ~UsbTurntable() override;

  std::string describe() const override;
  void home() override;
  // Returns the encoder's verified angle, within one step of the target; throws DeviceError
  // (with the reason) when the plate cannot be brought there.
  double move_to(double angle_rad) override;
  double position() const override;
  TurntableState state() const override;
  double resolution() const override;

 private:
  using Lines = std::vector<std::string>;
  // One command and its reply, unretried (io_ held). Throws the protocol errors of the .cpp.
  Lines exchange(const std::string& command, std::chrono::milliseconds timeout) const;
  // A command that is safe to repeat: re-sent when its reply is lost or garbled, after a
  // reconnection when the device left the bus. `check` throws when the reply's form is wrong.
  Lines query(const std::string& command, void (*check)(const Lines&)) const;
  void drain() const;      // discards late bytes of an abandoned reply
  void reconnect() const;  // waits for the device to come back (io_ held)
  void home_locked();
  int encoder_count() const;
  // Polls `?` until the plate stands; false when the device restarted (lost its zero).
  bool wait_until_still(double max_seconds);

  std::mutex operation_;   // one home or move at a time
  mutable std::mutex io_;  // one command/reply exchange at a time (status queries interleave)
  std::unique_ptr<UsbTransport> transport_;
  UsbTurntableSettings settings_;
  mutable std::string received_;  // bytes of a reply line not yet complete
  mutable std::atomic<TurntableState> state_{TurntableState::Idle};
  mutable std::atomic<bool> homed_{false};
  std::string firmware_;
};

}  // namespace sherd::drivers
