// Triangulation of decoded camera pixels into an organised point grid in the camera frame (mm):
// the midpoint of camera and projector rays for whole projector pixels; the camera ray through the
// plane of the projector column where phase shifting refined it.
// The camera and projector rays depend only on the calibration, so they are undistorted once per
// calibration (Triangulator's constructor); each scan then costs one ray intersection per
// decoded pixel.
#pragma once

#include <vector>

#include "core/types.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"

namespace sherd::structured_light {

// Undistorted normalised directions (x, y, 1) through every pixel of an image (row-major), rotated
// by `rotation`.
std::vector<Eigen::Vector3f> pixel_rays(const Intrinsics& intrinsics,
                                        const Eigen::Matrix3d& rotation);

struct TriangulatedView {
  OrganisedView view;             // camera frame, mm; colour from the white frame
  std::vector<float> ray_gap_mm;  // per cell: how far the camera ray passes from the decoded
                                  // projector ray (large where column and row disagree)
};

class Triangulator {
 public:
  // Throws InputError when the calibration has no image sizes.
  explicit Triangulator(const ProCamCalibration& calibration);

  // `white` (optional, same size as the map) colours the points grey.
  TriangulatedView triangulate(const DecodedMap& map, const GreyImage* white = nullptr,
                               int threads = 2) const;
  // The undistorted camera ray (x, y, 1) through a sub-pixel camera position.
  Eigen::Vector3d camera_ray(const Eigen::Vector2d& pixel) const;

 private:
  // The ray of decoded pixel i's projector column (sub-pixel where map.column_fine is set) at
  // projector row `row`.
  Eigen::Vector3f projector_ray(const DecodedMap& map, std::size_t i, int row) const;

  ProCamCalibration calibration_;
  Eigen::Vector3d projector_centre_;  // in the camera frame
  // Unit-free ray directions (x, y, 1) per camera pixel (camera frame) and per projector pixel
  // (rotated into the camera frame), row-major.
  std::vector<Eigen::Vector3f> camera_rays_, projector_rays_;
};

// Fills view.normals from the organised grid (the cross product of the differences to the
// neighbours across and down, each side where valid and within `max_edge_mm`), unit and facing the
// camera at the origin. A cell without a neighbour both ways has no normal: it is made invalid (an
// isolated point is no surface).
void estimate_grid_normals(OrganisedView& view, float max_edge_mm);

// A scanner check against the chessboard's known geometry: a plane fitted to the triangulated
// points inside the board's outer inner corners, the corners placed where their camera rays meet
// that plane, and the spans between outer corners (truth: (inner_columns − 1) and
// (inner_rows − 1) squares).
struct BoardMeasurement {
  std::size_t pixels = 0;    // camera pixels inside the outer inner corners
  std::size_t points = 0;    // triangulated points among them
  double plane_rms_mm = 0;   // RMS distance of those points to their plane
  double distance_mm = 0;    // camera centre to the board's centroid
  double long_span_mm = 0;   // corner 0 → corner inner_columns − 1
  double short_span_mm = 0;  // corner 0 → corner (inner_rows − 1) · inner_columns
};
// `corners` as find_board_corners returns them. Throws ProcessingError when fewer than 100 board
// points were triangulated.
BoardMeasurement measure_board(const Triangulator& triangulator, const TriangulatedView& view,
                               const std::vector<Eigen::Vector2f>& corners,
                               const Chessboard& board);

}  // namespace sherd::structured_light
