#include "simulators/sim_turntable.h"

#include "core/errors.h"
#include "drivers/motion_profile.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <thread>

namespace sherd::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
double wrap(double a) {
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}
double deg(double rad) { return rad * 180.0 / std::numbers::pi; }

using drivers::trapezoid_distance;
using drivers::trapezoid_seconds;

}  // namespace

TurntableFault turntable_fault_from_string(const std::string& name) {
  if (name == "none") return TurntableFault::None;
  if (name == "stall") return TurntableFault::Stall;
  if (name == "timeout") return TurntableFault::Timeout;
  if (name == "disconnect") return TurntableFault::Disconnect;
  throw InputError(fmt::format(
      "unknown turntable fault '{}': expected none, stall, timeout or disconnect", name));
}

SimulatedTurntable::SimulatedTurntable(TurntableModel model) : model_(model), rng_(model.seed) {
  if (model_.steps_per_revolution <= 0 || !(model_.speed_deg_s > 0) ||
      !(model_.acceleration_deg_s2 > 0) || !(model_.time_scale >= 0) ||
      model_.fault_at_move < 1 || !(model_.timeout_s > 0)) {
    throw InputError(fmt::format(
        "simulated turntable: steps_per_revolution ({}), speed_deg_s ({}), "
        "acceleration_deg_s2 ({}) and timeout_s ({}) must be positive, time_scale ({}) ≥ 0 and "
        "fault_at_move ({}) ≥ 1",
        model_.steps_per_revolution, model_.speed_deg_s, model_.acceleration_deg_s2,
        model_.timeout_s, model_.time_scale, model_.fault_at_move));
  }
}

std::string SimulatedTurntable::describe() const {
  return fmt::format("simulated turntable {} steps/rev, {:.0f}°/s, {:.0f}°/s²",
                     model_.steps_per_revolution, model_.speed_deg_s,
                     model_.acceleration_deg_s2);
}

double SimulatedTurntable::resolution() const {
  return kTwoPi / model_.steps_per_revolution;
}

double SimulatedTurntable::encoder_reading(double physical_rad) const {
  const double step = resolution();
  return wrap(std::round(wrap(physical_rad) / step) * step);
}

double SimulatedTurntable::physical_locked() const {
  if (!motion_) return physical_rad_;
  const double elapsed =
      std::chrono::duration<double>(Clock::now() - motion_->start).count() / model_.time_scale;
  const double v = model_.speed_deg_s * std::numbers::pi / 180.0;
  const double a = model_.acceleration_deg_s2 * std::numbers::pi / 180.0;
  const double covered = trapezoid_distance(elapsed, std::abs(motion_->distance_rad), v, a);
  return wrap(motion_->from_rad + std::copysign(covered, motion_->distance_rad));
}

void SimulatedTurntable::throw_if_disconnected() const {
  if (state_ == drivers::TurntableState::Disconnected) {
    throw DeviceError("turntable disconnected: check its USB cable and power, then restart the "
                      "station");
  }
}

void SimulatedTurntable::run_motion(std::unique_lock<std::mutex>& lock, double distance_rad,
                                    double seconds, drivers::TurntableState during) {
  last_move_seconds_ = seconds;
  const double wait = seconds * model_.time_scale;
  if (wait > 0) {
    motion_ = Motion{physical_rad_, distance_rad, seconds, Clock::now()};
    state_ = during;
    lock.unlock();  // state() and position() stay answerable while the plate turns
    std::this_thread::sleep_for(std::chrono::duration<double>(wait));
    lock.lock();
    motion_.reset();
  }
  physical_rad_ = wrap(physical_rad_ + distance_rad);
}

void SimulatedTurntable::home() {
  std::unique_lock lock(mutex_);
  throw_if_disconnected();
  if (motion_) throw DeviceError("turntable busy: home() called during a move; wait for it");
  const double back = -(physical_rad_ > std::numbers::pi ? physical_rad_ - kTwoPi : physical_rad_);
  const double v = model_.speed_deg_s * std::numbers::pi / 180.0;
  const double a = model_.acceleration_deg_s2 * std::numbers::pi / 180.0;
  run_motion(lock, back, trapezoid_seconds(std::abs(back), v, a), drivers::TurntableState::Homing);
  physical_rad_ = 0.0;  // the index mark defines zero
  moves_since_home_ = 0;
  state_ = drivers::TurntableState::Idle;
}

double SimulatedTurntable::move_to(double angle_rad) {
  if (!std::isfinite(angle_rad)) {
    throw InputError("turntable: target angle is not finite: pass an angle in radians");
  }
  std::unique_lock lock(mutex_);
  throw_if_disconnected();
  if (motion_) throw DeviceError("turntable busy: move_to() called during a move; wait for it");
  if (state_ == drivers::TurntableState::Fault) {
    throw DeviceError("turntable in fault after a stall or timeout: check the plate is free, "
                      "then re-home it");
  }
  const double target = wrap(angle_rad);
  double delta = target - physical_rad_;
  if (delta > std::numbers::pi) delta -= kTwoPi;
  if (delta < -std::numbers::pi) delta += kTwoPi;
  const double v = model_.speed_deg_s * std::numbers::pi / 180.0;
  const double a = model_.acceleration_deg_s2 * std::numbers::pi / 180.0;

  ++moves_since_home_;
  const bool fails = model_.fault != TurntableFault::None &&
                     moves_since_home_ == model_.fault_at_move;
  if (!fails) {
    run_motion(lock, delta, trapezoid_seconds(std::abs(delta), v, a),
               drivers::TurntableState::Moving);
    physical_rad_ = target;
    state_ = drivers::TurntableState::Idle;
    return encoder_reading(physical_rad_);
  }
  switch (model_.fault) {
    case TurntableFault::Stall: {
      // The plate stops short: it covers only part of the way.
      const double covered = delta * rng_.uniform(0.2, 0.8);
      run_motion(lock, covered, trapezoid_seconds(std::abs(covered), v, a),
                 drivers::TurntableState::Moving);
      state_ = drivers::TurntableState::Fault;
      throw DeviceError(fmt::format(
          "turntable stalled at {:.2f}° while moving to {:.2f}°: check the plate is free, then "
          "re-home",
          deg(encoder_reading(physical_rad_)), deg(target)));
    }
    case TurntableFault::Timeout:
      // The motor never answers: the plate stays, the driver waits, then gives up.
      run_motion(lock, 0.0, model_.timeout_s, drivers::TurntableState::Moving);
      state_ = drivers::TurntableState::Fault;
      throw DeviceError(fmt::format(
          "turntable did not reach {:.2f}° within {:.1f} s (it stands at {:.2f}°): check the "
          "motor power and cable, then re-home",
          deg(target), model_.timeout_s, deg(encoder_reading(physical_rad_))));
    case TurntableFault::Disconnect:
      state_ = drivers::TurntableState::Disconnected;
      throw DeviceError(fmt::format(
          "turntable disconnected while moving to {:.2f}°: check its USB cable and power, then "
          "restart the station",
          deg(target)));
    case TurntableFault::None: break;
  }
  return encoder_reading(physical_rad_);
}

double SimulatedTurntable::position() const {
  std::lock_guard lock(mutex_);
  throw_if_disconnected();
  return encoder_reading(physical_locked());
}

drivers::TurntableState SimulatedTurntable::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

double SimulatedTurntable::physical_angle() const {
  std::lock_guard lock(mutex_);
  return physical_locked();
}

double SimulatedTurntable::last_move_seconds() const {
  std::lock_guard lock(mutex_);
  return last_move_seconds_;
}

}  // namespace sherd::sim
