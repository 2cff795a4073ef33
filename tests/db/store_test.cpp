// The store against real SQLite files. Where the store's own reader could hide a mistake
// (schema version, pragmas, cascades), the file is inspected with the sqlite3 C API directly.
#include "db/store.h"

#include "core/errors.h"
#include "temp_dir.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <fstream>
#include <regex>
#include <set>
#include <thread>

namespace sherd::db {
namespace {

using test::TempDirTest;
using ::testing::HasSubstr;

// One integer answer to `sql`, read through a separate connection.
std::int64_t query_int(const std::filesystem::path& file, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK) << sql;
  EXPECT_EQ(sqlite3_step(stmt), SQLITE_ROW) << sql;
  const std::int64_t value = sqlite3_column_int64(stmt, 0);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return value;
}

std::string query_text(const std::filesystem::path& file, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK) << sql;
  EXPECT_EQ(sqlite3_step(stmt), SQLITE_ROW) << sql;
  std::string value = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return value;
}

class StoreTest : public TempDirTest {
 protected:
  std::filesystem::path db_file() const { return dir_ / "sherdscan.db"; }

  ViewRecord view(const std::string& scan_id, int index) const {
    ViewRecord v;
    v.scan_id = scan_id;
    v.index = index;
    v.raw_path = "raw/view-" + std::to_string(index) + ".bin";
    v.commanded_angle_deg = 45.0 * index;
    v.measured_angle_deg = 45.0 * index + 0.1125;
    v.started_at = "2024-05-01T10:00:00.000Z";
    v.captured_at = "2024-05-01T10:00:01.500Z";
    v.valid_points = 123456 + index;
    return v;
  }
};

TEST_F(StoreTest, MigratesAnEmptyFileToTheCurrentSchema) {
  {
    Store store(db_file());
    EXPECT_EQ(store.schema_version(), 2);
  }
  EXPECT_EQ(query_int(db_file(), "PRAGMA user_version"), 2);
  EXPECT_EQ(query_text(db_file(), "PRAGMA journal_mode"), "wal");
  for (const char* table :
       {"scans", "views", "sherds", "measurements", "artifacts", "stages", "events",
        "calibrations"}) {
    EXPECT_EQ(query_int(db_file(), std::string("SELECT count(*) FROM sqlite_master WHERE "
                                               "type = 'table' AND name = '") +
                                       table + "'"),
              1)
        << table;
  }
}

TEST_F(StoreTest, ReopeningKeepsTheDataAndDoesNotMigrateAgain) {
  std::string id;
  {
    Store store(db_file());
    id = store.create_scan("station", 8, {{"views", 8}}, "/tmp/out");
    store.add_view(view(id, 0));
  }
  Store store(db_file());
  EXPECT_EQ(store.schema_version(), 2);
  ASSERT_TRUE(store.scan(id).has_value());
  EXPECT_EQ(store.views(id).size(), 1u);
}

// A station database from before calibrations (schema 1) gains the table and keeps its scans.
TEST_F(StoreTest, MigratesAVersionOneDatabaseKeepingItsScans) {
  std::string id;
  {
    Store store(db_file());
    id = store.create_scan("station", 8, {{"views", 8}}, "/tmp/out");
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(db_file().c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "DROP TABLE calibrations; PRAGMA user_version = 1", nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  Store store(db_file());
  EXPECT_EQ(store.schema_version(), 2);
  EXPECT_TRUE(store.scan(id).has_value());
  EXPECT_FALSE(store.latest_calibration("turntable").has_value());
  store.add_calibration("turntable", id, {{"rms_residual_mm", 0.03}});
  EXPECT_EQ(store.latest_calibration("turntable")->scan_id, id);
}

TEST_F(StoreTest, TheLatestCalibrationOfAKindIsTheOneInForce) {
  Store store(db_file());
  const auto id = store.create_scan("calibration", 12, {{"views", 12}}, "/tmp/out");
  EXPECT_FALSE(store.latest_calibration("turntable").has_value());
  const auto first = store.add_calibration("turntable", id, {{"point_sd_mm", 0.5}});
  const auto second = store.add_calibration("turntable", "", {{"point_sd_mm", 0.25}});
  store.add_calibration("scanner", "", {{"fx", 801.5}});
  EXPECT_GT(second, first);
  const auto latest = store.latest_calibration("turntable");
  ASSERT_TRUE(latest.has_value());
  EXPECT_EQ(latest->id, second);
  EXPECT_EQ(latest->kind, "turntable");
  EXPECT_EQ(latest->scan_id, "");
  EXPECT_EQ(latest->result["point_sd_mm"], 0.25);
  EXPECT_EQ(latest->created_at.size(), std::string("2024-05-01T12:34:56.789Z").size());
  EXPECT_EQ(store.latest_calibration("scanner")->result["fx"], 801.5);
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM calibrations WHERE kind = 'turntable'"), 2);
  // A calibration of a scan that does not exist is refused, naming the database.
  EXPECT_THROW(store.add_calibration("turntable", "no-such-scan", {{"x", 1}}), InputError);
}

TEST_F(StoreTest, RefusesADatabaseNewerThanTheCode) {
  { Store store(db_file()); }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(db_file().c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "PRAGMA user_version = 7", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    Store store(db_file());
    FAIL() << "a version-7 database was opened";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(db_file().string()));
    EXPECT_THAT(e.what(), HasSubstr("version 7 is newer"));
  }
}

TEST_F(StoreTest, ACorruptFileGivesAClearInputError) {
  {
    std::ofstream garbage(db_file(), std::ios::binary);
    for (int i = 0; i < 4096; ++i) garbage.put(static_cast<char>((i * 7919 + 13) % 251));
  }
  try {
    Store store(db_file());
    FAIL() << "garbage was opened as a database";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(db_file().string()));
    EXPECT_THAT(e.what(), HasSubstr("not a database"));
    EXPECT_THAT(e.what(), HasSubstr("move it aside"));
  }
}

