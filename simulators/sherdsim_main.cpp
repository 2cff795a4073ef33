// sherdsim: writes a synthetic scene as DIR/scene.ply plus its ground truth DIR/truth.json
// (fields documented in simulators/pottery.h), for tests and benchmarks.
#include "simulators/pottery.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  CLI::App app{"sherdsim — synthetic pottery scenes with ground truth (scene.ply + truth.json)"};
  std::string scene = "frame", background = "black", out;
  int sherds = 4;
  std::uint64_t seed = 42;
  app.add_option("--scene", scene, "frame | plate | vessel | empty | calibration")
      ->check(CLI::IsMember({"frame", "plate", "vessel", "empty", "calibration"}))
      ->capture_default_str();
  app.add_option("--sherds", sherds, "number of sherds (frame, plate; empty: frame slots)")
      ->check(CLI::Range(0, sherd::sim::kMaxSherds))
      ->capture_default_str();
  app.add_option("--seed", seed, "random seed: the same seed gives the same scene")
      ->capture_default_str();
  app.add_option("--background", background, "plate and frame colour: black | white")
      ->check(CLI::IsMember({"black", "white"}))
      ->capture_default_str();
  app.add_option("--out", out, "output directory (created if missing)")->required();
  CLI11_PARSE(app, argc, argv);

  try {
    sherd::sim::SceneSpec spec;
    spec.kind = sherd::sim::scene_kind_from_string(scene);
    spec.background = sherd::sim::background_from_string(background);
    spec.sherds = sherds;
    spec.seed = seed;
    const auto made = sherd::sim::make_scene(spec);
    sherd::sim::write_scene(made, out);
    fmt::print("{}/scene.ply, {}/truth.json: {} scene, {} sherd(s), seed {}\n", out, out, scene,
               made.truth.size(), seed);
  } catch (const std::exception& e) {
    fmt::print(stderr, "sherdsim: {}\n", e.what());
    return 1;
  }
  return 0;
}
