#include "config/station_config.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <optional>
#include <set>
#include <string_view>
#include <vector>

namespace sherd::config {

namespace {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

// The accepted interval of a number, and how to say it in an error message.
struct Range {
  double lo = -kInf, hi = kInf;
  bool lo_open = false, hi_open = false;

  bool contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string describe(std::string_view what) const {
    if (lo == -kInf && hi == kInf) return fmt::format("{} (not nan or inf)", what);
    if (hi == kInf) return fmt::format("{} {} {}", what, lo_open ? "greater than" : "of at least", lo);
    if (lo == -kInf) return fmt::format("{} {} {}", what, hi_open ? "less than" : "of at most", hi);
    return fmt::format("{} {} {} {} {}{}", what, lo_open ? "above" : "from", lo,
                       lo_open ? "up to" : "to", hi, hi_open ? " (exclusive)" : "");
  }
};
Range any_finite() { return {}; }
Range above(double lo) { return {lo, kInf, true, false}; }
Range at_least(double lo) { return {lo, kInf, false, false}; }
Range from_to(double lo, double hi) { return {lo, hi, false, false}; }
Range above_to(double lo, double hi) { return {lo, hi, true, false}; }
Range from_below(double lo, double hi) { return {lo, hi, false, true}; }

// "a string \"abc\"", "an integer 8", … : what the file actually holds, for error messages.
std::string describe(const toml::node& node) {
  if (auto v = node.as_string()) return fmt::format("a string \"{}\"", v->get());
  if (auto v = node.as_integer()) return fmt::format("an integer {}", v->get());
  if (auto v = node.as_floating_point()) return fmt::format("a float {}", v->get());
  if (auto v = node.as_boolean()) return fmt::format("a boolean {}", v->get());
  if (auto v = node.as_array()) return fmt::format("an array of {} elements", v->size());
  if (node.is_table()) return "a table";
  if (node.is_date()) return "a date";
  if (node.is_time()) return "a time";
  return "a date-time";
}

// Where errors are reported: one line "<file>:<line>: <key>: expected <what>, got <what> — <hint>".
class ErrorReporter {
 public:
  explicit ErrorReporter(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const toml::node& node, std::string_view key, std::string_view expected,
                         std::string_view got, std::string_view hint = {}) const {
    const auto line = node.source().begin.line;
    const std::string where = line > 0 ? fmt::format("{}:{}", file_, line) : file_;
    throw InputError(fmt::format("{}: {}: expected {}, got {}{}{}", where, key, expected, got,
                                 hint.empty() ? "" : " — ", hint));
  }

 private:
  std::string file_;
};

std::string join(const std::vector<std::string_view>& words, std::string_view separator) {
  return fmt::format("{}", fmt::join(words, separator));
}

// One [table] of the file. Every read marks its key as known; reject_unknown_keys() then names
// the first key (in file order) that no read asked for — so the list of valid keys is exactly
// the reads below, with no second list to keep in step.
class Section {
 public:
  Section(const ErrorReporter& errors, const toml::table* table, std::string name)
      : errors_(errors), table_(table), name_(std::move(name)) {}

  void read(std::string_view key, bool& out) {
    if (auto* node = find(key)) {
      if (!node->is_boolean()) fail_type(*node, key, "true or false");
      out = node->as_boolean()->get();
    }
  }

  void read(std::string_view key, int& out, Range range) {
    if (auto* node = find(key)) out = static_cast<int>(integer(*node, key, range));
  }

  void read(std::string_view key, std::uint64_t& out) {
    if (auto* node = find(key)) out = static_cast<std::uint64_t>(integer(*node, key, at_least(0)));
  }

  void read(std::string_view key, double& out, Range range) {
    if (auto* node = find(key)) out = number(*node, key, range);
  }

