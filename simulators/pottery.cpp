#include "simulators/pottery.h"

#include "core/errors.h"
#include "processing/calibration/turntable_calibration.h"
#include "simulators/random.h"
#include "simulators/vessel.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace sherd::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kFrameRingRadiusMm = 95.0;
constexpr double kFrameHeightMm = 8.0;      // plinth height; a standing sherd sinks 5 mm into it
constexpr double kSherdSinkMm = 5.0;
constexpr double kPlateThicknessMm = 10.0;

// The turntable plate: a closed disk, top at z = 0. Repeated section points keep its edges
// sharp; intermediate rings keep the top's interpolated normals straight up.
Mesh make_plate(const Rgb8& colour, Rng& rng) {
  const double R = kPlateRadiusMm, t = kPlateThicknessMm;
  const std::vector<Point2> section{{0, -t}, {R, -t}, {R, -t}, {R, 0}, {R, 0},
                                    {100, 0}, {50, 0}, {0, 0}};
  Mesh plate = revolve_section(section, std::vector<Rgb8>(section.size(), colour), rng);
  // A plain, even colour (no clay mottling): the background that segmentation removes.
  plate.vertices.colours.assign(plate.vertices.size(), colour);
  return plate;
}

// A box with axes `pose.linear()` columns, centred at pose.translation(), half extents `half`;
// four vertices per face so each face keeps its own normal.
Mesh make_box(const Pose& pose, const Vec3d& half, const Rgb8& colour) {
  Mesh box;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {-1, 1}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const auto base = static_cast<std::uint32_t>(box.vertices.points.size());
      for (auto [a, b] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
        Vec3d p = Vec3d::Zero();
        p[axis] = sign * half[axis];
        p[u] = a * half[u];
        p[v] = b * half[v];
        box.vertices.points.push_back((pose * p).cast<float>());
        box.vertices.colours.push_back(colour);
      }
      // Counter-clockwise seen from outside: (u, v) is right-handed with +axis.
      if (sign > 0) {
        box.triangles.push_back({base, base + 1, base + 2});
        box.triangles.push_back({base, base + 2, base + 3});
      } else {
        box.triangles.push_back({base, base + 2, base + 1});
        box.triangles.push_back({base, base + 3, base + 2});
      }
    }
  }
  compute_vertex_normals(box);
  return box;
}

