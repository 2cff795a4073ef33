// Benchmark: every axis method on the same simulated sherds, straight from simulators/vessel.h (no
// scanner, no station): each sherd's closed mesh (outer and inner skin, lip, fracture faces) is
// sampled like a scan — uniform over its area, depth noise along the normal (σ 0.02–0.1 mm), holes
// where the scanner was occluded, a random pose — and each method's axis, with profile::analyse
// on it, is compared with the vessel's truth. Prints one JSON object per sherd and method, then a
// summary per method and per method × fragment-size class (medians and 90th percentiles).
// --points N samples each sherd at the density that gives it about N points instead (the speed
// line at 200 k points); --estimated-normals replaces the mesh's normals by normals estimated
// from the sampled points (PCA over their 12 nearest neighbours, as a scanner's cloud has them).
//   bench_axis [--sherds 300] [--seed 1] [--density 2.5 | --points 200000] [--estimated-normals]
//              [--methods normal-lines,refined,…]
#include "processing/axis/axis.h"

#include <pcl/features/normal_3d.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "bench/bench_stats.h"
#include "processing/profile/profile.h"
#include "simulators/vessel.h"

namespace {

using sherd::Cloud;
using sherd::Pose;
using sherd::Vec3d;
using sherd::Vec3f;
using sherd::bench::number_or_null;
using sherd::bench::quantile;
namespace sim = sherd::sim;

struct Truth {
  std::string family, kind;
  double circumference_share = 0.0;  // arc of the piece / 360°
  bool has_rim = false;
  Vec3d axis_point, axis_direction;  // world frame; the point at the sherd's centroid height
  Vec3d centroid;
  std::optional<double> rim_diameter_mm, rim_percent;
  double wall_thickness_mm = 0.0;
  double noise_mm = 0.0;
};

// Uniformly random rotation (a normalised Gaussian quaternion).
Eigen::Matrix3d random_rotation(sim::Rng& rng) {
  Eigen::Quaterniond q(rng.normal(), rng.normal(), rng.normal(), rng.normal());
  return q.normalized().toRotationMatrix();
}

// A scan-like point cloud of a closed mesh: `density` points per mm² of surface, normals
// interpolated from the vertex normals (a crease between surfaces stays sharp: the simulator
// gives each surface its own vertices), depth noise along the normal, `holes` spherical gaps.
Cloud sample_scan(const sherd::Mesh& mesh, double density, double noise_mm, int holes,
                  sim::Rng& rng) {
  const auto& P = mesh.vertices.points;
  const auto& N = mesh.vertices.normals;
  Cloud cloud;
  for (const auto& t : mesh.triangles) {
    const Vec3f a = P[t[0]], b = P[t[1]], c = P[t[2]];
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double expected = area * density;
    int count = static_cast<int>(expected);
    if (rng.uniform() < expected - count) ++count;
    for (int k = 0; k < count; ++k) {
      double u = rng.uniform(), v = rng.uniform();
      if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
      const float w0 = static_cast<float>(1.0 - u - v), w1 = static_cast<float>(u),
                  w2 = static_cast<float>(v);
      const Vec3f n = (w0 * N[t[0]] + w1 * N[t[1]] + w2 * N[t[2]]).normalized();
      const Vec3f p = w0 * a + w1 * b + w2 * c + static_cast<float>(noise_mm * rng.normal()) * n;
      cloud.points.push_back(p);
      cloud.normals.push_back(n);
    }
  }
  // Occlusion holes: spheres of 2–8 mm radius around random points of the cloud.
  for (int h = 0; h < holes && !cloud.empty(); ++h) {
    const Vec3f centre = cloud.points[static_cast<std::size_t>(rng.uniform() * cloud.size())];
    const float radius = static_cast<float>(rng.uniform(2.0, 8.0));
    std::vector<std::uint32_t> keep;
    for (std::uint32_t i = 0; i < cloud.size(); ++i) {
      if ((cloud.points[i] - centre).norm() > radius) keep.push_back(i);
    }
    cloud = cloud.subset(keep);
  }
  return cloud;
}

// Replaces the normals by PCA normals of the points' k nearest neighbours (PCL), each turned to
// the side of the normal it replaces: the sign a scanner takes from its viewpoint, the direction
// from the points alone.
void estimate_normals(Cloud& cloud) {
  constexpr int kNeighbours = 12;
  pcl::PointCloud<pcl::PointXYZ>::Ptr points(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : cloud.points) points->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(points);
  estimation.setKSearch(kNeighbours);
  pcl::PointCloud<pcl::Normal> normals;
  estimation.compute(normals);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3f n(normals[i].normal_x, normals[i].normal_y, normals[i].normal_z);
    if (!n.allFinite()) continue;  // too few neighbours: the sampled normal stays
    cloud.normals[i] = n.dot(cloud.normals[i]) < 0.0f ? Vec3f(-n) : n;
  }
}

