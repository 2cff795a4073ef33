// The spdlog sink writes each line to the events table under the scan of the logging thread.
#include "db/event_sink.h"

#include "temp_dir.h"

#include <gtest/gtest.h>
#include <spdlog/logger.h>

#include <thread>

namespace sherd::db {
namespace {

using EventSinkTest = test::TempDirTest;

TEST_F(EventSinkTest, TagsLinesWithTheScopesScanIdOnEachThread) {
  auto store = std::make_shared<Store>(dir_ / "sherdscan.db");
  const std::string a = store->create_scan("station", 8, nullptr, "out");
  const std::string b = store->create_scan("station", 8, nullptr, "out");
  spdlog::logger logger("pipeline", make_event_sink(store));
  logger.set_level(spdlog::level::trace);

  logger.info("before any scan");
  auto work = [&logger](const std::string& scan_id, int lines) {
    ScanLogScope scope(scan_id);
    for (int i = 0; i < lines; ++i) logger.info("line {} of {}", i, scan_id);
  };
  std::thread first(work, a, 30);
  std::thread second(work, b, 20);
  first.join();
  second.join();
  logger.warn("after the scans");

  EXPECT_EQ(store->event_count(a), 30);
  EXPECT_EQ(store->event_count(b), 20);
  EXPECT_EQ(store->event_count(""), 2);
}

TEST(ScanLogScope, NestsAndRestoresThePreviousScan) {
  EXPECT_EQ(ScanLogScope::current(), "");
  {
    ScanLogScope outer("20240501-100000-aaaa");
    {
      ScanLogScope inner("20240501-100000-bbbb");
      EXPECT_EQ(ScanLogScope::current(), "20240501-100000-bbbb");
      std::thread([] { EXPECT_EQ(ScanLogScope::current(), ""); }).join();
    }
    EXPECT_EQ(ScanLogScope::current(), "20240501-100000-aaaa");
  }
  EXPECT_EQ(ScanLogScope::current(), "");
}

}  // namespace
}  // namespace sherd::db