void append_mesh(Mesh& into, const Mesh& part) {
  const auto offset = static_cast<std::uint32_t>(into.vertices.points.size());
  into.vertices.append(part.vertices);
  for (const auto& t : part.triangles) {
    into.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
}

// Rotation taking the sherd's own frame (outer normal at its centre, tangent around the axis,
// direction along the profile) onto the given world directions.
Eigen::Matrix3d orient(const Point2& centre_normal, const Vec3d& normal_to, const Vec3d& tangent_to,
                       const Vec3d& along_to) {
  const Vec3d e_n = Vec3d(centre_normal.x(), 0.0, centre_normal.y()).normalized();
  const Vec3d e_t = Vec3d::UnitY();
  const Vec3d e_a = e_n.cross(e_t);
  Eigen::Matrix3d from, to;
  from << e_n, e_t, e_a;
  to << normal_to, tangent_to, along_to;
  return to * from.transpose();
}

std::vector<std::array<double, 2>> to_pairs(const std::vector<Point2>& pts) {
  std::vector<std::array<double, 2>> out;
  for (const auto& p : pts) {
    if (!out.empty() && std::abs(out.back()[0] - p.x()) < 1e-9 &&
        std::abs(out.back()[1] - p.y()) < 1e-9) {
      continue;  // the inner wall's points clamped onto the floor coincide
    }
    out.push_back({p.x(), p.y()});
  }
  return out;
}

// Truth of a piece placed by `pose` (vessel frame → world).
SherdTruth make_truth(int index, const VesselProfile& profile, const Mesh& vessel_frame_mesh,
                      const Pose& pose) {
  SherdTruth truth;
  truth.id = fmt::format("s{:02d}", index + 1);
  truth.family = to_string(profile.family);
  Vec3d centroid = Vec3d::Zero();
  double z_min = 1e9, z_max = -1e9;
  for (const auto& p : vessel_frame_mesh.vertices.points) {
    centroid += p.cast<double>();
    z_min = std::min(z_min, static_cast<double>(p.z()));
    z_max = std::max(z_max, static_cast<double>(p.z()));
  }
  centroid /= static_cast<double>(vessel_frame_mesh.vertices.size());
  truth.centroid = pose * centroid;
  truth.axis_point = pose * Vec3d(0.0, 0.0, centroid.z());
  truth.axis_direction = pose.linear() * Vec3d::UnitZ();
  truth.wall_thickness_mm = profile.wall_thickness_mm;
  truth.height_mm = z_max - z_min;
  truth.preserved_z_mm = {z_min, z_max};
  truth.outer_profile = to_pairs(profile.outer);
  truth.inner_profile = to_pairs(profile.inner);
  return truth;
}

SceneObject make_object(std::string name, int label, Mesh mesh) {
  SceneObject object;
  object.name = std::move(name);
  object.label = label;
  object.on_plate = true;
  object.mesh = std::move(mesh);
  return object;
}

// Records sherd `index` (placed by `pose`, vessel frame → world) as object and truth.
void add_sherd(Scene& scene, int index, const VesselProfile& profile, const SherdPiece& piece,
               const Pose& pose, Mesh placed) {
  SherdTruth truth = make_truth(index, profile, piece.mesh, pose);
  truth.has_rim = piece.has_rim;
  truth.has_base = piece.has_base;
  if (piece.has_rim) {
    truth.rim_diameter_mm = 2.0 * profile.rim_radius();
    truth.rim_percent = piece.rim_arc_rad / (2 * kPi) * 100.0;
  }
  truth.arc_deg = piece.arc_rad * 180.0 / kPi;
  truth.bbox = Box3::of(placed.vertices);
  scene.truth.push_back(truth);
  scene.objects.push_back(make_object(truth.id, index + 1, std::move(placed)));
}

}  // namespace

std::vector<SherdKind> tray_kinds(int count, Rng& rng) {
  const int rims = (count + 1) / 2;
  const int bases = count >= 3 ? std::max(1, count / 4) : 0;
  std::vector<SherdKind> kinds(static_cast<std::size_t>(count), SherdKind::Body);
  std::fill_n(kinds.begin(), rims, SherdKind::Rim);
  std::fill_n(kinds.begin() + rims, bases, SherdKind::Base);
  // Fisher–Yates by hand: std::shuffle's output differs between standard libraries.
  for (int i = count - 1; i > 0; --i) std::swap(kinds[i], kinds[rng.integer(0, i)]);
  return kinds;
}

BrokenVessel break_random_vessel(SherdKind kind, double max_extent_mm, Rng& rng) {
  const VesselLimits limits{.max_diameter_mm = max_vessel_diameter(kind, max_extent_mm)};
  for (int attempt = 0; attempt < 100; ++attempt) {
    VesselProfile profile = make_vessel_profile(random_family(rng), rng, limits);
    if (!can_break(profile, kind, max_extent_mm)) continue;
    const ClayColours clay = random_clay(rng);
    SherdPiece piece = break_sherd(profile, clay, rng, max_extent_mm, kind);
    return {std::move(profile), std::move(piece)};
  }
  throw InputError(fmt::format(
      "sherd simulator: no vessel gives a {} sherd within {:.0f} mm: use fewer sherds per scene",
      to_string(kind), max_extent_mm));
}