  // A free text (non-empty), or one of `allowed` when given.
  void read(std::string_view key, std::string& out,
            std::initializer_list<std::string_view> allowed = {}) {
    auto* node = find(key);
    if (!node) return;
    const std::vector<std::string_view> choices(allowed);
    if (!node->is_string()) {
      fail_type(*node, key, choices.empty() ? "a string" : "one of " + join(choices, " | "));
    }
    const std::string& text = node->as_string()->get();
    if (!choices.empty() && std::find(choices.begin(), choices.end(), text) == choices.end()) {
      errors_.fail(*node, full(key), "one of " + join(choices, " | "),
                   fmt::format("\"{}\"", text));
    }
    if (text.empty()) errors_.fail(*node, full(key), "a non-empty string", "\"\"");
    out = text;
  }

  void read(std::string_view key, Vec3d& out) {
    auto* node = find(key);
    if (!node) return;
    constexpr std::string_view kWhat = "an array of 3 finite numbers [x, y, z] in millimetres";
    const auto* array = node->as_array();
    if (!array || array->size() != 3) fail_type(*node, key, kWhat);
    for (int i = 0; i < 3; ++i) {
      const toml::node& element = *array->get(i);
      if (!element.is_number()) errors_.fail(element, full(key), kWhat, describe(element));
      out[i] = number(element, key, any_finite());
    }
  }

  // A path as written (not yet resolved); nullopt when the key is absent.
  std::optional<fs::path> read_path(std::string_view key) {
    std::string text;
    read(key, text);
    if (text.empty()) return std::nullopt;
    return fs::path(text);
  }

  // The node of a key already read, for a check that involves two keys.
  const toml::node& node(std::string_view key) const { return *table_->get(key); }
  bool has(std::string_view key) const { return table_ && table_->contains(key); }
  std::string full(std::string_view key) const { return fmt::format("{}.{}", name_, key); }

  void reject_unknown_keys() const {
    if (!table_) return;
    const toml::node* first = nullptr;
    std::string_view first_key;
    for (const auto& [key, node] : *table_) {
      if (known_.count(std::string(key.str()))) continue;
      if (!first || node.source().begin < first->source().begin) {
        first = &node;
        first_key = key.str();
      }
    }
    if (!first) return;
    std::vector<std::string_view> keys(known_.begin(), known_.end());
    errors_.fail(*first, full(first_key), fmt::format("one of the keys of [{}]", name_),
                 fmt::format("an unknown key \"{}\"", first_key),
                 fmt::format("the keys of [{}] are {}", name_, join(keys, ", ")));
  }

 private:
  const toml::node* find(std::string_view key) {
    known_.emplace(key);
    return table_ ? table_->get(key) : nullptr;
  }

  [[noreturn]] void fail_type(const toml::node& node, std::string_view key,
                              std::string_view expected) const {
    errors_.fail(node, full(key), expected, describe(node),
                 node.is_string() ? "write the value without quotes" : "");
  }

  std::int64_t integer(const toml::node& node, std::string_view key, Range range) const {
    if (!node.is_integer()) fail_type(node, key, range.describe("an integer"));
    const std::int64_t value = node.as_integer()->get();
    if (!range.contains(static_cast<double>(value))) {
      errors_.fail(node, full(key), range.describe("an integer"), fmt::format("{}", value));
    }
    return value;
  }

  // TOML distinguishes 1 from 1.0; a setting in millimetres accepts either.
  double number(const toml::node& node, std::string_view key, Range range) const {
    if (!node.is_number()) fail_type(node, key, range.describe("a number"));
    const double value = node.is_integer() ? static_cast<double>(node.as_integer()->get())
                                           : node.as_floating_point()->get();
    if (!std::isfinite(value) || !range.contains(value)) {
      errors_.fail(node, full(key), range.describe("a number"), fmt::format("{}", value));
    }
    return value;
  }

