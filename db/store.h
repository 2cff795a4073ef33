// The station's SQLite store: scans, views, sherds, measurements, artifacts, stage timings,
// calibrations and log events. Versioned migrations (PRAGMA user_version), WAL, foreign keys,
// bound parameters only. Thread-safe: one connection behind a mutex. The store never logs (its
// log sink writes through it).
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

struct sqlite3;

namespace sherd::db {

// Life of a scan job. acquiring → acquired → processing → done | failed.
enum class ScanState { Acquiring, Acquired, Processing, Done, Failed };
const char* to_string(ScanState state);
ScanState scan_state_from_string(const std::string& text);  // throws std::invalid_argument

// The timestamp format of every *_at / time column: ISO 8601 UTC with milliseconds,
// "2024-05-01T12:34:56.789Z" (sorts as text in time order).
std::string to_iso_utc(std::chrono::system_clock::time_point time);

struct ScanRecord {
  std::string id;
  std::string created_at;  // ISO 8601 UTC
  std::string updated_at;
  ScanState state = ScanState::Acquiring;
  std::string reason;      // why it failed (empty otherwise)
  std::string source;      // "station" or "process"
  int planned_views = 0;
  nlohmann::json settings; // the configuration the scan ran with
  std::string output_dir;
};

struct ViewRecord {
  std::string scan_id;
  int index = 0;
  std::string raw_path;
  double commanded_angle_deg = 0.0;
  double measured_angle_deg = 0.0;  // encoder, after the move
  std::string started_at, captured_at;
  std::int64_t valid_points = 0;
  nlohmann::json registration;      // pose and figures, filled by processing (null before)
};

struct SherdRecord {
  std::string scan_id;
  std::string sherd_id;
  std::int64_t points = 0;
  nlohmann::json summary;  // the sherd.json document
};

// One calibration result (kind "turntable", …), as made by a calibration job.
struct CalibrationRecord {
  std::int64_t id = 0;
  std::string created_at;  // ISO 8601 UTC
  std::string kind;
  std::string scan_id;     // the calibration scan it was computed from ("" if none)
  nlohmann::json result;   // the result document (e.g. sherdscan.turntable_calibration/1)
};

class Store {
 public:
  // Opens (creating if needed) and migrates. Throws sherd::InputError naming the file.
  explicit Store(const std::filesystem::path& file);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  int schema_version() const;

  // Scans. `create_scan` makes a unique id "YYYYMMDD-HHMMSS-xxxx".
  std::string create_scan(const std::string& source, int planned_views,
                          const nlohmann::json& settings, const std::string& output_dir);
  void set_scan_state(const std::string& scan_id, ScanState state, const std::string& reason = "");
  std::optional<ScanRecord> scan(const std::string& scan_id) const;
  std::vector<ScanRecord> scans(int limit = 50) const;  // newest first
  std::vector<ScanRecord> unfinished_scans() const;     // acquiring | acquired | processing

  // Views: recorded right after the raw file is on disk.
  void add_view(const ViewRecord& view);
  std::vector<ViewRecord> views(const std::string& scan_id) const;  // ordered by index
  void set_view_registration(const std::string& scan_id, int index, const nlohmann::json& figures);

  // Results. Re-processing a scan replaces its sherds, measurements and artifacts.
  void clear_results(const std::string& scan_id);
  void add_sherd(const SherdRecord& sherd);
  std::vector<SherdRecord> sherds(const std::string& scan_id) const;
  void add_measurement(const std::string& scan_id, const std::string& sherd_id,
                       const std::string& name, std::optional<double> value,
                       const std::string& unit, std::optional<double> sd = std::nullopt);
  void add_artifact(const std::string& scan_id, const std::string& sherd_id,
                    const std::string& kind, const std::string& path);
  // A sherd id "" marks a scan-level record (e.g. scan.json). artifacts(): (kind, path) pairs in
  // the order they were added.
  std::vector<std::pair<std::string, std::string>> artifacts(const std::string& scan_id) const;

  // Stage timings and figures ("acquisition", "registration", "segmentation", "axis", …).
  void add_stage(const std::string& scan_id, const std::string& stage, double duration_ms,
                 const nlohmann::json& figures);
  nlohmann::json stages(const std::string& scan_id) const;  // array of {stage, duration_ms, figures}

  // Calibrations: every result is kept (history); the latest of a kind is the one in force.
  std::int64_t add_calibration(const std::string& kind, const std::string& scan_id,
                               const nlohmann::json& result);
  std::optional<CalibrationRecord> latest_calibration(const std::string& kind) const;

  // Log events (written by the spdlog sink).
  void add_event(const std::string& time, const std::string& scan_id, const std::string& level,
                 const std::string& logger, const std::string& message);
  std::int64_t event_count(const std::string& scan_id) const;  // "" counts lines outside scans

 private:
  mutable std::mutex mutex_;
  sqlite3* db_ = nullptr;
  std::filesystem::path file_;
};

}  // namespace sherd::db
