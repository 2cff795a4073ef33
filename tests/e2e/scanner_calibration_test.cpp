// `sherdctl calibrate scanner --captures …` end to end on the real procam-graycode-calib captures:
// the program writes the calibration file and the database row, and agrees with the reference
// tool on the camera (the projector is compared in tests/processing, where the reference's units
// are explained).
#include "harness.h"

#include "db/store.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace sherd::testing {
namespace {

const std::filesystem::path kSample =
    std::filesystem::path(SHERD_SHARED_DATA) / "procam-graycode-calib/sample_data";

TEST(ScannerCalibration, FromCapturesWritesTheFileAndTheDatabase) {
  TestStation station({});
  std::vector<std::string> argv{binary("sherdctl").string(),
                                "--config",
                                station.config_file.string(),
                                "--json",
                                "calibrate",
                                "scanner",
                                "--data-dir",
                                station.data.string(),
                                "--reference",
                                (kSample / "calibration_result.xml").string(),
                                "--captures"};
  for (int i = 0; i < 5; ++i) argv.push_back((kSample / ("capture_" + std::to_string(i))).string());
  const auto result = run(argv);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto reply = nlohmann::json::parse(result.out);
  EXPECT_EQ(reply["poses_used"], 5);
  // Reference camera focal length 3452.4 px (calibration_result.xml); 1 % tolerance.
  EXPECT_NEAR(reply["camera"]["fx"].get<double>(), 3452.4, 34.5);
  EXPECT_NEAR(reply["reference"]["camera"]["fx"].get<double>(), 3452.39, 0.01);
  const std::filesystem::path file = reply["file"].get<std::string>();
  EXPECT_EQ(file, station.config.paths.data_dir / "calibration" / "scanner.xml");
  EXPECT_TRUE(std::filesystem::exists(file));
  const auto stored = db::Store(station.config.paths.database).latest_calibration("scanner");
  ASSERT_TRUE(stored.has_value());
  EXPECT_DOUBLE_EQ(stored->result["camera"]["fx"].get<double>(),
                   reply["camera"]["fx"].get<double>());
}

TEST(ScannerCalibration, AFolderWithoutCapturesIsOneClearLine) {
  TestStation station({});
  const auto empty = station.dir.path() / "empty";
  std::filesystem::create_directories(empty);
  const auto result =
      run({binary("sherdctl").string(), "--config", station.config_file.string(), "calibrate",
           "scanner", "--data-dir", station.data.string(), "--captures", empty.string()});
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("cannot read image"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("graycode_00.png"), std::string::npos) << result.err;
}

}  // namespace
}  // namespace sherd::testing
