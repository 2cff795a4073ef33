#include "db/store.h"

#include "core/errors.h"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <sqlite3.h>

#include <chrono>
#include <ctime>
#include <random>
#include <stdexcept>
#include <string_view>
#include <utility>

namespace sherd::db {

namespace {

// The schema, one migration per version (index + 1 = the PRAGMA user_version it brings the
// database to). Never edit a shipped migration: append a new one.
//
// Text ids "" (no sherd, no scan) are stored as NULL so that the composite foreign keys below do
// not apply to them (SQLite's MATCH SIMPLE skips a key with a NULL column).
constexpr std::string_view kMigrations[] = {
    R"sql(
CREATE TABLE scans (
  id            TEXT PRIMARY KEY,
  created_at    TEXT NOT NULL,
  updated_at    TEXT NOT NULL,
  state         TEXT NOT NULL
                CHECK (state IN ('acquiring', 'acquired', 'processing', 'done', 'failed')),
  reason        TEXT NOT NULL DEFAULT '',
  source        TEXT NOT NULL,
  planned_views INTEGER NOT NULL,
  settings      TEXT,
  output_dir    TEXT NOT NULL
);
CREATE INDEX scans_by_state ON scans(state);

CREATE TABLE views (
  scan_id             TEXT NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  idx                 INTEGER NOT NULL,
  raw_path            TEXT NOT NULL,
  commanded_angle_deg REAL NOT NULL,
  measured_angle_deg  REAL NOT NULL,
  started_at          TEXT NOT NULL,
  captured_at         TEXT NOT NULL,
  valid_points        INTEGER NOT NULL,
  registration        TEXT,
  UNIQUE (scan_id, idx)
);

CREATE TABLE sherds (
  scan_id  TEXT NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  sherd_id TEXT NOT NULL,
  points   INTEGER NOT NULL,
  summary  TEXT,
  PRIMARY KEY (scan_id, sherd_id)
);

CREATE TABLE measurements (
  id       INTEGER PRIMARY KEY,
  scan_id  TEXT NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  sherd_id TEXT,
  name     TEXT NOT NULL,
  value    REAL,
  unit     TEXT NOT NULL,
  sd       REAL,
  FOREIGN KEY (scan_id, sherd_id) REFERENCES sherds(scan_id, sherd_id) ON DELETE CASCADE
);
CREATE INDEX measurements_by_sherd ON measurements(scan_id, sherd_id);

CREATE TABLE artifacts (
  id       INTEGER PRIMARY KEY,
  scan_id  TEXT NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  sherd_id TEXT,
  kind     TEXT NOT NULL,
  path     TEXT NOT NULL,
  FOREIGN KEY (scan_id, sherd_id) REFERENCES sherds(scan_id, sherd_id) ON DELETE CASCADE
);
CREATE INDEX artifacts_by_scan ON artifacts(scan_id);

CREATE TABLE stages (
  id          INTEGER PRIMARY KEY,
  scan_id     TEXT NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  stage       TEXT NOT NULL,
  duration_ms REAL NOT NULL,
  figures     TEXT,
  recorded_at TEXT NOT NULL
);
CREATE INDEX stages_by_scan ON stages(scan_id);

CREATE TABLE events (
  id      INTEGER PRIMARY KEY,
  scan_id TEXT REFERENCES scans(id) ON DELETE CASCADE,
  time    TEXT NOT NULL,
  level   TEXT NOT NULL,
  logger  TEXT NOT NULL,
  message TEXT NOT NULL
);
CREATE INDEX events_by_scan ON events(scan_id);
)sql",
    // 2: calibration results (the turntable axis, later the scanner's intrinsics), newest last.
    R"sql(
CREATE TABLE calibrations (
  id         INTEGER PRIMARY KEY,
  created_at TEXT NOT NULL,
  kind       TEXT NOT NULL,
  scan_id    TEXT REFERENCES scans(id) ON DELETE SET NULL,
  result     TEXT NOT NULL
);
CREATE INDEX calibrations_by_kind ON calibrations(kind, id);
)sql",
};
constexpr int kSchemaVersion = static_cast<int>(std::size(kMigrations));

constexpr int kBusyTimeoutMs = 5000;

std::string utc_now_iso() { return to_iso_utc(std::chrono::system_clock::now()); }

