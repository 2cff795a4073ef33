#include "simulators/structured_light_world.h"

#include <arv.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "core/errors.h"
#include "processing/structured_light/triangulation.h"
#include "simulators/sim_scanner.h"
#include "simulators/vessel.h"

namespace sherd::sim {
namespace {

namespace sl = structured_light;
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr double kNearMm = 1.0;

// Pixel positions (with lens distortion) of points given in the device's own frame.
std::vector<cv::Point2d> project(const sl::Intrinsics& intrinsics,
                                 const std::vector<cv::Point3d>& points) {
  std::vector<cv::Point2d> pixels;
  if (points.empty()) return pixels;
  cv::Mat matrix;
  cv::eigen2cv(intrinsics.matrix, matrix);
  const cv::Mat distortion(1, 5, CV_64F, const_cast<double*>(intrinsics.distortion.data()));
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), matrix, distortion, pixels);
  return pixels;
}

// The nearest triangle per pixel of a device's image (z-buffer over the objects, which are given
// in the device's frame). Why by hand: no installed library ray-casts meshes on the CPU (see
// sim_scanner.cpp); unlike that pinhole rasteriser this one goes through the lens distortion
// (vertices projected by OpenCV, edges straight between them: the triangles are small).
struct ZBuffer {
  int width = 0, height = 0;
  std::vector<float> depth;  // z in the device frame; +inf where no triangle
  std::vector<std::int32_t> object, triangle;
};

ZBuffer rasterise(const sl::Intrinsics& intrinsics, const std::vector<Mesh>& objects) {
  ZBuffer zb{intrinsics.width, intrinsics.height, {}, {}, {}};
  const std::size_t cells = static_cast<std::size_t>(zb.width) * zb.height;
  zb.depth.assign(cells, std::numeric_limits<float>::infinity());
  zb.object.assign(cells, -1);
  zb.triangle.assign(cells, -1);
  // Beyond half again the field of view the distortion polynomial folds back: leave those out.
  const double reach_x = 1.5 * intrinsics.width / intrinsics.matrix(0, 0),
               reach_y = 1.5 * intrinsics.height / intrinsics.matrix(1, 1);
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const auto& points = objects[o].vertices.points;
    std::vector<cv::Point3d> in(points.size());
    std::vector<std::uint8_t> usable(points.size());
    for (std::size_t v = 0; v < points.size(); ++v) {
      const Vec3d p = points[v].cast<double>();
      in[v] = {p.x(), p.y(), p.z()};
      usable[v] =
          p.z() > kNearMm && std::abs(p.x() / p.z()) < reach_x && std::abs(p.y() / p.z()) < reach_y;
    }
    const std::vector<cv::Point2d> uv = project(intrinsics, in);
    const auto& triangles = objects[o].triangles;
    for (std::size_t t = 0; t < triangles.size(); ++t) {
      const auto [a, b, c] = triangles[t];
      if (!usable[a] || !usable[b] || !usable[c]) continue;
      const cv::Point2d A = uv[a], B = uv[b], C = uv[c];
      const double area = (B.x - A.x) * (C.y - A.y) - (B.y - A.y) * (C.x - A.x);
      if (std::abs(area) < 1e-12) continue;
      const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({A.x, B.x, C.x}))));
      const int x1 =
          std::min(zb.width - 1, static_cast<int>(std::floor(std::max({A.x, B.x, C.x}))));
      const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({A.y, B.y, C.y}))));
      const int y1 =
          std::min(zb.height - 1, static_cast<int>(std::floor(std::max({A.y, B.y, C.y}))));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          const double l0 = ((B.x - x) * (C.y - y) - (B.y - y) * (C.x - x)) / area;
          const double l1 = ((C.x - x) * (A.y - y) - (C.y - y) * (A.x - x)) / area;
          const double l2 = 1.0 - l0 - l1;
          if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9) continue;
          // 1/z is linear in the (undistorted) image: close enough within one small triangle.
          const double z = 1.0 / (l0 / in[a].z + l1 / in[b].z + l2 / in[c].z);
          const std::size_t i = static_cast<std::size_t>(y) * zb.width + x;
          if (z < zb.depth[i]) {
            zb.depth[i] = static_cast<float>(z);
            zb.object[i] = static_cast<std::int32_t>(o);
            zb.triangle[i] = static_cast<std::int32_t>(t);
          }
        }
    }
  }
  return zb;
}

double albedo_of(const Rgb8& c) { return (c.r + c.g + c.b) / (3.0 * 255.0); }

}  // namespace