TEST_F(StoreTest, AMissingDirectoryGivesAClearInputError) {
  EXPECT_THROW(Store(dir_ / "no-such-dir" / "sherdscan.db"), InputError);
}

TEST_F(StoreTest, ScanRoundTripsAndGetsAWellFormedUniqueId) {
  Store store(db_file());
  const nlohmann::json settings = {{"scan", {{"views", 12}}}, {"render", {{"dpi", 600}}}};
  const std::string id = store.create_scan("process", 12, settings, "/data/output");
  EXPECT_TRUE(std::regex_match(id, std::regex(R"(\d{8}-\d{6}-[0-9a-f]{4})"))) << id;

  const auto scan = store.scan(id);
  ASSERT_TRUE(scan.has_value());
  EXPECT_EQ(scan->id, id);
  EXPECT_EQ(scan->state, ScanState::Acquiring);
  EXPECT_EQ(scan->source, "process");
  EXPECT_EQ(scan->planned_views, 12);
  EXPECT_EQ(scan->settings, settings);
  EXPECT_EQ(scan->output_dir, "/data/output");
  EXPECT_EQ(scan->reason, "");
  // The id's date and time are the creation time: "YYYYMMDD-HHMMSS" vs "YYYY-MM-DDTHH:MM:SS".
  const std::string& at = scan->created_at;
  ASSERT_EQ(at.size(), 24u) << at;
  EXPECT_EQ(id.substr(0, 15), at.substr(0, 4) + at.substr(5, 2) + at.substr(8, 2) + "-" +
                                  at.substr(11, 2) + at.substr(14, 2) + at.substr(17, 2));

  store.set_scan_state(id, ScanState::Failed, "turntable stalled at move 3");
  EXPECT_EQ(store.scan(id)->state, ScanState::Failed);
  EXPECT_EQ(store.scan(id)->reason, "turntable stalled at move 3");

  EXPECT_FALSE(store.scan("20000101-000000-dead").has_value());
}

TEST_F(StoreTest, ManyScansInOneSecondGetDistinctIds) {
  Store store(db_file());
  std::set<std::string> ids;
  for (int i = 0; i < 100; ++i) ids.insert(store.create_scan("station", 8, nullptr, "out"));
  EXPECT_EQ(ids.size(), 100u);
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM scans"), 100);
}

TEST_F(StoreTest, ScansAreListedNewestFirstAndUnfinishedOnesAreFound) {
  Store store(db_file());
  const std::string a = store.create_scan("station", 8, nullptr, "out");
  const std::string b = store.create_scan("station", 8, nullptr, "out");
  const std::string c = store.create_scan("station", 8, nullptr, "out");
  const std::string d = store.create_scan("station", 8, nullptr, "out");
  const std::string e = store.create_scan("station", 8, nullptr, "out");
  store.set_scan_state(b, ScanState::Acquired);
  store.set_scan_state(c, ScanState::Processing);
  store.set_scan_state(d, ScanState::Done);
  store.set_scan_state(e, ScanState::Failed, "no sherds");

  const auto all = store.scans();
  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(all[0].id, e);
  EXPECT_EQ(all[4].id, a);
  EXPECT_EQ(store.scans(2).size(), 2u);

  std::vector<std::string> unfinished;
  for (const auto& scan : store.unfinished_scans()) unfinished.push_back(scan.id);
  EXPECT_EQ(unfinished, (std::vector<std::string>{a, b, c}));
}

