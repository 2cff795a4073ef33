// write_scene and the sherdsim CLI: the PLY read back by the station's reader holds the scene,
// truth.json parses and describes the same sherds.
#include "core/errors.h"
#include "processing/io/model_io.h"
#include "simulators/pottery.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <unistd.h>

namespace sherd::sim {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("sherd_sim_" + name + "_" +
                                                    std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

nlohmann::json read_json(const fs::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

TEST(SceneIo, WrittenSceneReadsBackWithColoursAndTruth) {
  const Scene scene = make_scene({.seed = 9, .kind = SceneKind::Plate, .sherds = 3,
                                  .background = Background::White});
  const fs::path dir = fresh_dir("write");
  write_scene(scene, dir);
  const Mesh back = io::read_model(dir / "scene.ply");
  const Mesh all = merged_mesh(scene);
  ASSERT_EQ(back.vertices.size(), all.vertices.size());
  ASSERT_EQ(back.triangles.size(), all.triangles.size());
  ASSERT_TRUE(back.vertices.has_colours());
  const Box3 a = Box3::of(back.vertices), b = Box3::of(all.vertices);
  EXPECT_LT((a.min - b.min).norm() + (a.max - b.max).norm(), 1e-3);
  EXPECT_NEAR(a.max.x(), kPlateRadiusMm, 1e-3);  // the plate, 300 mm across
  const auto truth = read_json(dir / "truth.json");
  EXPECT_EQ(truth["background"], "white");
  ASSERT_EQ(truth["sherds"].size(), 3u);
  fs::remove_all(dir);
}

TEST(SceneIo, UnwritableDirectoryIsAnInputError) {
  const Scene scene = make_scene({.kind = SceneKind::Empty, .sherds = 0});
  EXPECT_THROW(write_scene(scene, "/proc/sherd_cannot_be_here"), InputError);
}

TEST(SherdsimCli, WritesSceneAndTruthAndRejectsBadArguments) {
  const std::string exe = SHERD_BINARY_DIR "/simulators/sherdsim";
  const fs::path dir = fresh_dir("cli");
  const std::string ok = exe + " --scene vessel --seed 4 --background black --out " +
                         dir.string() + " > /dev/null";
  ASSERT_EQ(std::system(ok.c_str()), 0);
  const auto truth = read_json(dir / "truth.json");
  ASSERT_EQ(truth["sherds"].size(), 1u);
  EXPECT_TRUE(truth["sherds"][0]["complete"].get<bool>());
  EXPECT_DOUBLE_EQ(truth["sherds"][0]["rim_percent"].get<double>(), 100.0);
  EXPECT_TRUE(fs::file_size(dir / "scene.ply") > 1000);
  for (const std::string bad : {" --scene tray", " --sherds 11", " --background grey", ""}) {
    const std::string cmd = exe + bad + (bad.empty() ? "" : " --out " + dir.string()) +
                            " > /dev/null 2>&1";
    EXPECT_NE(std::system(cmd.c_str()), 0) << bad;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sherd::sim
