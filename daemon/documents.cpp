#include "daemon/documents.h"

namespace sherd::station {
namespace {

nlohmann::json optional_number(const std::optional<double>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

nlohmann::json polyline(const profile::Polyline2& line) {
  auto out = nlohmann::json::array();
  for (const auto& [r, z] : line) out.push_back({r, z});
  return out;
}

}  // namespace

nlohmann::json to_json(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json to_json(const Pose& pose) {
  auto rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    rows.push_back({pose.matrix()(r, 0), pose.matrix()(r, 1), pose.matrix()(r, 2), pose.matrix()(r, 3)});
  }
  return rows;
}

nlohmann::json sherd_document(const std::string& scan_id, const std::string& sherd_id,
                              const Mesh& sherd, const axis::AxisEstimate& axis,
                              const profile::Analysis* analysis) {
  const Box3 box = Box3::of(sherd.vertices);
  // The oriented axis (base → rim) comes from the analysis when there is one.
  const axis::AxisEstimate& final_axis = analysis ? analysis->axis : axis;

  nlohmann::json doc;
  doc["schema"] = "sherdscan.sherd/1";
  doc["scan_id"] = scan_id;
  doc["sherd_id"] = sherd_id;
  doc["points"] = sherd.vertices.size();
  doc["bbox_mm"] = {to_json(box.min), to_json(box.max)};
  doc["axis"] = {
      {"found", final_axis.found},
      {"point_mm", final_axis.found ? to_json(final_axis.point) : nlohmann::json(nullptr)},
      {"direction", final_axis.found ? to_json(final_axis.direction) : nlohmann::json(nullptr)},
      {"method", final_axis.method},
      {"confidence", {{"angle_sd_deg", final_axis.angle_sd_deg}, {"offset_sd_mm", final_axis.offset_sd_mm}}},
      {"reason", final_axis.found ? nlohmann::json(nullptr) : nlohmann::json(final_axis.reason)},
  };
  doc["orientation"] = {{"rim_up_certain", analysis ? analysis->rim_up_certain : false}};

  // Without an axis nothing along it can be measured: every measurement is null, the keys stay.
  nlohmann::json measurements = {
      {"rim_diameter_mm", nullptr}, {"base_diameter_mm", nullptr}, {"max_diameter_mm", nullptr},
      {"height_mm", nullptr},
      {"wall_thickness_mm", {{"min", nullptr}, {"mean", nullptr}, {"max", nullptr}}},
      {"rim_percent", nullptr}, {"rim_inclination_deg", nullptr}, {"volume_ml", nullptr}};
  nlohmann::json profile = {{"outer", nlohmann::json::array()}, {"inner", nlohmann::json::array()}};
  if (analysis) {
    const auto& m = analysis->measurements;
    measurements = {
        {"rim_diameter_mm", optional_number(m.rim_diameter_mm)},
        {"base_diameter_mm", optional_number(m.base_diameter_mm)},
        {"max_diameter_mm", m.max_diameter_mm},
        {"height_mm", m.height_mm},
        {"wall_thickness_mm",
         {{"min", m.wall_thickness_mm.min}, {"mean", m.wall_thickness_mm.mean}, {"max", m.wall_thickness_mm.max}}},
        {"rim_percent", optional_number(m.rim_percent)},
        {"rim_inclination_deg", optional_number(m.rim_inclination_deg)},
        {"volume_ml", optional_number(m.volume_ml)},
    };
    profile = {{"outer", polyline(analysis->profile.outer)}, {"inner", polyline(analysis->profile.inner)}};
    // Added fields: the closed section and the measurements' sds propagated from the axis's.
    profile["section"] = polyline(analysis->profile.section);
    // Added: the aggregate profile over all azimuths and the points' spread about it.
    profile["aggregate"] = {{"outer", polyline(analysis->profile.aggregate_outer)},
                            {"inner", polyline(analysis->profile.aggregate_inner)},
                            {"spread_mm", analysis->profile.aggregate_spread_mm}};
    const auto& sd = analysis->measurement_sds;
    doc["measurement_sds"] = {
        {"rim_diameter_mm", optional_number(sd.rim_diameter_mm)},
        {"base_diameter_mm", optional_number(sd.base_diameter_mm)},
        {"max_diameter_mm", sd.max_diameter_mm},
        {"height_mm", sd.height_mm},
        {"wall_thickness_mean_mm", sd.wall_thickness_mean_mm},
        {"rim_percent", optional_number(sd.rim_percent)},
        {"rim_inclination_deg", optional_number(sd.rim_inclination_deg)},
    };
    doc["arc_deg"] = analysis->arc_deg;
    doc["has_rim"] = analysis->has_rim;
    doc["has_base"] = analysis->has_base;
    doc["sherd_to_world"] = to_json(analysis->sherd_to_world);
  }
  doc["measurements"] = measurements;
  doc["profile"] = profile;
  doc["artifacts"] = {{"plate", "plate.png"}, {"profile", "profile.svg"}, {"mesh", "sherd.ply"}};
  return doc;
}

}  // namespace sherd::station
