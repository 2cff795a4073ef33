#include "processing/structured_light/calibration.h"

#include <fmt/format.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "core/errors.h"

namespace sherd::structured_light {
namespace {

cv::Mat to_cv(const Eigen::Matrix3d& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}

Eigen::Matrix3d to_eigen3(const cv::Mat& m) {
  Eigen::Matrix3d out;
  cv::cv2eigen(m, out);
  return out;
}

std::array<double, 5> to_distortion(const cv::Mat& m) {
  std::array<double, 5> out{};
  cv::Mat d;
  m.convertTo(d, CV_64F);
  for (int i = 0; i < 5 && i < static_cast<int>(d.total()); ++i) out[i] = d.at<double>(i);
  return out;
}

cv::Mat distortion_to_cv(const std::array<double, 5>& d) {
  return cv::Mat(1, 5, CV_64F, const_cast<double*>(d.data())).clone();
}

// One pose: camera corners (sub-pixel), and the corners carried into the projector image by a
// homography fitted to the decoded pixels around each corner (Moreno & Taubin 2012, §3).
struct PoseCorners {
  std::vector<cv::Point3f> board;              // every corner (camera calibration)
  std::vector<cv::Point2f> camera;             // every corner
  std::vector<cv::Point3f> board_transferred;  // corners with a projector position
  std::vector<cv::Point2f> camera_transferred;
  std::vector<cv::Point2f> projector;
  int skipped = 0;
};

bool find_pose_corners(const std::vector<GreyImage>& frames, const CalibrationOptions& options,
                       PoseCorners& pose) {
  const GreyImage& white = frames[options.patterns.white_frame()];
  const cv::Size pattern(options.board.inner_columns, options.board.inner_rows);
  std::vector<cv::Point2f> corners;
  for (const Eigen::Vector2f& p : find_board_corners(white, options.board))
    corners.emplace_back(p.x(), p.y());
  if (corners.empty()) return false;

  const DecodedMap map = decode(options.patterns, frames, options.thresholds, options.threads);
  // The reference tool's patch: ±ceil(width/180) pixels (±8 at 1280), and at least half-size²
  // decoded pixels in it.
  const int half = static_cast<int>(std::ceil(white.width / 180.0));
  for (std::size_t c = 0; c < corners.size(); ++c) {
    const cv::Point3f board_point(float(c % pattern.width * options.board.square_mm),
                                  float(c / pattern.width * options.board.square_mm), 0.f);
    pose.board.push_back(board_point);
    pose.camera.push_back(corners[c]);
    const int cx = static_cast<int>(std::lround(corners[c].x));
    const int cy = static_cast<int>(std::lround(corners[c].y));
    std::vector<cv::Point2f> camera_pixels, projector_pixels;
    for (int y = std::max(0, cy - half); y <= std::min(map.height - 1, cy + half); ++y)
      for (int x = std::max(0, cx - half); x <= std::min(map.width - 1, cx + half); ++x)
        if (map.decoded(x, y)) {
          const std::size_t i = static_cast<std::size_t>(y) * map.width + x;
          camera_pixels.emplace_back(float(x), float(y));
          projector_pixels.emplace_back(float(map.column[i]), float(map.row[i]));
        }
    if (static_cast<int>(camera_pixels.size()) < half * half) {
      ++pose.skipped;
      continue;
    }
    // Least squares over the whole patch, as Moreno & Taubin (and the reference) do: the
    // decoded positions are integer, the fit averages their quantisation out.
    const cv::Mat h = cv::findHomography(camera_pixels, projector_pixels);
    if (h.empty()) {
      ++pose.skipped;
      continue;
    }
    std::vector<cv::Point2f> in{corners[c]}, out;
    cv::perspectiveTransform(in, out, h);
    pose.board_transferred.push_back(board_point);
    pose.camera_transferred.push_back(corners[c]);
    pose.projector.push_back(out[0]);
  }
  return pose.projector.size() >= 3;
}

}  // namespace

std::vector<Eigen::Vector2f> find_board_corners(const GreyImage& grey, const Chessboard& board) {
  const cv::Mat image(grey.height, grey.width, CV_8U,
                      const_cast<std::uint8_t*>(grey.pixels.data()));
  std::vector<cv::Point2f> corners;
  if (!cv::findChessboardCorners(image, cv::Size(board.inner_columns, board.inner_rows), corners))
    return {};
  cv::cornerSubPix(image, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.01));
  std::vector<Eigen::Vector2f> out;
  for (const auto& c : corners) out.emplace_back(c.x, c.y);
  return out;
}

