// UsbTransport on the real bus through libusb-1.0 (synchronous bulk transfers). Not exercised in
// CI (no USB subsystem there); run tests/hardware/turntable_hardware_check on a station.
#pragma once

#include <atomic>
#include <memory>

#include "drivers/usb_transport.h"

struct libusb_context;
struct libusb_device_handle;

namespace sherd::drivers {

class LibusbTransport : public UsbTransport {
 public:
  // Initialises a private libusb context; opens nothing yet. Throws DeviceError when libusb
  // cannot start (no USB subsystem).
  explicit LibusbTransport(UsbDeviceId id);
  ~LibusbTransport() override;
  LibusbTransport(const LibusbTransport&) = delete;
  LibusbTransport& operator=(const LibusbTransport&) = delete;

  void open() override;
  void close() override;
  bool is_open() const override;
  void write(std::string_view bytes, std::chrono::milliseconds timeout) override;
  std::string read(std::chrono::milliseconds timeout) override;
  std::string describe() const override;

 private:
  // Throws DeviceGone for LIBUSB_ERROR_NO_DEVICE (and for a hot-unplug the hotplug callback saw),
  // DeviceError for anything else.
  [[noreturn]] void fail(int code, const char* what) const;

  UsbDeviceId id_;
  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  unsigned char in_endpoint_ = 0, out_endpoint_ = 0;
  int in_packet_size_ = 64;
  int hotplug_handle_ = 0;
  bool hotplug_registered_ = false;
  std::atomic<bool> unplugged_{false};  // set by the hotplug callback while a transfer runs
};

}  // namespace sherd::drivers