StructuredLightWorld::StructuredLightWorld(const sl::ProCamCalibration& calibration,
                                           const std::optional<BackgroundPlane>& background,
                                           const std::vector<Mesh>& objects,
                                           const StructuredLightOptics& optics)
    : calibration_(calibration), optics_(optics) {
  if (calibration.camera.width <= 0 || calibration.projector.width <= 0)
    throw InputError("structured-light world: the calibration has no camera or projector size");
  const std::size_t cells = static_cast<std::size_t>(width()) * height();
  const std::vector<Eigen::Vector3f> rays =
      sl::pixel_rays(calibration.camera, Eigen::Matrix3d::Identity());
  const ZBuffer seen = rasterise(calibration.camera, objects);

  // What each camera pixel sees: the nearest of its triangle and the background plane.
  truth_.points.assign(cells, Vec3f::Constant(kNan));
  truth_.normals.assign(cells, Vec3f::Constant(kNan));
  truth_.lit.assign(cells, 0);
  std::vector<double> albedo(cells, 0), cosine(cells, 0);
  std::vector<Vec3d> shading_normal(cells, Vec3d::Zero());
  for (std::size_t i = 0; i < cells; ++i) {
    const Vec3d ray = rays[i].cast<double>();  // (x, y, 1): the parameter is the depth
    double depth = std::numeric_limits<double>::infinity();
    if (background) {
      const Vec3d plane_normal = background->normal.normalized();
      const double facing = plane_normal.dot(ray);
      if (std::abs(facing) > 1e-9 && background->offset_mm / facing > kNearMm) {
        depth = background->offset_mm / facing;
        truth_.normals[i] = plane_normal.cast<float>();
        shading_normal[i] = plane_normal;
        albedo[i] = background->albedo;
      }
    }
    if (seen.object[i] >= 0) {
      const Mesh& mesh = objects[seen.object[i]];
      const auto [a, b, c] = mesh.triangles[seen.triangle[i]];
      const Vec3d A = mesh.vertices.points[a].cast<double>(),
                  B = mesh.vertices.points[b].cast<double>(),
                  C = mesh.vertices.points[c].cast<double>();
      // The ray through the triangle's plane (Cramer's rule): exact depth and barycentrics.
      Eigen::Matrix3d m;
      m << ray, A - B, A - C;
      const Vec3d solution = m.fullPivLu().solve(A);  // (depth, β, γ)
      if (solution.allFinite() && solution.x() > kNearMm && solution.x() < depth) {
        depth = solution.x();
        const double beta = solution.y(), gamma = solution.z(), alpha = 1 - beta - gamma;
        truth_.normals[i] = (B - A).cross(C - A).normalized().cast<float>();
        shading_normal[i] =
            mesh.vertices.has_normals()
                ? Vec3d((alpha * mesh.vertices.normals[a] + beta * mesh.vertices.normals[b] +
                         gamma * mesh.vertices.normals[c])
                            .cast<double>()
                            .normalized())
                : truth_.normals[i].cast<double>();
        albedo[i] = mesh.vertices.has_colours() ? alpha * albedo_of(mesh.vertices.colours[a]) +
                                                      beta * albedo_of(mesh.vertices.colours[b]) +
                                                      gamma * albedo_of(mesh.vertices.colours[c])
                                                : 0.6;
      }
    }
    if (!std::isfinite(depth)) continue;
    truth_.points[i] = (depth * ray).cast<float>();
    // Normals towards the camera (the surface side it sees).
    if (truth_.normals[i].dot(truth_.points[i]) > 0) truth_.normals[i] *= -1;
    if (shading_normal[i].dot(depth * ray) > 0) shading_normal[i] *= -1;
  }

  // Where the projector lights each seen point, and whether it reaches it: the point must face the
  // projector and be the nearest surface along the projector's ray (shadow otherwise).
  const Eigen::Matrix3d r = calibration.rotation;
  const Vec3d t = calibration.translation_mm;
  const Vec3d projector_centre = -r.transpose() * t;
  std::vector<Mesh> in_projector = objects;
  for (Mesh& mesh : in_projector) {
    Pose camera_to_projector = Pose::Identity();
    camera_to_projector.linear() = r;
    camera_to_projector.translation() = t;
    mesh.vertices.transform(camera_to_projector);
  }
  const ZBuffer occluders = rasterise(calibration.projector, in_projector);
  std::vector<cv::Point3d> in_frame;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < cells; ++i) {
    if (!std::isfinite(truth_.points[i].x())) continue;
    const Vec3d p = r * truth_.points[i].cast<double>() + t;
    if (p.z() <= kNearMm) continue;
    in_frame.emplace_back(p.x(), p.y(), p.z());
    index.push_back(i);
  }
  const std::vector<cv::Point2d> uv = project(calibration.projector, in_frame);
  projector_x_.assign(cells, -1.f);
  projector_y_.assign(cells, -1.f);
  ambient_grey_.assign(cells, 0.f);
  lit_grey_.assign(cells, 0.f);
  const int pw = calibration.projector.width, ph = calibration.projector.height;
  for (std::size_t k = 0; k < index.size(); ++k) {
    const std::size_t i = index[k];
    ambient_grey_[i] = static_cast<float>(optics.gain * albedo[i] * optics.ambient);
    const Vec3d p = truth_.points[i].cast<double>();
    const Vec3d to_projector = (projector_centre - p).normalized();
    const double cos_incidence = shading_normal[i].dot(to_projector);
    const double x = uv[k].x, y = uv[k].y;
    if (cos_incidence <= 0 || x < -0.5 || y < -0.5 || x > pw - 0.5 || y > ph - 0.5) continue;
    // Occluded when something in the 3×3 projector pixels around is nearer by more than 0.5 mm
    // (the neighbourhood and the margin keep a surface from shadowing itself).
    const int cx = std::clamp(static_cast<int>(std::lround(x)), 0, pw - 1),
              cy = std::clamp(static_cast<int>(std::lround(y)), 0, ph - 1);
    float farthest = 0;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = std::clamp(cx + dx, 0, pw - 1), ny = std::clamp(cy + dy, 0, ph - 1);
        farthest = std::max(farthest, occluders.depth[static_cast<std::size_t>(ny) * pw + nx]);
      }
    if (in_frame[k].z > farthest + 0.5) continue;
    truth_.lit[i] = 1;
    projector_x_[i] = static_cast<float>(std::clamp(x, 0.0, pw - 1.0));
    projector_y_[i] = static_cast<float>(std::clamp(y, 0.0, ph - 1.0));
    lit_grey_[i] = static_cast<float>(optics.gain * albedo[i] * cos_incidence);
  }
}