namespace {

// Where the frame's sherds stand: evenly around a ring, or at the centre for a single one.
double frame_ring_radius(int sherds) { return sherds <= 1 ? 0.0 : kFrameRingRadiusMm; }

// Largest sherd extent that leaves a gap between neighbours on the ring (and stays low enough
// that a front sherd does not hide the one behind it from a side-looking scanner).
double frame_max_extent(int sherds) {
  if (sherds <= 1) return 110.0;
  const double chord = 2.0 * kFrameRingRadiusMm * std::sin(kPi / sherds);
  return std::min(110.0, chord - 28.0);
}

void place_frame(Scene& scene, Rng& master, const Rgb8& bg) {
  const int k = scene.spec.sherds;
  const double ring = frame_ring_radius(k);
  const double max_extent = frame_max_extent(k);
  Rng order = master.fork();
  const std::vector<SherdKind> kinds = tray_kinds(k, order);
  Mesh frame;
  for (int i = 0; i < k; ++i) {
    Rng rng = master.fork();
    const auto [profile, piece] = break_random_vessel(kinds[i], max_extent, rng);

    const double psi = 2 * kPi * i / std::max(k, 1) + rng.uniform(-0.1, 0.1);
    const double facing = rng.chance(0.5) ? 1.0 : -1.0;
    const Vec3d h = facing * Vec3d(std::cos(psi), std::sin(psi), 0.0);
    const Vec3d t = Vec3d::UnitZ().cross(h);
    // Standing rim up, rim down or on a side, a little askew, as sherds sit in a real frame.
    const double alpha = rng.integer(0, 3) * kPi / 2 + rng.uniform(-0.2, 0.2);
    const Vec3d t_to = std::cos(alpha) * t - std::sin(alpha) * Vec3d::UnitZ();
    const Vec3d up_to = std::cos(alpha) * Vec3d::UnitZ() + std::sin(alpha) * t;
    Pose pose = Pose::Identity();
    pose.linear() = orient(piece.centre_normal, h, t_to, up_to);

    Mesh placed = piece.mesh;
    placed.vertices.transform(pose);
    const Box3 box = Box3::of(placed.vertices);
    const Vec3d target(ring * std::cos(psi), ring * std::sin(psi), 0.0);
    const Vec3d shift(target.x() - 0.5 * (box.min.x() + box.max.x()),
                      target.y() - 0.5 * (box.min.y() + box.max.y()),
                      kFrameHeightMm - kSherdSinkMm - box.min.z());
    pose.pretranslate(shift);
    placed = piece.mesh;
    placed.vertices.transform(pose);

    // The plinth holding it: the footprint of its lowest part, in the plinth's own axes.
    double a0 = 1e9, a1 = -1e9, b0 = 1e9, b1 = -1e9;
    for (const auto& p : placed.vertices.points) {
      if (p.z() > kFrameHeightMm + 4.0) continue;
      const Vec3d q = p.cast<double>() - target;
      a0 = std::min(a0, q.dot(h));
      a1 = std::max(a1, q.dot(h));
      b0 = std::min(b0, q.dot(t));
      b1 = std::max(b1, q.dot(t));
    }
    Pose plinth = Pose::Identity();
    plinth.linear() << h, t, Vec3d::UnitZ();
    plinth.translation() = target + 0.5 * (a0 + a1) * h + 0.5 * (b0 + b1) * t +
                           Vec3d(0, 0, kFrameHeightMm / 2);
    append_mesh(frame, make_box(plinth, {0.5 * (a1 - a0) + 6.0, 0.5 * (b1 - b0) + 6.0,
                                         kFrameHeightMm / 2}, bg));

    add_sherd(scene, i, profile, piece, pose, std::move(placed));
  }
  if (k > 0) scene.objects.insert(scene.objects.begin() + 1, make_object("frame", 0, frame));
}

void place_empty_frame(Scene& scene, const Rgb8& bg) {
  const int k = scene.spec.sherds;
  if (k == 0) return;
  Mesh frame;
  for (int i = 0; i < k; ++i) {
    const double psi = 2 * kPi * i / k;
    const Vec3d h(std::cos(psi), std::sin(psi), 0.0);
    Pose plinth = Pose::Identity();
    plinth.linear() << h, Vec3d::UnitZ().cross(h), Vec3d::UnitZ();
    plinth.translation() = frame_ring_radius(k) * h + Vec3d(0, 0, kFrameHeightMm / 2);
    append_mesh(frame, make_box(plinth, {12.0, 0.5 * frame_max_extent(k), kFrameHeightMm / 2}, bg));
  }
  scene.objects.push_back(make_object("frame", 0, frame));
}

void place_on_plate(Scene& scene, Rng& master) {
  const int k = scene.spec.sherds;
  // About a quarter of the plate's area covered.
  const double plate_area = kPi * (kPlateRadiusMm - 5.0) * (kPlateRadiusMm - 5.0);
  const double first_extent =
      std::clamp(std::sqrt(0.25 * plate_area / std::max(k, 1)), 40.0, 100.0);
  Rng order = master.fork();
  const std::vector<SherdKind> kinds = tray_kinds(k, order);
  std::vector<std::pair<Vec3d, double>> taken;  // footprint circles: centre, radius
  for (int i = 0; i < k; ++i) {
    Rng rng = master.fork();
    // Break a piece and look for a free spot (rejection sampling); where none is left, break a
    // smaller piece: the seed still fixes everything.
    for (double max_extent = first_extent;; max_extent = std::max(38.0, 0.8 * max_extent)) {
      const auto [profile, piece] = break_random_vessel(kinds[i], max_extent, rng);
      // Lying with the outer face up or down, turned at random about the vertical.
      const double facing = rng.chance(0.5) ? 1.0 : -1.0;
      const double beta = rng.uniform(0.0, 2 * kPi);
      const Vec3d n_to = facing * Vec3d::UnitZ();
      const Vec3d a_to(std::cos(beta), std::sin(beta), 0.0);
      Pose pose = Pose::Identity();
      pose.linear() = orient(piece.centre_normal, n_to, a_to.cross(n_to), a_to);
      Mesh placed = piece.mesh;
      placed.vertices.transform(pose);
      const Box3 box = Box3::of(placed.vertices);
      const double radius = 0.5 * Eigen::Vector2d(box.extent().x(), box.extent().y()).norm();
      const double reach = kPlateRadiusMm - 5.0 - radius;
      std::optional<Vec3d> spot;
      for (int attempt = 0; attempt < 2000 && !spot && reach > 0.0; ++attempt) {
        const Vec3d c(rng.uniform(-reach, reach), rng.uniform(-reach, reach), 0.0);
        if (c.norm() > reach) continue;
        const bool free = std::all_of(taken.begin(), taken.end(), [&](const auto& other) {
          return (other.first - c).norm() > other.second + radius + 4.0;
        });
        if (free) spot = c;
      }
      if (!spot) {
        if (max_extent > 38.0) continue;
        throw InputError(fmt::format(
            "sherd simulator: cannot lay {} sherds on the {:.0f} mm plate without overlap "
            "(seed {}): use fewer sherds or another seed",
            k, 2 * kPlateRadiusMm, scene.spec.seed));
      }
      taken.emplace_back(*spot, radius);
      pose.pretranslate(Vec3d(spot->x() - 0.5 * (box.min.x() + box.max.x()),
                              spot->y() - 0.5 * (box.min.y() + box.max.y()), -box.min.z()));
      placed = piece.mesh;
      placed.vertices.transform(pose);
      add_sherd(scene, i, profile, piece, pose, std::move(placed));
      break;
    }
  }
}

void place_vessel(Scene& scene, Rng& master) {
  Rng rng = master.fork();
  // An amphora scaled down to the scanner's view would be a toy (rim < 60 mm): whole vessels on
  // the plate are bowls, plates, beakers and jars.
  const auto family = static_cast<Family>(rng.integer(0, 3));
  const VesselProfile profile =
      make_vessel_profile(family, rng, {.max_diameter_mm = 260.0, .max_height_mm = 175.0});
  const ClayColours clay = random_clay(rng);
  const Mesh mesh = revolve_vessel(profile, clay, rng);
  // At most ~185 mm tall with foot and lip: the default scanner (camera at 260 mm, looking at
  // z = 50 mm) sees up to about 190 mm above the plate centre. Not quite centred, as an operator
  // puts it down.
  Pose pose = Pose::Identity();
  pose.rotate(Eigen::AngleAxisd(rng.uniform(0.0, 2 * kPi), Vec3d::UnitZ()));
  pose.pretranslate(Vec3d(rng.uniform(-12.0, 12.0), rng.uniform(-12.0, 12.0), 0.0));
  Mesh placed = mesh;
  placed.vertices.transform(pose);

  SherdTruth truth = make_truth(0, profile, mesh, pose);
  truth.complete = true;
  truth.has_rim = true;
  truth.has_base = true;
  truth.rim_diameter_mm = 2.0 * profile.rim_radius();
  truth.rim_percent = 100.0;
  truth.arc_deg = 360.0;
  truth.bbox = Box3::of(placed.vertices);
  scene.truth.push_back(truth);
  scene.objects.push_back(make_object(truth.id, 1, std::move(placed)));
}

// The calibration object (calibration::kCalibrationObject), matte light grey: the disc, and each
// sphere with its post as one surface of revolution about the post's axis (the post's section
// runs up to where it meets the sphere, then the sphere's arc over the top). The profile is
// sampled finely so that the faceting of the meshed spheres stays far below the scanner's noise
// (sagitta < 0.005 mm), which the estimator's accuracy tests rely on.
void place_calibration_object(Scene& scene, Rng& master) {
  Rng rng = master.fork();
  const auto& object = calibration::kCalibrationObject;
  const Rgb8 grey{200, 200, 196};
  auto uniform_colour = [&](Mesh mesh) {
    mesh.vertices.colours.assign(mesh.vertices.size(), grey);  // matte, no mottling
    return mesh;
  };
  const double R = object.disc_radius_mm, t = object.disc_thickness_mm;
  Mesh all = uniform_colour(revolve_section({{0, 0}, {R, 0}, {R, 0}, {R, t}, {R, t}, {0, t}},
                                            std::vector<Rgb8>(6, grey), rng));
  for (const auto& sphere : object.spheres) {
    const double r = sphere.radius_mm, p = object.post_radius_mm;
    const double zc = t + sphere.height_mm;
    const double join = std::asin(p / r);  // polar angle (from the bottom) where the post meets
    std::vector<Point2> section{{0, t}, {p, t}, {p, t}};
    constexpr int kArcSamples = 120;
    for (int i = 0; i <= kArcSamples; ++i) {
      const double polar = join + (kPi - join) * i / kArcSamples;
      section.emplace_back(i == kArcSamples ? 0.0 : r * std::sin(polar), zc - r * std::cos(polar));
    }
    Mesh pin = uniform_colour(revolve_section(section, std::vector<Rgb8>(section.size(), grey), rng));
    const double a = sphere.azimuth_deg * kPi / 180.0;
    Pose at = Pose::Identity();
    at.translation() = Vec3d(sphere.distance_mm * std::cos(a), sphere.distance_mm * std::sin(a), 0);
    pin.vertices.transform(at);
    append_mesh(all, pin);
  }
  // Put down by hand: near the centre, turned any way.
  Pose placement = Pose::Identity();
  placement.rotate(Eigen::AngleAxisd(rng.uniform(0.0, 2 * kPi), Vec3d::UnitZ()));
  placement.pretranslate(Vec3d(rng.uniform(-8.0, 8.0), rng.uniform(-8.0, 8.0), 0.0));
  all.vertices.transform(placement);
  scene.calibration_placement = placement;
  scene.objects.push_back(make_object("calibration_object", 0, std::move(all)));
}

}  // namespace