// One simulated sherd: a vessel of `family`, a piece of `kind` within max_extent_mm, sampled and
// placed by a random pose. nullopt where the vessel has no room for that kind of piece.
struct Sampling {
  double density = 2.5;    // points per mm² of surface
  std::size_t points = 0;  // > 0: the density that gives about this many points instead
  bool estimated_normals = false;
};

std::optional<std::pair<Cloud, Truth>> make_sherd(sim::Family family, sim::SherdKind kind,
                                                  double max_extent_mm, const Sampling& sampling,
                                                  sim::Rng& rng) {
  const sim::VesselLimits limits{.max_diameter_mm = sim::max_vessel_diameter(kind, max_extent_mm)};
  const sim::VesselProfile profile = sim::make_vessel_profile(family, rng, limits);
  if (!sim::can_break(profile, kind, max_extent_mm)) return std::nullopt;
  const sim::ClayColours clay = sim::random_clay(rng);
  const sim::SherdPiece piece = sim::break_sherd(profile, clay, rng, max_extent_mm, kind);
  Truth truth;
  truth.family = sim::to_string(family);
  truth.kind = sim::to_string(kind);
  truth.circumference_share = piece.arc_rad / (2.0 * M_PI);
  truth.has_rim = piece.has_rim;
  truth.noise_mm = rng.uniform(0.02, 0.1);
  double density = sampling.density;
  if (sampling.points > 0) {
    double area = 0.0;
    for (const auto& t : piece.mesh.triangles) {
      const auto& P = piece.mesh.vertices.points;
      area += 0.5 * (P[t[1]] - P[t[0]]).cross(P[t[2]] - P[t[0]]).norm();
    }
    density = static_cast<double>(sampling.points) / std::max(area, 1.0);
  }
  Cloud cloud = sample_scan(piece.mesh, density, truth.noise_mm, rng.integer(0, 4), rng);
  if (sampling.estimated_normals) estimate_normals(cloud);
  Pose pose = Pose::Identity();
  pose.linear() = random_rotation(rng);
  pose.translation() =
      Vec3d(rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(-200, 200));
  Vec3d centroid = Vec3d::Zero();
  for (const auto& p : cloud.points) centroid += p.cast<double>();
  centroid /= static_cast<double>(std::max<std::size_t>(cloud.size(), 1));
  cloud.transform(pose);
  truth.centroid = pose * centroid;
  truth.axis_point = pose * Vec3d(0.0, 0.0, centroid.z());
  truth.axis_direction = pose.linear() * Vec3d::UnitZ();
  if (piece.has_rim) {
    truth.rim_diameter_mm = 2.0 * profile.rim_radius();
    truth.rim_percent = piece.rim_arc_rad / (2.0 * M_PI) * 100.0;
  }
  truth.wall_thickness_mm = profile.wall_thickness_mm;
  return std::pair{std::move(cloud), truth};
}

// The semi-automatic reference method needs the sherd upright within 20°: the same sherd turned so
// that its axis (base → rim) lies within max_tilt_deg of the world z axis, in a random direction.
std::pair<Cloud, Truth> stood_up(const Cloud& cloud, const Truth& truth, double max_tilt_deg,
                                 sim::Rng& rng) {
  const double tilt = rng.uniform(0.0, max_tilt_deg) * M_PI / 180.0,
               azimuth = rng.uniform(0.0, 2.0 * M_PI);
  const Vec3d target(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth),
                     std::cos(tilt));
  Pose turn = Pose::Identity();
  turn.linear() =
      Eigen::Quaterniond::FromTwoVectors(truth.axis_direction, target).toRotationMatrix();
  Cloud upright = cloud;
  upright.transform(turn);
  Truth t = truth;
  t.axis_point = turn * truth.axis_point;
  t.axis_direction = turn.linear() * truth.axis_direction;
  t.centroid = turn * truth.centroid;
  return {std::move(upright), t};
}

std::string size_class(double share) {
  if (share < 0.15) return "05-15%";
  if (share < 0.30) return "15-30%";
  return "30-50%";
}

// The figures of one method on one sherd; NaN where not measured.
struct Row {
  bool found = false;
  double seconds = NAN, axis_deg = NAN, offset_mm = NAN, rim_diameter_pct = NAN,
         rim_percent_points = NAN, wall_mm = NAN;
  double angle_sd_deg = NAN, offset_sd_mm = NAN;
  double rim_diameter_sd_pct = NAN;  // propagated from the axis sds (profile::MeasurementSds)
  double profile_spread_mm = NAN;    // refined: the points' spread about the common profile
  double local_scatter_mm = NAN;     // … and about their own azimuth's
  std::string reason;
};