void StructuredLightWorld::render(std::span<const std::uint8_t> pattern,
                                  std::span<std::uint8_t> out) const {
  const int pw = calibration_.projector.width, ph = calibration_.projector.height;
  const std::size_t cells = static_cast<std::size_t>(width()) * height();
  if (pattern.size() != static_cast<std::size_t>(pw) * ph || out.size() != cells)
    throw InputError(fmt::format(
        "structured-light world: a {}-pixel pattern for a {}x{} projector and a {}-pixel "
        "frame for a {}x{} camera",
        pattern.size(), pw, ph, out.size(), width(), height()));
  // The projector's image as it lands, defocused.
  cv::Mat shown;
  cv::Mat(ph, pw, CV_8U, const_cast<std::uint8_t*>(pattern.data()))
      .convertTo(shown, CV_32F, 1.0 / 255);
  if (optics_.projector_blur_px > 0)
    cv::GaussianBlur(shown, shown, cv::Size(0, 0), optics_.projector_blur_px);
  cv::Mat image(height(), width(), CV_32F);
  auto* grey = image.ptr<float>();
  for (std::size_t i = 0; i < cells; ++i) {
    grey[i] = ambient_grey_[i];
    if (projector_x_[i] < 0) continue;
    const float x = projector_x_[i], y = projector_y_[i];
    const int x0 = std::min(static_cast<int>(x), pw - 2),
              y0 = std::min(static_cast<int>(y), ph - 2);
    const float wx = x - x0, wy = y - y0;
    const float* row0 = shown.ptr<float>(y0);
    const float* row1 = shown.ptr<float>(y0 + 1);
    const float value = (1 - wy) * ((1 - wx) * row0[x0] + wx * row0[x0 + 1]) +
                        wy * ((1 - wx) * row1[x0] + wx * row1[x0 + 1]);
    grey[i] += lit_grey_[i] * value;
  }
  if (optics_.camera_blur_px > 0)
    cv::GaussianBlur(image, image, cv::Size(0, 0), optics_.camera_blur_px);
  if (optics_.noise_grey > 0) {
    cv::Mat noise(height(), width(), CV_32F);
    std::uint64_t frame_seed;
    {
      std::lock_guard lock(noise_mutex_);
      frame_seed = optics_.seed * 0x9E3779B97F4A7C15ULL + ++frames_rendered_;
    }
    cv::RNG(frame_seed).fill(noise, cv::RNG::NORMAL, 0.0, optics_.noise_grey);
    image += noise;
  }
  cv::Mat frame(height(), width(), CV_8U, out.data());
  image.convertTo(frame, CV_8U);  // rounds and saturates to 0…255
}

