// The simulated turntable firmware against the protocol of drivers/README.md: replies, motion
// times and positions hand-computed from the trapezoidal profile, the index sensor, and each
// fault as specified. Time is driven by hand (simulated seconds).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/errors.h"
#include "simulators/turntable_firmware.h"

namespace sherd::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Sends one line at `t` and returns what the firmware has sent by `t` (replies that are ready).
std::string say(TurntableFirmware& fw, const std::string& line, double t) {
  fw.receive(line + "\n", t);
  return fw.transmit(t);
}

// Motor on and homed at t = 0 (the plate powers up at the index: homing takes no time).
void home(TurntableFirmware& fw) { EXPECT_EQ(say(fw, "G28", 0.0), "ok\n"); }

TEST(TurntableFirmware, AnswersQueriesAndRefusesWhatItCannotDo) {
  TurntableFirmware fw(FirmwareModel{});
  EXPECT_EQ(say(fw, "M115", 0), "FIRMWARE:sherd-turntable-sim VERSION:1.0 STEPS:3200\nok\n");
  EXPECT_EQ(say(fw, "?", 0), "idle A:0.0000 T:0.0000 H:0 E:0\nok\n");
  EXPECT_EQ(say(fw, "M114", 0).rfind("error:4 ", 0), 0u);    // position unknown before homing
  EXPECT_EQ(say(fw, "G1 A90", 0).rfind("error:3 ", 0), 0u);  // motor off at power-up
  EXPECT_EQ(say(fw, "M17", 0), "ok\n");
  EXPECT_EQ(say(fw, "G1 A90", 0).rfind("error:4 ", 0), 0u);  // not homed
  EXPECT_EQ(say(fw, "M3 S100", 0), "error:1 unknown command 'M3'\n");
  EXPECT_EQ(say(fw, "G1 A9x0", 0).rfind("error:2 ", 0), 0u);
  EXPECT_EQ(say(fw, "G1 F90", 0).rfind("error:2 ", 0), 0u);  // no target
  EXPECT_EQ(say(fw, std::string(100, 'G'), 0).rfind("error:7 ", 0), 0u);
  // CR LF endings and a line split over two transfers are one command.
  fw.receive("M1", 0);
  EXPECT_EQ(fw.transmit(0), "");
  fw.receive("14\r\n", 0);
  EXPECT_EQ(fw.transmit(0).rfind("error:4 ", 0), 0u);  // that was M114
}

TEST(TurntableFirmware, HomingTurnsForwardToTheIndexAndAnswersWhenDone) {
  FirmwareModel model;
  model.power_up_angle_deg = 90;
  TurntableFirmware fw(model);
  // 270° forward at 90°/s, 360°/s²: ramps of 0.25 s, 3.25 s in all.
  fw.receive("G28\n", 0);
  EXPECT_NEAR(fw.plate_angle_rad(1.625), (90 + 135) * kDeg, 1e-9);  // half way, by symmetry
  EXPECT_EQ(fw.transmit(3.2), "");
  EXPECT_EQ(fw.transmit(3.26), "ok\n");
  EXPECT_NEAR(fw.last_motion_seconds(), 3.25, 1e-9);
  EXPECT_NEAR(fw.plate_angle_rad(3.3), 0.0, 1e-12);
  EXPECT_EQ(say(fw, "M114", 3.3), "A:0.0000 C:0\nok\n");
}

TEST(TurntableFirmware, MoveIsAcceptedAtOnceAndFollowsTheTrapezoid) {
  TurntableFirmware fw(FirmwareModel{});
  home(fw);
  EXPECT_EQ(say(fw, "G1 A90 F90", 1.0), "ok\n");
  // 90° at 90°/s with 360°/s²: 1.25 s; half way (45°) at 0.625 s; 11.25° at the end of the ramp.
  EXPECT_NEAR(fw.plate_angle_rad(1.25), 11.25 * kDeg, 1e-9);
  EXPECT_NEAR(fw.plate_angle_rad(1.625), 45 * kDeg, 1e-9);
  EXPECT_EQ(say(fw, "?", 1.625), "moving A:45.0000 T:90.0000 H:1 E:1\nok\n");
  EXPECT_EQ(say(fw, "G1 A10", 1.7).rfind("error:5 ", 0), 0u);  // busy
  EXPECT_EQ(say(fw, "?", 2.3), "idle A:90.0000 T:90.0000 H:1 E:1\nok\n");
  EXPECT_EQ(say(fw, "M114", 2.3), "A:90.0000 C:800\nok\n");
  // The shortest way, F capped at the maximum speed: 90° → -9° = 351° is 99° backwards.
  EXPECT_EQ(say(fw, "G1 A-9 F1000", 3.0), "ok\n");
  EXPECT_NEAR(fw.last_motion_seconds(), 99.0 / 90.0 + 0.25, 1e-9);
  EXPECT_NEAR(fw.plate_angle_rad(10), 351 * kDeg, 1e-9);
  // A target between steps goes to the nearest step (360/3200 = 0.1125°).
  EXPECT_EQ(say(fw, "G1 A20.06", 10), "ok\n");
  EXPECT_EQ(say(fw, "M114", 20), "A:20.0250 C:178\nok\n");
  // M18 frees the plate: its zero is lost.
  EXPECT_EQ(say(fw, "M18", 20), "ok\n");
  EXPECT_EQ(say(fw, "M114", 20).rfind("error:4 ", 0), 0u);
}