Row evaluate(const Cloud& cloud, const Truth& truth, sherd::axis::Method method) {
  Row row;
  const auto start = std::chrono::steady_clock::now();
  const sherd::axis::AxisEstimate axis = sherd::axis::estimate(cloud, method);
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  row.found = axis.found;
  row.reason = axis.reason;
  if (axis.profile_spread_mm > 0.0) row.profile_spread_mm = axis.profile_spread_mm;
  if (axis.local_scatter_mm > 0.0) row.local_scatter_mm = axis.local_scatter_mm;
  if (!axis.found) return row;
  const Vec3d direction = axis.direction.normalized();
  row.axis_deg =
      std::acos(std::min(1.0, std::abs(direction.dot(truth.axis_direction)))) * 180.0 / M_PI;
  // Distance of the estimated axis line from the true axis point at the sherd's height.
  row.offset_mm = (truth.axis_point - axis.point).cross(direction).norm();
  row.angle_sd_deg = axis.angle_sd_deg;
  row.offset_sd_mm = axis.offset_sd_mm;
  try {
    const auto analysis = sherd::profile::analyse(cloud, axis);
    const auto& m = analysis.measurements;
    if (truth.rim_diameter_mm && m.rim_diameter_mm) {
      row.rim_diameter_pct =
          100.0 * std::abs(*m.rim_diameter_mm - *truth.rim_diameter_mm) / *truth.rim_diameter_mm;
    }
    if (m.rim_diameter_mm && analysis.measurement_sds.rim_diameter_mm) {
      row.rim_diameter_sd_pct =
          100.0 * *analysis.measurement_sds.rim_diameter_mm / *m.rim_diameter_mm;
    }
    if (truth.rim_percent && m.rim_percent)
      row.rim_percent_points = std::abs(*m.rim_percent - *truth.rim_percent);
    if (m.wall_thickness_mm.mean > 0.0)
      row.wall_mm = std::abs(m.wall_thickness_mm.mean - truth.wall_thickness_mm);
  } catch (const std::exception& e) {
    row.reason = std::string("no profile: ") + e.what();
  }
  return row;
}

struct Summary {
  int sherds = 0, found = 0, covered_angle = 0, covered_offset = 0, with_sd = 0;
  std::vector<double> seconds, axis_deg, offset_mm, rim_diameter_pct, rim_percent_points, wall_mm;

  void add(const Row& r) {
    ++sherds;
    seconds.push_back(r.seconds);
    if (!r.found) return;
    ++found;
    axis_deg.push_back(r.axis_deg);
    offset_mm.push_back(r.offset_mm);
    if (std::isfinite(r.rim_diameter_pct)) rim_diameter_pct.push_back(r.rim_diameter_pct);
    if (std::isfinite(r.rim_percent_points)) rim_percent_points.push_back(r.rim_percent_points);
    if (std::isfinite(r.wall_mm)) wall_mm.push_back(r.wall_mm);
    if (r.angle_sd_deg > 0.0) {
      ++with_sd;
      covered_angle += r.axis_deg <= 2.0 * r.angle_sd_deg;
      covered_offset += r.offset_mm <= 2.0 * r.offset_sd_mm;
    }
  }
  nlohmann::json json() const {
    auto stats = [](const std::vector<double>& v) {
      return nlohmann::json{{"median", number_or_null(quantile(v, 0.5))},
                            {"p90", number_or_null(quantile(v, 0.9))},
                            {"n", v.size()}};
    };
    return {
        {"sherds", sherds},
        {"found_share", sherds ? static_cast<double>(found) / sherds : 0.0},
        {"axis_angle_error_deg", stats(axis_deg)},
        {"axis_offset_mm", stats(offset_mm)},
        {"rim_diameter_error_pct", stats(rim_diameter_pct)},
        {"rim_percent_error_points", stats(rim_percent_points)},
        {"wall_thickness_error_mm", stats(wall_mm)},
        {"seconds_per_sherd", stats(seconds)},
        // Honesty of the reported sds: share of sherds whose true error is within 2 sd.
        {"angle_within_2sd_share", number_or_null(with_sd ? double(covered_angle) / with_sd : NAN)},
        {"offset_within_2sd_share",
         number_or_null(with_sd ? double(covered_offset) / with_sd : NAN)}};
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "bench_axis: every axis method on the same simulated sherds, against the vessel's truth"};
  int sherds = 300;
  std::uint64_t seed = 1;
  Sampling sampling;
  std::string methods_arg;
  app.add_option("--sherds", sherds, "number of simulated sherds")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--seed", seed)->capture_default_str();
  auto* density =
      app.add_option("--density", sampling.density, "sampled points per mm² of sherd surface")
          ->capture_default_str();
  app.add_option("--points", sampling.points,
                 "sample each sherd with about this many points (instead of --density)")
      ->excludes(density);
  app.add_flag("--estimated-normals", sampling.estimated_normals,
               "normals estimated from the sampled points (PCA, 12 neighbours) instead of the "
               "mesh's");
  app.add_option("--methods", methods_arg, "comma-separated method names (default: all)");
  std::vector<int> only;
  app.add_option("--only", only,
                 "evaluate only these sherd numbers (the same sherds as in the full run)")
      ->delimiter(',');
  CLI11_PARSE(app, argc, argv);