// Builds the one-line error every failure of the store reports: which database, what it was
// doing, what SQLite said, and what to do about it.
[[noreturn]] void fail(const std::filesystem::path& file, std::string_view doing, int code,
                       std::string_view sqlite_message) {
  std::string_view hint;
  switch (code & 0xff) {
    case SQLITE_CONSTRAINT:
      hint = "the scan or sherd it refers to must exist, and the record must not exist yet";
      break;
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      hint = "another process holds the database locked; stop it or retry";
      break;
    case SQLITE_NOTADB:
    case SQLITE_CORRUPT:
      hint = "the file is not a sherdscan database (or is damaged): move it aside to start a "
             "new one";
      break;
    case SQLITE_READONLY:
    case SQLITE_CANTOPEN:
    case SQLITE_PERM:
      hint = "check that the directory exists and is writable by this user";
      break;
    case SQLITE_FULL:
      hint = "the disk is full: free some space";
      break;
    default:
      hint = "check the file, its permissions and the free disk space";
  }
  throw InputError(
      fmt::format("{}: cannot {}: {} — {}", file.string(), doing, sqlite_message, hint));
}

// A prepared statement that finalises itself. Values are only ever bound, never spliced into the
// SQL text.
class Statement {
 public:
  Statement(sqlite3* db, const std::filesystem::path& file, std::string_view sql,
            std::string doing)
      : db_(db), file_(file), doing_(std::move(doing)) {
    const int rc = sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr);
    if (rc != SQLITE_OK) fail(file_, doing_, rc, sqlite3_errmsg(db_));
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  // Binds the arguments to ?1, ?2, … in order.
  template <class... Values>
  Statement& bind(const Values&... values) {
    int index = 0;
    (bind_one(++index, values), ...);
    return *this;
  }

  // Steps once; true while a row is available.
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    fail(file_, doing_, rc, sqlite3_errmsg(db_));
  }
  // Runs a statement that returns no rows; returns the number of rows it changed.
  int run() {
    while (step()) {
    }
    return sqlite3_changes(db_);
  }

  std::string text(int column) const {
    const auto* chars = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, column));
    return chars ? std::string(chars, sqlite3_column_bytes(stmt_, column)) : std::string();
  }
  double real(int column) const { return sqlite3_column_double(stmt_, column); }
  std::int64_t integer(int column) const { return sqlite3_column_int64(stmt_, column); }
  std::optional<double> optional_real(int column) const {
    if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return std::nullopt;
    return real(column);
  }
  nlohmann::json json(int column) const {
    if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return nullptr;
    return nlohmann::json::parse(text(column));
  }

 private:
  void check(int rc) {
    if (rc != SQLITE_OK) fail(file_, doing_, rc, sqlite3_errmsg(db_));
  }
  void bind_one(int i, std::nullptr_t) { check(sqlite3_bind_null(stmt_, i)); }
  void bind_one(int i, const std::string& v) {
    check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
  }
  void bind_one(int i, const char* v) { bind_one(i, std::string(v)); }
  void bind_one(int i, double v) { check(sqlite3_bind_double(stmt_, i, v)); }
  void bind_one(int i, int v) { check(sqlite3_bind_int64(stmt_, i, v)); }
  void bind_one(int i, std::int64_t v) { check(sqlite3_bind_int64(stmt_, i, v)); }
  template <class T>
  void bind_one(int i, const std::optional<T>& v) {
    v ? bind_one(i, *v) : bind_one(i, nullptr);
  }
  // JSON is stored as its text; a null document as SQL NULL (e.g. a view not registered yet).
  void bind_one(int i, const nlohmann::json& v) {
    v.is_null() ? bind_one(i, nullptr) : bind_one(i, v.dump());
  }

  sqlite3* db_;
  const std::filesystem::path& file_;
  std::string doing_;
  sqlite3_stmt* stmt_ = nullptr;
};

// "" means "none" for the optional scan/sherd columns (see the schema).
std::optional<std::string> none_if_empty(const std::string& id) {
  return id.empty() ? std::nullopt : std::optional<std::string>(id);
}

void exec(sqlite3* db, const std::filesystem::path& file, std::string_view sql,
          std::string_view doing) {
  char* message = nullptr;
  const int rc = sqlite3_exec(db, std::string(sql).c_str(), nullptr, nullptr, &message);
  if (rc != SQLITE_OK) {
    const std::string text = message ? message : sqlite3_errstr(rc);
    sqlite3_free(message);
    fail(file, doing, rc, text);
  }
}

constexpr std::string_view kScanColumns =
    "id, created_at, updated_at, state, reason, source, planned_views, settings, output_dir";

ScanRecord read_scan(const Statement& row) {
  ScanRecord scan;
  scan.id = row.text(0);
  scan.created_at = row.text(1);
  scan.updated_at = row.text(2);
  scan.state = scan_state_from_string(row.text(3));
  scan.reason = row.text(4);
  scan.source = row.text(5);
  scan.planned_views = static_cast<int>(row.integer(6));
  scan.settings = row.json(7);
  scan.output_dir = row.text(8);
  return scan;
}

}  // namespace

