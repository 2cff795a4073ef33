// The USB turntable driver over the simulated firmware (FirmwareTransport in place of libusb).
// Truth: the firmware's physical plate angle and the lines it received. For every fault: either
// the move ends verified at the target (the plate truly there), or it throws with the reason —
// never an angle that is not where the plate stands; moves are never repeated blind.
#include "drivers/usb_turntable.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <numbers>
#include <thread>

#include "core/errors.h"
#include "simulators/turntable_firmware.h"

namespace sherd::drivers {
namespace {

using sim::FirmwareFault;
using sim::FirmwareModel;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kStep = 2 * std::numbers::pi / 3200;

struct Rig {
  std::shared_ptr<sim::TurntableFirmware> firmware;
  sim::FirmwareTransport* bus = nullptr;
  std::unique_ptr<UsbTurntable> table;

  explicit Rig(FirmwareModel model, UsbTurntableSettings settings = fast()) {
    firmware = std::make_shared<sim::TurntableFirmware>(model);
    auto transport = std::make_unique<sim::FirmwareTransport>(firmware, 0.0);  // instant motion
    bus = transport.get();
    table = std::make_unique<UsbTurntable>(std::move(transport), settings);
  }
  static UsbTurntableSettings fast() {
    UsbTurntableSettings s;
    s.reply_timeout = std::chrono::milliseconds(250);  // generous: the machine may be loaded
    s.reconnect_timeout = std::chrono::milliseconds(300);
    return s;
  }
  double plate() const { return firmware->plate_angle_rad(bus->now_s()); }
  int count(const std::string& prefix) const {
    const auto lines = firmware->received_lines();
    return static_cast<int>(std::count_if(
        lines.begin(), lines.end(), [&](const std::string& l) { return l.rfind(prefix, 0) == 0; }));
  }
};

double angular_distance(double a, double b) {
  return std::abs(std::remainder(a - b, 2 * std::numbers::pi));
}

// The verified angle is where the plate stands (the encoder quantises to a step) and near the
// target.
void expect_verified(const Rig& rig, double reported, double target) {
  EXPECT_LE(angular_distance(reported, rig.plate()), kStep / 2 + 1e-9);
  EXPECT_LE(angular_distance(reported, target), kStep + 1e-9);
}

FirmwareModel with_fault(FirmwareFault fault, int at = 1, int count = 1) {
  FirmwareModel model;
  model.power_up_angle_deg = 123.4;
  model.fault = fault;
  model.fault_at = at;
  model.fault_count = count;
  model.replug_after_s = 0.5;
  return model;
}

TEST(UsbTurntable, HomesAndMovesToVerifiedAngles) {
  Rig rig(with_fault(FirmwareFault::None));
  EXPECT_NE(rig.table->describe().find("STEPS:3200"), std::string::npos);
  EXPECT_DOUBLE_EQ(rig.table->resolution(), kStep);
  rig.table->home();
  EXPECT_LE(angular_distance(rig.plate(), 0.0), 1e-12);  // the index defines zero
  for (double deg : {45.0, 300.0, 10.03, 359.99, 180.0}) {
    const double reported = rig.table->move_to(deg * kDeg);
    expect_verified(rig, reported, deg * kDeg);
    EXPECT_DOUBLE_EQ(rig.table->position(), reported);
  }
  EXPECT_EQ(rig.count("G1 "), 5);
  EXPECT_EQ(rig.count("G28"), 1);
  EXPECT_EQ(rig.table->state(), TurntableState::Idle);
}

TEST(UsbTurntable, MovingWithoutHomingHomesFirst) {
  Rig rig(with_fault(FirmwareFault::None));
  expect_verified(rig, rig.table->move_to(90 * kDeg), 90 * kDeg);
  EXPECT_EQ(rig.count("G28"), 1);
}

TEST(UsbTurntable, StallIsSeenOnTheEncoderReHomedAndMovedAgain) {
  Rig rig(with_fault(FirmwareFault::Stall, 2));
  rig.table->home();
  rig.table->move_to(30 * kDeg);
  expect_verified(rig, rig.table->move_to(120 * kDeg), 120 * kDeg);  // the stalled move
  EXPECT_EQ(rig.count("G28"), 2);
  EXPECT_EQ(rig.count("G1 "), 3);
}

TEST(UsbTurntable, PersistentStallFailsWithTheReason) {
  Rig rig(with_fault(FirmwareFault::Stall, 1, 100));
  rig.table->home();
  try {
    rig.table->move_to(135 * kDeg);
    FAIL() << "a plate that always stalls cannot reach 135°";
  } catch (const DeviceError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("could not reach 135.000° in 3 attempts"), std::string::npos) << what;
    EXPECT_NE(what.find("missed steps"), std::string::npos) << what;
  }
  EXPECT_EQ(rig.count("G1 "), 3);
  EXPECT_EQ(rig.table->state(), TurntableState::Fault);
}

TEST(UsbTurntable, LostReplyToAMoveIsNeverAnsweredByMovingAgain) {
  Rig rig(with_fault(FirmwareFault::NoReply));
  rig.table->home();
  expect_verified(rig, rig.table->move_to(200 * kDeg), 200 * kDeg);
  EXPECT_EQ(rig.count("G1 "), 1);
}

TEST(UsbTurntable, LostRepliesToQueriesAreAskedAgain) {
  Rig rig(with_fault(FirmwareFault::NoReply, 1, 3));  // the G1's, then two `?`s
  rig.table->home();
  expect_verified(rig, rig.table->move_to(200 * kDeg), 200 * kDeg);
  EXPECT_EQ(rig.count("G1 "), 1);
  EXPECT_EQ(rig.count("?"), 3);
}

TEST(UsbTurntable, SilentControllerFailsTheMoveWithTheReason) {
  Rig rig(with_fault(FirmwareFault::NoReply, 1, 1000));
  rig.table->home();
  try {
    rig.table->move_to(200 * kDeg);
    FAIL() << "a silent controller cannot confirm a move";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("no valid answer to ? in 3 attempts"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(rig.count("G1 "), 1);
  EXPECT_EQ(rig.table->state(), TurntableState::Fault);
}

TEST(UsbTurntable, GarbledReplyToAMoveIsCheckedNotRepeated) {
  Rig rig(with_fault(FirmwareFault::Garbled, 1, 2));  // the G1's and the first `?`
  rig.table->home();
  expect_verified(rig, rig.table->move_to(75 * kDeg), 75 * kDeg);
  EXPECT_EQ(rig.count("G1 "), 1);
}

TEST(UsbTurntable, PersistentlyGarbledRepliesFailWithTheReason) {
  Rig rig(with_fault(FirmwareFault::Garbled, 1, 1000));
  rig.table->home();
  try {
    rig.table->move_to(75 * kDeg);
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("garbled reply"), std::string::npos) << e.what();
  }
  EXPECT_EQ(rig.count("G1 "), 1);
}

TEST(UsbTurntable, DisconnectMidMoveReconnectsReHomesAndArrives) {
  Rig rig(with_fault(FirmwareFault::Disconnect, 2));
  rig.table->home();
  rig.table->move_to(10 * kDeg);
  expect_verified(rig, rig.table->move_to(100 * kDeg), 100 * kDeg);
  EXPECT_EQ(rig.firmware->boot_count(rig.bus->now_s()), 2);
  EXPECT_EQ(rig.count("G28"), 2);  // after the restart the zero had to be found again
  EXPECT_EQ(rig.table->state(), TurntableState::Idle);
}

TEST(UsbTurntable, UnplugFailsWithTheReasonAndSaysDisconnected) {
  Rig rig(with_fault(FirmwareFault::Unplug, 1));
  rig.table->home();
  try {
    rig.table->move_to(100 * kDeg);
    FAIL();
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("gone from USB and not back"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(rig.table->state(), TurntableState::Disconnected);
  EXPECT_THROW(rig.table->position(), DeviceError);
}

TEST(UsbTurntable, FailedHomingIsTriedAgain) {
  Rig rig(with_fault(FirmwareFault::Homing, 1, 1));
  rig.table->home();
  EXPECT_LE(angular_distance(rig.plate(), 0.0), 1e-12);
  EXPECT_EQ(rig.count("G28"), 2);
}

TEST(UsbTurntable, DeadIndexSensorFailsWithTheReason) {
  Rig rig(with_fault(FirmwareFault::Homing, 1, 100));
  try {
    rig.table->home();
    FAIL();
  } catch (const DeviceError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("homing failed 2 times"), std::string::npos) << what;
    EXPECT_NE(what.find("index not found"), std::string::npos) << what;
  }
  EXPECT_EQ(rig.table->state(), TurntableState::Fault);
  EXPECT_THROW(rig.table->move_to(10 * kDeg), DeviceError);  // never moves unhomed
  EXPECT_EQ(rig.count("G1 "), 0);
}

TEST(UsbTurntable, StepsPerRevolutionMustMatchTheController) {
  FirmwareModel model;
  model.steps_per_revolution = 6400;
  EXPECT_THROW(Rig{model}, InputError);
}

TEST(UsbTurntable, AbsentDeviceIsReportedAtStart) {
  FirmwareModel model = with_fault(FirmwareFault::Unplug);
  auto firmware = std::make_shared<sim::TurntableFirmware>(model);
  auto transport = std::make_unique<sim::FirmwareTransport>(firmware, 0.0);
  firmware->receive("G28\nM17\nG1 A90\n", transport->now_s());  // unplugs itself
  EXPECT_THROW(UsbTurntable(std::move(transport), Rig::fast()), DeviceError);
}

TEST(UsbTurntable, StateIsMovingWhileThePlateTurns) {
  auto firmware = std::make_shared<sim::TurntableFirmware>(FirmwareModel{});
  auto transport = std::make_unique<sim::FirmwareTransport>(firmware, 0.1);  // 10× real time
  UsbTurntable table(std::move(transport), Rig::fast());
  table.home();
  std::atomic<bool> saw_moving{false};
  std::thread watcher([&] {
    for (int i = 0; i < 200 && !saw_moving; ++i) {
      saw_moving = table.state() == TurntableState::Moving;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  table.move_to(170 * kDeg);  // 2.14 s simulated, 0.21 s real
  watcher.join();
  EXPECT_TRUE(saw_moving);
  EXPECT_EQ(table.state(), TurntableState::Idle);
}

}  // namespace
}  // namespace sherd::drivers
