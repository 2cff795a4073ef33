#include "daemon/jobs.h"

#include "core/errors.h"
#include "daemon/pipeline.h"
#include "db/event_sink.h"
#include "processing/io/model_io.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <optional>
#include <set>

namespace sherd::station {
namespace {

std::string utc_now() {
  const auto now = std::chrono::system_clock::now();
  const auto t = std::chrono::system_clock::to_time_t(now);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", tm.tm_year + 1900, tm.tm_mon + 1,
                     tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
}

constexpr double kDeg = M_PI / 180.0;

// The calibration object lies on the plate for a calibration scan only: put on at construction,
// taken off at destruction (also when the scan fails).
class CalibrationObjectOnPlate {
 public:
  explicit CalibrationObjectOnPlate(const std::function<void(bool)>& place) : place_(place) {
    if (place_) place_(true);
  }
  ~CalibrationObjectOnPlate() {
    try {
      if (place_) place_(false);
    } catch (const std::exception& e) {
      spdlog::error("taking the calibration object off the plate: {}", e.what());
    }
  }
  CalibrationObjectOnPlate(const CalibrationObjectOnPlate&) = delete;
  CalibrationObjectOnPlate& operator=(const CalibrationObjectOnPlate&) = delete;

 private:
  const std::function<void(bool)>& place_;
};

}  // namespace

void Subscription::push(const nlohmann::json& event) {
  {
    std::lock_guard lock(mutex_);
    events_.push_back(event);
  }
  ready_.notify_all();
}

std::optional<nlohmann::json> Subscription::next() {
  std::unique_lock lock(mutex_);
  ready_.wait(lock, [&] { return !events_.empty() || closed_; });
  if (events_.empty()) return std::nullopt;
  auto event = std::move(events_.front());
  events_.pop_front();
  return event;
}

void Subscription::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

JobRunner::JobRunner(const config::StationConfig& config, std::shared_ptr<db::Store> store, Station station)
    : config_(config), store_(std::move(store)), station_(std::move(station)) {}

JobRunner::~JobRunner() { stop(); }

void JobRunner::start() {
  if (station_.turntable_calibration) {
    spdlog::info("turntable calibration in force from {}", config_.calibration.turntable_file.string());
  } else {
    spdlog::warn("{}", station_.calibration_note);
  }
  for (const auto& scan : store_->unfinished_scans()) {
    if (scan.source == "calibration") {
      // A calibration is quick to repeat and its object may have been taken off: not resumed.
      store_->set_scan_state(scan.id, db::ScanState::Failed,
                             fmt::format("interrupted by a restart of sherdd: run `sherdctl calibrate turntable` "
                                         "again ({})", calibration_in_force()));
      continue;
    }
    std::lock_guard lock(mutex_);
    if (scan.source != "station") continue;
    if (scan.state == db::ScanState::Acquiring) {
      spdlog::info("resuming scan {}: acquisition ({} of {} views on disk)", scan.id,
                   store_->views(scan.id).size(), scan.planned_views);
      to_acquire_.push_back(scan.id);
    } else {
      spdlog::info("resuming scan {}: processing from its raw views", scan.id);
      to_process_.push_back(scan.id);
    }
  }
  acquisition_thread_ = std::thread([this] { worker_loop(to_acquire_, acquiring_, &JobRunner::acquire); });
  processing_thread_ = std::thread([this] { worker_loop(to_process_, processing_, &JobRunner::process); });
}

void JobRunner::stop() {
  if (stopping_.exchange(true)) {
    if (acquisition_thread_.joinable()) acquisition_thread_.join();
    if (processing_thread_.joinable()) processing_thread_.join();
    return;
  }
  work_.notify_all();
  if (acquisition_thread_.joinable()) acquisition_thread_.join();
  if (processing_thread_.joinable()) processing_thread_.join();
  std::lock_guard lock(mutex_);
  for (auto& [id, weak] : subscribers_) {
    if (auto sub = weak.lock()) sub->close();
  }
  subscribers_.clear();
}

std::pair<std::string, std::shared_ptr<Subscription>> JobRunner::submit(const std::string& source, int views,
                                                                        const nlohmann::json& settings) {
  if (stopping_) throw InputError("sherdd is shutting down: no new jobs; start it again and retry");
  const auto scan_id = store_->create_scan(source, views, settings, config_.paths.output_dir.string());
  auto subscription = std::make_shared<Subscription>();
  {
    std::lock_guard lock(mutex_);
    subscribers_.emplace(scan_id, subscription);
    to_acquire_.push_back(scan_id);
  }
  work_.notify_all();
  spdlog::info("{} {} queued ({} views)", source == "calibration" ? "calibration" : "scan", scan_id, views);
  return {scan_id, subscription};
}

std::pair<std::string, std::shared_ptr<Subscription>> JobRunner::submit_scan(const MaterialChoice& materials) {
  check_materials(materials, config_.render);
  return submit("station", config_.scan.views,
                {{"views", config_.scan.views},
                 {"start_angle_deg", config_.scan.start_angle_deg},
                 {"dpi", config_.render.dpi},
                 {"material", materials.scan.empty() ? config_.render.material : materials.scan},
                 {"sherd_materials", materials.per_sherd},
                 {"config", config_.source.string()}});
}

std::pair<std::string, std::shared_ptr<Subscription>> JobRunner::submit_turntable_calibration() {
  return submit("calibration", config_.calibration.views,
                {{"kind", "turntable"},
                 {"views", config_.calibration.views},
                 {"start_angle_deg", 0.0},
                 {"turntable_file", config_.calibration.turntable_file.string()},
                 {"config", config_.source.string()}});
}

std::shared_ptr<Subscription> JobRunner::subscribe(const std::string& scan_id) {
  auto subscription = std::make_shared<Subscription>();
  std::lock_guard lock(mutex_);
  subscribers_.emplace(scan_id, subscription);
  return subscription;
}

void JobRunner::publish(const std::string& scan_id, nlohmann::json event) {
  event["scan_id"] = scan_id;
  const bool final_event = event.value("event", "") == "finished";
  std::lock_guard lock(mutex_);
  auto [first, last] = subscribers_.equal_range(scan_id);
  for (auto it = first; it != last;) {
    if (auto sub = it->second.lock()) {
      sub->push(event);
      if (final_event) sub->close();
      ++it;
    } else {
      it = subscribers_.erase(it);
    }
  }
  if (final_event) subscribers_.erase(scan_id);
}

nlohmann::json JobRunner::status() const {
  nlohmann::json turntable = {{"device", station_.turntable->describe()},
                              {"state", drivers::to_string(station_.turntable->state())}};
  try {
    turntable["position_deg"] = station_.turntable->position() / kDeg;
  } catch (const std::exception& e) {
    turntable["position_deg"] = nullptr;
    turntable["error"] = e.what();
  }
  std::lock_guard lock(mutex_);
  nlohmann::json calibration = {{"calibrated", station_.turntable_calibration.has_value()},
                                {"file", config_.calibration.turntable_file.string()}};
  if (station_.turntable_calibration) {
    calibration.update(calibration::to_json(*station_.turntable_calibration));
  } else {
    calibration["note"] = station_.calibration_note;
  }
  const auto& prior = station_.prior_uncertainty;
  calibration["prior_uncertainty"] = {{"angle_sd_deg", prior.angle_sd_deg},
                                      {"tilt_sd_deg", prior.tilt_sd_deg},
                                      {"translation_sd_mm", prior.translation_sd_mm}};
  return {{"station", config_.name},
          {"turntable_calibration", calibration},
          {"scanner", station_.scanner->describe()},
          {"turntable", turntable},
          {"acquiring", acquiring_.empty() ? nlohmann::json(nullptr) : nlohmann::json(acquiring_)},
          {"processing", processing_.empty() ? nlohmann::json(nullptr) : nlohmann::json(processing_)},
          {"queued_acquisitions", to_acquire_.size()},
          {"queued_processing", to_process_.size()},
          {"output_dir", config_.paths.output_dir.string()},
          {"database", config_.paths.database.string()}};
}

void JobRunner::worker_loop(std::deque<std::string>& queue, std::string& in_hand,
                            void (JobRunner::*work)(const std::string&)) {
  while (true) {
    std::string scan_id;
    {
      std::unique_lock lock(mutex_);
      work_.wait(lock, [&] { return stopping_ || !queue.empty(); });
      if (stopping_) return;
      scan_id = queue.front();
      queue.pop_front();
      in_hand = scan_id;
    }
    (this->*work)(scan_id);
    std::lock_guard lock(mutex_);
    in_hand.clear();
  }
}

void JobRunner::fail(const std::string& scan_id, const std::string& reason) {
  spdlog::error("scan {} failed: {}", scan_id, reason);
  store_->set_scan_state(scan_id, db::ScanState::Failed, reason);
  publish(scan_id, {{"event", "finished"}, {"state", "failed"}, {"reason", reason}});
}

void JobRunner::acquire(const std::string& scan_id) {
  db::ScanLogScope log_scope(scan_id);
  const auto start = std::chrono::steady_clock::now();
  try {
    const auto scan = store_->scan(scan_id);
    if (!scan) throw InputError(fmt::format("scan {} vanished from the database", scan_id));
    std::set<int> on_disk;
    for (const auto& v : store_->views(scan_id)) on_disk.insert(v.index);
    const bool calibration = scan->source == "calibration";
    std::optional<CalibrationObjectOnPlate> object_on_plate;
    if (calibration) object_on_plate.emplace(station_.place_calibration_object);
    const int planned = scan->planned_views;
    const double start_deg = scan->settings.value("start_angle_deg", 0.0);
    const auto raw_dir = config_.paths.raw_dir / scan_id;
    std::filesystem::create_directories(raw_dir);

    if (static_cast<int>(on_disk.size()) < planned) {
      publish(scan_id, {{"event", "stage"}, {"stage", "acquisition"}, {"state", "started"},
                        {"views", planned}, {"on_disk", on_disk.size()}});
      // Homing gives the encoder its zero; after a restart the plate may stand anywhere.
      station_.turntable->home();
    }
    for (int index = 0; index < planned; ++index) {
      if (on_disk.count(index)) continue;
      if (stopping_) {
        spdlog::info("stopping: scan {} keeps its {} views and resumes at the next start", scan_id,
                     store_->views(scan_id).size());
        return;
      }
      const double commanded_deg = start_deg + 360.0 * index / planned;
      db::ViewRecord record;
      record.scan_id = scan_id;
      record.index = index;
      record.commanded_angle_deg = commanded_deg;
      record.started_at = utc_now();
      record.measured_angle_deg = station_.turntable->move_to(commanded_deg * kDeg) / kDeg;
      const auto view = station_.scanner->capture();
      record.captured_at = utc_now();
      record.valid_points = static_cast<std::int64_t>(view.valid_count());
      const auto raw = raw_dir / fmt::format("view_{:03}.pcd", index);
      io::write_view(raw, view);  // on disk before it is recorded: the record never points at nothing
      record.raw_path = raw.string();
      store_->add_view(record);
      spdlog::info("view {}/{} at {:.3f}° ({} points) → {}", index + 1, planned,
                   record.measured_angle_deg, record.valid_points, raw.string());
      publish(scan_id, {{"event", "view"}, {"index", index}, {"views", planned},
                        {"angle_deg", record.measured_angle_deg}, {"points", record.valid_points}});
    }
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    store_->add_stage(scan_id, "acquisition", ms, {{"views", planned}, {"resumed_with", on_disk.size()}});
    store_->set_scan_state(scan_id, db::ScanState::Acquired);
    if (calibration) {
      object_on_plate.reset();
      calibrate_turntable(scan_id);
      return;
    }
    {
      std::lock_guard lock(mutex_);
      to_process_.push_back(scan_id);
    }
    work_.notify_all();
  } catch (const std::exception& e) {
    const bool calibration = store_->scan(scan_id).value_or(db::ScanRecord{}).source == "calibration";
    fail(scan_id, fmt::format("acquisition: {} (views already captured are kept in {}{}{})", e.what(),
                              (config_.paths.raw_dir / scan_id).string(), calibration ? "; " : "",
                              calibration ? calibration_in_force() : ""));
  }
}

std::string JobRunner::calibration_in_force() const {
  std::lock_guard lock(mutex_);
  return station_.turntable_calibration ? "the previous calibration stays in force"
                                        : "the station stays uncalibrated";
}

void JobRunner::calibrate_turntable(const std::string& scan_id) {
  const auto start = std::chrono::steady_clock::now();
  try {
    store_->set_scan_state(scan_id, db::ScanState::Processing);
    publish(scan_id, {{"event", "stage"}, {"stage", "calibration"}, {"state", "started"}});
    // From the raw files, like a scan's processing: what is computed is what is kept.
    const auto records = store_->views(scan_id);
    std::vector<OrganisedView> captured;
    captured.reserve(records.size());
    for (const auto& record : records) captured.push_back(io::read_view(record.raw_path));
    std::vector<calibration::CalibrationView> views;
    for (std::size_t i = 0; i < records.size(); ++i) {
      views.push_back({&captured[i], records[i].measured_angle_deg * kDeg});
    }
    const auto result = calibration::estimate_turntable_axis(views);

    const auto& file = config_.calibration.turntable_file;
    const nlohmann::json provenance = {{"created_at", utc_now()}, {"scan_id", scan_id},
                                       {"raw_dir", (config_.paths.raw_dir / scan_id).string()}};
    calibration::write_turntable_calibration(file, result, provenance);
    nlohmann::json document = calibration::to_json(result);
    document.update(provenance);
    document["file"] = file.string();
    store_->add_calibration("turntable", scan_id, document);
    {
      std::lock_guard lock(mutex_);
      apply_turntable_calibration(station_, result, config_);
    }
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    store_->add_stage(scan_id, "calibration", ms, document);
    store_->set_scan_state(scan_id, db::ScanState::Done);
    publish(scan_id, {{"event", "stage"}, {"stage", "calibration"}, {"ms", ms}});
    spdlog::info("turntable calibrated: axis direction ({:.6f}, {:.6f}, {:.6f}) ± {:.4f}°, point ({:.3f}, "
                 "{:.3f}, {:.3f}) mm ± {:.4f} mm, RMS {:.4f} mm ({} views, {} spheres) → {}",
                 result.axis_direction.x(), result.axis_direction.y(), result.axis_direction.z(),
                 result.direction_sd_deg, result.axis_point_mm.x(), result.axis_point_mm.y(),
                 result.axis_point_mm.z(), result.point_sd_mm, result.rms_residual_mm, result.views_used,
                 result.spheres_used, file.string());
    publish(scan_id, {{"event", "finished"}, {"state", "done"}, {"calibration", document}});
  } catch (const std::exception& e) {
    fail(scan_id, fmt::format("turntable calibration: {} (raw views kept in {}; {})", e.what(),
                              (config_.paths.raw_dir / scan_id).string(), calibration_in_force()));
  }
}

void JobRunner::process(const std::string& scan_id) {
  db::ScanLogScope log_scope(scan_id);
  const auto start = std::chrono::steady_clock::now();
  try {
    store_->set_scan_state(scan_id, db::ScanState::Processing);
    std::vector<ViewFile> views;
    for (const auto& v : store_->views(scan_id)) {
      views.push_back({v.index, v.raw_path, v.measured_angle_deg * kDeg});
    }
    Pose scanner_to_world;
    registration::PriorUncertainty prior;
    {
      std::lock_guard lock(mutex_);  // a calibration may be changing them
      scanner_to_world = station_.scanner_to_world;
      prior = station_.prior_uncertainty;
    }
    const auto scan = store_->scan(scan_id);
    Pipeline pipeline(config_, *store_, [this, scan_id](const nlohmann::json& e) { publish(scan_id, e); },
                      scan ? MaterialChoice::from_json(scan->settings) : MaterialChoice{});
    const auto outcome = pipeline.process_views(scan_id, views, scanner_to_world, prior);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    store_->add_stage(scan_id, "processing", ms, {{"sherds", outcome.sherds.size()}});
    store_->set_scan_state(scan_id, db::ScanState::Done);
    auto sherds = nlohmann::json::array();
    for (const auto& s : outcome.sherds) {
      sherds.push_back({{"sherd_id", s.sherd_id}, {"plate", s.plate.string()}, {"axis_found", s.axis_found},
                        {"reason", s.reason}});
    }
    spdlog::info("scan {} done: {} sherds in {}", scan_id, outcome.sherds.size(), outcome.dir.string());
    publish(scan_id, {{"event", "finished"}, {"state", "done"}, {"output_dir", outcome.dir.string()},
                      {"sherds", sherds}});
  } catch (const std::exception& e) {
    fail(scan_id, fmt::format("processing: {} (raw views kept; re-run after fixing)", e.what()));
  }
}

}  // namespace sherd::station