std::string to_iso_utc(std::chrono::system_clock::time_point time) {
  using namespace std::chrono;
  const auto ms = duration_cast<milliseconds>(time.time_since_epoch()).count() % 1000;
  return fmt::format("{:%Y-%m-%dT%H:%M:%S}.{:03d}Z", fmt::gmtime(system_clock::to_time_t(time)),
                     ms);
}

const char* to_string(ScanState state) {
  switch (state) {
    case ScanState::Acquiring: return "acquiring";
    case ScanState::Acquired: return "acquired";
    case ScanState::Processing: return "processing";
    case ScanState::Done: return "done";
    case ScanState::Failed: return "failed";
  }
  throw std::invalid_argument("unknown ScanState");
}

ScanState scan_state_from_string(const std::string& text) {
  for (auto state : {ScanState::Acquiring, ScanState::Acquired, ScanState::Processing,
                     ScanState::Done, ScanState::Failed}) {
    if (text == to_string(state)) return state;
  }
  throw std::invalid_argument(fmt::format(
      "unknown scan state \"{}\" (expected acquiring, acquired, processing, done or failed)", text));
}

Store::Store(const std::filesystem::path& file) : file_(file) {
  const int rc = sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE |
                                                         SQLITE_OPEN_FULLMUTEX,
                                 nullptr);
  if (rc != SQLITE_OK) {
    const std::string message = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close(db_);
    db_ = nullptr;
    fail(file_, "open the database", rc, message);
  }
  try {
    sqlite3_extended_result_codes(db_, 1);
    sqlite3_busy_timeout(db_, kBusyTimeoutMs);
    // The first statement reads the header: a file that is not a database fails here.
    const int version = schema_version();
    if (version > kSchemaVersion) {
      throw InputError(fmt::format(
          "{}: database schema version {} is newer than this sherdscan knows ({}) — use a newer "
          "sherdscan, or point data_dir at another directory",
          file_.string(), version, kSchemaVersion));
    }
    // WAL: readers (sherdctl) never block the daemon's writes. Set outside any transaction.
    exec(db_, file_, "PRAGMA journal_mode=WAL; PRAGMA foreign_keys=ON;",
         "set up the database connection");
    for (int v = version; v < kSchemaVersion; ++v) {
      // Each migration and its version bump commit together or not at all.
      exec(db_, file_, "BEGIN IMMEDIATE", "start a schema migration");
      try {
        exec(db_, file_, kMigrations[v], fmt::format("migrate the schema to version {}", v + 1));
        exec(db_, file_, fmt::format("PRAGMA user_version = {}", v + 1),
             "record the schema version");
        exec(db_, file_, "COMMIT", "commit a schema migration");
      } catch (...) {
        sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
        throw;
      }
    }
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

Store::~Store() { sqlite3_close(db_); }

int Store::schema_version() const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, "PRAGMA user_version", "read the schema version");
  stmt.step();
  return static_cast<int>(stmt.integer(0));
}

std::string Store::create_scan(const std::string& source, int planned_views,
                               const nlohmann::json& settings, const std::string& output_dir) {
  std::lock_guard lock(mutex_);
  thread_local std::mt19937 rng{std::random_device{}()};
  const auto time = std::chrono::system_clock::now();
  const std::string now = to_iso_utc(time);
  const std::string stamp =
      fmt::format("{:%Y%m%d-%H%M%S}", fmt::gmtime(std::chrono::system_clock::to_time_t(time)));
  // Two scans in the same second differ by their random suffix; retry on the rare collision.
  for (int attempt = 0; attempt < 64; ++attempt) {
    const std::string id = fmt::format("{}-{:04x}", stamp, rng() & 0xffffu);
    Statement stmt(db_, file_,
                   "INSERT OR IGNORE INTO scans (id, created_at, updated_at, state, source, "
                   "planned_views, settings, output_dir) VALUES (?1, ?2, ?2, ?3, ?4, ?5, ?6, ?7)",
                   "create a scan");
    stmt.bind(id, now, to_string(ScanState::Acquiring), source, planned_views, settings,
              output_dir);
    if (stmt.run() == 1) return id;
  }
  throw InputError(fmt::format("{}: cannot create a scan: no free scan id in this second — retry",
                               file_.string()));
}

