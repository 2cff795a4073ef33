// sherdd with the USB turntable driver on the simulated controller firmware
// ([turntable] driver = "usb-simulated"): the real driver code under the real daemon. A fault the
// driver can recover from leaves a complete scan whose every view stands at its commanded angle
// (within one encoder step) and whose events tell what happened; one it cannot fails the scan with
// the reason, keeps the views already taken, and the daemon keeps serving.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "db/store.h"
#include "harness.h"

namespace sherd::testing {
namespace {

// The scan's log lines in the database (what the operator's `sherdctl show` history is made of).
std::vector<std::string> events(const std::filesystem::path& db, const std::string& scan_id) {
  sqlite3* handle = nullptr;
  std::vector<std::string> messages;
  if (sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* statement = nullptr;
    sqlite3_prepare_v2(handle, "SELECT message FROM events WHERE scan_id = ? ORDER BY id", -1,
                       &statement, nullptr);
    sqlite3_bind_text(statement, 1, scan_id.c_str(), -1, SQLITE_TRANSIENT);
    while (sqlite3_step(statement) == SQLITE_ROW) {
      messages.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(statement, 0)));
    }
    sqlite3_finalize(statement);
  }
  sqlite3_close(handle);
  return messages;
}

bool any_contains(const std::vector<std::string>& lines, const std::string& text) {
  for (const auto& line : lines) {
    if (line.find(text) != std::string::npos) return true;
  }
  return false;
}

std::map<std::string, std::string> usb_station(const std::string& fault, int at, int count) {
  return {{"turntable.driver", "\"usb-simulated\""},
          {"turntable.time_scale", "0"},
          {"turntable.fault", "\"" + fault + "\""},
          {"turntable.fault_at_move", std::to_string(at)},
          {"turntable.fault_count", std::to_string(count)},
          {"turntable.reply_timeout_ms", "300"},
          {"turntable.reconnect_timeout_s", "1.0"}};
}

TEST(UsbTurntableStation, DisconnectMidScanIsRecoveredAndEveryViewIsAtItsAngle) {
  TestStation station(usb_station("disconnect", 4, 1));
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto scan =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err << daemon.log();

  db::Store store(station.data / "sherdscan.db");
  const auto scans = store.scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, db::ScanState::Done) << scans[0].reason;
  const auto views = store.views(scans[0].id);
  ASSERT_EQ(static_cast<int>(views.size()), station.config.scan.views);
  const double step = 360.0 / station.config.turntable.steps_per_revolution;
  for (const auto& v : views) {
    EXPECT_NEAR(v.measured_angle_deg, v.commanded_angle_deg, step) << "view " << v.index;
  }
  EXPECT_FALSE(store.sherds(scans[0].id).empty());
  const auto log = events(station.data / "sherdscan.db", scans[0].id);
  // The fourth move (to 135°) lost the controller: noticed, waited for, re-homed, moved again.
  EXPECT_TRUE(any_contains(log, "moving to 135.000°") || any_contains(log, "move to 135.000°"))
      << daemon.log();
  EXPECT_TRUE(any_contains(log, "turntable back on USB")) << daemon.log();
  EXPECT_EQ(daemon.terminate(), 0);
}

TEST(UsbTurntableStation, PersistentStallFailsTheScanWithTheReasonAndKeepsItsViews) {
  TestStation station(usb_station("stall", 3, 1000));
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto scan =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  EXPECT_EQ(scan.exit_code, 1);
  EXPECT_NE(scan.err.find("missed steps"), std::string::npos) << scan.err;

  db::Store store(station.data / "sherdscan.db");
  const auto scans = store.scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, db::ScanState::Failed);
  EXPECT_NE(scans[0].reason.find("could not reach 90.000° in 3 attempts"), std::string::npos)
      << scans[0].reason;
  EXPECT_EQ(store.views(scans[0].id).size(), 2u);  // the two sound moves; none at a wrong angle
  const auto log = events(station.data / "sherdscan.db", scans[0].id);
  EXPECT_TRUE(any_contains(log, "re-homing and moving again")) << daemon.log();

  const auto status =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "status"});
  EXPECT_EQ(status.exit_code, 0) << status.err;
}

TEST(UsbTurntableStation, DeadIndexSensorFailsTheScanWithTheReason) {
  TestStation station(usb_station("homing", 1, 1000));
  Daemon daemon(station.config_file, station.data);
  daemon.start();
  const auto scan =
      run({binary("sherdctl").string(), "--socket", daemon.socket().string(), "scan"});
  EXPECT_EQ(scan.exit_code, 1);
  EXPECT_NE(scan.err.find("homing failed"), std::string::npos) << scan.err;
  db::Store store(station.data / "sherdscan.db");
  const auto scans = store.scans();
  ASSERT_EQ(scans.size(), 1u);
  EXPECT_EQ(scans[0].state, db::ScanState::Failed);
  EXPECT_TRUE(store.views(scans[0].id).empty());
}

TEST(UsbTurntableStation, AFaultOnlyTheFirmwareHasIsRefusedForTheSimpleSimulator) {
  TestStation station(std::map<std::string, std::string>{{"turntable.fault", "\"garbled\""}});
  const auto result = run({binary("sherdd").string(), "--config", station.config_file.string(),
                           "--data-dir", station.data.string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("needs turntable.driver = \"usb-simulated\""), std::string::npos)
      << result.err;
}

}  // namespace
}  // namespace sherd::testing