CalibrationReport calibrate(const std::vector<std::filesystem::path>& capture_dirs,
                            const CalibrationOptions& options) {
  CalibrationReport report;
  std::vector<std::vector<cv::Point3f>> board, board_transferred;
  std::vector<std::vector<cv::Point2f>> camera, camera_transferred, projector;
  cv::Size camera_size;
  for (const auto& dir : capture_dirs) {
    const auto frames = read_sequence(dir, "graycode_", options.patterns.frame_count());
    camera_size = cv::Size(frames[0].width, frames[0].height);
    PoseCorners pose;
    if (!find_pose_corners(frames, options, pose)) continue;
    board.push_back(pose.board);
    camera.push_back(pose.camera);
    board_transferred.push_back(pose.board_transferred);
    camera_transferred.push_back(pose.camera_transferred);
    projector.push_back(pose.projector);
    report.projector_corners += static_cast<int>(pose.projector.size());
    report.corners_skipped += pose.skipped;
    ++report.poses_used;
  }
  if (report.poses_used < 3)
    throw ProcessingError(fmt::format(
        "calibrate scanner: the {}x{} chessboard was found in {} of {} poses, at least 3 are "
        "needed; check the board size and capture more poses with the board fully in view",
        options.board.inner_columns, options.board.inner_rows, report.poses_used,
        capture_dirs.size()));

  const cv::Size projector_size(options.patterns.projector_width,
                                options.patterns.projector_height);
  cv::Mat camera_matrix, camera_distortion, projector_matrix, projector_distortion;
  std::vector<cv::Mat> rvecs, tvecs;
  ProCamCalibration& out = report.calibration;
  out.camera_rms_px = cv::calibrateCamera(board, camera, camera_size, camera_matrix,
                                          camera_distortion, rvecs, tvecs);
  out.projector_rms_px = cv::calibrateCamera(board_transferred, projector, projector_size,
                                             projector_matrix, projector_distortion, rvecs, tvecs);
  // Intrinsics fixed, as the reference does: the stereo step only finds the pose between them.
  cv::Mat rotation, translation, essential, fundamental;
  out.stereo_rms_px =
      cv::stereoCalibrate(board_transferred, camera_transferred, projector, camera_matrix,
                          camera_distortion, projector_matrix, projector_distortion, camera_size,
                          rotation, translation, essential, fundamental, cv::CALIB_FIX_INTRINSIC);

  out.camera = {camera_size.width, camera_size.height, to_eigen3(camera_matrix),
                to_distortion(camera_distortion)};
  out.projector = {projector_size.width, projector_size.height, to_eigen3(projector_matrix),
                   to_distortion(projector_distortion)};
  out.rotation = to_eigen3(rotation);
  for (int i = 0; i < 3; ++i) out.translation_mm[i] = translation.at<double>(i);
  return report;
}

ProCamCalibration read_calibration(const std::filesystem::path& file) {
  cv::FileStorage fs;
  try {
    fs.open(file.string(), cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    throw InputError(fmt::format("scanner calibration {}: not an OpenCV calibration file ({})",
                                 file.string(), e.what()));
  }
  if (!fs.isOpened())
    throw InputError(
        fmt::format("scanner calibration {}: cannot open; run `sherdctl calibrate "
                    "scanner` or check the path in station.toml",
                    file.string()));
  auto matrix = [&](const char* name, const char* alternative = nullptr) {
    cv::Mat m;
    fs[name] >> m;
    if (m.empty() && alternative) fs[alternative] >> m;
    if (m.empty())
      throw InputError(
          fmt::format("scanner calibration {}: no '{}' matrix; the file is "
                      "incomplete, run `sherdctl calibrate scanner` again",
                      file.string(), name));
    m.convertTo(m, CV_64F);
    return m;
  };
  ProCamCalibration c;
  c.camera.matrix = to_eigen3(matrix("cam_int"));
  c.camera.distortion = to_distortion(matrix("cam_dist"));
  c.projector.matrix = to_eigen3(matrix("proj_int"));
  c.projector.distortion = to_distortion(matrix("proj_dist"));
  c.rotation = to_eigen3(matrix("rotation", "roration"));
  const cv::Mat t = matrix("translation");
  for (int i = 0; i < 3; ++i) c.translation_mm[i] = t.at<double>(i);
  fs["rms"] >> c.stereo_rms_px;
  cv::Mat shape;
  fs["img_shape"] >> shape;  // rows, cols of the camera image
  if (shape.total() == 2) {
    shape.convertTo(shape, CV_64F);
    c.camera.height = static_cast<int>(shape.at<double>(0));
    c.camera.width = static_cast<int>(shape.at<double>(1));
  }
  cv::Mat projector_shape;
  fs["proj_shape"] >> projector_shape;
  if (projector_shape.total() == 2) {
    projector_shape.convertTo(projector_shape, CV_64F);
    c.projector.height = static_cast<int>(projector_shape.at<double>(0));
    c.projector.width = static_cast<int>(projector_shape.at<double>(1));
  }
  return c;
}

void write_calibration(const std::filesystem::path& file, const ProCamCalibration& c) {
  cv::FileStorage fs(file.string(), cv::FileStorage::WRITE);
  if (!fs.isOpened())
    throw InputError(fmt::format("scanner calibration: cannot write {}", file.string()));
  fs << "img_shape" << cv::Mat((cv::Mat_<double>(2, 1) << c.camera.height, c.camera.width));
  fs << "proj_shape" << cv::Mat((cv::Mat_<double>(2, 1) << c.projector.height, c.projector.width));
  fs << "rms" << c.stereo_rms_px;
  fs << "cam_int" << to_cv(c.camera.matrix) << "cam_dist" << distortion_to_cv(c.camera.distortion);
  fs << "proj_int" << to_cv(c.projector.matrix) << "proj_dist"
     << distortion_to_cv(c.projector.distortion);
  fs << "rotation" << to_cv(c.rotation);
  cv::Mat t(3, 1, CV_64F);
  for (int i = 0; i < 3; ++i) t.at<double>(i) = c.translation_mm[i];
  fs << "translation" << t;
}

}  // namespace sherd::structured_light
