// Benchmark: view registration against ground truth, our method side by side with PCL's
// IterativeClosestPoint and GeneralizedIterativeClosestPoint (default settings) from the same
// seeds.
//  1. A directory in the Stanford `.conf` layout (default: the Stanford bunny), the turntable views
//     bunNNN only, each seeded by the nominal angle NNN in its name about the turntable axis.
//  2. The simulated station (scenes "frame" and "vessel") for --seeds seeds, 8 views each, the
//     encoder angle perturbed by up to ±0.5° and the translation by up to 0.2 mm.
// Errors compare relative poses (view 0 → view i), so the arbitrary world frame cancels; the
// translation error is given at the scanner origin, the world origin and the view's centroid.
// Ours also reports its whole time over the pairs it refined (seconds per pair).
// Prints one JSON object per view and method, then a summary per data set and method (and for the
// reference poses themselves, "reference": how well the views agree under them).
//   bench_registration [--conf DIR/bun.conf] [--config config/station.toml] [--seeds 3]
//                      [--scenes frame vessel] [--methods icp gicp | none] [--geometry-only]
#include "processing/registration/registration.h"
#include "bench/bench_stats.h"
#include "config/station_config.h"
#include "core/errors.h"
#include "daemon/pipeline.h"
#include "daemon/station.h"
#include "simulators/sim_turntable.h"

#include <fmt/format.h>
#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>

namespace {

using sherd::OrganisedView;
using sherd::Pose;
using Clock = std::chrono::steady_clock;
using CloudT = pcl::PointCloud<pcl::PointXYZ>;

constexpr double kDeg = M_PI / 180.0;

struct BenchView {
  std::string name;
  OrganisedView view;
  Pose prior;  // the seed every method starts from
  Pose truth;  // scanner → some fixed world frame
};

struct DataSet {
  std::string name;
  std::vector<BenchView> views;
  // What our method is told about the seeds: how uncertain they are and how large a correction is
  // still believable (the PCL methods get the seeds only).
  sherd::registration::PriorUncertainty prior;
  sherd::registration::Params params;
};

struct ViewError {
  double rotation_deg = 0.0;
  double translation_mm = 0.0;  // of the scanner origin: includes rotation error × lever arm
  double centroid_mm = 0.0;     // of the view's centroid: what the fused model actually suffers
  // Of the world origin (DESIGN.md: on the turntable axis at the plate centre; for a .conf set its
  // world origin): where the object stands, so the lever arm is the object's own size, as for a
  // .conf set's translation, whose origin lies within the object.
  double world_origin_mm = 0.0;
};

Eigen::Vector3d centroid(const OrganisedView& view) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < view.cells(); ++i) {
    if (view.valid[i]) sum += view.points[i].cast<double>();
  }
  return sum / std::max<double>(1.0, static_cast<double>(view.valid_count()));
}

// Error of view i's final pose, relative to view 0, against the truth relative to view 0.
ViewError relative_error(const Pose& est0, const Pose& est_i, const Pose& truth0,
                         const Pose& truth_i, const Eigen::Vector3d& view_centroid) {
  const Pose est_rel = est0.inverse() * est_i;
  const Pose truth_rel = truth0.inverse() * truth_i;
  const Eigen::AngleAxisd delta((truth_rel.inverse() * est_rel).rotation());
  const Eigen::Vector3d world_origin =
      truth_i.inverse() * Eigen::Vector3d::Zero();  // view i's frame
  return {delta.angle() / kDeg, (est_rel.translation() - truth_rel.translation()).norm(),
          (est_rel * view_centroid - truth_rel * view_centroid).norm(),
          (est_rel * world_origin - truth_rel * world_origin).norm()};
}

using sherd::bench::number_or_null;
using sherd::bench::quantile;

// ---------------------------------------------------------------------------------------------
// Stanford .conf layout

// The rigid transform of one `bmesh` line: p_world = R(q)^T p_scan + t (the conjugate quaternion,
// see the data set's SOURCE.txt), converted from metres to millimetres.
Pose conf_pose(double tx, double ty, double tz, double qx, double qy, double qz, double qw) {
  const Eigen::Quaterniond q(qw, qx, qy, qz);
  Pose pose = Pose::Identity();
  pose.linear() = q.normalized().toRotationMatrix().transpose();
  pose.translation() = 1000.0 * Eigen::Vector3d(tx, ty, tz);
  return pose;
}

