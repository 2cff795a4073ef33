#include "drivers/libusb_transport.h"

#include <fmt/format.h>
#include <libusb.h>
#include <spdlog/spdlog.h>

#include <vector>

namespace sherd::drivers {
namespace {

// CDC-ACM SET_CONTROL_LINE_STATE with DTR and RTS: many CDC firmwares (Arduino-style) only send
// once the host has raised DTR, as a terminal would.
constexpr std::uint8_t kCdcRequestType = 0x21;  // class request to an interface
constexpr std::uint8_t kSetControlLineState = 0x22;
constexpr std::uint16_t kDtrRts = 0x03;

std::string ids(const UsbDeviceId& id) {
  return fmt::format("{:04x}:{:04x}{}{}", id.vendor_id, id.product_id,
                     id.serial.empty() ? "" : " serial ", id.serial);
}

int on_hotplug(libusb_context*, libusb_device*, libusb_hotplug_event event, void* user) {
  if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT) static_cast<std::atomic<bool>*>(user)->store(true);
  return 0;  // stay registered
}

}  // namespace

LibusbTransport::LibusbTransport(UsbDeviceId id) : id_(std::move(id)) {
  if (const int r = libusb_init(&context_); r != 0) {
    throw DeviceError(
        fmt::format("USB turntable {}: libusb cannot start ({}): is there a USB "
                    "subsystem (/dev/bus/usb) on this machine?",
                    ids(id_), libusb_error_name(r)));
  }
  // Hot-unplug is also seen as LIBUSB_ERROR_NO_DEVICE on the next transfer; the callback only
  // makes it known sooner (it fires from the event handling inside a synchronous transfer).
  if (libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
    hotplug_registered_ = libusb_hotplug_register_callback(
                              context_, LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT, LIBUSB_HOTPLUG_NO_FLAGS,
                              id_.vendor_id, id_.product_id, LIBUSB_HOTPLUG_MATCH_ANY, on_hotplug,
                              &unplugged_, &hotplug_handle_) == LIBUSB_SUCCESS;
  }
}

LibusbTransport::~LibusbTransport() {
  close();
  if (hotplug_registered_) libusb_hotplug_deregister_callback(context_, hotplug_handle_);
  libusb_exit(context_);
}

std::string LibusbTransport::describe() const { return fmt::format("USB {}", ids(id_)); }

bool LibusbTransport::is_open() const { return handle_ != nullptr && !unplugged_; }

void LibusbTransport::open() {
  close();
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context_, &list);
  if (count < 0) fail(static_cast<int>(count), "listing USB devices");
  libusb_device_handle* found = nullptr;
  for (ssize_t i = 0; i < count && !found; ++i) {
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(list[i], &descriptor) != 0) continue;
    if (descriptor.idVendor != id_.vendor_id || descriptor.idProduct != id_.product_id) continue;
    libusb_device_handle* handle = nullptr;
    if (libusb_open(list[i], &handle) != 0) continue;  // e.g. no permission: reported below
    if (!id_.serial.empty()) {
      unsigned char serial[256] = {};
      const int n = libusb_get_string_descriptor_ascii(handle, descriptor.iSerialNumber, serial,
                                                       sizeof serial);
      if (n < 0 || id_.serial != std::string(reinterpret_cast<char*>(serial), n)) {
        libusb_close(handle);
        continue;
      }
    }
    found = handle;
  }
  libusb_free_device_list(list, 1);
  if (!found) {
    throw DeviceError(fmt::format(
        "USB turntable {} not found (or not permitted): check it is plugged in (lsusb), that "
        "config/99-sherdscan-turntable.rules is installed in /etc/udev/rules.d, and the ids in "
        "[turntable]",
        ids(id_)));
  }
  handle_ = found;
  unplugged_ = false;
  // The kernel's cdc_acm driver holds both CDC interfaces; libusb detaches it on claim and gives
  // it back on release.
  libusb_set_auto_detach_kernel_driver(handle_, 1);
  const int data = id_.interface_number;
  const int control = data > 0 ? data - 1 : -1;  // CDC: the communication interface precedes
  if (const int r = libusb_claim_interface(handle_, data); r != 0) {
    close();
    fail(r, "claiming the data interface");
  }
  if (control >= 0 && libusb_claim_interface(handle_, control) == 0) {
    libusb_control_transfer(handle_, kCdcRequestType, kSetControlLineState, kDtrRts,
                            static_cast<std::uint16_t>(control), nullptr, 0, 1000);
  }
  // The bulk endpoints of the data interface, from its descriptor.
  libusb_config_descriptor* config = nullptr;
  if (const int r = libusb_get_active_config_descriptor(libusb_get_device(handle_), &config); r) {
    close();
    fail(r, "reading the configuration descriptor");
  }
  for (int i = 0; i < config->bNumInterfaces; ++i) {
    for (int a = 0; a < config->interface[i].num_altsetting; ++a) {
      const auto& alt = config->interface[i].altsetting[a];
      if (alt.bInterfaceNumber != data) continue;
      for (int e = 0; e < alt.bNumEndpoints; ++e) {
        const auto& ep = alt.endpoint[e];
        if ((ep.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_BULK) continue;
        if (ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) {
          in_endpoint_ = ep.bEndpointAddress;
          in_packet_size_ = ep.wMaxPacketSize;
        } else {
          out_endpoint_ = ep.bEndpointAddress;
        }
      }
    }
  }
  libusb_free_config_descriptor(config);
  if (!in_endpoint_ || !out_endpoint_) {
    close();
    throw DeviceError(
        fmt::format("USB turntable {}: interface {} has no bulk IN and OUT endpoints: set "
                    "[turntable] usb_interface to the CDC data interface (lsusb -v)",
                    ids(id_), data));
  }
  spdlog::info("USB turntable {} opened (interface {}, endpoints {:#04x}/{:#04x})", ids(id_), data,
               out_endpoint_, in_endpoint_);
}