TEST_F(StoreTest, SettingTheStateOfAnUnknownScanThrows) {
  Store store(db_file());
  EXPECT_THROW(store.set_scan_state("20000101-000000-dead", ScanState::Done), InputError);
}

TEST_F(StoreTest, ViewsRoundTripInIndexOrder) {
  Store store(db_file());
  const std::string id = store.create_scan("station", 3, nullptr, "out");
  for (int index : {2, 0, 1}) store.add_view(view(id, index));

  const auto views = store.views(id);
  ASSERT_EQ(views.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(views[i].scan_id, id);
    EXPECT_EQ(views[i].index, i);
    EXPECT_EQ(views[i].raw_path, "raw/view-" + std::to_string(i) + ".bin");
    EXPECT_DOUBLE_EQ(views[i].commanded_angle_deg, 45.0 * i);
    EXPECT_DOUBLE_EQ(views[i].measured_angle_deg, 45.0 * i + 0.1125);
    EXPECT_EQ(views[i].started_at, "2024-05-01T10:00:00.000Z");
    EXPECT_EQ(views[i].captured_at, "2024-05-01T10:00:01.500Z");
    EXPECT_EQ(views[i].valid_points, 123456 + i);
    EXPECT_TRUE(views[i].registration.is_null());
  }

  const nlohmann::json figures = {{"rmse_mm", 0.21}, {"correction_deg", 0.4}};
  store.set_view_registration(id, 1, figures);
  EXPECT_EQ(store.views(id)[1].registration, figures);
  EXPECT_TRUE(store.views(id)[0].registration.is_null());
  EXPECT_THROW(store.set_view_registration(id, 7, figures), InputError);
}

TEST_F(StoreTest, ForeignKeysAndUniquenessAreEnforced) {
  Store store(db_file());
  const std::string id = store.create_scan("station", 8, nullptr, "out");
  try {
    store.add_view(view("20000101-000000-dead", 0));
    FAIL() << "a view of an unknown scan was recorded";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("FOREIGN KEY"));
    EXPECT_THAT(e.what(), HasSubstr("20000101-000000-dead"));
  }
  store.add_view(view(id, 0));
  EXPECT_THROW(store.add_view(view(id, 0)), InputError);  // UNIQUE(scan_id, idx)
  EXPECT_THROW(store.add_sherd({"20000101-000000-dead", "s1", 10, nullptr}), InputError);
  EXPECT_THROW(store.add_measurement(id, "no-such-sherd", "rim_diameter_mm", 100.0, "mm"),
               InputError);
  EXPECT_THROW(store.add_artifact(id, "no-such-sherd", "plate", "p.png"), InputError);
  EXPECT_THROW(store.add_stage("20000101-000000-dead", "axis", 1.0, nullptr), InputError);
  EXPECT_THROW(store.add_event("2024-05-01T10:00:00.000Z", "20000101-000000-dead", "info", "x", "m"),
               InputError);
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM views"), 1);
}