// A Cyberware range scan (ASCII PLY): vertices x y z in metres, then `element range_grid` with one
// list per grid cell (num_cols × num_rows from obj_info, row-major) holding 0 or 1 vertex index.
// Parsed here because io::read_model returns the points without the grid, and PCL's PLYReader
// (which does keep it) lives in pcl_io, which this benchmark is not linked against. Metres → mm.
OrganisedView read_range_scan(const std::filesystem::path& file) {
  std::ifstream in(file);
  const auto fail = [&](const std::string& what) {
    return sherd::InputError(fmt::format(
        "{}: {}; the .conf benchmark needs Cyberware ASCII range scans", file.string(), what));
  };
  if (!in) throw fail("cannot open");
  std::string line;
  int cols = 0, rows = 0;
  std::size_t vertices = 0, cells = 0, vertex_properties = 0;
  std::string element;
  std::map<std::string, std::size_t> column;  // x, y, z → position within a vertex line
  bool ascii = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // the bunNNN copies are CRLF
    std::istringstream f(line);
    std::string word, a, b;
    f >> word;
    if (word == "end_header") break;
    if (word == "format") {
      f >> a;
      ascii = a == "ascii";
    }
    if (word == "obj_info" && (f >> a >> b)) {
      if (a == "num_cols") cols = std::stoi(b);
      if (a == "num_rows") rows = std::stoi(b);
    }
    if (word == "element") {
      std::size_t count = 0;
      f >> element >> count;
      if (element == "vertex") vertices = count;
      if (element == "range_grid") cells = count;
    }
    if (word == "property" && element == "vertex") {
      f >> a >> b;
      column[b] = vertex_properties++;
    }
  }
  if (!ascii || !column.count("x") || !column.count("y") || !column.count("z")) {
    throw fail("not an ASCII PLY with x y z vertices");
  }
  if (cols <= 0 || rows <= 0 || cells != static_cast<std::size_t>(cols) * rows) {
    throw fail(fmt::format("no range_grid of num_cols × num_rows cells ({} × {}, {} cells)", cols,
                           rows, cells));
  }
  std::vector<sherd::Vec3f> points(vertices);
  std::vector<double> values(vertex_properties);
  for (auto& p : points) {
    for (auto& v : values) {
      if (!(in >> v)) throw fail("vertex list ends early or holds a non-number");
    }
    p = 1000.0f * sherd::Vec3f(values[column["x"]], values[column["y"]], values[column["z"]]);
  }
  OrganisedView view;
  view.width = cols;
  view.height = rows;
  view.points.assign(cells, sherd::Vec3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  view.valid.assign(cells, 0);
  for (std::size_t cell = 0; cell < cells; ++cell) {
    int count = 0;
    std::size_t index = 0;
    if (!(in >> count) || count < 0 || count > 1 || (count == 1 && !(in >> index)) ||
        index >= vertices) {
      throw fail(fmt::format("range_grid cell {} is corrupt (expected `0` or `1 INDEX`)", cell));
    }
    if (count == 1 && points[index].allFinite()) {
      view.points[cell] = points[index];
      view.valid[cell] = 1;
    }
  }
  return view;
}

