// The USB turntable on a station, through libusb: the layer CI cannot reach. Opens the device,
// homes, makes a round of verified moves (each checked again with a fresh M114 read), optionally
// asks for an unplug mid-round to check reconnection, and prints one line per step.
// Exit 0 when every step passed.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <exception>
#include <iostream>
#include <memory>
#include <numbers>
#include <string>

#include "drivers/libusb_transport.h"
#include "drivers/usb_turntable.h"

int main(int argc, char** argv) {
  CLI::App app{"turntable_hardware_check: the USB turntable through libusb (needs the device)"};
  int vid = 0x1209, pid = 0x0001, interface_number = 1, steps = 3200, views = 8;
  std::string serial;
  bool unplug = false;
  double speed = 90.0, acceleration = 360.0;
  app.add_option("--vid", vid, "vendor id (0x… accepted)")->capture_default_str();
  app.add_option("--pid", pid, "product id")->capture_default_str();
  app.add_option("--serial", serial, "serial number (default: the first device with the ids)");
  app.add_option("--interface", interface_number, "CDC data interface")->capture_default_str();
  app.add_option("--steps", steps, "steps per revolution")->capture_default_str();
  app.add_option("--speed", speed, "degrees per second")->capture_default_str();
  app.add_option("--acceleration", acceleration, "degrees per second²")->capture_default_str();
  app.add_option("--views", views, "stops over one revolution")->capture_default_str();
  app.add_flag("--unplug", unplug,
               "ask the operator to pull and replug the cable during the round (reconnection)");
  CLI11_PARSE(app, argc, argv);

  constexpr double kDeg = std::numbers::pi / 180.0;
  int failures = 0;
  auto report = [&](bool ok, const std::string& what) {
    failures += ok ? 0 : 1;
    fmt::print("{} {}\n", ok ? "PASS" : "FAIL", what);
  };
  try {
    sherd::drivers::UsbTurntableSettings settings;
    settings.steps_per_revolution = steps;
    settings.speed_deg_s = speed;
    settings.acceleration_deg_s2 = acceleration;
    settings.reconnect_timeout = std::chrono::seconds(unplug ? 30 : 5);
    auto transport = std::make_unique<sherd::drivers::LibusbTransport>(
        sherd::drivers::UsbDeviceId{static_cast<std::uint16_t>(vid),
                                    static_cast<std::uint16_t>(pid), serial, interface_number});
    sherd::drivers::UsbTurntable table(std::move(transport), settings);
    report(true, fmt::format("opened: {}", table.describe()));
    table.home();
    const double homed = table.position();  // 0, or one count either side
    report(std::min(homed, 2 * std::numbers::pi - homed) <= table.resolution() * 1.01,
           fmt::format("homed: encoder at {:.4f}°", homed / kDeg));
    for (int i = 0; i <= views; ++i) {
      if (unplug && i == views / 2) {
        fmt::print("Pull the turntable's USB cable during the next move and plug it back in.\n");
      }
      const double target = 360.0 * (i % views) / views;
      const double reached = table.move_to(target * kDeg) / kDeg;
      const double again = table.position() / kDeg;
      const double off = std::abs(std::remainder(reached - target, 360.0));
      report(off <= 360.0 / steps + 1e-9 && std::abs(again - reached) < 1e-9,
             fmt::format("move to {:.3f}°: encoder {:.4f}°, read again {:.4f}°", target, reached,
                         again));
    }
  } catch (const std::exception& e) {
    report(false, e.what());
  }
  fmt::print("{}\n", failures == 0 ? "turntable OK" : fmt::format("{} step(s) failed", failures));
  return failures == 0 ? 0 : 1;
}
