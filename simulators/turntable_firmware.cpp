#include "simulators/turntable_firmware.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <numbers>
#include <sstream>
#include <thread>

#include "core/errors.h"
#include "drivers/motion_profile.h"

namespace sherd::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr std::size_t kMaxLine = 96;       // the controller's line buffer
constexpr double kHomingSearchRev = 1.25;  // how far G28 turns looking for the index

double wrap(double a) {
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

// A word's number ("A12.5" → 12.5); nullopt when it is not a finite number.
std::optional<double> number(std::string_view text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

}  // namespace

FirmwareFault firmware_fault_from_string(const std::string& name) {
  if (name == "none") return FirmwareFault::None;
  if (name == "stall") return FirmwareFault::Stall;
  if (name == "no_reply") return FirmwareFault::NoReply;
  if (name == "garbled") return FirmwareFault::Garbled;
  if (name == "disconnect") return FirmwareFault::Disconnect;
  if (name == "unplug") return FirmwareFault::Unplug;
  if (name == "homing") return FirmwareFault::Homing;
  throw InputError(
      fmt::format("unknown turntable firmware fault '{}': expected none, stall, "
                  "no_reply, garbled, disconnect, unplug or homing",
                  name));
}

TurntableFirmware::TurntableFirmware(FirmwareModel model) : model_(model), rng_(model.seed) {
  if (model_.steps_per_revolution <= 0 || !(model_.max_speed_deg_s > 0) ||
      !(model_.acceleration_deg_s2 > 0) || model_.fault_at < 1 || model_.fault_count < 1 ||
      !(model_.replug_after_s >= 0)) {
    throw InputError(fmt::format(
        "simulated turntable firmware: steps_per_revolution ({}), max_speed_deg_s ({}), "
        "acceleration_deg_s2 ({}), fault_at ({}) and fault_count ({}) must be positive, "
        "replug_after_s ({}) ≥ 0",
        model_.steps_per_revolution, model_.max_speed_deg_s, model_.acceleration_deg_s2,
        model_.fault_at, model_.fault_count, model_.replug_after_s));
  }
  plate_rad_ = wrap(model_.power_up_angle_deg * kDeg);
}

double TurntableFirmware::step_rad() const { return kTwoPi / model_.steps_per_revolution; }

int TurntableFirmware::encoder_count(double angle_rad) const {
  const int steps = model_.steps_per_revolution;
  return static_cast<int>(std::lround(wrap(angle_rad) / step_rad())) % steps;
}

double TurntableFirmware::angle_at(double now_s) const {
  if (!motion_) return plate_rad_;
  // A stalled plate follows the profile over the shorter way it actually makes, then stands.
  const double covered =
      drivers::trapezoid_distance(now_s - motion_->start_s, std::abs(motion_->distance_rad),
                                  motion_->speed_rad_s, model_.acceleration_deg_s2 * kDeg);
  return wrap(motion_->from_rad + std::copysign(covered, motion_->distance_rad));
}

void TurntableFirmware::power_cycle() {
  motion_.reset();
  enabled_ = homed_ = false;
  motor_count_ = 0;
  partial_.clear();
  pending_.clear();
  outbox_.clear();
  blocked_until_ = 0;
  silent_replies_ = garbled_replies_ = 0;
}

void TurntableFirmware::advance(double now_s) {
  now_ = std::max(now_, now_s);
  if (motion_ && motion_->unplug_at_s && now_ >= *motion_->unplug_at_s) {
    plate_rad_ = angle_at(*motion_->unplug_at_s);  // the plate stops where power was lost
    power_cycle();
    gone_since_ = now_;
    back_at_ = model_.fault == FirmwareFault::Unplug ? std::numeric_limits<double>::infinity()
                                                     : now_ + model_.replug_after_s;
  }
  if (motion_ && now_ >= motion_->start_s + motion_->seconds) {
    plate_rad_ = wrap(motion_->from_rad + motion_->distance_rad);
    if (motion_->homing && motion_->homing_finds_index) {
      plate_rad_ = 0.0;  // the index mark defines zero
      motor_count_ = 0;
      homed_ = true;
    }
    motion_.reset();
  }
  if (gone_since_ && now_ >= back_at_) {
    gone_since_.reset();
    ++boot_;  // re-enumerates freshly powered: motor off, not homed
  }
  while (!gone_since_ && !pending_.empty() && now_ >= blocked_until_) {
    const std::string line = pending_.front();
    pending_.pop_front();
    process(line, now_);
  }
}

void TurntableFirmware::receive(std::string_view bytes, double now_s) {
  std::lock_guard lock(mutex_);
  advance(now_s);
  if (gone_since_) return;
  for (char c : bytes) {
    if (c == '\n') {
      pending_.push_back(partial_);
      partial_.clear();
    } else if (c != '\r') {
      partial_ += c;
    }
  }
  advance(now_s);
}

std::string TurntableFirmware::transmit(double now_s) {
  std::lock_guard lock(mutex_);
  advance(now_s);
  std::string out;
  while (!outbox_.empty() && outbox_.front().first <= now_) {
    out += outbox_.front().second;
    outbox_.pop_front();
  }
  return out;
}

bool TurntableFirmware::on_bus(double now_s) {
  std::lock_guard lock(mutex_);
  advance(now_s);
  return !gone_since_;
}

int TurntableFirmware::boot_count(double now_s) {
  std::lock_guard lock(mutex_);
  advance(now_s);
  return boot_;
}

double TurntableFirmware::plate_angle_rad(double now_s) {
  std::lock_guard lock(mutex_);
  advance(now_s);
  return angle_at(now_);
}

std::vector<std::string> TurntableFirmware::received_lines() const {
  std::lock_guard lock(mutex_);
  return received_;
}

double TurntableFirmware::last_motion_seconds() const {
  std::lock_guard lock(mutex_);
  return last_motion_seconds_;
}

void TurntableFirmware::reply(std::vector<std::string> lines, double ready_s) {
  if (silent_replies_ > 0) {
    --silent_replies_;
    return;
  }
  std::string text;
  for (const auto& line : lines) text += line + "\n";
  if (garbled_replies_ > 0) {
    --garbled_replies_;
    // Line noise: every other byte before the newlines gets its top bit set.
    for (std::size_t i = 0; i < text.size(); i += 2) {
      if (text[i] != '\n') text[i] = static_cast<char>(text[i] ^ 0x80);
    }
  }
  outbox_.emplace_back(ready_s, std::move(text));
}

void TurntableFirmware::process(const std::string& line, double now_s) {
  received_.push_back(line);
  std::string command = line;
  while (!command.empty() && command.back() == ' ') command.pop_back();
  if (command.empty()) return;
  if (command.size() > kMaxLine) {
    reply({fmt::format("error:7 line too long (over {} characters)", kMaxLine)}, now_s);
    return;
  }
  const bool moving = motion_.has_value();
  const std::string word = command.substr(0, command.find(' '));
  if (command == "?") {
    const double angle = angle_at(now_s);
    reply({fmt::format("{} A:{:.4f} T:{:.4f} H:{} E:{}",
                       moving ? (motion_->homing ? "homing" : "moving") : "idle",
                       encoder_count(angle) * step_rad() / kDeg, motor_count_ * step_rad() / kDeg,
                       homed_ ? 1 : 0, enabled_ ? 1 : 0),
           "ok"},
          now_s);
  } else if (command == "M114") {
    if (!homed_) {
      reply({"error:4 not homed: position unknown, send G28"}, now_s);
      return;
    }
    const int count = encoder_count(angle_at(now_s));
    reply({fmt::format("A:{:.4f} C:{}", count * step_rad() / kDeg, count), "ok"}, now_s);
  } else if (command == "M115") {
    reply({fmt::format("FIRMWARE:sherd-turntable-sim VERSION:1.0 STEPS:{}",
                       model_.steps_per_revolution),
           "ok"},
          now_s);
  } else if (command == "M17") {
    enabled_ = true;
    reply({"ok"}, now_s);
  } else if (command == "M18") {
    if (moving) {
      reply({"error:5 busy: the plate is moving"}, now_s);
      return;
    }
    enabled_ = false;
    homed_ = false;  // a free plate can be turned by hand: the zero is lost
    reply({"ok"}, now_s);
  } else if (command == "G28") {
    if (moving) {
      reply({"error:5 busy: the plate is moving"}, now_s);
      return;
    }
    start_homing(now_s);
  } else if (word == "G1") {
    start_move(command, now_s);
  } else {
    reply({fmt::format("error:1 unknown command '{}'", word)}, now_s);
  }
}

void TurntableFirmware::start_homing(double now_s) {
  ++g28_seen_;
  const bool sensor_dead = model_.fault == FirmwareFault::Homing && g28_seen_ >= model_.fault_at &&
                           g28_seen_ < model_.fault_at + model_.fault_count;
  enabled_ = true;
  homed_ = false;
  const double v = model_.max_speed_deg_s * kDeg, a = model_.acceleration_deg_s2 * kDeg;
  // Forward until the index mark passes the sensor (at 0°), or give up after the search range.
  const double distance = sensor_dead ? kHomingSearchRev * kTwoPi : wrap(kTwoPi - plate_rad_);
  const double seconds = drivers::trapezoid_seconds(distance, v, a);
  motion_ = Motion{plate_rad_, distance, v, now_s, seconds, true, !sensor_dead, std::nullopt};
  last_motion_seconds_ = seconds;
  blocked_until_ = now_s + seconds;  // G28 answers when it is done; later lines wait
  if (sensor_dead) {
    reply({fmt::format("error:6 homing failed: index not found within {:.0f} degrees",
                       kHomingSearchRev * 360.0)},
          blocked_until_);
  } else {
    reply({"ok"}, blocked_until_);
  }
}

void TurntableFirmware::start_move(const std::string& command, double now_s) {
  std::optional<double> target_deg, speed_deg_s;
  std::istringstream words(command.substr(2));
  for (std::string w; words >> w;) {
    std::optional<double> value = number(std::string_view(w).substr(1));
    if (w[0] == 'A' && value) {
      target_deg = value;
    } else if (w[0] == 'F' && value && *value > 0) {
      speed_deg_s = value;
    } else {
      reply({fmt::format("error:2 bad parameter '{}': expected A<degrees> F<degrees/s>", w)},
            now_s);
      return;
    }
  }
  if (!target_deg) {
    reply({"error:2 missing parameter: G1 needs A<degrees>"}, now_s);
    return;
  }
  if (!enabled_) {
    reply({"error:3 motor disabled: send M17"}, now_s);
    return;
  }
  if (!homed_) {
    reply({"error:4 not homed: position unknown, send G28"}, now_s);
    return;
  }
  if (motion_) {
    reply({"error:5 busy: the plate is moving"}, now_s);
    return;
  }
  ++g1_seen_;
  const bool struck =
      g1_seen_ >= model_.fault_at && g1_seen_ < model_.fault_at + model_.fault_count;
  const FirmwareFault fault = struck ? model_.fault : FirmwareFault::None;
  if (g1_seen_ == model_.fault_at) {
    if (model_.fault == FirmwareFault::NoReply) silent_replies_ = model_.fault_count;
    if (model_.fault == FirmwareFault::Garbled) garbled_replies_ = model_.fault_count;
  }

  const int steps = model_.steps_per_revolution;
  const int target =
      static_cast<int>(std::lround(*target_deg / 360.0 * steps) % steps + steps) % steps;
  int delta = target - motor_count_;  // the shortest way round
  if (delta > steps / 2) delta -= steps;
  if (delta < -steps / 2) delta += steps;
  const double distance = delta * step_rad();
  const double v = std::min(speed_deg_s.value_or(model_.max_speed_deg_s), model_.max_speed_deg_s);
  const double seconds =
      drivers::trapezoid_seconds(std::abs(distance), v * kDeg, model_.acceleration_deg_s2 * kDeg);
  Motion motion{plate_rad_, distance, v * kDeg, now_s, seconds, false, false, std::nullopt};
  if (fault == FirmwareFault::Stall) motion.distance_rad = distance * rng_.uniform(0.2, 0.8);
  if (fault == FirmwareFault::Disconnect || fault == FirmwareFault::Unplug) {
    motion.unplug_at_s = now_s + seconds / 2;
  }
  motion_ = motion;
  motor_count_ = target;  // open loop: the motor believes it arrives
  last_motion_seconds_ = seconds;
  reply({"ok"}, now_s);  // accepted; the host polls `?` until idle
}

FirmwareTransport::FirmwareTransport(std::shared_ptr<TurntableFirmware> firmware, double time_scale)
    : firmware_(std::move(firmware)),
      seconds_per_real_second_(time_scale > 0 ? 1.0 / time_scale : 1e6) {}

double FirmwareTransport::now_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count() *
         seconds_per_real_second_;
}

std::string FirmwareTransport::describe() const { return "simulated firmware on USB"; }

void FirmwareTransport::open() {
  const double now = now_s();
  if (!firmware_->on_bus(now)) {
    throw DeviceError("USB turntable (simulated firmware) not found on the bus");
  }
  boot_ = firmware_->boot_count(now);
  open_ = true;
}

void FirmwareTransport::close() { open_ = false; }

bool FirmwareTransport::is_open() const {
  const double now = now_s();
  return open_ && firmware_->on_bus(now) && firmware_->boot_count(now) == boot_;
}

void FirmwareTransport::throw_if_gone() const {
  if (!is_open()) {
    throw drivers::DeviceGone("USB turntable (simulated firmware): the device left the bus");
  }
}

void FirmwareTransport::write(std::string_view bytes, std::chrono::milliseconds) {
  throw_if_gone();
  firmware_->receive(bytes, now_s());
}

std::string FirmwareTransport::read(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    throw_if_gone();
    std::string bytes = firmware_->transmit(now_s());
    if (!bytes.empty() || std::chrono::steady_clock::now() >= deadline) return bytes;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

}  // namespace sherd::sim
