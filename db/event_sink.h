// An spdlog sink that writes every log line to the events table, tagged with the scan the
// logging thread is working on (set with ScanLogScope). Lines outside any scan get scan_id "".
#pragma once

#include "db/store.h"

#include <spdlog/sinks/sink.h>

#include <memory>
#include <string>

namespace sherd::db {

std::shared_ptr<spdlog::sinks::sink> make_event_sink(std::shared_ptr<Store> store);

// While alive, log lines from this thread belong to `scan_id`.
class ScanLogScope {
 public:
  explicit ScanLogScope(std::string scan_id);
  ~ScanLogScope();
  ScanLogScope(const ScanLogScope&) = delete;
  ScanLogScope& operator=(const ScanLogScope&) = delete;

  static const std::string& current();  // "" outside any scope

 private:
  std::string previous_;
};

}  // namespace sherd::db