  std::vector<sherd::axis::Method> methods;
  std::stringstream names(methods_arg);
  for (std::string name; std::getline(names, name, ',');) {
    const auto m = sherd::axis::method_from_string(name);
    if (!m) {
      std::cerr << "bench_axis: unknown method '" << name
                << "'; known: " << sherd::axis::method_names() << "\n";
      return 2;
    }
    methods.push_back(*m);
  }
  if (methods.empty()) methods = sherd::axis::all_methods();

  const sim::Family families[] = {sim::Family::Bowl, sim::Family::Plate, sim::Family::Beaker,
                                  sim::Family::Jar, sim::Family::Amphora};
  const sim::SherdKind kinds[] = {sim::SherdKind::Rim, sim::SherdKind::Body, sim::SherdKind::Base};
  std::map<std::string, Summary> by_method;
  std::map<std::pair<std::string, std::string>, Summary> by_class;
  sim::Rng rng(seed);
  int made = 0;
  for (int attempt = 0; made < sherds && attempt < 20 * sherds; ++attempt) {
    const sim::Family family = families[made % 5];
    const sim::SherdKind kind = kinds[(made / 5) % 3];
    sim::Rng sherd_rng = rng.fork();
    // The extent limit sets the vessel size and so the arc share of the piece (5–50 %).
    const double max_extent = sherd_rng.uniform(40.0, 220.0);
    auto made_sherd = make_sherd(family, kind, max_extent, sampling, sherd_rng);
    if (!made_sherd) continue;
    if (!only.empty() && std::find(only.begin(), only.end(), made) == only.end()) {
      ++made;
      continue;
    }
    const auto& [cloud, truth] = *made_sherd;
    const auto upright = stood_up(cloud, truth, 20.0, sherd_rng);
    for (const auto method : methods) {
      const bool semi = method == sherd::axis::Method::ReferenceSemiAutomatic;
      const Row row =
          semi ? evaluate(upright.first, upright.second, method) : evaluate(cloud, truth, method);
      const std::string name = sherd::axis::to_string(method);
      by_method[name].add(row);
      by_class[{name, size_class(truth.circumference_share)}].add(row);
      std::cout << nlohmann::json{{"bench", "axis"},
                                  {"sherd", made},
                                  {"method", name},
                                  {"family", truth.family},
                                  {"kind", truth.kind},
                                  {"points", cloud.size()},
                                  {"circumference_share", truth.circumference_share},
                                  {"noise_mm", truth.noise_mm},
                                  {"found", row.found},
                                  {"reason", row.reason},
                                  {"axis_angle_error_deg", number_or_null(row.axis_deg)},
                                  {"axis_offset_mm", number_or_null(row.offset_mm)},
                                  {"angle_sd_deg", number_or_null(row.angle_sd_deg)},
                                  {"offset_sd_mm", number_or_null(row.offset_sd_mm)},
                                  {"rim_diameter_error_pct", number_or_null(row.rim_diameter_pct)},
                                  {"rim_diameter_sd_pct", number_or_null(row.rim_diameter_sd_pct)},
                                  {"rim_percent_error_points",
                                   number_or_null(row.rim_percent_points)},
                                  {"wall_thickness_error_mm", number_or_null(row.wall_mm)},
                                  {"profile_spread_mm", number_or_null(row.profile_spread_mm)},
                                  {"local_scatter_mm", number_or_null(row.local_scatter_mm)},
                                  {"seconds", row.seconds}}
                       .dump()
                << std::endl;
    }
    ++made;
  }
  for (const auto& [name, s] : by_method) {
    auto line = s.json();
    line["bench"] = "axis";
    line["summary"] = true;
    line["method"] = name;
    line["size_class"] = "all";
    std::cout << line.dump() << std::endl;
  }
  for (const auto& [key, s] : by_class) {
    auto line = s.json();
    line["bench"] = "axis";
    line["summary"] = true;
    line["method"] = key.first;
    line["size_class"] = key.second;
    std::cout << line.dump() << std::endl;
  }
  return 0;
}
