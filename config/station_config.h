// The station configuration (config/station.toml), parsed with toml++ and validated strictly:
// an unknown key, a wrong type or a value out of range stops the program with one line naming
// the file, line, key and what is expected.
#pragma once

#include "core/types.h"

#include <cstdint>
#include <filesystem>
#include <string>

namespace sherd::config {

struct PathSettings {
  std::filesystem::path data_dir;    // [station] data_dir ("var"); relative → to the working dir
  std::filesystem::path database;    // data_dir/sherdscan.db
  std::filesystem::path raw_dir;     // data_dir/raw      (raw views, written before processing)
  std::filesystem::path output_dir;  // [station] output_dir, default data_dir/output
  std::filesystem::path socket;      // [station] socket, default data_dir/sherdd.sock
  std::filesystem::path log_file;    // data_dir/sherdd.log
  // Whether output_dir / socket were set explicitly in [station] (then set_data_dir keeps them).
  bool output_dir_from_config = false;
  bool socket_from_config = false;
};

struct ScanSettings {
  int views = 8;                 // turntable stops per scan, evenly spaced over 360°
  double start_angle_deg = 0.0;  // angle of the first view
};

struct ScannerSettings {
  // "simulated" (ray-cast views), "structured-light-simulated" (the structured-light scanner on
  // the simulated GigE camera and projector), "structured-light" (Aravis camera + projector)
  std::string driver = "simulated";
  int width = 640, height = 480;     // pixels
  double fx = 800.0, fy = 800.0;     // focal lengths in pixels
  double cx = 319.5, cy = 239.5;     // principal point in pixels
  // Calibrated pose of the scanner in the world (= turntable) frame: optical centre and a point
  // the optical axis passes through; image "up" is towards +z of the world.
  Vec3d position_mm{0.0, -420.0, 260.0};
  Vec3d look_at_mm{0.0, 0.0, 50.0};
  // Projector optical centre in the scanner frame (the structured-light baseline), for shadowing.
  Vec3d projector_offset_mm{120.0, 0.0, 0.0};
  // Noise model of the simulated scanner.
  double depth_noise_mm = 0.05;       // standard deviation along the viewing ray
  double grazing_limit_deg = 78.0;    // beyond this incidence angle no point is measured
  double dropout_fraction = 0.01;     // random missing cells
  // Structured-light drivers ("structured-light", "structured-light-simulated"): the Aravis camera
  // (device id or IP; "" = the first found), the calibration file of `sherdctl calibrate scanner`
  // (default data_dir/calibration/scanner.xml), the pattern set and the decoder's thresholds.
  std::string camera_id;
  std::filesystem::path calibration_file;
  bool calibration_file_from_config = false;
  std::string patterns = "gray";  // gray | phase (Gray code + phase-shifted fringes)
  int black_threshold = 40;       // white − black frame, grey levels: below is shadow
  int white_threshold = 5;        // |pattern − inverse|, grey levels: below the bit is unclear
  int edge_bits = 1;              // unclear bits per axis tolerated (a stripe edge)
  double min_modulation = 8.0;    // phase: fringe amplitude, grey levels
  int phase_period_px = 16;
  int phase_steps = 4;
  double max_ray_gap_mm = 0.0;    // drop points whose rays pass further apart; 0 = keep all
  int projector_width = 1024, projector_height = 768;  // where the calibration file has none
  // Camera trigger per pattern: "software" (the driver triggers once the projector shows the
  // pattern) or "line" (the projector's sync output drives `trigger_line`, rising edge).
  std::string trigger = "software";
  std::string trigger_line = "Line1";
  // The projector as a display (DRM/KMS): the card, and its connector ("" = the first connected).
  std::string projector_device = "/dev/dri/card0";
  std::string projector_connector;
};

struct TurntableSettings {
  std::string driver = "simulated";  // simulated | usb (libusb) | usb-simulated (USB driver on the simulated firmware)
  int steps_per_revolution = 3200;   // encoder / microstep resolution
  double speed_deg_s = 90.0;
  double acceleration_deg_s2 = 360.0;
  double time_scale = 1.0;           // simulated motion time multiplier (0 = instantaneous)
  std::string fault = "none";        // simulated fault: none | stall | timeout | disconnect
  int fault_at_move = 1;             // the move (1-based, counting from the first move of a scan) that fails
  double angle_sd_deg = 0.1;         // accuracy of the encoder's angle (1σ): weight of the turntable prior
  // usb-simulated faults: no_reply | garbled | unplug | homing besides stall and disconnect;
  // how many consecutive commands a fault strikes (drivers/README.md)
  int fault_count = 1;
  // The USB controller (usb, usb-simulated): ids, serial (empty: any), CDC data interface,
  // timeouts and how often a missed move is re-homed and made again.
  int usb_vendor_id = 0x1209;
  int usb_product_id = 0x0001;
  std::string usb_serial;
  int usb_interface = 1;
  int reply_timeout_ms = 500;
  double reconnect_timeout_s = 5.0;
  int move_attempts = 3;
};

struct SimulationSettings {
  std::uint64_t seed = 42;
  std::string scene = "frame";       // frame (sherds upright in a holding frame) | plate | vessel | empty | calibration
  int sherds = 4;                    // number of sherds for frame / plate scenes
  std::string background = "black";  // black | white
  // How far the simulated scanner is physically mounted off its configured ([scanner]) pose:
  // a tilt about an axis through its optical centre, and a shift of that centre, in directions
  // drawn from `seed`. 0 = mounted exactly as configured.
  double scanner_tilt_error_deg = 0.0;
  double scanner_offset_error_mm = 0.0;
};

struct CalibrationSettings {
  int views = 12;                         // turntable stops of a calibration scan, over 360°
  std::filesystem::path turntable_file;   // [calibration] turntable_file, default data_dir/calibration/turntable.json
  bool turntable_file_from_config = false;  // set explicitly (then set_data_dir keeps it)
};

struct RegistrationSettings {
  bool refine_with_icp = true;
  double voxel_mm = 0.5;                  // downsampling before ICP
  double max_correspondence_mm = 3.0;
  int max_iterations = 40;
  double max_correction_deg = 3.0;        // a larger correction from the turntable prior is flagged
  double max_correction_mm = 5.0;
  bool use_colour = true;                 // photometric term where views have colour
  bool weight_by_incidence = true;        // grazing points pull less (registration.h)
};

struct SegmentationSettings {
  std::string background = "black";     // black | white | none: colour of plate/frame to remove
  double cluster_tolerance_mm = 2.5;     // Euclidean clustering distance
  int min_points = 400;                  // smaller clusters are reported as debris
  double min_extent_mm = 12.0;
  double max_extent_mm = 450.0;
  double volume_radius_mm = 160.0;       // scanning volume: cylinder about the turntable axis
  double volume_min_z_mm = 0.5;          // just above the plate
  double volume_max_z_mm = 400.0;
  double contact_erosion_mm = 0.0;       // split touching sherds (trays seen from above); 0: off
  double frame_height_mm = 0.0;          // top of the holding frame's plinths; 0: no frame
};

struct RenderSettings {
  int dpi = 600;
  std::string material = "clay";              // a preset from the materials file
  std::filesystem::path materials_file;       // relative → to the directory of the config file
  std::string section_side = "right";         // right (German/Austrian) | left (British)
  std::string png = "rgb8";                   // rgb8 (8-bit colour) | grey16 (16-bit grey)
};

struct StationConfig {
  std::filesystem::path source;  // the file it was read from (absolute)
  std::string name = "simulated station";
  PathSettings paths;
  ScanSettings scan;
  ScannerSettings scanner;
  TurntableSettings turntable;
  SimulationSettings simulation;
  CalibrationSettings calibration;
  RegistrationSettings registration;
  SegmentationSettings segmentation;
  RenderSettings render;
};

// Reads and validates `file`. Throws sherd::InputError with one line:
//   "<file>:<line>: <key>: expected <what>, got <what> — <what to do>".
StationConfig load_station_config(const std::filesystem::path& file);

// Re-roots every path derived from data_dir (used by `sherdd --data-dir`).
void set_data_dir(StationConfig& config, const std::filesystem::path& data_dir);

}  // namespace sherd::config