  const ErrorReporter& errors_;
  const toml::table* table_;
  std::string name_;
  std::set<std::string, std::less<>> known_;
};

toml::table parse(const fs::path& file) {
  std::error_code error;
  if (!fs::exists(file, error)) {
    throw InputError(fmt::format(
        "{}: cannot read the station configuration: no such file — pass the path of a "
        "station.toml with --config (config/station.toml is the documented default)",
        file.string()));
  }
  if (fs::is_directory(file, error)) {
    throw InputError(fmt::format(
        "{}: cannot read the station configuration: it is a directory — pass the path of a "
        "station.toml file",
        file.string()));
  }
  try {
    return toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    const auto& begin = e.source().begin;
    if (begin.line == 0) {  // toml++ could not read the file at all
      throw InputError(fmt::format("{}: cannot read the station configuration: {} — check the "
                                   "file's permissions",
                                   file.string(), e.description()));
    }
    throw InputError(fmt::format("{}:{}: TOML syntax error: {} (column {}) — fix the syntax on "
                                 "that line",
                                 file.string(), begin.line, e.description(), begin.column));
  }
}

}  // namespace

StationConfig load_station_config(const fs::path& file) {
  const toml::table root = parse(file);
  const ErrorReporter errors(file.string());
  StationConfig config;
  config.source = fs::absolute(file).lexically_normal();

  // The tables of the file, in the order the documented file has them.
  const std::vector<std::string_view> names = {"station",      "scan",         "scanner",
                                               "turntable",    "simulation",   "calibration",
                                               "registration", "segmentation", "render"};
  for (const auto& [key, node] : root) {
    if (std::find(names.begin(), names.end(), key.str()) == names.end()) {
      errors.fail(node, key.str(), "one of the tables " + join(names, ", "),
                  node.is_table() ? fmt::format("an unknown table [{}]", key.str())
                                  : fmt::format("an unknown top-level key \"{}\"", key.str()),
                  "every setting belongs to one of these tables");
    }
    if (!node.is_table()) {
      errors.fail(node, key.str(), fmt::format("a table [{}]", key.str()), describe(node));
    }
  }
  auto section = [&](std::string_view name) {
    return Section(errors, root[name].as_table(), std::string(name));
  };

  Section station = section("station");
  station.read("name", config.name);
  const fs::path data_dir = station.read_path("data_dir").value_or("var");
  const auto output_dir = station.read_path("output_dir");
  const auto socket = station.read_path("socket");
  station.reject_unknown_keys();
  // Explicit overrides are relative to the working directory, like data_dir.
  if (output_dir) config.paths.output_dir = fs::absolute(*output_dir).lexically_normal();
  if (socket) config.paths.socket = fs::absolute(*socket).lexically_normal();
  config.paths.output_dir_from_config = output_dir.has_value();
  config.paths.socket_from_config = socket.has_value();
  set_data_dir(config, data_dir);

  Section scan = section("scan");
  scan.read("views", config.scan.views, from_to(1, 360));
  scan.read("start_angle_deg", config.scan.start_angle_deg, from_below(0, 360));
  scan.reject_unknown_keys();

  auto& sc = config.scanner;
  Section scanner = section("scanner");
  scanner.read("driver", sc.driver, {"simulated", "structured-light-simulated", "structured-light"});
  scanner.read("width", sc.width, from_to(16, 16384));
  scanner.read("height", sc.height, from_to(16, 16384));
  scanner.read("fx", sc.fx, above(0));
  scanner.read("fy", sc.fy, above(0));
  scanner.read("cx", sc.cx, from_below(0, sc.width));
  scanner.read("cy", sc.cy, from_below(0, sc.height));
  scanner.read("position_mm", sc.position_mm);
  scanner.read("look_at_mm", sc.look_at_mm);
  scanner.read("projector_offset_mm", sc.projector_offset_mm);
  scanner.read("depth_noise_mm", sc.depth_noise_mm, from_to(0, 10));
  scanner.read("grazing_limit_deg", sc.grazing_limit_deg, above_to(0, 90));
  scanner.read("dropout_fraction", sc.dropout_fraction, from_below(0, 1));
  scanner.read("camera_id", sc.camera_id);
  const auto scanner_calibration = scanner.read_path("calibration_file");
  if (scanner_calibration) {
    sc.calibration_file = fs::absolute(*scanner_calibration).lexically_normal();
    sc.calibration_file_from_config = true;
  }  // else set_data_dir above has put it under data_dir
  scanner.read("patterns", sc.patterns, {"gray", "phase"});
  scanner.read("black_threshold", sc.black_threshold, from_to(0, 255));
  scanner.read("white_threshold", sc.white_threshold, from_to(0, 255));
  scanner.read("edge_bits", sc.edge_bits, from_to(0, 2));
  scanner.read("min_modulation", sc.min_modulation, from_to(0, 128));
  scanner.read("phase_period_px", sc.phase_period_px, from_to(4, 1024));
  scanner.read("phase_steps", sc.phase_steps, from_to(3, 32));
  scanner.read("max_ray_gap_mm", sc.max_ray_gap_mm, from_to(0, 1000));
  scanner.read("projector_width", sc.projector_width, from_to(16, 16384));
  scanner.read("projector_height", sc.projector_height, from_to(16, 16384));
  scanner.read("trigger", sc.trigger, {"software", "line"});
  scanner.read("trigger_line", sc.trigger_line);
  scanner.read("projector_device", sc.projector_device);
  scanner.read("projector_connector", sc.projector_connector);
  scanner.reject_unknown_keys();
  if ((sc.look_at_mm - sc.position_mm).norm() < 1e-6) {
    const char* key = scanner.has("look_at_mm") ? "look_at_mm" : "position_mm";
    errors.fail(scanner.node(key), scanner.full(key),
                "a look-at point other than the scanner position", "the same point",
                "the optical axis needs two distinct points");
  }

  auto& tt = config.turntable;
  Section turntable = section("turntable");
  turntable.read("driver", tt.driver, {"simulated", "usb", "usb-simulated"});
  turntable.read("steps_per_revolution", tt.steps_per_revolution, from_to(1, 10'000'000));
  turntable.read("speed_deg_s", tt.speed_deg_s, above(0));
  turntable.read("acceleration_deg_s2", tt.acceleration_deg_s2, above(0));
  turntable.read("time_scale", tt.time_scale, at_least(0));
  turntable.read("fault", tt.fault,
                 {"none", "stall", "timeout", "disconnect", "no_reply", "garbled", "unplug", "homing"});
  turntable.read("fault_at_move", tt.fault_at_move, from_to(1, 1'000'000));
  turntable.read("angle_sd_deg", tt.angle_sd_deg, above_to(0, 10));
  turntable.read("fault_count", tt.fault_count, from_to(1, 1'000'000));
  turntable.read("usb_vendor_id", tt.usb_vendor_id, from_to(0, 0xffff));
  turntable.read("usb_product_id", tt.usb_product_id, from_to(0, 0xffff));
  turntable.read("usb_serial", tt.usb_serial);
  turntable.read("usb_interface", tt.usb_interface, from_to(0, 255));
  turntable.read("reply_timeout_ms", tt.reply_timeout_ms, from_to(1, 60'000));
  turntable.read("reconnect_timeout_s", tt.reconnect_timeout_s, from_to(0, 600));
  turntable.read("move_attempts", tt.move_attempts, from_to(1, 10));
  turntable.reject_unknown_keys();

  auto& sim = config.simulation;
  Section simulation = section("simulation");
  simulation.read("seed", sim.seed);
  simulation.read("scene", sim.scene, {"frame", "plate", "vessel", "empty", "calibration"});
  simulation.read("sherds", sim.sherds, from_to(1, 10));
  simulation.read("background", sim.background, {"black", "white"});
  simulation.read("scanner_tilt_error_deg", sim.scanner_tilt_error_deg, from_to(0, 10));
  simulation.read("scanner_offset_error_mm", sim.scanner_offset_error_mm, from_to(0, 50));
  simulation.reject_unknown_keys();

  Section calibration = section("calibration");
  calibration.read("views", config.calibration.views, from_to(3, 360));
  const auto turntable_file = calibration.read_path("turntable_file");
  calibration.reject_unknown_keys();
  if (turntable_file) {
    config.calibration.turntable_file = fs::absolute(*turntable_file).lexically_normal();
    config.calibration.turntable_file_from_config = true;
  }  // else set_data_dir above has put it under data_dir

  auto& reg = config.registration;
  Section registration = section("registration");
  registration.read("refine_with_icp", reg.refine_with_icp);
  registration.read("voxel_mm", reg.voxel_mm, above_to(0, 100));
  registration.read("max_correspondence_mm", reg.max_correspondence_mm, above(0));
  registration.read("max_iterations", reg.max_iterations, from_to(1, 10'000));
  registration.read("max_correction_deg", reg.max_correction_deg, above_to(0, 180));
  registration.read("max_correction_mm", reg.max_correction_mm, above(0));
  registration.read("use_colour", reg.use_colour);
  registration.read("weight_by_incidence", reg.weight_by_incidence);
  registration.reject_unknown_keys();

  auto& seg = config.segmentation;
  Section segmentation = section("segmentation");
  segmentation.read("background", seg.background, {"black", "white", "none"});
  segmentation.read("cluster_tolerance_mm", seg.cluster_tolerance_mm, above(0));
  segmentation.read("min_points", seg.min_points, from_to(1, 100'000'000));
  segmentation.read("min_extent_mm", seg.min_extent_mm, above(0));
  segmentation.read("max_extent_mm", seg.max_extent_mm, above(seg.min_extent_mm));
  segmentation.read("volume_radius_mm", seg.volume_radius_mm, above(0));
  segmentation.read("volume_min_z_mm", seg.volume_min_z_mm, any_finite());
  segmentation.read("volume_max_z_mm", seg.volume_max_z_mm, above(seg.volume_min_z_mm));
  segmentation.read("contact_erosion_mm", seg.contact_erosion_mm, from_to(0, 50));
  segmentation.read("frame_height_mm", seg.frame_height_mm, from_to(0, 100));
  segmentation.reject_unknown_keys();

  auto& rs = config.render;
  Section render = section("render");
  render.read("dpi", rs.dpi, from_to(72, 4800));
  render.read("material", rs.material);
  const fs::path materials = render.read_path("materials_file").value_or("materials.xml");
  render.read("section_side", rs.section_side, {"right", "left"});
  render.read("png", rs.png, {"rgb8", "grey16"});
  render.reject_unknown_keys();
  // Relative to the config file, so that a config and its materials travel together.
  rs.materials_file = (config.source.parent_path() / materials).lexically_normal();

  return config;
}

void set_data_dir(StationConfig& config, const fs::path& data_dir) {
  auto& paths = config.paths;
  paths.data_dir = fs::absolute(data_dir).lexically_normal();
  paths.database = paths.data_dir / "sherdscan.db";
  paths.raw_dir = paths.data_dir / "raw";
  paths.log_file = paths.data_dir / "sherdd.log";
  if (!paths.output_dir_from_config) paths.output_dir = paths.data_dir / "output";
  if (!paths.socket_from_config) paths.socket = paths.data_dir / "sherdd.sock";
  if (!config.calibration.turntable_file_from_config) {
    config.calibration.turntable_file = paths.data_dir / "calibration" / "turntable.json";
  }
  if (!config.scanner.calibration_file_from_config) {
    config.scanner.calibration_file = paths.data_dir / "calibration" / "scanner.xml";
  }
}

}  // namespace sherd::config
