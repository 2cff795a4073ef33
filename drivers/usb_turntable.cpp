#include "drivers/usb_turntable.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <numbers>
#include <regex>
#include <thread>

#include "drivers/motion_profile.h"

namespace sherd::drivers {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kHomingSearchRev = 1.25;  // the protocol's bound on G28's search
constexpr milliseconds kPollInterval{20};
constexpr int kToleranceSteps = 1;  // an encoder may read one count either side of the motor

// The protocol's failures, each handled differently by the callers below.
class NoReply : public DeviceError {  // no complete reply within the timeout
 public:
  using DeviceError::DeviceError;
};
class Garbled : public DeviceError {  // bytes that are not the protocol
 public:
  using DeviceError::DeviceError;
};
class Refused : public DeviceError {  // `error:<code> <text>`
 public:
  Refused(int code, const std::string& text)
      : DeviceError(fmt::format("the turntable refused: error {} {}", code, text)), code(code) {}
  int code;
};
constexpr int kNotHomed = 4;
constexpr int kHomingFailed = 6;

double wrap(double a) {
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

std::string printable(const std::string& line) {
  std::string out;
  for (unsigned char c : line) {
    out +=
        c >= 0x20 && c < 0x7f ? std::string(1, static_cast<char>(c)) : fmt::format("\\x{:02x}", c);
  }
  return out;
}

void expect_one_line(const std::vector<std::string>& lines, const std::regex& form,
                     const char* what) {
  if (lines.size() != 1 || !std::regex_match(lines[0], form)) {
    throw Garbled(fmt::format("unexpected reply to {}: '{}'", what,
                              lines.empty() ? std::string() : printable(lines[0])));
  }
}
void check_status(const std::vector<std::string>& lines) {
  static const std::regex form(R"((idle|moving|homing) A:-?\d+\.\d+ T:-?\d+\.\d+ H:[01] E:[01])");
  expect_one_line(lines, form, "?");
}
void check_position(const std::vector<std::string>& lines) {
  static const std::regex form(R"(A:-?\d+\.\d+ C:\d+)");
  expect_one_line(lines, form, "M114");
}
void check_identity(const std::vector<std::string>& lines) {
  static const std::regex form(R"(FIRMWARE:\S+ VERSION:\S+ STEPS:\d+)");
  expect_one_line(lines, form, "M115");
}
void check_empty(const std::vector<std::string>& lines) {
  if (!lines.empty()) throw Garbled(fmt::format("unexpected data '{}'", printable(lines[0])));
}

// "<key>:<value>" from a checked reply line.
std::string field(const std::string& line, const std::string& key) {
  const auto at = line.find(key + ":");
  const auto start = at + key.size() + 1;
  return line.substr(start, line.find(' ', start) - start);
}

}  // namespace

UsbTurntable::UsbTurntable(std::unique_ptr<UsbTransport> transport, UsbTurntableSettings settings)
    : transport_(std::move(transport)), settings_(settings) {
  transport_->open();
  const auto identity = query("M115", check_identity);
  firmware_ = identity[0];
  const int steps = std::stoi(field(firmware_, "STEPS"));
  if (steps != settings_.steps_per_revolution) {
    throw InputError(fmt::format(
        "[turntable] steps_per_revolution = {} but the controller ({}) reports {}: set it to {}",
        settings_.steps_per_revolution, transport_->describe(), steps, steps));
  }
  spdlog::info("turntable: {} on {}", firmware_, transport_->describe());
}

UsbTurntable::~UsbTurntable() = default;

std::string UsbTurntable::describe() const {
  return fmt::format("USB turntable ({}, {})", transport_->describe(), firmware_);
}

TurntableState UsbTurntable::state() const { return state_; }

double UsbTurntable::resolution() const { return kTwoPi / settings_.steps_per_revolution; }

UsbTurntable::Lines UsbTurntable::exchange(const std::string& command, milliseconds timeout) const {
  transport_->write(command + "\n", settings_.reply_timeout);
  const auto deadline = Clock::now() + timeout;
  Lines lines;
  for (;;) {
    for (auto end = received_.find('\n'); end != std::string::npos; end = received_.find('\n')) {
      std::string line = received_.substr(0, end);
      received_.erase(0, end + 1);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      for (unsigned char c : line) {
        if (c < 0x20 || c >= 0x7f) {
          throw Garbled(fmt::format("garbled reply to {}: '{}'", command, printable(line)));
        }
      }
      if (line == "ok") return lines;
      static const std::regex error_form(R"(error:(\d+) (.*))");
      std::smatch match;
      if (std::regex_match(line, match, error_form)) {
        throw Refused(std::stoi(match[1]), match[2]);
      }
      if (line.rfind("error", 0) == 0) {
        throw Garbled(fmt::format("malformed error reply to {}: '{}'", command, line));
      }
      lines.push_back(line);
    }
    const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now());
    if (left <= milliseconds(0)) {
      throw NoReply(fmt::format("no reply to {} within {} ms", command, timeout.count()));
    }
    received_ += transport_->read(std::min(left, milliseconds(50)));
  }
}

