// The simulated turntable against hand-computed motion times, encoder steps and the specified
// behaviour of each fault.
#include "core/errors.h"
#include "simulators/sim_turntable.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <numbers>
#include <thread>

namespace sherd::sim {
namespace {

using drivers::TurntableState;
constexpr double kDeg = std::numbers::pi / 180.0;

TurntableModel instant() {
  TurntableModel m;  // 3200 steps, 90°/s, 360°/s²
  m.time_scale = 0.0;
  return m;
}

TEST(Turntable, MoveTimeFollowsTheTrapezoidalProfile) {
  SimulatedTurntable table(instant());
  // 90° at 90°/s with 360°/s²: ramps of 0.25 s cover 11.25° each, 67.5° cruise in 0.75 s.
  table.move_to(90 * kDeg);
  EXPECT_NEAR(table.last_move_seconds(), 1.25, 1e-9);
  // 10° never reaches full speed: two ramps of 5°, t = 2·√(10/360) s.
  table.move_to(100 * kDeg);
  EXPECT_NEAR(table.last_move_seconds(), 2 * std::sqrt(10.0 / 360.0), 1e-9);
  // The shortest way: 100° → 350° is 110° backwards.
  table.move_to(350 * kDeg);
  EXPECT_NEAR(table.last_move_seconds(), 110.0 / 90.0 + 0.25, 1e-9);
  EXPECT_NEAR(table.physical_angle(), 350 * kDeg, 1e-12);
}

TEST(Turntable, EncoderIsQuantisedToItsSteps) {
  SimulatedTurntable table(instant());
  const double step = 2 * std::numbers::pi / 3200;
  EXPECT_NEAR(table.resolution(), step, 1e-15);
  for (double target : {0.3, 1.0, 2.71828, 6.2}) {
    const double reported = table.move_to(target);
    EXPECT_NEAR(std::remainder(reported / step, 1.0), 0.0, 1e-6);  // a whole number of steps
    EXPECT_LE(std::abs(reported - target), step / 2 + 1e-12);
    EXPECT_GT(std::abs(reported - target), 0.0);  // these targets fall between steps
    EXPECT_DOUBLE_EQ(table.position(), reported);
    EXPECT_DOUBLE_EQ(table.physical_angle(), target);
  }
  // Angles wrap into [0, 2π).
  EXPECT_NEAR(table.move_to(-90 * kDeg), 270 * kDeg, step / 2);
}

TEST(Turntable, StallStopsShortAndNeedsAReHome) {
  TurntableModel m = instant();
  m.fault = TurntableFault::Stall;
  m.fault_at_move = 2;
  SimulatedTurntable table(m);
  table.move_to(10 * kDeg);
  try {
    table.move_to(90 * kDeg);
    FAIL() << "the second move should stall";
  } catch (const DeviceError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("turntable stalled at"), std::string::npos) << what;
    EXPECT_NE(what.find("while moving to 90.00°"), std::string::npos) << what;
    EXPECT_NE(what.find("re-home"), std::string::npos) << what;
  }
  const double physical = table.physical_angle();
  EXPECT_GT(physical, 10 * kDeg);
  EXPECT_LT(physical, 90 * kDeg);
  EXPECT_LE(std::abs(table.position() - physical), table.resolution() / 2 + 1e-12);
  EXPECT_EQ(table.state(), TurntableState::Fault);
  EXPECT_THROW(table.move_to(90 * kDeg), DeviceError);
  table.home();
  EXPECT_EQ(table.state(), TurntableState::Idle);
  EXPECT_DOUBLE_EQ(table.physical_angle(), 0.0);
  EXPECT_NO_THROW(table.move_to(45 * kDeg));
  EXPECT_THROW(table.move_to(90 * kDeg), DeviceError);  // counted again from the home
}

TEST(Turntable, TimeoutLeavesThePlateAndThrows) {
  TurntableModel m = instant();
  m.fault = TurntableFault::Timeout;
  m.timeout_s = 4.0;
  SimulatedTurntable table(m);
  try {
    table.move_to(30 * kDeg);
    FAIL() << "the first move should time out";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("did not reach 30.00° within 4.0 s"), std::string::npos)
        << e.what();
  }
  EXPECT_DOUBLE_EQ(table.physical_angle(), 0.0);
  EXPECT_DOUBLE_EQ(table.last_move_seconds(), 4.0);
  EXPECT_EQ(table.state(), TurntableState::Fault);
}

TEST(Turntable, DisconnectIsFinal) {
  TurntableModel m = instant();
  m.fault = TurntableFault::Disconnect;
  m.fault_at_move = 3;
  SimulatedTurntable table(m);
  table.move_to(10 * kDeg);
  table.move_to(20 * kDeg);
  EXPECT_THROW(table.move_to(30 * kDeg), DeviceError);
  EXPECT_EQ(table.state(), TurntableState::Disconnected);
  EXPECT_THROW(table.position(), DeviceError);
  EXPECT_THROW(table.home(), DeviceError);
  EXPECT_THROW(table.move_to(0.0), DeviceError);
  EXPECT_NEAR(table.physical_angle(), 20 * kDeg, 1e-12);  // the plate itself stays where it was
}

TEST(Turntable, StateAndPositionAnswerFromAnotherThreadDuringAMove) {
  TurntableModel m;
  m.time_scale = 0.5;  // a 90° move: 1.25 simulated s, 0.625 s here
  SimulatedTurntable table(m);
  std::atomic<bool> done{false};
  std::thread mover([&] {
    table.move_to(90 * kDeg);
    done = true;
  });
  bool saw_moving = false;
  double mid = -1.0;
  while (!done) {
    if (table.state() == TurntableState::Moving) {
      saw_moving = true;
      mid = table.position();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  mover.join();
  EXPECT_TRUE(saw_moving);
  EXPECT_GE(mid, 0.0);
  EXPECT_LE(mid, 90 * kDeg + table.resolution());
  EXPECT_EQ(table.state(), TurntableState::Idle);
}

TEST(Turntable, RejectsBadModelsAndTargets) {
  TurntableModel m = instant();
  m.steps_per_revolution = 0;
  EXPECT_THROW(SimulatedTurntable{m}, InputError);
  m = instant();
  m.fault_at_move = 0;
  EXPECT_THROW(SimulatedTurntable{m}, InputError);
  SimulatedTurntable table(instant());
  EXPECT_THROW(table.move_to(std::nan("")), InputError);
  EXPECT_THROW(turntable_fault_from_string("smoke"), InputError);
}

}  // namespace
}  // namespace sherd::sim