VesselOnTable vessel_on_table(int camera_width, int camera_height, std::uint64_t seed) {
  VesselOnTable world;
  Rng rng(seed);
  const VesselProfile profile =
      make_vessel_profile(random_family(rng), rng, {.max_diameter_mm = 110, .max_height_mm = 110});
  const ClayColours clay = random_clay(rng);
  Mesh vessel = revolve_vessel(profile, clay, rng);

  // World: the table top is z = 0, the vessel stands on it at the origin.
  const double distance = 470, down = 35 * std::numbers::pi / 180;
  const Vec3d target(0, 0, 50);
  const Vec3d eye = target + distance * Vec3d(0, -std::cos(down), std::sin(down));
  const Pose camera_to_world = look_at_pose(eye, target);
  const Vec3d projector_eye = camera_to_world * Vec3d(250, 0, 0);
  const Pose projector_to_world = look_at_pose(projector_eye, target);
  const Pose camera_to_projector = projector_to_world.inverse() * camera_to_world;

  sl::ProCamCalibration& c = world.calibration;
  const double fc = camera_width * distance / 180.0;  // 180 mm across at the target
  c.camera.width = camera_width;
  c.camera.height = camera_height;
  c.camera.matrix << fc, 0, (camera_width - 1) / 2.0, 0, fc, (camera_height - 1) / 2.0, 0, 0, 1;
  c.camera.distortion = {-0.05, 0, 0, 0, 0};
  const double fp = 1024 * (projector_eye - target).norm() / 360.0;  // 360 mm across
  c.projector.width = 1024;
  c.projector.height = 768;
  c.projector.matrix << fp, 0, 511.5, 0, fp, 383.5, 0, 0, 1;
  c.projector.distortion = {-0.03, 0, 0, 0, 0};
  c.rotation = camera_to_projector.linear();
  c.translation_mm = camera_to_projector.translation();

  const Pose world_to_camera = camera_to_world.inverse();
  vessel.vertices.transform(world_to_camera);
  world.objects.push_back(std::move(vessel));
  world.table.normal = world_to_camera.linear() * Vec3d::UnitZ();
  world.table.offset_mm = world.table.normal.dot(world_to_camera.translation());
  world.table.albedo = 0.5;
  return world;
}

sl::ProCamCalibration procam_aimed_at(const sl::Intrinsics& camera,
                                      const Vec3d& projector_offset_mm, const Vec3d& target_mm,
                                      int projector_width, int projector_height, double coverage) {
  sl::ProCamCalibration c;
  c.camera = camera;
  // Projector axes in the camera frame: z towards the target, x as near the camera's x as that
  // allows (x = y × z, y down, as for the camera).
  const Vec3d z = (target_mm - projector_offset_mm).normalized();
  const Vec3d x = Vec3d::UnitY().cross(z).normalized();
  Eigen::Matrix3d projector_to_camera;
  projector_to_camera << x, z.cross(x), z;
  c.rotation = projector_to_camera.transpose();  // X_p = R (X_c − o)
  c.translation_mm = -c.rotation * projector_offset_mm;
  const double f = camera.matrix(0, 0) * projector_width / camera.width / coverage;
  c.projector.width = projector_width;
  c.projector.height = projector_height;
  c.projector.matrix << f, 0, (projector_width - 1) / 2.0, 0, f, (projector_height - 1) / 2.0, 0, 0,
      1;
  return c;
}

struct SimulatedGigECamera::State {
  std::mutex mutex;  // guards world: set_world against the camera thread
  std::shared_ptr<const StructuredLightWorld> world;
  const drivers::SimulatedProjector* projector = nullptr;
  ArvGvFakeCamera* fake = nullptr;
  std::vector<std::uint8_t> frame;  // the whole sensor, before the region is cut out
};

