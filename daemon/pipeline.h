// The scan pipeline after acquisition: registration → segmentation → per sherd: axis → profile →
// measurements → plate, with every stage timed and its figures stored. Used by sherdd for the
// station's scans and by `sherdctl process` for existing files.
#pragma once

#include "config/station_config.h"
#include "core/types.h"
#include "db/store.h"
#include "processing/registration/registration.h"
#include "processing/segmentation/segmentation.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace sherd::station {

// Progress events for clients ({"event": "stage" | "sherd" | …, …}).
using EventFn = std::function<void(const nlohmann::json& event)>;

struct ViewFile {
  int index = 0;
  std::filesystem::path raw_path;
  double angle_rad = 0.0;  // encoder angle the view was captured at
};

struct SherdOutcome {
  std::string sherd_id;
  std::filesystem::path dir;
  std::filesystem::path plate;
  bool axis_found = false;
  std::string reason;  // why no axis (empty when found)
};

struct ScanOutcome {
  std::string scan_id;
  std::filesystem::path dir;  // <output_dir>/<scan_id>
  std::vector<SherdOutcome> sherds;
};

// The material preset of each plate: the scan's (empty: the station's `[render] material`),
// overridden per sherd id ("s01"…). Chosen per scan request (`sherdctl scan|process --material
// NAME --sherd-material ID=NAME`) and kept in the scan's settings, so a resumed scan keeps it.
struct MaterialChoice {
  std::string scan;
  std::map<std::string, std::string> per_sherd;

  const std::string& for_sherd(const std::string& sherd_id,
                               const config::RenderSettings& station) const;
  nlohmann::json to_json() const;  // {"material": …, "sherd_materials": {id: preset}}
  // From a request or a scan's settings (absent keys: the station's choice). Throws
  // sherd::InputError naming the key when it is not a string / a map of strings.
  static MaterialChoice from_json(const nlohmann::json& doc);
};

// Throws sherd::InputError naming the unknown preset, who asked for it and the presets the
// materials file has (or what is wrong with the file): called before a scan starts.
void check_materials(const MaterialChoice& choice, const config::RenderSettings& station);

segmentation::Params segmentation_params(const config::SegmentationSettings& settings);
registration::Params registration_params(const config::RegistrationSettings& settings);

class Pipeline {
 public:
  Pipeline(const config::StationConfig& config, db::Store& store, EventFn on_event = {},
           MaterialChoice materials = {});

  // Views of the station, read back from their raw files: placed by the turntable prior with the
  // calibrated scanner pose, refined, then segmented and analysed.
  ScanOutcome process_views(const std::string& scan_id, const std::vector<ViewFile>& views,
                            const Pose& scanner_to_world,
                            const registration::PriorUncertainty& prior_uncertainty);

  // An existing model (already in one frame): segmented with `params`, then analysed.
  ScanOutcome process_model(const std::string& scan_id, const Mesh& model,
                            const segmentation::Params& params, const std::string& source_file);

 private:
  ScanOutcome analyse_scan(const std::string& scan_id, const Mesh& fused,
                           const segmentation::Params& params, nlohmann::json scan_document);
  SherdOutcome analyse_sherd(const std::string& scan_id, const segmentation::Part& part,
                             const std::filesystem::path& scan_dir);
  void record_stage(const std::string& scan_id, const std::string& stage, double ms,
                    const nlohmann::json& figures);
  void emit(const nlohmann::json& event) const;

  const config::StationConfig& config_;
  db::Store& store_;
  EventFn on_event_;
  MaterialChoice materials_;
};

}  // namespace sherd::station