void Store::set_scan_state(const std::string& scan_id, ScanState state, const std::string& reason) {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, "UPDATE scans SET state = ?2, reason = ?3, updated_at = ?4 WHERE id = ?1",
                 fmt::format("set the state of scan {}", scan_id));
  if (stmt.bind(scan_id, to_string(state), reason, utc_now_iso()).run() == 0) {
    throw InputError(fmt::format("{}: unknown scan id \"{}\" — list the scans with `sherdctl jobs`",
                                 file_.string(), scan_id));
  }
}

std::optional<ScanRecord> Store::scan(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, fmt::format("SELECT {} FROM scans WHERE id = ?1", kScanColumns),
                 fmt::format("read scan {}", scan_id));
  stmt.bind(scan_id);
  if (!stmt.step()) return std::nullopt;
  return read_scan(stmt);
}

std::vector<ScanRecord> Store::scans(int limit) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 fmt::format("SELECT {} FROM scans ORDER BY created_at DESC, rowid DESC LIMIT ?1",
                             kScanColumns),
                 "list the scans");
  stmt.bind(limit);
  std::vector<ScanRecord> result;
  while (stmt.step()) result.push_back(read_scan(stmt));
  return result;
}

std::vector<ScanRecord> Store::unfinished_scans() const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 fmt::format("SELECT {} FROM scans WHERE state IN (?1, ?2, ?3) "
                             "ORDER BY created_at, rowid",
                             kScanColumns),
                 "list the unfinished scans");
  stmt.bind(to_string(ScanState::Acquiring), to_string(ScanState::Acquired),
            to_string(ScanState::Processing));
  std::vector<ScanRecord> result;
  while (stmt.step()) result.push_back(read_scan(stmt));
  return result;
}

void Store::add_view(const ViewRecord& view) {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 "INSERT INTO views (scan_id, idx, raw_path, commanded_angle_deg, "
                 "measured_angle_deg, started_at, captured_at, valid_points, registration) "
                 "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
                 fmt::format("record view {} of scan {}", view.index, view.scan_id));
  stmt.bind(view.scan_id, view.index, view.raw_path, view.commanded_angle_deg,
            view.measured_angle_deg, view.started_at, view.captured_at, view.valid_points,
            view.registration)
      .run();
}

std::vector<ViewRecord> Store::views(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 "SELECT scan_id, idx, raw_path, commanded_angle_deg, measured_angle_deg, "
                 "started_at, captured_at, valid_points, registration FROM views "
                 "WHERE scan_id = ?1 ORDER BY idx",
                 fmt::format("read the views of scan {}", scan_id));
  stmt.bind(scan_id);
  std::vector<ViewRecord> result;
  while (stmt.step()) {
    ViewRecord view;
    view.scan_id = stmt.text(0);
    view.index = static_cast<int>(stmt.integer(1));
    view.raw_path = stmt.text(2);
    view.commanded_angle_deg = stmt.real(3);
    view.measured_angle_deg = stmt.real(4);
    view.started_at = stmt.text(5);
    view.captured_at = stmt.text(6);
    view.valid_points = stmt.integer(7);
    view.registration = stmt.json(8);
    result.push_back(std::move(view));
  }
  return result;
}

void Store::set_view_registration(const std::string& scan_id, int index,
                                  const nlohmann::json& figures) {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, "UPDATE views SET registration = ?3 WHERE scan_id = ?1 AND idx = ?2",
                 fmt::format("record the registration of view {} of scan {}", index, scan_id));
  if (stmt.bind(scan_id, index, figures).run() == 0) {
    throw InputError(fmt::format("{}: scan \"{}\" has no view {} — record the view first",
                                 file_.string(), scan_id, index));
  }
}

void Store::clear_results(const std::string& scan_id) {
  std::lock_guard lock(mutex_);
  // Measurements and per-sherd artifacts go with their sherds (ON DELETE CASCADE); scan-level
  // ones are deleted explicitly. One transaction: a reader never sees half-cleared results.
  exec(db_, file_, "BEGIN IMMEDIATE", "start clearing results");
  try {
    for (std::string_view sql : {"DELETE FROM measurements WHERE scan_id = ?1",
                                 "DELETE FROM artifacts WHERE scan_id = ?1",
                                 "DELETE FROM sherds WHERE scan_id = ?1"}) {
      Statement(db_, file_, sql, fmt::format("clear the results of scan {}", scan_id))
          .bind(scan_id)
          .run();
    }
    exec(db_, file_, "COMMIT", "commit clearing results");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void Store::add_sherd(const SherdRecord& sherd) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_, "INSERT INTO sherds (scan_id, sherd_id, points, summary) VALUES (?1, ?2, ?3, ?4)",
            fmt::format("record sherd {} of scan {}", sherd.sherd_id, sherd.scan_id))
      .bind(sherd.scan_id, sherd.sherd_id, sherd.points, sherd.summary)
      .run();
}