const char* to_string(SceneKind kind) {
  switch (kind) {
    case SceneKind::Frame: return "frame";
    case SceneKind::Plate: return "plate";
    case SceneKind::Vessel: return "vessel";
    case SceneKind::Empty: return "empty";
    case SceneKind::Calibration: return "calibration";
  }
  return "unknown";
}

const char* to_string(Background background) {
  return background == Background::Black ? "black" : "white";
}

SceneKind scene_kind_from_string(const std::string& name) {
  for (auto kind : {SceneKind::Frame, SceneKind::Plate, SceneKind::Vessel, SceneKind::Empty,
                    SceneKind::Calibration}) {
    if (name == to_string(kind)) return kind;
  }
  throw InputError(fmt::format(
      "unknown scene kind '{}': expected frame, plate, vessel, empty or calibration", name));
}

Background background_from_string(const std::string& name) {
  if (name == "black") return Background::Black;
  if (name == "white") return Background::White;
  throw InputError(fmt::format("unknown background '{}': expected black or white", name));
}

Rgb8 background_colour(Background background) {
  return background == Background::Black ? Rgb8{22, 22, 24} : Rgb8{236, 236, 232};
}

Scene make_scene(const SceneSpec& spec) {
  if (spec.sherds < 0 || spec.sherds > kMaxSherds) {
    throw InputError(fmt::format(
        "sherd simulator: {} sherds requested: a {:.0f} mm plate holds 0 to {}; ask for fewer",
        spec.sherds, 2 * kPlateRadiusMm, kMaxSherds));
  }
  Scene scene;
  scene.spec = spec;
  Rng master(spec.seed);
  const Rgb8 bg = background_colour(spec.background);
  scene.objects.push_back(make_object("plate", 0, make_plate(bg, master)));
  switch (spec.kind) {
    case SceneKind::Frame: place_frame(scene, master, bg); break;
    case SceneKind::Plate: place_on_plate(scene, master); break;
    case SceneKind::Vessel: place_vessel(scene, master); break;
    case SceneKind::Empty: place_empty_frame(scene, bg); break;
    case SceneKind::Calibration: place_calibration_object(scene, master); break;
  }
  return scene;
}

