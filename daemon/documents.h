// The JSON documents of the output contract (../shared/DESIGN.md): sherd.json per sherd.
#pragma once

#include "core/types.h"
#include "processing/axis/axis.h"
#include "processing/profile/profile.h"

#include <nlohmann/json.hpp>

#include <string>

namespace sherd::station {

nlohmann::json to_json(const Vec3d& v);
nlohmann::json to_json(const Pose& pose);  // 4×4 row-major

// `analysis` is null when no axis was found (then `axis.found` is false and `axis.reason` says why).
nlohmann::json sherd_document(const std::string& scan_id, const std::string& sherd_id,
                              const Mesh& sherd, const axis::AxisEstimate& axis,
                              const profile::Analysis* analysis);

}  // namespace sherd::station