void UsbTurntable::drain() const {
  received_.clear();
  // Whatever is still on its way belongs to the abandoned exchange.
  while (!transport_->read(milliseconds(20)).empty()) {
  }
}

void UsbTurntable::reconnect() const {
  state_ = TurntableState::Disconnected;
  homed_ = false;
  transport_->close();
  received_.clear();
  const auto deadline = Clock::now() + settings_.reconnect_timeout;
  for (;;) {
    try {
      transport_->open();
      spdlog::warn("turntable back on USB ({}); it restarted, so it is homed again before moving",
                   transport_->describe());
      state_ = TurntableState::Idle;
      return;
    } catch (const DeviceError& e) {
      if (Clock::now() >= deadline) {
        throw DeviceError(fmt::format(
            "turntable gone from USB and not back within {:.1f} s ({}): check its cable and "
            "power, then scan again",
            settings_.reconnect_timeout.count() / 1000.0, e.what()));
      }
    }
    std::this_thread::sleep_for(milliseconds(100));
  }
}

UsbTurntable::Lines UsbTurntable::query(const std::string& command,
                                        void (*check)(const Lines&)) const {
  std::lock_guard io(io_);
  std::string last;
  for (int attempt = 1; attempt <= settings_.query_attempts; ++attempt) {
    try {
      if (!transport_->is_open()) reconnect();
      Lines lines = exchange(command, settings_.reply_timeout);
      check(lines);
      return lines;
    } catch (const DeviceGone& e) {
      last = e.what();
      spdlog::warn("turntable: {} during {}; reconnecting", last, command);
      reconnect();
    } catch (const Refused&) {
      throw;
    } catch (const DeviceError& e) {  // NoReply, Garbled: asking again is harmless
      last = e.what();
      spdlog::warn("turntable: {} (attempt {}/{}); asking again", last, attempt,
                   settings_.query_attempts);
      drain();
    }
  }
  throw DeviceError(fmt::format(
      "turntable: no valid answer to {} in {} attempts (last: {}): check the USB cable and the "
      "controller's power, then scan again",
      command, settings_.query_attempts, last));
}

int UsbTurntable::encoder_count() const {
  return std::stoi(field(query("M114", check_position)[0], "C"));
}

double UsbTurntable::position() const {
  if (state_ == TurntableState::Disconnected) {
    throw DeviceError("turntable disconnected: waiting for it to come back on USB");
  }
  return encoder_count() * resolution();
}

void UsbTurntable::home() {
  std::lock_guard operation(operation_);
  home_locked();
}

void UsbTurntable::home_locked() {
  const double v = settings_.speed_deg_s, a = settings_.acceleration_deg_s2;
  const milliseconds homing_timeout =
      settings_.reply_timeout +
      milliseconds(static_cast<long>(1000 * trapezoid_seconds(kHomingSearchRev * 360, v, a)));
  std::string last;
  for (int attempt = 1; attempt <= settings_.homing_attempts; ++attempt) {
    state_ = TurntableState::Homing;
    try {
      query("M17", check_empty);
      {
        // G28 may be repeated: it seeks the index from wherever the plate is.
        std::lock_guard io(io_);
        check_empty(exchange("G28", homing_timeout));
      }
      const int count = encoder_count();
      if (std::min(count, settings_.steps_per_revolution - count) <= kToleranceSteps) {
        homed_ = true;
        state_ = TurntableState::Idle;
        spdlog::info("turntable homed: index found, encoder at {} counts", count);
        return;
      }
      last = fmt::format("encoder reads {} counts after homing, not 0", count);
    } catch (const Refused& e) {
      if (e.code != kHomingFailed && e.code != kNotHomed) throw;
      last = e.what();
    } catch (const DeviceGone& e) {
      last = e.what();
      std::lock_guard io(io_);
      reconnect();
    } catch (const NoReply& e) {
      last = e.what();
      std::lock_guard io(io_);
      drain();
    } catch (const Garbled& e) {
      last = e.what();
      std::lock_guard io(io_);
      drain();
    }
    spdlog::warn("turntable homing failed (attempt {}/{}): {}", attempt, settings_.homing_attempts,
                 last);
  }
  state_ = TurntableState::Fault;
  throw DeviceError(fmt::format(
      "turntable homing failed {} times (last: {}): check the index sensor and that the plate "
      "turns freely, then scan again",
      settings_.homing_attempts, last));
}

