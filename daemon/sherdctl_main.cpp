// sherdctl — the operator's and scripts' client: press scan, calibrate the turntable, look at the
// station and past scans (through sherdd's socket), or run the pipeline offline on existing files
// (no daemon needed).
#include "config/station_config.h"
#include "core/errors.h"
#include "daemon/pipeline.h"
#include "daemon/protocol.h"
#include "daemon/server.h"
#include "db/event_sink.h"
#include "db/store.h"
#include "processing/io/model_io.h"
#include "processing/structured_light/calibration.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <optional>
#include <functional>
#include <iostream>

namespace {

using nlohmann::json;
using sherd::station::JsonLineSocket;

struct Options {
  std::string config_file = "config/station.toml";
  std::string socket;
  bool as_json = false;
};

std::filesystem::path socket_path(const Options& options) {
  if (!options.socket.empty()) return options.socket;
  if (const char* env = std::getenv("SHERD_SOCKET")) return env;
  return sherd::config::load_station_config(options.config_file).paths.socket;
}

json request(const Options& options, const json& message) {
  auto socket = sherd::station::connect_unix(socket_path(options));
  socket.send(message);
  auto reply = socket.receive();
  if (!reply) throw sherd::InputError("sherdd closed the connection without answering: see its log");
  if (!reply->value("ok", false)) throw sherd::InputError(reply->value("error", "sherdd refused the request"));
  return *reply;
}

std::string fixed(const json& value, const char* unit) {
  return value.is_number() ? fmt::format("{:.1f} {}", value.get<double>(), unit) : "—";
}

// Streams a job's events (after the first reply) to the terminal; `on_done` gets the finished
// event of a job that succeeded (unless as_json: then every event is printed as it is). Returns
// the exit code. `job` names the job in messages ("scan", "calibration").
int follow_events(JsonLineSocket& socket, const std::string& scan_id, bool as_json, const std::string& job,
                  const std::function<void(const json&)>& on_done) {
  while (auto event = socket.receive()) {
    if (as_json) std::cout << event->dump() << std::endl;
    const std::string kind = event->value("event", "");
    if (kind == "view") {
      std::cerr << fmt::format("[acquisition] view {}/{} at {:.2f}° ({} points)\n",
                               event->value("index", 0) + 1, event->value("views", 0),
                               event->value("angle_deg", 0.0), event->value("points", 0));
    } else if (kind == "stage" && event->contains("ms")) {
      std::cerr << fmt::format("[{}] {:.0f} ms\n", event->value("stage", ""), event->value("ms", 0.0));
    } else if (kind == "sherd") {
      const std::string reason = event->value("reason", "");
      std::cerr << fmt::format("[sherd {}] {}{}\n", event->value("sherd_id", ""),
                               event->value("axis_found", false) ? "axis found" : "no axis",
                               reason.empty() ? "" : ": " + reason);
    } else if (kind == "finished") {
      if (event->value("state", "") != "done") {
        std::cerr << fmt::format("sherdctl: {} {} failed: {}\n", job, scan_id, event->value("reason", ""));
        return 1;
      }
      if (on_done && !as_json) on_done(*event);
      return 0;
    }
  }
  std::cerr << fmt::format("sherdctl: lost the connection to sherdd; {} {} goes on (or, a scan, resumes when "
                           "sherdd runs again): follow it with `sherdctl show {} --wait`\n", job, scan_id, scan_id);
  return 1;
}

// --material NAME and --sherd-material ID=NAME (repeatable) as a MaterialChoice.
sherd::station::MaterialChoice material_choice(const std::string& material,
                                               const std::vector<std::string>& sherd_materials) {
  sherd::station::MaterialChoice choice{material, {}};
  for (const auto& pair : sherd_materials) {
    const auto equals = pair.find('=');
    if (equals == std::string::npos || equals == 0 || equals + 1 == pair.size())
      throw sherd::InputError(fmt::format(
          "--sherd-material '{}': give SHERD_ID=PRESET, e.g. --sherd-material s02=felt", pair));
    choice.per_sherd[pair.substr(0, equals)] = pair.substr(equals + 1);
  }
  return choice;
}

int cmd_scan(const Options& options, const sherd::station::MaterialChoice& materials) {
  auto socket = sherd::station::connect_unix(socket_path(options));
  json request = materials.to_json();
  request["cmd"] = "scan";
  socket.send(request);
  auto reply = socket.receive();
  if (!reply || !reply->value("ok", false)) {
    throw sherd::InputError(reply ? reply->value("error", "scan refused") : "sherdd closed the connection");
  }
  const std::string scan_id = reply->value("scan_id", "");
  std::cerr << fmt::format("scan {} started\n", scan_id);
  return follow_events(socket, scan_id, options.as_json, "scan", [&scan_id](const json& finished) {
    const auto& sherds = finished["sherds"];
    if (sherds.empty()) std::cerr << fmt::format("scan {}: no sherds found\n", scan_id);
    for (const auto& s : sherds) std::cout << s.value("plate", "") << '\n';
  });
}

std::string triple(const json& a, const char* format) {
  return fmt::format(fmt::runtime(format), a.at(0).get<double>(), a.at(1).get<double>(), a.at(2).get<double>());
}

int cmd_calibrate(const Options& options, const std::string& kind) {
  if (kind != "turntable") throw sherd::InputError(sherd::station::calibration_refusal(kind));
  auto socket = sherd::station::connect_unix(socket_path(options));
  socket.send({{"cmd", "calibrate"}, {"kind", kind}});
  auto reply = socket.receive();
  if (!reply || !reply->value("ok", false)) {
    throw sherd::InputError(reply ? reply->value("error", "calibration refused") : "sherdd closed the connection");
  }
  const std::string job_id = reply->value("scan_id", "");
  std::cerr << fmt::format("turntable calibration {} started: the calibration object must stand on the plate\n",
                           job_id);
  return follow_events(socket, job_id, options.as_json, "calibration", [](const json& finished) {
    const auto& c = finished["calibration"];
    std::cout << fmt::format(
        "turntable axis in the scanner frame\n"
        "  direction  {}  ± {:.4f}°\n"
        "  point      {} mm  ± {:.4f} mm across, ± {:.4f} mm along (on the plate top)\n"
        "  RMS        {:.4f} mm of the sphere centres ({} views, {} spheres, {} centres, {} rejected)\n"
        "  saved to   {}\n",
        triple(c["axis_direction"], "[{:.6f}, {:.6f}, {:.6f}]"), c.value("direction_sd_deg", 0.0),
        triple(c["axis_point_mm"], "[{:.3f}, {:.3f}, {:.3f}]"), c.value("point_sd_mm", 0.0),
        c.value("height_sd_mm", 0.0), c.value("rms_residual_mm", 0.0), c.value("views_used", 0),
        c.value("spheres_used", 0), c.value("centres_used", 0), c.value("centres_rejected", 0),
        c.value("file", ""));
  });
}

// Scanner (camera + projector) calibration from capture folders of a chessboard under the
// Gray-code sequence; runs here, without sherdd. Writes the calibration file and records the result
// in the station's database.
struct ScannerCalibrationArgs {
  std::vector<std::string> captures;
  std::string out, reference, data_dir;
  int projector_width = 1024, projector_height = 768;
  int board_columns = 9, board_rows = 7;
  double square_mm = 75;
  int black_threshold = 40, white_threshold = 5;
};

json intrinsics_json(const sherd::structured_light::Intrinsics& in) {
  return {{"fx", in.matrix(0, 0)}, {"fy", in.matrix(1, 1)}, {"cx", in.matrix(0, 2)},
          {"cy", in.matrix(1, 2)}, {"distortion", in.distortion}};
}

json calibration_json(const sherd::structured_light::ProCamCalibration& c) {
  const Eigen::Vector3d t = c.translation_mm;
  return {{"camera", intrinsics_json(c.camera)},
          {"projector", intrinsics_json(c.projector)},
          {"rotation_deg", Eigen::AngleAxisd(c.rotation).angle() * 180 / M_PI},
          {"translation_mm", {t.x(), t.y(), t.z()}},
          {"stereo_rms_px", c.stereo_rms_px}};
}

int cmd_calibrate_scanner(const Options& options, const ScannerCalibrationArgs& args) {
  namespace sl = sherd::structured_light;
  auto config = sherd::config::load_station_config(options.config_file);
  if (!args.data_dir.empty()) sherd::config::set_data_dir(config, args.data_dir);
  sl::CalibrationOptions calibration_options;
  calibration_options.patterns = {args.projector_width, args.projector_height};
  calibration_options.thresholds = {args.black_threshold, args.white_threshold};
  calibration_options.board = {args.board_columns, args.board_rows, args.square_mm};
  std::vector<std::filesystem::path> dirs(args.captures.begin(), args.captures.end());
  const sl::CalibrationReport report = sl::calibrate(dirs, calibration_options);
  const std::filesystem::path out =
      args.out.empty() ? config.paths.data_dir / "calibration" / "scanner.xml"
                       : std::filesystem::path(args.out);
  if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
  sl::write_calibration(out, report.calibration);
  json result = calibration_json(report.calibration);
  result["file"] = out.string();
  result["poses_used"] = report.poses_used;
  result["projector_corners"] = report.projector_corners;
  result["camera_rms_px"] = report.calibration.camera_rms_px;
  result["projector_rms_px"] = report.calibration.projector_rms_px;
  std::optional<sl::ProCamCalibration> reference;
  if (!args.reference.empty()) {
    reference = sl::read_calibration(args.reference);
    result["reference"] = calibration_json(*reference);
  }
  std::filesystem::create_directories(config.paths.database.parent_path());
  sherd::db::Store(config.paths.database).add_calibration("scanner", "", result);
  if (options.as_json) {
    std::cout << result.dump(2) << '\n';
    return 0;
  }
  const sl::ProCamCalibration& c = report.calibration;
  auto row = [&](const char* name, auto&& value) {
    std::cout << fmt::format("  {:<22}{:>14.4f}", name, value(c));
    if (reference) std::cout << fmt::format("{:>14.4f}", value(*reference));
    std::cout << '\n';
  };
  std::cout << fmt::format("scanner calibration from {} poses ({} projector corners)\n",
                           report.poses_used, report.projector_corners);
  std::cout << fmt::format("  {:<22}{:>14}{}\n", "", "ours",
                           reference ? fmt::format("{:>14}", "reference") : "");
  using P = const sl::ProCamCalibration&;
  row("camera fx, px", [](P p) { return p.camera.matrix(0, 0); });
  row("camera fy, px", [](P p) { return p.camera.matrix(1, 1); });
  row("camera cx, px", [](P p) { return p.camera.matrix(0, 2); });
  row("camera cy, px", [](P p) { return p.camera.matrix(1, 2); });
  row("projector fx, px", [](P p) { return p.projector.matrix(0, 0); });
  row("projector fy, px", [](P p) { return p.projector.matrix(1, 1); });
  row("projector cx, px", [](P p) { return p.projector.matrix(0, 2); });
  row("projector cy, px", [](P p) { return p.projector.matrix(1, 2); });
  row("rotation, deg", [](P p) { return Eigen::AngleAxisd(p.rotation).angle() * 180 / M_PI; });
  row("translation x, mm", [](P p) { return p.translation_mm.x(); });
  row("translation y, mm", [](P p) { return p.translation_mm.y(); });
  row("translation z, mm", [](P p) { return p.translation_mm.z(); });
  row("stereo RMS, px", [](P p) { return p.stereo_rms_px; });
  std::cout << fmt::format("  saved to {}\n", out.string());
  return 0;
}

int cmd_status(const Options& options) {
  const auto status = request(options, {{"cmd", "status"}})["status"];
  if (options.as_json) {
    std::cout << status.dump(2) << '\n';
    return 0;
  }
  const auto& t = status["turntable"];
  std::cout << fmt::format("station     {}\nscanner     {}\nturntable   {} — {}{}\n", status.value("station", ""),
                           status.value("scanner", ""), t.value("device", ""), t.value("state", ""),
                           t["position_deg"].is_number() ? fmt::format(" at {:.2f}°", t["position_deg"].get<double>()) : "");
  std::cout << fmt::format("acquiring   {}\nprocessing  {}\nqueued      {} to acquire, {} to process\noutput      {}\n",
                           status["acquiring"].is_null() ? "—" : status["acquiring"].get<std::string>(),
                           status["processing"].is_null() ? "—" : status["processing"].get<std::string>(),
                           status.value("queued_acquisitions", 0), status.value("queued_processing", 0),
                           status.value("output_dir", ""));
  const auto& c = status["turntable_calibration"];
  if (c.value("calibrated", false)) {
    std::cout << fmt::format("calibration turntable axis ± {:.4f}°, point ± {:.4f} mm, RMS {:.4f} mm ({})\n",
                             c.value("direction_sd_deg", 0.0), c.value("point_sd_mm", 0.0),
                             c.value("rms_residual_mm", 0.0), c.value("file", ""));
  } else {
    std::cout << fmt::format("calibration {}\n", c.value("note", "none"));
  }
  return 0;
}

int cmd_jobs(const Options& options, int limit) {
  const auto jobs = request(options, {{"cmd", "jobs"}, {"limit", limit}})["jobs"];
  if (options.as_json) {
    std::cout << jobs.dump(2) << '\n';
    return 0;
  }
  std::cout << fmt::format("{:<22} {:<10} {:>5} {:>6}  {}\n", "SCAN", "STATE", "VIEWS", "SHERDS", "CREATED / REASON");
  for (const auto& j : jobs) {
    std::cout << fmt::format("{:<22} {:<10} {:>2}/{:<2} {:>6}  {}\n", j.value("scan_id", ""), j.value("state", ""),
                             j.value("views", 0), j.value("planned_views", 0), j.value("sherds", 0),
                             j.value("reason", "").empty() ? j.value("created_at", "") : j.value("reason", ""));
  }
  return 0;
}

int cmd_show(const Options& options, const std::string& scan_id, bool wait) {
  if (wait) {
    auto socket = sherd::station::connect_unix(socket_path(options));
    socket.send({{"cmd", "follow"}, {"scan_id", scan_id}});
    auto reply = socket.receive();
    if (!reply || !reply->value("ok", false)) {
      throw sherd::InputError(reply ? reply->value("error", "") : "sherdd closed the connection");
    }
    const int code = follow_events(socket, scan_id, false, "scan", nullptr);  // the summary below says it all
    if (code != 0) return code;
  }
  const auto shown = request(options, {{"cmd", "show"}, {"scan_id", scan_id}});
  if (options.as_json) {
    std::cout << shown.dump(2) << '\n';
    return 0;
  }
  const auto& scan = shown["scan"];
  std::cout << fmt::format("scan {}  {}{}\ncreated {}  updated {}\nviews {}/{}  output {}\n", scan.value("scan_id", ""),
                           scan.value("state", ""), scan.value("reason", "").empty() ? "" : ": " + scan.value("reason", ""),
                           scan.value("created_at", ""), scan.value("updated_at", ""), scan.value("views", 0),
                           scan.value("planned_views", 0), scan.value("output_dir", ""));
  for (const auto& stage : shown["stages"]) {
    std::cout << fmt::format("  stage {:<16} {:>8.0f} ms\n", stage.value("stage", ""), stage.value("duration_ms", 0.0));
  }
  for (const auto& s : shown["sherds"]) {
    const auto& m = s["measurements"];
    std::cout << fmt::format("  sherd {}  {} points  axis {}  rim Ø {}  rim {}  wall {}\n", s.value("sherd_id", ""),
                             s.value("points", 0), s["axis"].value("found", false) ? "found" : "not found",
                             fixed(m["rim_diameter_mm"], "mm"), fixed(m["rim_percent"], "%"),
                             fixed(m["wall_thickness_mm"]["mean"], "mm"));
  }
  return 0;
}

int cmd_process(const Options& options, const std::vector<std::string>& files, const std::string& out_dir,
                const std::string& units, const std::string& background,
                const sherd::station::MaterialChoice& materials) {
  auto config = sherd::config::load_station_config(options.config_file);
  sherd::station::check_materials(materials, config.render);
  config.paths.output_dir = std::filesystem::absolute(out_dir);
  std::filesystem::create_directories(config.paths.output_dir);
  auto store = std::make_shared<sherd::db::Store>(config.paths.output_dir / "sherdscan.db");

  // Offline there is no daemon log: lines go to the terminal, a log file and the events table.
  std::vector<spdlog::sink_ptr> sinks{
      std::make_shared<spdlog::sinks::basic_file_sink_mt>((config.paths.output_dir / "sherdctl.log").string()),
      sherd::db::make_event_sink(store)};
  spdlog::set_default_logger(std::make_shared<spdlog::logger>("sherdctl", sinks.begin(), sinks.end()));

  // Files are not on the station's plate: no scanning volume, no holding frame; the background
  // only if asked for.
  auto params = sherd::station::segmentation_params(config.segmentation);
  params.volume_radius_mm = 0.0;
  params.frame_height_mm = 0.0;
  params.background = background == "black"   ? sherd::segmentation::BackgroundColour::Black
                      : background == "white" ? sherd::segmentation::BackgroundColour::White
                                              : sherd::segmentation::BackgroundColour::None;
  const auto file_units = units == "m" ? sherd::io::Units::Metres : sherd::io::Units::Millimetres;

  int failures = 0;
  for (const auto& file : files) {
    json settings = materials.to_json();
    settings.update({{"file", file}, {"units", units}, {"background", background}});
    const auto scan_id = store->create_scan("process", 0, settings, config.paths.output_dir.string());
    sherd::db::ScanLogScope scope(scan_id);
    try {
      store->set_scan_state(scan_id, sherd::db::ScanState::Processing);
      const auto model = sherd::io::read_model(file, file_units);
      sherd::station::Pipeline pipeline(
          config, *store,
          [](const json& e) {
            if (e.value("event", "") == "sherd" && !e.value("axis_found", false)) {
              std::cerr << fmt::format("  sherd {}: no axis: {}\n", e.value("sherd_id", ""), e.value("reason", ""));
            }
          },
          materials);
      const auto outcome = pipeline.process_model(scan_id, model, params, file);
      store->set_scan_state(scan_id, sherd::db::ScanState::Done);
      std::cerr << fmt::format("{}: {} sherd(s) → {}\n", file, outcome.sherds.size(), outcome.dir.string());
      for (const auto& s : outcome.sherds) std::cout << s.plate.string() << '\n';
    } catch (const std::exception& e) {
      ++failures;
      store->set_scan_state(scan_id, sherd::db::ScanState::Failed, e.what());
      std::cerr << "sherdctl: " << e.what() << '\n';
    }
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sherdctl — operate the sherdscan station (through sherdd) or process files offline"};
  app.require_subcommand(1);
  Options options;
  app.add_option("-c,--config", options.config_file, "station configuration (for the socket path and processing settings)")
      ->capture_default_str();
  app.add_option("--socket", options.socket, "sherdd's control socket (default: from the config; env SHERD_SOCKET)");
  app.add_flag("--json", options.as_json, "print machine-readable JSON instead of text");

  auto* scan = app.add_subcommand("scan", "press scan: acquire and process one scan; prints the plates' paths");
  // The plates' material, per scan and per sherd (both for scan and process).
  std::string material;
  std::vector<std::string> sherd_materials;
  const auto add_material_options = [&](CLI::App* command) {
    command->add_option("--material", material,
                        "material preset of the plates (a <material> in the materials file; default: "
                        "[render] material)");
    command->add_option("--sherd-material", sherd_materials,
                        "SHERD_ID=PRESET: another preset for one sherd (s01, s02…; repeatable)");
  };
  add_material_options(scan);
  app.add_subcommand("status", "state of the station: devices, job in hand, queues");
  int limit = 20;
  auto* jobs = app.add_subcommand("jobs", "recent scans and their states");
  jobs->add_option("-n,--limit", limit, "how many scans")->capture_default_str();
  std::string scan_id;
  bool wait = false;
  auto* show = app.add_subcommand("show", "one scan: views, stages, sherds and measurements");
  show->add_option("SCAN_ID", scan_id, "the scan's id (see `sherdctl jobs`)")->required();
  show->add_flag("--wait", wait, "wait until the scan has finished first");
  std::string calibration_kind;
  auto* calibrate = app.add_subcommand("calibrate", "run a calibration procedure: turntable through sherdd (stored in a "
                                                     "file and the database, used at once); scanner from --captures, "
                                                     "here (stored in a file and the database)");
  calibrate->add_option("KIND", calibration_kind, "turntable (the axis, from a scan of the calibration object) "
                                                   "or scanner (camera + projector, from --captures)")
      ->required()
      ->check(CLI::IsMember({"turntable", "scanner"}));
  ScannerCalibrationArgs scanner_args;
  calibrate->add_option("--captures", scanner_args.captures,
                        "scanner: folders of one chessboard pose each, graycode_00.png… (the Gray-code "
                        "sequence, then white and black); calibrates here, without sherdd")
      ->check(CLI::ExistingDirectory);
  calibrate->add_option("--out", scanner_args.out, "scanner: calibration file to write (default "
                                                   "DATA_DIR/calibration/scanner.xml)");
  calibrate->add_option("--data-dir", scanner_args.data_dir,
                        "scanner: override station.data_dir (the database and default --out)");
  calibrate->add_option("--reference", scanner_args.reference,
                        "scanner: a calibration file (OpenCV XML) to print beside ours")
      ->check(CLI::ExistingFile);
  calibrate->add_option("--projector-width", scanner_args.projector_width, "scanner: projector pixels")
      ->capture_default_str();
  calibrate->add_option("--projector-height", scanner_args.projector_height, "scanner: projector pixels")
      ->capture_default_str();
  calibrate->add_option("--board-columns", scanner_args.board_columns,
                        "inner corners along the board's long side")->capture_default_str();
  calibrate->add_option("--board-rows", scanner_args.board_rows,
                        "inner corners along the board's short side")->capture_default_str();
  calibrate->add_option("--square-mm", scanner_args.square_mm, "scanner: chessboard square side")
      ->capture_default_str();
  calibrate->add_option("--black-thr", scanner_args.black_threshold,
                        "white − black at or below this is shadow (grey levels)")->capture_default_str();
  calibrate->add_option("--white-thr", scanner_args.white_threshold,
                        "|pattern − inverse| below this is ambiguous (grey levels)")->capture_default_str();
  std::vector<std::string> files;
  std::string out_dir, units = "mm", background = "none";
  auto* process = app.add_subcommand("process", "run the pipeline offline on existing files (no daemon needed)");
  process->add_option("FILE", files, "PLY, OBJ, OFF, STL or PCD: one sherd, a vessel or a tray")->required()->check(CLI::ExistingFile);
  process->add_option("-o,--out", out_dir, "output directory (one folder per file)")->required();
  process->add_option("--units", units, "units of the files")->check(CLI::IsMember({"mm", "m"}))->capture_default_str();
  process->add_option("--background", background, "colour of a background to remove")
      ->check(CLI::IsMember({"none", "black", "white"}))->capture_default_str();
  add_material_options(process);
  CLI11_PARSE(app, argc, argv);

  try {
    if (*scan) return cmd_scan(options, material_choice(material, sherd_materials));
    if (*calibrate && calibration_kind == "scanner" && !scanner_args.captures.empty())
      return cmd_calibrate_scanner(options, scanner_args);
    if (*calibrate) return cmd_calibrate(options, calibration_kind);
    if (app.got_subcommand("status")) return cmd_status(options);
    if (*jobs) return cmd_jobs(options, limit);
    if (*show) return cmd_show(options, scan_id, wait);
    if (*process)
      return cmd_process(options, files, out_dir, units, background, material_choice(material, sherd_materials));
  } catch (const std::exception& e) {
    std::cerr << "sherdctl: " << e.what() << '\n';
    return 2;
  }
  return 0;
}