SimulatedGigECamera::SimulatedGigECamera(std::shared_ptr<const StructuredLightWorld> world,
                                         const drivers::SimulatedProjector& projector,
                                         const std::string& serial)
    : state_(new State) {
  if (projector.width() != world->calibration().projector.width ||
      projector.height() != world->calibration().projector.height)
    throw InputError("simulated GigE camera: the projector is not the world's projector size");
  state_->world = std::move(world);
  state_->projector = &projector;
  state_->frame.resize(static_cast<std::size_t>(state_->world->width()) * state_->world->height());
  state_->fake = arv_gv_fake_camera_new("127.0.0.1", serial.c_str());
  if (!arv_gv_fake_camera_is_running(state_->fake)) {
    g_object_unref(state_->fake);
    throw DeviceError(
        "simulated GigE camera: cannot bind 127.0.0.1 UDP port 3956; another simulated camera "
        "(or arv-fake-gv-camera) is running on this machine: stop it");
  }
  // Aravis's fill-pattern callback (its camera thread, at each trigger): the world under the
  // pattern shown now, cut to the buffer's region.
  auto film_world = [](ArvBuffer* buffer, void* data, guint32, guint32, ArvPixelFormat) {
    State& s = *static_cast<State*>(data);
    std::shared_ptr<const StructuredLightWorld> held;
    {
      std::lock_guard lock(s.mutex);
      held = s.world;
    }
    const StructuredLightWorld& world = *held;
    world.render(s.projector->shown(), s.frame);
    auto* pixels =
        static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
    gint x = 0, y = 0, width = 0, height = 0;
    arv_buffer_get_image_region(buffer, &x, &y, &width, &height);
    for (int v = 0; v < height; ++v)
      for (int u = 0; u < width; ++u) {
        const int wx = x + u, wy = y + v;
        pixels[static_cast<std::size_t>(v) * width + u] =
            wx < world.width() && wy < world.height()
                ? s.frame[static_cast<std::size_t>(wy) * world.width() + wx]
                : 0;
      }
  };
  arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(state_->fake), film_world,
                                   state_.get());
}

SimulatedGigECamera::~SimulatedGigECamera() { g_object_unref(state_->fake); }

void SimulatedGigECamera::set_world(std::shared_ptr<const StructuredLightWorld> world) {
  std::lock_guard lock(state_->mutex);
  if (world->width() != state_->world->width() || world->height() != state_->world->height() ||
      world->calibration().projector.width != state_->world->calibration().projector.width ||
      world->calibration().projector.height != state_->world->calibration().projector.height)
    throw InputError("simulated GigE camera: a new world must keep the camera and projector sizes");
  state_->world = std::move(world);
}

SimulatedStructuredLightScanner::SimulatedStructuredLightScanner(
    Scene scene, const Pose& camera_to_world, const sl::ProCamCalibration& calibration,
    const sl::ScannerOptions& options, const StructuredLightOptics& optics,
    std::function<double()> plate_angle)
    : scene_(std::move(scene)),
      camera_to_world_(camera_to_world),
      calibration_(calibration),
      optics_(optics),
      plate_angle_(std::move(plate_angle)),
      projector_(calibration.projector.width, calibration.projector.height) {
  fake_ = std::make_unique<SimulatedGigECamera>(world_at(plate_angle_()), projector_);
  drivers::AravisCameraSettings settings;
  settings.id = "127.0.0.1";
  settings.width = calibration.camera.width;
  settings.height = calibration.camera.height;
  camera_ = std::make_unique<drivers::AravisCamera>(settings);
  scanner_ =
      std::make_unique<sl::StructuredLightScanner>(*camera_, projector_, calibration, options);
}

SimulatedStructuredLightScanner::~SimulatedStructuredLightScanner() {
  scanner_.reset();
  camera_.reset();  // the driver lets go of the camera before the simulated camera goes
  fake_.reset();
  arv_shutdown();
}

std::string SimulatedStructuredLightScanner::describe() const {
  return "simulated " + scanner_->describe();
}

std::shared_ptr<const StructuredLightWorld> SimulatedStructuredLightScanner::world_at(
    double plate_angle) const {
  Pose turned = Pose::Identity();
  turned.linear() = Eigen::AngleAxisd(plate_angle, Vec3d::UnitZ()).toRotationMatrix();
  const Pose world_to_camera = camera_to_world_.inverse();
  std::vector<Mesh> objects;
  for (const SceneObject& object : scene_.objects) {
    Mesh mesh = object.mesh;
    mesh.vertices.transform(object.on_plate ? world_to_camera * turned : world_to_camera);
    objects.push_back(std::move(mesh));
  }
  return std::make_shared<const StructuredLightWorld>(calibration_, std::nullopt, objects, optics_);
}

OrganisedView SimulatedStructuredLightScanner::capture() {
  fake_->set_world(world_at(plate_angle_()));
  return scanner_->capture();
}

}  // namespace sherd::sim