std::vector<SherdRecord> Store::sherds(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 "SELECT scan_id, sherd_id, points, summary FROM sherds WHERE scan_id = ?1 "
                 "ORDER BY sherd_id",
                 fmt::format("read the sherds of scan {}", scan_id));
  stmt.bind(scan_id);
  std::vector<SherdRecord> result;
  while (stmt.step()) {
    result.push_back({stmt.text(0), stmt.text(1), stmt.integer(2), stmt.json(3)});
  }
  return result;
}

void Store::add_measurement(const std::string& scan_id, const std::string& sherd_id,
                            const std::string& name, std::optional<double> value,
                            const std::string& unit, std::optional<double> sd) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_,
            "INSERT INTO measurements (scan_id, sherd_id, name, value, unit, sd) "
            "VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            fmt::format("record measurement {} of sherd {} of scan {}", name, sherd_id, scan_id))
      .bind(scan_id, none_if_empty(sherd_id), name, value, unit, sd)
      .run();
}

void Store::add_artifact(const std::string& scan_id, const std::string& sherd_id,
                         const std::string& kind, const std::string& path) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_,
            "INSERT INTO artifacts (scan_id, sherd_id, kind, path) VALUES (?1, ?2, ?3, ?4)",
            fmt::format("record artifact {} of scan {}", path, scan_id))
      .bind(scan_id, none_if_empty(sherd_id), kind, path)
      .run();
}

std::vector<std::pair<std::string, std::string>> Store::artifacts(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, "SELECT kind, path FROM artifacts WHERE scan_id = ?1 ORDER BY id",
                 fmt::format("read the artifacts of scan {}", scan_id));
  stmt.bind(scan_id);
  std::vector<std::pair<std::string, std::string>> result;
  while (stmt.step()) result.emplace_back(stmt.text(0), stmt.text(1));
  return result;
}

void Store::add_stage(const std::string& scan_id, const std::string& stage, double duration_ms,
                      const nlohmann::json& figures) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_,
            "INSERT INTO stages (scan_id, stage, duration_ms, figures, recorded_at) "
            "VALUES (?1, ?2, ?3, ?4, ?5)",
            fmt::format("record stage {} of scan {}", stage, scan_id))
      .bind(scan_id, stage, duration_ms, figures, utc_now_iso())
      .run();
}

nlohmann::json Store::stages(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 "SELECT stage, duration_ms, figures FROM stages WHERE scan_id = ?1 ORDER BY id",
                 fmt::format("read the stages of scan {}", scan_id));
  stmt.bind(scan_id);
  auto result = nlohmann::json::array();
  while (stmt.step()) {
    result.push_back(
        {{"stage", stmt.text(0)}, {"duration_ms", stmt.real(1)}, {"figures", stmt.json(2)}});
  }
  return result;
}

void Store::add_event(const std::string& time, const std::string& scan_id, const std::string& level,
                      const std::string& logger, const std::string& message) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_,
            "INSERT INTO events (scan_id, time, level, logger, message) VALUES (?1, ?2, ?3, ?4, ?5)",
            "record a log event")
      .bind(none_if_empty(scan_id), time, level, logger, message)
      .run();
}

std::int64_t Store::event_count(const std::string& scan_id) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_, "SELECT count(*) FROM events WHERE scan_id IS ?1",
                 "count log events");
  stmt.bind(none_if_empty(scan_id));
  stmt.step();
  return stmt.integer(0);
}

std::int64_t Store::add_calibration(const std::string& kind, const std::string& scan_id,
                                    const nlohmann::json& result) {
  std::lock_guard lock(mutex_);
  Statement(db_, file_,
            "INSERT INTO calibrations (created_at, kind, scan_id, result) VALUES (?1, ?2, ?3, ?4)",
            fmt::format("record a {} calibration", kind))
      .bind(utc_now_iso(), kind, none_if_empty(scan_id), result)
      .run();
  return sqlite3_last_insert_rowid(db_);
}

std::optional<CalibrationRecord> Store::latest_calibration(const std::string& kind) const {
  std::lock_guard lock(mutex_);
  Statement stmt(db_, file_,
                 "SELECT id, created_at, kind, scan_id, result FROM calibrations WHERE kind = ?1 "
                 "ORDER BY id DESC LIMIT 1",
                 fmt::format("read the latest {} calibration", kind));
  stmt.bind(kind);
  if (!stmt.step()) return std::nullopt;
  return CalibrationRecord{stmt.integer(0), stmt.text(1), stmt.text(2), stmt.text(3), stmt.json(4)};
}

}  // namespace sherd::db
