#include "db/event_sink.h"

#include <spdlog/sinks/base_sink.h>

#include <mutex>
#include <utility>

namespace sherd::db {

namespace {

thread_local std::string current_scan_id;

// Writes each line as one events row. The scan id is read on the logging thread, so this sink
// belongs on synchronous loggers (an async logger would log from its worker thread).
class EventSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit EventSink(std::shared_ptr<Store> store) : store_(std::move(store)) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    const auto level = spdlog::level::to_string_view(msg.level);
    // The raw message, not the formatted line: time, level and logger have their own columns.
    store_->add_event(to_iso_utc(msg.time), ScanLogScope::current(),
                      std::string(level.data(), level.size()),
                      std::string(msg.logger_name.data(), msg.logger_name.size()),
                      std::string(msg.payload.data(), msg.payload.size()));
  }
  void flush_() override {}  // every event is committed as it is written

 private:
  std::shared_ptr<Store> store_;
};

}  // namespace

std::shared_ptr<spdlog::sinks::sink> make_event_sink(std::shared_ptr<Store> store) {
  return std::make_shared<EventSink>(std::move(store));
}

ScanLogScope::ScanLogScope(std::string scan_id)
    : previous_(std::exchange(current_scan_id, std::move(scan_id))) {}

ScanLogScope::~ScanLogScope() { current_scan_id = std::move(previous_); }

const std::string& ScanLogScope::current() { return current_scan_id; }

}  // namespace sherd::db