TEST(TurntableFirmware, StallStopsThePlateShortWhileTheMotorBelievesItArrived) {
  FirmwareModel model;
  model.fault = FirmwareFault::Stall;
  model.fault_at = 2;
  TurntableFirmware fw(model);
  home(fw);
  // Targets on whole steps (0.1125°), so that the expected angles are exact.
  say(fw, "G1 A45", 0);
  EXPECT_EQ(say(fw, "G1 A135", 5), "ok\n");  // the second move stalls
  const double plate = fw.plate_angle_rad(20);
  EXPECT_GT(plate, (45 + 0.2 * 90 - 0.01) * kDeg);
  EXPECT_LT(plate, (45 + 0.8 * 90 + 0.01) * kDeg);
  const std::string status = say(fw, "?", 20);
  EXPECT_NE(status.find("idle"), std::string::npos) << status;
  EXPECT_NE(status.find("T:135.0000"), std::string::npos) << status;  // open loop
  const std::string m114 = say(fw, "M114", 20);
  const int count = std::stoi(m114.substr(m114.find("C:") + 2));
  EXPECT_NEAR(count * 0.1125 * kDeg, plate, 0.1125 * kDeg / 2 + 1e-12);  // the encoder tells
  EXPECT_EQ(say(fw, "G1 A225", 20), "ok\n");  // the third move is sound again: 90° on
  EXPECT_NEAR(fw.plate_angle_rad(40), plate + 90 * kDeg, 1e-9);
}

TEST(TurntableFirmware, NoReplyLosesRepliesButStillExecutes) {
  FirmwareModel model;
  model.fault = FirmwareFault::NoReply;
  model.fault_count = 2;
  TurntableFirmware fw(model);
  home(fw);
  EXPECT_EQ(say(fw, "G1 A90", 0), "");
  EXPECT_EQ(say(fw, "?", 5), "");
  EXPECT_EQ(say(fw, "M114", 5), "A:90.0000 C:800\nok\n");
}

TEST(TurntableFirmware, GarbledRepliesAreNotText) {
  FirmwareModel model;
  model.fault = FirmwareFault::Garbled;
  TurntableFirmware fw(model);
  home(fw);
  const std::string reply = say(fw, "G1 A90", 0);
  ASSERT_EQ(reply.size(), 3u);
  EXPECT_NE(reply, "ok\n");
  EXPECT_EQ(static_cast<unsigned char>(reply[0]), static_cast<unsigned char>('o' ^ 0x80));
  EXPECT_EQ(say(fw, "M114", 5), "A:90.0000 C:800\nok\n");  // only one reply was hit
}

TEST(TurntableFirmware, DisconnectLeavesTheBusMidMoveAndComesBackRestarted) {
  FirmwareModel model;
  model.fault = FirmwareFault::Disconnect;
  model.replug_after_s = 0.5;
  TurntableFirmware fw(model);
  home(fw);
  EXPECT_EQ(fw.boot_count(0), 1);
  EXPECT_EQ(say(fw, "G1 A90", 0), "ok\n");
  EXPECT_TRUE(fw.on_bus(0.6));
  EXPECT_FALSE(fw.on_bus(0.63));                          // half of the 1.25 s move
  EXPECT_NEAR(fw.plate_angle_rad(0.7), 45 * kDeg, 1e-9);  // stopped where power went
  EXPECT_TRUE(fw.on_bus(1.13));
  EXPECT_EQ(fw.boot_count(1.13), 2);
  EXPECT_EQ(say(fw, "?", 1.2), "idle A:45.0000 T:0.0000 H:0 E:0\nok\n");
}

TEST(TurntableFirmware, UnplugIsForGood) {
  FirmwareModel model;
  model.fault = FirmwareFault::Unplug;
  TurntableFirmware fw(model);
  home(fw);
  say(fw, "G1 A90", 0);
  EXPECT_FALSE(fw.on_bus(1e6));
}

TEST(TurntableFirmware, DeadIndexSensorFailsHomingAfterTheSearchRange) {
  FirmwareModel model;
  model.fault = FirmwareFault::Homing;
  model.fault_count = 1;
  TurntableFirmware fw(model);
  fw.receive("G28\n", 0);
  // 450° at 90°/s with ramps of 0.25 s: 5.25 s.
  EXPECT_EQ(fw.transmit(5.2), "");
  EXPECT_EQ(fw.transmit(5.3).rfind("error:6 homing failed", 0), 0u);
  EXPECT_NEAR(fw.plate_angle_rad(6), 90 * kDeg, 1e-9);  // 1.25 turns from 0
  EXPECT_EQ(say(fw, "G28", 6), "");  // the second homing finds the index (270° away)...
  EXPECT_EQ(fw.transmit(6 + 3.26), "ok\n");
}

TEST(TurntableFirmware, RejectsAnImpossibleModel) {
  FirmwareModel model;
  model.steps_per_revolution = 0;
  EXPECT_THROW(TurntableFirmware{model}, InputError);
  EXPECT_THROW(firmware_fault_from_string("fire"), InputError);
}

}  // namespace
}  // namespace sherd::sim
