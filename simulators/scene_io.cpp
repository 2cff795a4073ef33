// write_scene lives apart from pottery.cpp so that code which only builds scenes (the scanner,
// most tests) does not pull in the PLY writer of sherd_io.
#include "core/errors.h"
#include "processing/io/model_io.h"
#include "simulators/pottery.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <system_error>

namespace sherd::sim {

void write_scene(const Scene& scene, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    throw InputError(fmt::format("cannot create scene directory {}: {}: choose a writable --out",
                                 dir.string(), ec.message()));
  }
  io::write_ply(dir / "scene.ply", merged_mesh(scene));
  const auto truth_path = dir / "truth.json";
  std::ofstream out(truth_path);
  out << truth_to_json(scene).dump(2) << '\n';
  if (!out) {
    throw InputError(fmt::format("cannot write {}: check the disk space and permissions",
                                 truth_path.string()));
  }
}

}  // namespace sherd::sim
