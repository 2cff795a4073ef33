// The daemon's job runner: one acquisition thread (one set of hardware: scans are acquired one
// after another) and one processing thread, so that processing of scan N overlaps acquisition of
// scan N+1. Raw views are on disk and in the database before processing starts; on start-up
// every unfinished scan is resumed from what the database holds.
//
// A turntable calibration is a job of the acquisition thread too (it needs the hardware): a
// "scan" with source "calibration" whose views (kept on disk like any scan's) go to the
// estimator instead of the pipeline; its result is stored (file + database) and put in force at
// once, so every scan acquired after it uses it. A failed calibration leaves the previous one.
#pragma once

#include "config/station_config.h"
#include "daemon/pipeline.h"
#include "daemon/station.h"
#include "db/store.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace sherd::station {

// Events of one scan, delivered to one client connection.
class Subscription {
 public:
  void push(const nlohmann::json& event);
  // Waits for the next event; nullopt once the subscription is closed and drained.
  std::optional<nlohmann::json> next();
  void close();

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<nlohmann::json> events_;
  bool closed_ = false;
};

class JobRunner {
 public:
  JobRunner(const config::StationConfig& config, std::shared_ptr<db::Store> store, Station station);
  ~JobRunner();

  // Queues the unfinished scans found in the database, then starts the threads.
  void start();
  // Finishes cleanly: no new jobs; acquisition stops after the view in hand (the scan stays
  // resumable); processing finishes the scan in hand. Idempotent.
  void stop();

  // Creates a scan and queues its acquisition; the returned subscription sees all its events.
  // `materials` is kept in the scan's settings; an unknown preset throws sherd::InputError before
  // the scan exists (a typo costs no acquisition).
  std::pair<std::string, std::shared_ptr<Subscription>> submit_scan(const MaterialChoice& materials = {});
  std::shared_ptr<Subscription> subscribe(const std::string& scan_id);
  // Queues a turntable calibration (a job id like a scan's; events as for a scan, the finished
  // event carries {"calibration": {…}} with the figures).
  std::pair<std::string, std::shared_ptr<Subscription>> submit_turntable_calibration();

  nlohmann::json status() const;

 private:
  // Takes scan ids from `queue` one at a time (marking the one `in_hand`) and runs `work` on each.
  void worker_loop(std::deque<std::string>& queue, std::string& in_hand,
                   void (JobRunner::*work)(const std::string&));
  void acquire(const std::string& scan_id);
  // The calibration scan's views → estimator → file, database, station (under mutex_).
  void calibrate_turntable(const std::string& scan_id);
  // What a failed calibration leaves: "the previous calibration stays in force" or "… uncalibrated".
  std::string calibration_in_force() const;
  void process(const std::string& scan_id);
  void fail(const std::string& scan_id, const std::string& reason);
  void publish(const std::string& scan_id, nlohmann::json event);
  // A job for the acquisition thread; the subscription sees its events.
  std::pair<std::string, std::shared_ptr<Subscription>> submit(const std::string& source, int views,
                                                               const nlohmann::json& settings);

  const config::StationConfig& config_;
  std::shared_ptr<db::Store> store_;
  Station station_;  // the calibration fields under mutex_ (written by a calibration, read by processing)

  mutable std::mutex mutex_;
  std::condition_variable work_;
  std::deque<std::string> to_acquire_, to_process_;
  std::string acquiring_, processing_;  // scan ids in hand ("" when idle)
  std::multimap<std::string, std::weak_ptr<Subscription>> subscribers_;
  std::atomic<bool> stopping_{false};
  std::thread acquisition_thread_, processing_thread_;
};

}  // namespace sherd::station
