// The seam under the USB turntable driver: exactly the libusb operations it needs (find and claim
// the device, bulk OUT, bulk IN, notice an unplug), nothing of the line protocol. Two
// implementations: LibusbTransport (the real bus) and sim::FirmwareTransport (the simulated
// firmware, for CI, where no USB subsystem exists). Everything above this seam is the same code
// on a station and in the tests.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/errors.h"

namespace sherd::drivers {

// The device dropped off the bus (unplugged, powered off, reset): the handle is dead. The caller
// may close() and open() again once the device is back.
class DeviceGone : public DeviceError {
 public:
  using DeviceError::DeviceError;
};

// Which device to open.
struct UsbDeviceId {
  std::uint16_t vendor_id = 0x1209;   // pid.codes
  std::uint16_t product_id = 0x0001;  // pid.codes test PID: set what `lsusb` shows
  std::string serial;                 // empty: the first device with these ids
  int interface_number = 1;           // CDC-ACM data interface (bulk IN + bulk OUT)
};

class UsbTransport {
 public:
  virtual ~UsbTransport() = default;
  // Finds the device, claims its interface (detaching a kernel driver) and readies the bulk
  // endpoints. Throws DeviceError when no such device is attached or it cannot be claimed.
  virtual void open() = 0;
  // Releases the interface and the handle; safe to call when not open.
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  // Bulk OUT of all of `bytes` within `timeout`. Throws DeviceGone when the device left the bus,
  // DeviceError on a timeout or another transfer error.
  virtual void write(std::string_view bytes, std::chrono::milliseconds timeout) = 0;
  // Bulk IN: the bytes that arrive within `timeout` (one packet at most; empty when nothing came).
  // Throws DeviceGone when the device left the bus, DeviceError on another transfer error.
  virtual std::string read(std::chrono::milliseconds timeout) = 0;
  virtual std::string describe() const = 0;
};

}  // namespace sherd::drivers