// The turntable views (names bunNNN, NNN = nominal plate angle in degrees) of a .conf directory.
// Prior: bun.conf's world frame is bun000's scanner frame, the plate turns about its Y axis, and a
// scan at nominal angle a satisfies p_world ≈ Ry(+a) p_scan (bun090's conjugate quaternion is
// +90.2° about Y, bun270's −90.0°, bun315's −45.2°). Our world frame has the turntable axis as z;
// S = Rx(+90°) maps bun000's Y onto z, and S·Ry(a)·S⁻¹ = Rz(a), so the prior S·Ry(a) is exactly
// turntable_prior(S, −a) (which is Rz(+a)·S). The axis passes through bun000's origin: bun090,
// bun180 and bun270 sit within 0.4 mm of a pure rotation about it.
DataSet read_conf(const std::filesystem::path& conf) {
  std::ifstream in(conf);
  if (!in)
    throw sherd::InputError(
        fmt::format("{}: cannot open; pass --conf DIR/NAME.conf", conf.string()));
  const std::regex turntable_name(R"(^(bun)(\d{3})(\.ply)?$)");
  const Pose to_z_up(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  DataSet set{conf.stem().string(), {}, {}, {}};
  // The nominal angles in the file names are not turntable readings: bun.conf puts bun045 at
  // 34.3° (10.7° off) and bun045 and bun315 tens of millimetres off the axis the others turn about
  // (the bunny was moved between scans). Our method is told so: a prior good to a few degrees and
  // a few centimetres, and corrections up to 15° and 80 mm believable.
  set.prior = {.angle_sd_deg = 5.0, .tilt_sd_deg = 1.0, .translation_sd_mm = 20.0};
  set.params.max_correction_deg = 15.0;
  set.params.max_correction_mm = 80.0;
  // The Cyberware sweeps a laser stripe along x and looks along its scan frame's +z: 99.6–100 % of
  // each turntable view's range-grid triangles face +z (their normals within 90° of it).
  set.params.parallel_rays_towards_scanner = sherd::Vec3d::UnitZ();
  set.params.weight_by_incidence = true;  // as the station's: a triangulating scanner
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // CRLF copies of the data set exist
    std::istringstream fields(line);
    std::string keyword, file;
    fields >> keyword;
    if (keyword != "bmesh") continue;  // the "camera" line and blank lines
    double tx, ty, tz, qx, qy, qz, qw;
    if (!(fields >> file >> tx >> ty >> tz >> qx >> qy >> qz >> qw)) {
      throw sherd::InputError(
          fmt::format("{}:{}: expected `bmesh FILE tx ty tz qx qy qz qw`", conf.string(), line_no));
    }
    std::smatch m;
    if (!std::regex_match(file, m, turntable_name)) continue;  // off-turntable views (chin, top2…)
    const double nominal_deg = std::stod(m[2].str());
    auto path = conf.parent_path() / file;
    if (path.extension() != ".ply") path += ".ply";  // bun.conf~ names bun270 without .ply
    set.views.push_back({path.stem().string(), read_range_scan(path),
                         sherd::registration::turntable_prior(to_z_up, -nominal_deg * kDeg),
                         to_z_up * conf_pose(tx, ty, tz, qx, qy, qz, qw)});
  }
  std::sort(set.views.begin(), set.views.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  if (set.views.size() < 2) {
    throw sherd::InputError(fmt::format(
        "{}: fewer than two turntable views (bunNNN); nothing to register", conf.string()));
  }
  return set;
}

// ---------------------------------------------------------------------------------------------
// Simulated station

DataSet simulate(sherd::config::StationConfig config, std::uint64_t seed, const std::string& scene,
                 bool geometry_only) {
  config.simulation.seed = seed;
  config.simulation.scene = scene;
  config.turntable.time_scale = 0.0;
  auto station = sherd::station::make_station(config);
  // The simulated turntable knows where the plate physically stands: that is the ground truth.
  const auto* plate = dynamic_cast<const sherd::sim::SimulatedTurntable*>(station.turntable.get());
  if (plate == nullptr)
    throw sherd::InputError("the simulated benchmark needs turntable.driver = \"simulated\"");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle_noise(-0.5, 0.5), unit(-1.0, 1.0), shift(0.0, 0.2);
  DataSet set{"simulated-" + scene, {}, {}, {}};
  // The seeds below: ±0.5° uniform about the axis (σ 0.29°), up to 0.2 mm in any direction.
  set.prior = {.angle_sd_deg = 0.29, .tilt_sd_deg = 0.05, .translation_sd_mm = 0.15};
  // Registered as the station registers them ([registration] in the configuration).
  set.params = sherd::station::registration_params(config.registration);
  if (geometry_only) set.params.use_colour = false;
  station.turntable->home();
  const int views = 8;
  for (int i = 0; i < views; ++i) {
    const double encoder = station.turntable->move_to(360.0 * i / views * kDeg);
    BenchView v;
    v.name = fmt::format("seed{}-view{}", seed, i);
    v.view = station.scanner->capture();
    v.truth =
        sherd::registration::turntable_prior(station.scanner_to_world, plate->physical_angle());
    Eigen::Vector3d direction;
    do direction = {unit(rng), unit(rng), unit(rng)};
    while (direction.norm() < 1e-3 || direction.norm() > 1.0);
    const Eigen::Translation3d offset(shift(rng) * direction.normalized());
    v.prior = offset * sherd::registration::turntable_prior(station.scanner_to_world,
                                                            encoder + angle_noise(rng) * kDeg);
    set.views.push_back(std::move(v));
  }
  return set;
}

// ---------------------------------------------------------------------------------------------
// Methods

struct MethodResult {
  std::vector<Pose> poses;
  std::vector<double> seconds;  // per view
  // Ours: the whole call (preparing the views, both rounds of pairs, the graph, the figures) over
  // the pairs it refined.
  double seconds_per_pair = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::vector<std::string>> flags;
};

MethodResult run_ours(const DataSet& set) {
  std::vector<sherd::registration::ViewInput> inputs;
  for (const auto& v : set.views) inputs.push_back({&v.view, v.prior});
  const auto start = Clock::now();
  const auto result = sherd::registration::register_views(inputs, set.prior, set.params);
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  for (const auto& e : result.edges) {
    // The pair's own result against the truth, beside the priors': what the global solve is fed.
    const auto& target = set.views[e.target];
    const auto& source = set.views[e.source];
    const auto error = relative_error(Pose::Identity(), e.relative, target.truth, source.truth,
                                      centroid(source.view));
    const auto seed = relative_error(target.prior, source.prior, target.truth, source.truth,
                                     centroid(source.view));
    std::cout << nlohmann::json{{"bench", "registration"},
                                {"set", set.name},
                                {"method", "ours"},
                                {"edge", {set.views[e.target].name, set.views[e.source].name}},
                                {"status", e.status},
                                {"neighbours", e.neighbours},
                                {"overlap_at_prior", e.overlap_at_prior},
                                {"overlap", e.overlap},
                                {"rms_mm", e.rms_mm},
                                {"iterations", e.iterations},
                                {"colour", e.used_colour},
                                {"correction_deg", e.correction_deg},
                                {"correction_mm", e.correction_mm},
                                {"rotation_error_deg", error.rotation_deg},
                                {"centroid_error_mm", error.centroid_mm},
                                {"seed_rotation_error_deg", seed.rotation_deg}}
                     .dump()
              << std::endl;
  }
  MethodResult out;
  out.seconds_per_pair =
      seconds / static_cast<double>(std::max<std::size_t>(1, result.edges.size()));
  for (const auto& r : result.views) {
    out.poses.push_back(r.pose);
    // One call registers all views (and fuses them): its time is shared out evenly.
    out.seconds.push_back(seconds / static_cast<double>(set.views.size()));
    out.flags.push_back(r.flags);
  }
  return out;
}

// Both PCL methods get the voxel grid that ours downsamples to, registration voxel_mm
// (full-resolution GICP needs covariances of every point and would take minutes per view).
CloudT::Ptr downsampled(const OrganisedView& view, double voxel_mm) {
  auto raw = std::make_shared<CloudT>();
  for (std::size_t i = 0; i < view.cells(); ++i) {
    if (view.valid[i]) raw->push_back({view.points[i].x(), view.points[i].y(), view.points[i].z()});
  }
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(raw);
  const auto leaf = static_cast<float>(voxel_mm);
  grid.setLeafSize(leaf, leaf, leaf);
  auto out = std::make_shared<CloudT>();
  grid.filter(*out);
  return out;
}

// Each view against the union of the views placed before it; view 0 stays at its prior.
template <typename Registration>
MethodResult run_pcl(const DataSet& set, double voxel_mm) {
  MethodResult out;
  auto placed = std::make_shared<CloudT>();
  for (std::size_t i = 0; i < set.views.size(); ++i) {
    const auto start = Clock::now();
    const auto source = downsampled(set.views[i].view, voxel_mm);
    Pose pose = set.views[i].prior;
    std::vector<std::string> flags;
    if (i > 0) {
      Registration method;  // default settings
      method.setInputSource(source);
      method.setInputTarget(placed);
      CloudT aligned;
      method.align(aligned, pose.matrix().cast<float>());
      pose = Pose(method.getFinalTransformation().template cast<double>());
      if (!method.hasConverged()) flags.push_back("not_converged");
    }
    out.seconds.push_back(std::chrono::duration<double>(Clock::now() - start).count());
    CloudT moved;
    pcl::transformPointCloud(*source, moved, pose.matrix().cast<float>());
    *placed += moved;
    out.poses.push_back(pose);
    out.flags.push_back(flags);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

struct Samples {
  std::vector<double> rotation_deg, translation_mm, centroid_mm, world_origin_mm, seconds;
  std::vector<double> seconds_per_pair;     // ours: one per data set (all its time over its edges)
  std::vector<double> overlap_distance_mm;  // one per data set
};

// How well the views agree with each other under `poses`, whatever the reference says: the median
// distance from each view's points to the nearest point of every other view, over the distances
// below 2 mm (the overlap). For the Stanford data it compares a method with bun.conf, itself an ICP
// result (SOURCE.txt: ~0.3 mm), on equal terms.
double median_overlap_distance_mm(const DataSet& set, const std::vector<Pose>& poses) {
  std::vector<CloudT::Ptr> clouds;
  for (std::size_t i = 0; i < set.views.size(); ++i) {
    auto cloud = downsampled(set.views[i].view, 1.0);
    pcl::transformPointCloud(*cloud, *cloud, poses[i].matrix().cast<float>());
    clouds.push_back(cloud);
  }
  std::vector<double> distances;
  std::vector<int> index(1);
  std::vector<float> distance_sq(1);
  for (std::size_t j = 0; j < clouds.size(); ++j) {
    if (clouds[j]->empty()) continue;
    pcl::KdTreeFLANN<pcl::PointXYZ> tree;
    tree.setInputCloud(clouds[j]);
    for (std::size_t i = 0; i < clouds.size(); ++i) {
      if (i == j) continue;
      for (const auto& p : *clouds[i]) {
        if (tree.nearestKSearch(p, 1, index, distance_sq) == 1 && distance_sq[0] < 4.0f) {
          distances.push_back(std::sqrt(distance_sq[0]));
        }
      }
    }
  }
  return quantile(distances, 0.5);
}

void evaluate(const DataSet& set, const std::string& method, const MethodResult& r,
              std::map<std::string, std::map<std::string, Samples>>& all) {
  auto& s = all[set.name][method];
  s.overlap_distance_mm.push_back(median_overlap_distance_mm(set, r.poses));
  if (std::isfinite(r.seconds_per_pair)) s.seconds_per_pair.push_back(r.seconds_per_pair);
  for (std::size_t i = 1; i < set.views.size(); ++i) {
    const auto& v = set.views[i];
    const auto c = centroid(v.view);
    const auto e = relative_error(r.poses[0], r.poses[i], set.views[0].truth, v.truth, c);
    const auto seed = relative_error(set.views[0].prior, v.prior, set.views[0].truth, v.truth, c);
    s.rotation_deg.push_back(e.rotation_deg);
    s.translation_mm.push_back(e.translation_mm);
    s.centroid_mm.push_back(e.centroid_mm);
    s.world_origin_mm.push_back(e.world_origin_mm);
    s.seconds.push_back(r.seconds[i]);
    std::cout << nlohmann::json{{"bench", "registration"},
                                {"set", set.name},
                                {"method", method},
                                {"view", set.views[i].name},
                                {"rotation_error_deg", e.rotation_deg},
                                {"translation_error_mm", e.translation_mm},
                                {"centroid_error_mm", e.centroid_mm},
                                {"world_origin_error_mm", e.world_origin_mm},
                                {"seed_rotation_error_deg", seed.rotation_deg},
                                {"seed_translation_error_mm", seed.translation_mm},
                                {"seed_centroid_error_mm", seed.centroid_mm},
                                {"seconds", r.seconds[i]},
                                {"flags", r.flags[i]}}
                     .dump()
              << std::endl;
  }
}

// PCL's methods to run beside ours (--methods).
std::set<std::string> pcl_methods;

void run_all(const DataSet& set, std::map<std::string, std::map<std::string, Samples>>& all) {
  const double voxel_mm = set.params.voxel_mm;
  std::vector<Pose> truth;
  for (const auto& v : set.views) truth.push_back(v.truth);
  all[set.name]["reference"].overlap_distance_mm.push_back(median_overlap_distance_mm(set, truth));
  evaluate(set, "ours", run_ours(set), all);
  if (pcl_methods.contains("icp")) {
    evaluate(set, "icp",
             run_pcl<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>(set, voxel_mm), all);
  }
  if (pcl_methods.contains("gicp")) {
    evaluate(
        set, "gicp",
        run_pcl<pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>>(set, voxel_mm),
        all);
  }
}

void print_summaries(const std::map<std::string, std::map<std::string, Samples>>& all) {
  for (const auto& [set, methods] : all) {
    const auto& ours = methods.at("ours");
    for (const auto& [method, s] : methods) {
      nlohmann::json line{
          {"bench", "registration"},
          {"summary", set},
          {"method", method},
          {"views", s.rotation_deg.size()},
          {"median_rotation_error_deg", number_or_null(quantile(s.rotation_deg, 0.5))},
          {"p95_rotation_error_deg", number_or_null(quantile(s.rotation_deg, 0.95))},
          {"median_translation_error_mm", number_or_null(quantile(s.translation_mm, 0.5))},
          {"median_centroid_error_mm", number_or_null(quantile(s.centroid_mm, 0.5))},
          {"median_world_origin_error_mm", number_or_null(quantile(s.world_origin_mm, 0.5))},
          {"median_seconds_per_view", number_or_null(quantile(s.seconds, 0.5))},
          {"median_seconds_per_pair", number_or_null(quantile(s.seconds_per_pair, 0.5))},
          {"median_overlap_distance_mm", number_or_null(quantile(s.overlap_distance_mm, 0.5))}};
      if (method == "ours") {
        for (const char* other : {"icp", "gicp"}) {
          if (!methods.contains(other)) continue;
          const auto& o = methods.at(other);
          const auto ratio = [](const std::vector<double>& a, const std::vector<double>& b) {
            return number_or_null(quantile(a, 0.5) / quantile(b, 0.5));
          };
          line[fmt::format("ours_over_{}", other)] = {
              {"median_rotation_error", ratio(ours.rotation_deg, o.rotation_deg)},
              {"median_translation_error", ratio(ours.translation_mm, o.translation_mm)},
              {"median_centroid_error", ratio(ours.centroid_mm, o.centroid_mm)},
              {"median_seconds", ratio(ours.seconds, o.seconds)}};
        }
      }
      std::cout << line.dump() << std::endl;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "bench_registration: view registration errors against ground truth, ours vs PCL ICP and "
      "GICP"};
  std::string conf = "../shared/data/stanford-bunny/data/bun.conf";
  std::string config_file = "config/station.toml";
  int seeds = 3;
  app.add_option("--conf", conf, "a .conf file (Stanford layout); empty: skip")
      ->capture_default_str();
  app.add_option("--config", config_file, "station configuration of the simulated scans")
      ->capture_default_str();
  app.add_option("--seeds", seeds, "simulated seeds (each: a frame and a vessel scan); 0: skip")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  std::vector<std::string> scenes{"frame", "vessel"};
  app.add_option("--scenes", scenes, "simulated scenes per seed")
      ->capture_default_str()
      ->check(CLI::IsMember({"frame", "vessel"}));
  std::vector<std::string> methods{"icp", "gicp"};
  app.add_option("--methods", methods, "PCL's methods to run beside ours (none: only ours)")
      ->capture_default_str()
      ->check(CLI::IsMember({"icp", "gicp", "none"}));
  bool geometry_only = false;
  app.add_flag("--geometry-only", geometry_only,
               "our method without its photometric term on simulated scans (as [registration] "
               "use_colour = false)");
  CLI11_PARSE(app, argc, argv);
  pcl_methods.insert(methods.begin(), methods.end());
  spdlog::set_level(spdlog::level::warn);

  try {
    std::map<std::string, std::map<std::string, Samples>> all;
    if (!conf.empty()) run_all(read_conf(conf), all);
    if (seeds > 0) {
      const auto config = sherd::config::load_station_config(config_file);
      for (int seed = 1; seed <= seeds; ++seed) {
        for (const auto& scene : scenes) {
          run_all(simulate(config, static_cast<std::uint64_t>(seed), scene, geometry_only), all);
        }
      }
    }
    print_summaries(all);
  } catch (const std::exception& e) {
    std::cerr << "bench_registration: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
