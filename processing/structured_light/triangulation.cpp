#include "processing/structured_light/triangulation.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <thread>

#include "core/errors.h"

namespace sherd::structured_light {
namespace {

// Inside the convex quadrilateral `quad` (either winding).
bool inside(const std::array<Eigen::Vector2f, 4>& quad, float x, float y) {
  int sign = 0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2f a = quad[k], b = quad[(k + 1) % 4];
    const int s = (b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x()) > 0 ? 1 : -1;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

}  // namespace

std::vector<Eigen::Vector3f> pixel_rays(const Intrinsics& intrinsics,
                                        const Eigen::Matrix3d& rotation) {
  std::vector<cv::Point2f> pixels;
  pixels.reserve(static_cast<std::size_t>(intrinsics.width) * intrinsics.height);
  for (int y = 0; y < intrinsics.height; ++y)
    for (int x = 0; x < intrinsics.width; ++x) pixels.emplace_back(float(x), float(y));
  cv::Mat matrix;
  cv::eigen2cv(intrinsics.matrix, matrix);
  const cv::Mat distortion(1, 5, CV_64F, const_cast<double*>(intrinsics.distortion.data()));
  std::vector<cv::Point2f> normalised;
  // Iterative undistortion to convergence: the default 5 iterations leave pixel-level error at the
  // image corners for strong distortion such as the reference camera's.
  cv::undistortPoints(pixels, normalised, matrix, distortion, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-9));
  std::vector<Eigen::Vector3f> rays(normalised.size());
  const Eigen::Matrix3f r = rotation.cast<float>();
  for (std::size_t i = 0; i < normalised.size(); ++i)
    rays[i] = r * Eigen::Vector3f(normalised[i].x, normalised[i].y, 1.f);
  return rays;
}

Triangulator::Triangulator(const ProCamCalibration& calibration) : calibration_(calibration) {
  if (calibration.camera.width <= 0 || calibration.projector.width <= 0)
    throw InputError(
        "scanner calibration: camera or projector image size missing (img_shape / proj_shape); "
        "set them or calibrate again with `sherdctl calibrate scanner`");
  // X_p = R X_c + T  ⇒  projector centre in the camera frame is −Rᵀ T, its rays Rᵀ d.
  projector_centre_ = -calibration.rotation.transpose() * calibration.translation_mm;
  camera_rays_ = pixel_rays(calibration.camera, Eigen::Matrix3d::Identity());
  projector_rays_ = pixel_rays(calibration.projector, calibration.rotation.transpose());
}

TriangulatedView Triangulator::triangulate(const DecodedMap& map, const GreyImage* white,
                                           int threads) const {
  if (map.width != calibration_.camera.width || map.height != calibration_.camera.height)
    throw InputError(
        fmt::format("structured light: decoded map is {}x{}, the calibrated camera "
                    "is {}x{}; set the camera region to the calibrated one",
                    map.width, map.height, calibration_.camera.width, calibration_.camera.height));
  const std::size_t cells = static_cast<std::size_t>(map.width) * map.height;
  TriangulatedView out;
  OrganisedView& view = out.view;
  view.width = map.width;
  view.height = map.height;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  view.points.assign(cells, Vec3f::Constant(nan));
  view.valid.assign(cells, 0);
  if (white) view.colours.assign(cells, Rgb8{});
  out.ray_gap_mm.assign(cells, nan);

  const Eigen::Vector3d c = projector_centre_;
  auto run = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      if (map.state[i] != PixelState::kDecoded) continue;
      const Eigen::Vector3d u = camera_rays_[i].cast<double>();
      const Eigen::Vector3d v = projector_ray(map, i, map.row[i]).cast<double>();
      Eigen::Vector3d point;
      double gap = 0;
      if (map.column_fine.empty()) {
        // Whole projector pixels in both directions: the midpoint of the closest points of the
        // rays s·u (camera, from the origin) and c + t·v (projector). In double: the rays meet at
        // a small angle, so uu·vv − uv² cancels most of its digits.
        const double uu = u.dot(u), uv = u.dot(v), vv = v.dot(v), uc = u.dot(c), vc = v.dot(c);
        const double det = uu * vv - uv * uv;
        if (std::abs(det) < 1e-12 * uu * vv) continue;  // parallel rays: no depth
        const double s = (uc * vv - uv * vc) / det;
        const double t = (uv * uc - uu * vc) / det;
        if (s <= 0 || t <= 0) continue;  // behind the camera or the projector
        point = 0.5 * (s * u + c + t * v);
        gap = (s * u - c - t * v).norm();
      } else {
        // A sub-pixel column and a whole-pixel row: the camera ray meets the plane of the column
        // (through c, spanned by its rays at the decoded row and the next), so the point stays on
        // its camera ray and the row's rounding does not move it. Assumes a baseline across the
        // projector's columns, as phase shifting along columns does.
        const int next_row =
            map.row[i] + 1 < calibration_.projector.height ? map.row[i] + 1 : map.row[i] - 1;
        const Eigen::Vector3d normal = v.cross(projector_ray(map, i, next_row).cast<double>());
        const double un = u.dot(normal);
        if (std::abs(un) < 1e-9 * u.norm() * normal.norm()) continue;  // ray in the plane
        const double s = c.dot(normal) / un;
        point = s * u;
        if (s <= 0 || (point - c).dot(v) <= 0) continue;  // behind the camera or the projector
        gap = (point - c).cross(v).norm() / v.norm();
      }
      view.points[i] = point.cast<float>();
      out.ray_gap_mm[i] = static_cast<float>(gap);
      view.valid[i] = 1;
      if (white) {
        const std::uint8_t g = white->pixels[i];
        view.colours[i] = Rgb8{g, g, g};
      }
    }
  };
  threads = std::max(1, threads);
  {
    std::vector<std::jthread> workers;
    for (int t = 1; t < threads; ++t)
      workers.emplace_back(run, cells * t / threads, cells * (t + 1) / threads);
    run(0, cells / threads);
  }
  return out;
}