bool UsbTurntable::wait_until_still(double max_seconds) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(max_seconds);
  for (;;) {
    const std::string status = query("?", check_status)[0];
    if (field(status, "H") != "1") return false;  // restarted: its zero is gone
    if (status.rfind("idle", 0) == 0) return true;
    if (Clock::now() >= deadline) {
      throw DeviceError(fmt::format(
          "turntable still moving {:.1f} s after a move began ({}): check the plate and the "
          "motor, then scan again",
          max_seconds, status));
    }
    std::this_thread::sleep_for(kPollInterval);
  }
}

double UsbTurntable::move_to(double angle_rad) {
  if (!std::isfinite(angle_rad)) {
    throw InputError("turntable: target angle is not finite: pass an angle in radians");
  }
  std::lock_guard operation(operation_);
  const int steps = settings_.steps_per_revolution;
  const int target = static_cast<int>(std::lround(wrap(angle_rad) / resolution())) % steps;
  const double target_deg = target * resolution() / kDeg;
  // A move longer than half a turn never happens (shortest way); allow twice its time.
  const double max_seconds =
      2 * trapezoid_seconds(180, settings_.speed_deg_s, settings_.acceleration_deg_s2) +
      settings_.reply_timeout.count() / 1000.0;
  std::string last;
  for (int attempt = 1; attempt <= settings_.move_attempts; ++attempt) {
    try {
      if (!homed_) home_locked();
      state_ = TurntableState::Moving;
      try {
        std::lock_guard io(io_);
        check_empty(exchange(fmt::format("G1 A{:.6f} F{:.3f}", target_deg, settings_.speed_deg_s),
                             settings_.reply_timeout));
      } catch (const Refused& e) {
        if (e.code != kNotHomed) throw;
        homed_ = false;
        last = e.what();
        continue;
      } catch (const DeviceGone&) {
        throw;
      } catch (const DeviceError& e) {
        // The reply to a move was lost or garbled: the move may well be under way. It is never
        // sent again blind; where the plate went is asked instead.
        spdlog::warn("turntable: {}; not repeating the move, asking where the plate is", e.what());
        std::lock_guard io(io_);
        drain();
      }
      if (!wait_until_still(max_seconds)) {
        last = "the controller restarted during the move";
        spdlog::warn("turntable: {} to {:.3f}° (attempt {}/{}); re-homing and moving again", last,
                     target_deg, attempt, settings_.move_attempts);
        continue;
      }
      const int count = encoder_count();
      const int off = std::abs(count - target) % steps;
      if (std::min(off, steps - off) <= kToleranceSteps) {
        state_ = TurntableState::Idle;
        return count * resolution();
      }
      last = fmt::format("missed steps: encoder at {:.3f}° after a move to {:.3f}°",
                         count * resolution() / kDeg, target_deg);
      homed_ = false;  // the motor's count is wrong now; only the index can put it right
      spdlog::warn("turntable {} (attempt {}/{}); re-homing and moving again", last, attempt,
                   settings_.move_attempts);
    } catch (const DeviceGone& e) {
      last = e.what();
      spdlog::warn("turntable left USB while moving to {:.3f}° (attempt {}/{}): {}; reconnecting",
                   target_deg, attempt, settings_.move_attempts, last);
      std::lock_guard io(io_);
      reconnect();
    } catch (const Refused& e) {
      if (e.code != kNotHomed) {
        state_ = TurntableState::Fault;
        throw;
      }
      homed_ = false;
      last = e.what();
    } catch (const DeviceError&) {
      if (state_ != TurntableState::Disconnected) state_ = TurntableState::Fault;
      throw;
    }
  }
  state_ = TurntableState::Fault;
  throw DeviceError(fmt::format(
      "turntable could not reach {:.3f}° in {} attempts (last: {}): check the plate turns freely, "
      "the USB cable and the power, then scan again",
      target_deg, settings_.move_attempts, last));
}

}  // namespace sherd::drivers
