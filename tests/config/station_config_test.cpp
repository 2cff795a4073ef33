// The station configuration: the shipped file, defaults, paths, and one exact error line for
// each kind of mistake (small TOML files written into a temporary directory).
#include "config/station_config.h"

#include "core/errors.h"

#include <gtest/gtest.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <fstream>
#include <map>
#include <vector>

namespace sherd::config {
namespace {

namespace fs = std::filesystem;

const fs::path kShipped = fs::path(SHERD_SOURCE_DIR) / "config" / "station.toml";

class StationConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           (std::string("sherd-config-") + info->name() + "-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& text, const std::string& name = "station.toml") const {
    const fs::path file = dir_ / name;
    std::ofstream(file) << text;
    return file;
  }

  // The message of the InputError that loading `text` raises ("" if none).
  std::string error_of(const std::string& text) const {
    try {
      load_station_config(write(text));
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  std::string file() const { return (dir_ / "station.toml").string(); }

  fs::path dir_;
};

TEST_F(StationConfigTest, ShippedFileHasTheDocumentedDefaultStation) {
  const StationConfig c = load_station_config(kShipped);
  EXPECT_EQ(c.source, fs::path(SHERD_SOURCE_DIR) / "config" / "station.toml");
  EXPECT_EQ(c.name, "simulated station");
  EXPECT_EQ(c.paths.data_dir, fs::current_path() / "var");
  EXPECT_EQ(c.paths.database, fs::current_path() / "var" / "sherdscan.db");
  EXPECT_EQ(c.paths.raw_dir, fs::current_path() / "var" / "raw");
  EXPECT_EQ(c.paths.output_dir, fs::current_path() / "var" / "output");
  EXPECT_EQ(c.paths.socket, fs::current_path() / "var" / "sherdd.sock");
  EXPECT_EQ(c.paths.log_file, fs::current_path() / "var" / "sherdd.log");
  EXPECT_EQ(c.scan.views, 8);
  EXPECT_EQ(c.scan.start_angle_deg, 0.0);
  EXPECT_EQ(c.scanner.driver, "simulated");
  EXPECT_EQ(c.scanner.width, 640);
  EXPECT_EQ(c.scanner.height, 480);
  EXPECT_EQ(c.scanner.fx, 800.0);
  EXPECT_EQ(c.scanner.cy, 239.5);
  EXPECT_EQ(c.scanner.position_mm, Vec3d(0.0, -420.0, 260.0));
  EXPECT_EQ(c.scanner.look_at_mm, Vec3d(0.0, 0.0, 50.0));
  EXPECT_EQ(c.scanner.projector_offset_mm, Vec3d(120.0, 0.0, 0.0));
  EXPECT_EQ(c.scanner.depth_noise_mm, 0.05);
  EXPECT_EQ(c.turntable.steps_per_revolution, 3200);
  EXPECT_EQ(c.turntable.fault, "none");
  EXPECT_EQ(c.simulation.seed, 42u);
  EXPECT_EQ(c.simulation.scene, "frame");
  EXPECT_EQ(c.simulation.sherds, 4);
  EXPECT_TRUE(c.registration.refine_with_icp);
  EXPECT_EQ(c.registration.max_iterations, 40);
  EXPECT_EQ(c.segmentation.background, "black");
  EXPECT_EQ(c.segmentation.min_points, 400);
  EXPECT_EQ(c.render.dpi, 600);
  EXPECT_EQ(c.render.material, "clay");
  EXPECT_EQ(c.render.materials_file, fs::path(SHERD_SOURCE_DIR) / "config" / "materials.xml");
  EXPECT_TRUE(fs::exists(c.render.materials_file));
  EXPECT_EQ(c.render.section_side, "right");
  // A simulated scanner mounted exactly as configured; the encoder good to 0.1°.
  EXPECT_EQ(c.simulation.scanner_tilt_error_deg, 0.0);
  EXPECT_EQ(c.simulation.scanner_offset_error_mm, 0.0);
  EXPECT_EQ(c.turntable.angle_sd_deg, 0.1);
  EXPECT_EQ(c.calibration.views, 12);
  EXPECT_EQ(c.calibration.turntable_file, fs::current_path() / "var" / "calibration" / "turntable.json");
}

// The shipped file is the documentation: every setting must be written out in it.
TEST_F(StationConfigTest, ShippedFileWritesOutEverySetting) {
  const std::map<std::string, std::vector<std::string>> documented = {
      {"station", {"name", "data_dir"}},
      {"scan", {"views", "start_angle_deg"}},
      {"scanner",
       {"driver", "width", "height", "fx", "fy", "cx", "cy", "position_mm", "look_at_mm",
        "projector_offset_mm", "depth_noise_mm", "grazing_limit_deg", "dropout_fraction"}},
      {"turntable",
       {"driver", "steps_per_revolution", "speed_deg_s", "acceleration_deg_s2", "time_scale",
        "fault", "fault_at_move", "angle_sd_deg"}},
      {"simulation",
       {"seed", "scene", "sherds", "background", "scanner_tilt_error_deg",
        "scanner_offset_error_mm"}},
      {"calibration", {"views"}},
      {"registration",
       {"refine_with_icp", "voxel_mm", "max_correspondence_mm", "max_iterations",
        "max_correction_deg", "max_correction_mm"}},
      {"segmentation",
       {"background", "cluster_tolerance_mm", "min_points", "min_extent_mm", "max_extent_mm",
        "volume_radius_mm", "volume_min_z_mm", "volume_max_z_mm", "contact_erosion_mm",
        "frame_height_mm"}},
      {"render", {"dpi", "material", "materials_file", "section_side"}},
  };
  const toml::table shipped = toml::parse_file(kShipped.string());
  for (const auto& [table, keys] : documented) {
    for (const auto& key : keys) {
      EXPECT_TRUE(shipped[table][key]) << table << "." << key << " is missing";
    }
  }
  // The optional overrides are documented as comments, not set.
  std::ifstream in(kShipped);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("# output_dir = "), std::string::npos);
  EXPECT_NE(text.find("# socket = "), std::string::npos);
  EXPECT_NE(text.find("# turntable_file = "), std::string::npos);
}

TEST_F(StationConfigTest, MissingKeysTakeTheHeaderDefaults) {
  const StationConfig shipped = load_station_config(kShipped);
  const StationConfig empty = load_station_config(write("# nothing set\n"));
  const StationConfig defaults;
  // The shipped file and an empty one describe the same station.
  EXPECT_EQ(empty.paths.data_dir, shipped.paths.data_dir);
  EXPECT_EQ(empty.scan.views, defaults.scan.views);
  EXPECT_EQ(empty.scanner.look_at_mm, shipped.scanner.look_at_mm);
  EXPECT_EQ(empty.turntable.acceleration_deg_s2, shipped.turntable.acceleration_deg_s2);
  EXPECT_EQ(empty.simulation.background, shipped.simulation.background);
  EXPECT_EQ(empty.registration.voxel_mm, shipped.registration.voxel_mm);
  EXPECT_EQ(empty.segmentation.volume_max_z_mm, shipped.segmentation.volume_max_z_mm);
  EXPECT_EQ(empty.render.materials_file, dir_ / "materials.xml");
}

TEST_F(StationConfigTest, ReadsValuesOfEveryKind) {
  const StationConfig c = load_station_config(write(R"(
[scan]
views = 12
start_angle_deg = 15      # an integer is accepted where a number is expected
[scanner]
width = 1280
cx = 1000.0               # valid because width is 1280 here
position_mm = [10, -300.5, 200]
[turntable]
fault = "stall"
fault_at_move = 3
time_scale = 0
[simulation]
seed = 123456789012
scene = "calibration"
scanner_tilt_error_deg = 1.5
scanner_offset_error_mm = 3
[calibration]
views = 24
turntable_file = "cal/tt.json"
[registration]
refine_with_icp = false
[segmentation]
contact_erosion_mm = 5
frame_height_mm = 12
[render]
section_side = "left"
)"));
  EXPECT_EQ(c.scan.views, 12);
  EXPECT_EQ(c.scan.start_angle_deg, 15.0);
  EXPECT_EQ(c.scanner.width, 1280);
  EXPECT_EQ(c.scanner.cx, 1000.0);
  EXPECT_EQ(c.scanner.position_mm, Vec3d(10.0, -300.5, 200.0));
  EXPECT_EQ(c.turntable.fault, "stall");
  EXPECT_EQ(c.turntable.fault_at_move, 3);
  EXPECT_EQ(c.turntable.time_scale, 0.0);
  EXPECT_EQ(c.simulation.seed, 123456789012u);
  EXPECT_EQ(c.simulation.scene, "calibration");
  EXPECT_EQ(c.simulation.scanner_tilt_error_deg, 1.5);
  EXPECT_EQ(c.simulation.scanner_offset_error_mm, 3.0);
  EXPECT_EQ(c.calibration.views, 24);
  EXPECT_EQ(c.calibration.turntable_file, fs::current_path() / "cal" / "tt.json");
  EXPECT_FALSE(c.registration.refine_with_icp);
  EXPECT_EQ(c.segmentation.contact_erosion_mm, 5.0);
  EXPECT_EQ(c.segmentation.frame_height_mm, 12.0);
  EXPECT_EQ(c.render.section_side, "left");
}

TEST_F(StationConfigTest, ResolvesPathsAndSetDataDirReRootsOnlyDerivedOnes) {
  StationConfig c = load_station_config(write(R"(
[station]
data_dir = "var/station"
output_dir = "/srv/plates"
[render]
materials_file = "looks/materials.xml"
)"));
  EXPECT_EQ(c.paths.data_dir, fs::current_path() / "var" / "station");
  EXPECT_EQ(c.paths.database, fs::current_path() / "var" / "station" / "sherdscan.db");
  EXPECT_EQ(c.paths.output_dir, fs::path("/srv/plates"));
  EXPECT_EQ(c.paths.socket, fs::current_path() / "var" / "station" / "sherdd.sock");
  EXPECT_EQ(c.render.materials_file, dir_ / "looks" / "materials.xml");

  set_data_dir(c, "/var/lib/other");
  EXPECT_EQ(c.paths.data_dir, fs::path("/var/lib/other"));
  EXPECT_EQ(c.paths.database, fs::path("/var/lib/other/sherdscan.db"));
  EXPECT_EQ(c.paths.raw_dir, fs::path("/var/lib/other/raw"));
  EXPECT_EQ(c.paths.log_file, fs::path("/var/lib/other/sherdd.log"));
  EXPECT_EQ(c.paths.socket, fs::path("/var/lib/other/sherdd.sock"));
  EXPECT_EQ(c.paths.output_dir, fs::path("/srv/plates"));  // explicit: kept
  EXPECT_EQ(c.calibration.turntable_file, fs::path("/var/lib/other/calibration/turntable.json"));
}

TEST_F(StationConfigTest, UnknownKeyNamesFileLineAndTheValidKeys) {
  EXPECT_EQ(error_of("[scan]\nviews = 8\nveiws = 9\n"),
            file() + ":3: scan.veiws: expected one of the keys of [scan], got an unknown key "
                     "\"veiws\" — the keys of [scan] are start_angle_deg, views");
}

TEST_F(StationConfigTest, UnknownTableNamesFileAndLine) {
  EXPECT_EQ(error_of("[scan]\nviews = 8\n\n[scaner]\nwidth = 640\n"),
            file() + ":4: scaner: expected one of the tables station, scan, scanner, turntable, "
                     "simulation, calibration, registration, segmentation, render, got an unknown table "
                     "[scaner] — every setting belongs to one of these tables");
}

TEST_F(StationConfigTest, WrongTypeNamesFileLineKeyAndWhatIsExpected) {
  EXPECT_EQ(error_of("[scan]\nviews = \"8\"\n"),
            file() + ":2: scan.views: expected an integer from 1 to 360, got a string \"8\" — "
                     "write the value without quotes");
  EXPECT_EQ(error_of("[registration]\n\nrefine_with_icp = 1\n"),
            file() + ":3: registration.refine_with_icp: expected true or false, got an integer 1");
  EXPECT_EQ(error_of("[scan]\nviews = 8.0\n"),
            file() + ":2: scan.views: expected an integer from 1 to 360, got a float 8");
  EXPECT_EQ(error_of("[scanner]\nposition_mm = [0, 1]\n"),
            file() + ":2: scanner.position_mm: expected an array of 3 finite numbers [x, y, z] in "
                     "millimetres, got an array of 2 elements");
  EXPECT_EQ(error_of("scan = 8\n"),
            file() + ":1: scan: expected a table [scan], got an integer 8");
}

TEST_F(StationConfigTest, ValueOutOfRangeNamesTheRange) {
  EXPECT_EQ(error_of("[render]\ndpi = 10\n"),
            file() + ":2: render.dpi: expected an integer from 72 to 4800, got 10");
  EXPECT_EQ(error_of("[scanner]\n\n\ndropout_fraction = 1.0\n"),
            file() + ":4: scanner.dropout_fraction: expected a number from 0 to 1 (exclusive), "
                     "got 1");
  EXPECT_EQ(error_of("[registration]\nvoxel_mm = -0.5\n"),
            file() + ":2: registration.voxel_mm: expected a number above 0 up to 100, got -0.5");
  EXPECT_EQ(error_of("[scanner]\ndepth_noise_mm = nan\n"),
            file() + ":2: scanner.depth_noise_mm: expected a number from 0 to 10, got nan");
  EXPECT_EQ(error_of("[calibration]\nviews = 2\n"),
            file() + ":2: calibration.views: expected an integer from 3 to 360, got 2");
  EXPECT_EQ(error_of("[simulation]\nseed = -1\n"),
            file() + ":2: simulation.seed: expected an integer of at least 0, got -1");
  // Ranges that depend on another key.
  EXPECT_EQ(error_of("[scanner]\nwidth = 320\ncx = 319.5\n"), "");
  EXPECT_EQ(error_of("[scanner]\nwidth = 320\ncx = 320\n"),
            file() + ":3: scanner.cx: expected a number from 0 to 320 (exclusive), got 320");
  EXPECT_EQ(error_of("[segmentation]\nmin_extent_mm = 50\nmax_extent_mm = 40\n"),
            file() + ":3: segmentation.max_extent_mm: expected a number greater than 50, got 40");
  EXPECT_EQ(error_of("[scanner]\nlook_at_mm = [0.0, -420.0, 260.0]\n"),
            file() + ":2: scanner.look_at_mm: expected a look-at point other than the scanner "
                     "position, got the same point — the optical axis needs two distinct points");
}

TEST_F(StationConfigTest, UnknownEnumValueListsTheChoices) {
  EXPECT_EQ(error_of("[turntable]\nfault = \"jam\"\n"),
            file() + ":2: turntable.fault: expected one of none | stall | timeout | disconnect | "
                     "no_reply | garbled | unplug | homing, got \"jam\"");
  EXPECT_EQ(error_of("[render]\nsection_side = \"top\"\n"),
            file() + ":2: render.section_side: expected one of right | left, got \"top\"");
  EXPECT_EQ(error_of("[scanner]\ndriver = \"kinect\"\n"),
            file() + ":2: scanner.driver: expected one of simulated | structured-light-simulated | "
                "structured-light, got \"kinect\"");
}

TEST_F(StationConfigTest, SyntaxErrorNamesFileAndLine) {
  const std::string message = error_of("[scan]\nviews = 8\nstart_angle_deg = = 3\n");
  EXPECT_EQ(message.rfind(file() + ":3: TOML syntax error: ", 0), 0u) << message;
}

TEST_F(StationConfigTest, MissingFileSaysWhatToDo) {
  const fs::path missing = dir_ / "nope.toml";
  try {
    load_station_config(missing);
    FAIL() << "a missing file loaded";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              missing.string() +
                  ": cannot read the station configuration: no such file — pass the path of a "
                  "station.toml with --config (config/station.toml is the documented default)");
  }
}

}  // namespace
}  // namespace sherd::config