Eigen::Vector3f Triangulator::projector_ray(const DecodedMap& map, std::size_t i, int row) const {
  const int width = calibration_.projector.width;
  const std::size_t row_start = static_cast<std::size_t>(row) * width;
  if (map.column_fine.empty()) return projector_rays_[row_start + map.column[i]];
  // Sub-pixel column: linear between the rays of its two neighbouring projector pixels.
  const float x = std::clamp(map.column_fine[i], 0.f, float(width - 1));
  const int left = std::min(static_cast<int>(x), width - 2);
  const float w = x - float(left);
  return (1 - w) * projector_rays_[row_start + left] + w * projector_rays_[row_start + left + 1];
}

Eigen::Vector3d Triangulator::camera_ray(const Eigen::Vector2d& pixel) const {
  cv::Mat matrix;
  cv::eigen2cv(calibration_.camera.matrix, matrix);
  const cv::Mat distortion(1, 5, CV_64F,
                           const_cast<double*>(calibration_.camera.distortion.data()));
  std::vector<cv::Point2d> in{{pixel.x(), pixel.y()}}, out;
  cv::undistortPoints(in, out, matrix, distortion, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  return {out[0].x, out[0].y, 1.0};
}

void estimate_grid_normals(OrganisedView& view, float max_edge_mm) {
  const int w = view.width, h = view.height;
  std::vector<Vec3f> normals(view.cells(),
                             Vec3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  auto usable = [&](int x, int y, const Vec3f& from) {
    if (x < 0 || y < 0 || x >= w || y >= h) return false;
    const std::size_t j = static_cast<std::size_t>(y) * w + x;
    return view.valid[j] && (view.points[j] - from).norm() <= max_edge_mm;
  };
  // The difference across a cell in one direction: both neighbours where usable, else one side.
  auto difference = [&](int x, int y, int dx, int dy, Vec3f& out) {
    const Vec3f& p = view.points[static_cast<std::size_t>(y) * w + x];
    const bool ahead = usable(x + dx, y + dy, p), behind = usable(x - dx, y - dy, p);
    if (!ahead && !behind) return false;
    const Vec3f a = ahead ? view.points[static_cast<std::size_t>(y + dy) * w + x + dx] : p;
    const Vec3f b = behind ? view.points[static_cast<std::size_t>(y - dy) * w + x - dx] : p;
    out = a - b;
    return true;
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (!view.valid[i]) continue;
      Vec3f across, down;
      Vec3f n = Vec3f::Zero();
      if (difference(x, y, 1, 0, across) && difference(x, y, 0, 1, down)) n = across.cross(down);
      if (!(n.norm() > 0)) {
        view.valid[i] = 0;
        view.points[i] = Vec3f::Constant(std::numeric_limits<float>::quiet_NaN());
        continue;
      }
      n.normalize();
      normals[i] = n.dot(view.points[i]) > 0 ? Vec3f(-n) : n;  // towards the camera
    }
  view.normals = std::move(normals);
}

BoardMeasurement measure_board(const Triangulator& triangulator, const TriangulatedView& view,
                               const std::vector<Eigen::Vector2f>& corners,
                               const Chessboard& board) {
  const int n = board.inner_columns, m = board.inner_rows;
  if (static_cast<int>(corners.size()) != n * m)
    throw InputError(fmt::format("board check: {} corners given, the {}x{} board has {}",
                                 corners.size(), n, m, n * m));
  const std::array<Eigen::Vector2f, 4> quad{corners[0], corners[n - 1], corners[n * m - 1],
                                            corners[n * (m - 1)]};
  const OrganisedView& v = view.view;
  BoardMeasurement out;
  std::vector<Eigen::Vector3d> points;
  for (int y = 0; y < v.height; ++y)
    for (int x = 0; x < v.width; ++x) {
      if (!inside(quad, float(x), float(y))) continue;
      ++out.pixels;
      const std::size_t i = static_cast<std::size_t>(y) * v.width + x;
      if (v.valid[i]) points.push_back(v.points[i].cast<double>());
    }
  if (points.size() < 100)
    throw ProcessingError(
        fmt::format("board check: only {} points triangulated on the board; "
                    "check the exposure and the decode thresholds",
                    points.size()));
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= double(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - centroid) * (p - centroid).transpose();
  const Eigen::Vector3d normal =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
  double squares = 0;
  for (const auto& p : points) squares += std::pow((p - centroid).dot(normal), 2);
  auto on_plane = [&](const Eigen::Vector2f& corner) {
    const Eigen::Vector3d ray = triangulator.camera_ray(corner.cast<double>());
    return Eigen::Vector3d(ray * (centroid.dot(normal) / ray.dot(normal)));
  };
  out.points = points.size();
  out.plane_rms_mm = std::sqrt(squares / double(points.size()));
  out.distance_mm = centroid.norm();
  out.long_span_mm = (on_plane(quad[1]) - on_plane(quad[0])).norm();
  out.short_span_mm = (on_plane(quad[3]) - on_plane(quad[0])).norm();
  return out;
}

}  // namespace sherd::structured_light