void LibusbTransport::close() {
  if (!handle_) return;
  libusb_release_interface(handle_, id_.interface_number);
  if (id_.interface_number > 0) libusb_release_interface(handle_, id_.interface_number - 1);
  libusb_close(handle_);
  handle_ = nullptr;
  in_endpoint_ = out_endpoint_ = 0;
}

void LibusbTransport::fail(int code, const char* what) const {
  const std::string message =
      fmt::format("USB turntable {}: {} failed: {}", ids(id_), what, libusb_error_name(code));
  if (code == LIBUSB_ERROR_NO_DEVICE || unplugged_) {
    throw DeviceGone(message + " — the device left the bus: check its cable and power");
  }
  throw DeviceError(message);
}

void LibusbTransport::write(std::string_view bytes, std::chrono::milliseconds timeout) {
  if (!handle_ || unplugged_) fail(LIBUSB_ERROR_NO_DEVICE, "bulk write");
  std::vector<unsigned char> buffer(bytes.begin(), bytes.end());
  int sent = 0;
  const int r =
      libusb_bulk_transfer(handle_, out_endpoint_, buffer.data(), static_cast<int>(buffer.size()),
                           &sent, static_cast<unsigned>(timeout.count()));
  if (r == LIBUSB_ERROR_PIPE) libusb_clear_halt(handle_, out_endpoint_);
  if (r != 0) fail(r, "bulk write");
  if (sent != static_cast<int>(buffer.size())) fail(LIBUSB_ERROR_TIMEOUT, "bulk write (partial)");
}

std::string LibusbTransport::read(std::chrono::milliseconds timeout) {
  if (!handle_ || unplugged_) fail(LIBUSB_ERROR_NO_DEVICE, "bulk read");
  std::vector<unsigned char> buffer(static_cast<std::size_t>(in_packet_size_));
  int received = 0;
  const int r =
      libusb_bulk_transfer(handle_, in_endpoint_, buffer.data(), static_cast<int>(buffer.size()),
                           &received, static_cast<unsigned>(timeout.count()));
  if (r == LIBUSB_ERROR_PIPE) libusb_clear_halt(handle_, in_endpoint_);
  if (r != 0 && r != LIBUSB_ERROR_TIMEOUT) fail(r, "bulk read");
  if (unplugged_) fail(LIBUSB_ERROR_NO_DEVICE, "bulk read");
  return std::string(reinterpret_cast<char*>(buffer.data()), static_cast<std::size_t>(received));
}

}  // namespace sherd::drivers