TEST_F(StoreTest, ResultsRoundTripAndClearResultsRemovesOnlyThem) {
  Store store(db_file());
  const std::string id = store.create_scan("station", 8, nullptr, "out");
  const std::string other = store.create_scan("station", 8, nullptr, "out");
  store.add_view(view(id, 0));

  const nlohmann::json summary = {{"schema", "sherdscan.sherd/1"}, {"points", 5000}};
  store.add_sherd({id, "s02", 5000, summary});
  store.add_sherd({id, "s01", 4000, nullptr});
  store.add_sherd({other, "s01", 10, nullptr});
  store.add_measurement(id, "s01", "rim_diameter_mm", 182.5, "mm", 0.4);
  store.add_measurement(id, "s01", "rim_percent", std::nullopt, "%");
  store.add_measurement(other, "s01", "rim_percent", 12.0, "%");
  store.add_artifact(id, "", "scan", "out/scan.json");
  store.add_artifact(id, "s01", "plate", "out/s01/plate.png");
  store.add_artifact(id, "s02", "profile", "out/s02/profile.svg");
  store.add_stage(id, "registration", 812.5, {{"rmse_mm", 0.2}});
  store.add_stage(id, "segmentation", 95.0, nullptr);

  const auto sherds = store.sherds(id);
  ASSERT_EQ(sherds.size(), 2u);
  EXPECT_EQ(sherds[0].sherd_id, "s01");
  EXPECT_EQ(sherds[0].points, 4000);
  EXPECT_TRUE(sherds[0].summary.is_null());
  EXPECT_EQ(sherds[1].sherd_id, "s02");
  EXPECT_EQ(sherds[1].scan_id, id);
  EXPECT_EQ(sherds[1].summary, summary);

  using Artifacts = std::vector<std::pair<std::string, std::string>>;
  EXPECT_EQ(store.artifacts(id), (Artifacts{{"scan", "out/scan.json"},
                                            {"plate", "out/s01/plate.png"},
                                            {"profile", "out/s02/profile.svg"}}));

  const auto stages = store.stages(id);
  ASSERT_EQ(stages.size(), 2u);
  EXPECT_EQ(stages[0]["stage"], "registration");
  EXPECT_DOUBLE_EQ(stages[0]["duration_ms"].get<double>(), 812.5);
  EXPECT_EQ(stages[0]["figures"], (nlohmann::json{{"rmse_mm", 0.2}}));
  EXPECT_EQ(stages[1]["stage"], "segmentation");
  EXPECT_TRUE(stages[1]["figures"].is_null());

  // Measurements have no reader in the store's API: check the rows as written.
  const std::string where = "FROM measurements WHERE scan_id = '" + id + "' AND name = ";
  EXPECT_EQ(query_text(db_file(), "SELECT value " + where + "'rim_diameter_mm'"), "182.5");
  EXPECT_EQ(query_text(db_file(), "SELECT sd " + where + "'rim_diameter_mm'"), "0.4");
  EXPECT_EQ(query_int(db_file(), "SELECT value IS NULL AND sd IS NULL " + where + "'rim_percent'"),
            1);

  store.clear_results(id);
  EXPECT_TRUE(store.sherds(id).empty());
  EXPECT_TRUE(store.artifacts(id).empty());
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM measurements WHERE scan_id = '" + id + "'"),
            0);
  // Raw views, stage history and other scans stay.
  EXPECT_EQ(store.views(id).size(), 1u);
  EXPECT_EQ(store.stages(id).size(), 2u);
  EXPECT_EQ(store.sherds(other).size(), 1u);
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM measurements"), 1);

  // Re-processing can record the same sherd ids again.
  store.add_sherd({id, "s01", 4100, nullptr});
  EXPECT_EQ(store.sherds(id).at(0).points, 4100);
}

TEST_F(StoreTest, EventsRoundTripWithAndWithoutAScan) {
  Store store(db_file());
  const std::string id = store.create_scan("station", 8, nullptr, "out");
  store.add_event("2024-05-01T10:00:00.000Z", "", "info", "sherdd", "started");
  store.add_event("2024-05-01T10:00:01.000Z", id, "warning", "acquisition", "view 3: 12% dropouts");
  store.add_event("2024-05-01T10:00:02.000Z", id, "info", "acquisition", "done");
  EXPECT_EQ(store.event_count(id), 2);
  EXPECT_EQ(store.event_count(""), 1);
  EXPECT_EQ(query_int(db_file(), "SELECT count(*) FROM events WHERE scan_id IS NULL"), 1);
  EXPECT_EQ(query_text(db_file(), "SELECT message FROM events WHERE level = 'warning'"),
            "view 3: 12% dropouts");
  EXPECT_EQ(query_text(db_file(), "SELECT logger || '|' || time FROM events WHERE level = 'warning'"),
            "acquisition|2024-05-01T10:00:01.000Z");
}

TEST_F(StoreTest, ValuesAreBoundNotSplicedIntoSql) {
  Store store(db_file());
  const std::string hostile = "x'); DROP TABLE scans; --";
  const std::string id = store.create_scan(hostile, 1, nullptr, hostile);
  EXPECT_EQ(store.scan(id)->source, hostile);
  EXPECT_EQ(store.scan(id)->output_dir, hostile);
}

TEST_F(StoreTest, ConcurrentWritersFromManyThreadsLoseNothing) {
  Store store(db_file());
  const std::string id = store.create_scan("station", 8, nullptr, "out");
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&store, &id, t] {
      for (int i = 0; i < 25; ++i) {
        store.add_event("2024-05-01T10:00:00.000Z", id, "info", "t" + std::to_string(t), "line");
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(store.event_count(id), 100);
}

TEST(ScanState, NamesRoundTripAndUnknownNamesThrow) {
  EXPECT_STREQ(to_string(ScanState::Processing), "processing");
  EXPECT_EQ(scan_state_from_string("acquired"), ScanState::Acquired);
  EXPECT_THROW(scan_state_from_string("finished"), std::invalid_argument);
}

TEST(IsoTime, FormatsAKnownInstantInUtc) {
  // 2021-01-01T00:00:00Z is 1609459200 s after the epoch.
  const auto t = std::chrono::system_clock::time_point(std::chrono::milliseconds(1609459200123));
  EXPECT_EQ(to_iso_utc(t), "2021-01-01T00:00:00.123Z");
}

}  // namespace
}  // namespace sherd::db