Mesh merged_mesh(const Scene& scene) {
  Mesh all;
  for (const auto& object : scene.objects) append_mesh(all, object.mesh);
  return all;
}

nlohmann::json truth_to_json(const Scene& scene) {
  using nlohmann::json;
  auto vec = [](const Vec3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  auto optional = [](const std::optional<double>& x) { return x ? json(*x) : json(nullptr); };
  const Rgb8 bg = background_colour(scene.spec.background);
  json sherds = json::array();
  for (const auto& t : scene.truth) {
    sherds.push_back({
        {"id", t.id},
        {"family", t.family},
        {"complete", t.complete},
        {"has_rim", t.has_rim},
        {"has_base", t.has_base},
        {"axis", {{"point_mm", vec(t.axis_point)}, {"direction", vec(t.axis_direction)}}},
        {"centroid_mm", vec(t.centroid)},
        {"bbox_mm", json::array({vec(t.bbox.min), vec(t.bbox.max)})},
        {"rim_diameter_mm", optional(t.rim_diameter_mm)},
        {"rim_percent", optional(t.rim_percent)},
        {"wall_thickness_mm", t.wall_thickness_mm},
        {"arc_deg", t.arc_deg},
        {"height_mm", t.height_mm},
        {"preserved_z_mm", t.preserved_z_mm},
        {"profile", {{"outer", t.outer_profile}, {"inner", t.inner_profile}}},
    });
  }
  return {
      {"schema", "sherdscan.truth/1"},
      {"seed", scene.spec.seed},
      {"scene", to_string(scene.spec.kind)},
      {"background", to_string(scene.spec.background)},
      {"units", "mm"},
      {"plate",
       {{"radius_mm", kPlateRadiusMm}, {"top_z_mm", 0.0}, {"colour", {bg.r, bg.g, bg.b}}}},
      {"sherds", sherds},
  };
}

}  // namespace sherd::sim
