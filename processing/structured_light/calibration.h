// Projector-camera calibration from a chessboard seen under the Gray-code sequence (Moreno &
// Taubin 2012: projector corners by local homographies around each chessboard corner), with
// OpenCV's calib3d for corner detection and the standard camera / stereo calibration.
#pragma once

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <vector>

#include "processing/structured_light/gray_code.h"

namespace sherd::structured_light {

// Pinhole + Brown distortion (k1, k2, p1, p2, k3), OpenCV's convention, pixels.
struct Intrinsics {
  int width = 0, height = 0;
  Eigen::Matrix3d matrix = Eigen::Matrix3d::Identity();
  std::array<double, 5> distortion{};
};

// Camera and projector intrinsics and the camera→projector pose: X_projector = R·X_camera + T (mm).
struct ProCamCalibration {
  Intrinsics camera, projector;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
  double stereo_rms_px = 0;     // cv::stereoCalibrate's reprojection RMS (the reference's "rms")
  double camera_rms_px = 0;     // cv::calibrateCamera on the camera corners
  double projector_rms_px = 0;  // cv::calibrateCamera on the projector corners
};

struct Chessboard {
  int inner_columns = 9, inner_rows = 7;  // inner corners along the board's long / short side
  double square_mm = 75;
};

struct CalibrationOptions {
  GrayCodePatterns patterns;
  DecodeThresholds thresholds;
  Chessboard board;
  int threads = 2;
};

// What was used: poses whose board was found, and corners transferred to the projector.
struct CalibrationReport {
  ProCamCalibration calibration;
  int poses_used = 0;
  int projector_corners = 0;  // over all poses
  int corners_skipped = 0;    // too few decoded pixels around them
};

// The board's inner corners in an image (sub-pixel, OpenCV's row-major order: inner_columns per
// row); empty when the board is not found.
std::vector<Eigen::Vector2f> find_board_corners(const GreyImage& image, const Chessboard& board);

// Calibrates from capture folders, each holding one pose's full sequence named graycode_NN.png.
// Throws InputError for unreadable captures and ProcessingError when fewer than 3 poses show the
// board (calibration would be underdetermined).
CalibrationReport calibrate(const std::vector<std::filesystem::path>& capture_dirs,
                            const CalibrationOptions& options);

// Reads / writes the OpenCV FileStorage layout of the reference tool (cam_int, cam_dist, proj_int,
// proj_dist, rotation, translation, rms, img_shape). The reader also accepts the reference's
// misspelt "roration" tag. Image sizes not in the file stay 0.
ProCamCalibration read_calibration(const std::filesystem::path& file);
void write_calibration(const std::filesystem::path& file, const ProCamCalibration& calibration);

}  // namespace sherd::structured_light
