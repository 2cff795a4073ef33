// Structured-light benchmark on the real procam-graycode-calib captures (../shared/data):
//   {"bench":"structured_light","case":"decode_real",...}        decoded share on the board, per pose
//   {"bench":"structured_light","case":"calibration",...}        ours beside calibration_result.xml
//   {"bench":"structured_light","case":"board_geometry",...}     triangulated board vs 75 mm squares
//   {"bench":"structured_light","case":"speed",...}              decode + triangulate, 1280×1024×42
// Usage: bench_structured_light [SHARED_DATA_DIR] (default ../shared/data beside the repository).
#include <nlohmann/json.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>

#include "bench/bench_stats.h"
#include "processing/structured_light/calibration.h"
#include "processing/structured_light/gray_code.h"
#include "processing/structured_light/triangulation.h"

namespace sl = sherd::structured_light;
using nlohmann::json;

namespace {

json intrinsics_json(const sl::Intrinsics& in) {
  return {{"fx", in.matrix(0, 0)}, {"fy", in.matrix(1, 1)}, {"cx", in.matrix(0, 2)},
          {"cy", in.matrix(1, 2)}, {"dist", in.distortion}};
}

json calibration_json(const sl::ProCamCalibration& c) {
  const Eigen::AngleAxisd r(c.rotation);
  return {{"camera", intrinsics_json(c.camera)},
          {"projector", intrinsics_json(c.projector)},
          {"rotation_deg", r.angle() * 180 / M_PI},
          {"translation_mm", {c.translation_mm.x(), c.translation_mm.y(), c.translation_mm.z()}},
          {"stereo_rms_px", c.stereo_rms_px}};
}

// Inside the quadrilateral of the board's four outermost inner corners (convex, any winding).
bool inside(const std::array<Eigen::Vector2f, 4>& quad, float x, float y) {
  int sign = 0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2f a = quad[k], b = quad[(k + 1) % 4];
    const float cross = (b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x());
    const int s = cross > 0 ? 1 : -1;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  const std::filesystem::path shared =
      argc > 1 ? std::filesystem::path(argv[1])
               : std::filesystem::path(SHERD_SOURCE_DIR) / "../shared/data";
  const auto sample = shared / "procam-graycode-calib/sample_data";
  const sl::GrayCodePatterns patterns{1024, 768};
  const sl::Chessboard board;
  std::vector<std::filesystem::path> dirs;
  for (int i = 0; i < 5; ++i) dirs.push_back(sample / ("capture_" + std::to_string(i)));

  // Calibration beside the reference.
  const sl::CalibrationReport report = sl::calibrate(dirs, {});
  sl::ProCamCalibration reference = sl::read_calibration(sample / "calibration_result.xml");
  reference.projector.width = patterns.projector_width;  // not stored in the reference file
  reference.projector.height = patterns.projector_height;
  std::cout << json{{"bench", "structured_light"},
                    {"case", "calibration"},
                    {"poses", report.poses_used},
                    {"projector_corners", report.projector_corners},
                    {"corners_skipped", report.corners_skipped},
                    {"ours", calibration_json(report.calibration)},
                    {"ours_camera_rms_px", report.calibration.camera_rms_px},
                    {"ours_projector_rms_px", report.calibration.projector_rms_px},
                    {"reference", calibration_json(reference)},
                    {"rms_ratio_ours_over_reference",
                     report.calibration.stereo_rms_px / reference.stereo_rms_px}}
                   .dump()
            << "\n";

  const sl::Triangulator ours(report.calibration), theirs(reference);
  for (std::size_t pose = 0; pose < dirs.size(); ++pose) {
    const auto frames = sl::read_sequence(dirs[pose], "graycode_", patterns.frame_count());
    const sl::DecodedMap map = sl::decode(patterns, frames, {40, 5});
    const auto corners = sl::find_board_corners(frames[patterns.white_frame()], board);
    if (corners.empty()) continue;
    const int n = board.inner_columns, m = board.inner_rows;
    const std::array<Eigen::Vector2f, 4> quad{corners[0], corners[n - 1], corners[n * m - 1],
                                              corners[n * (m - 1)]};
    std::size_t on_board = 0, decoded = 0;
    for (int y = 0; y < map.height; ++y)
      for (int x = 0; x < map.width; ++x)
        if (inside(quad, float(x), float(y))) {
          ++on_board;
          decoded += map.decoded(x, y);
        }
    // Board geometry from the dense points (not the calibration's own corners): the triangulated
    // pixel nearest each outer corner; spans should be 8 × 75 = 600 mm and 6 × 75 = 450 mm; the
    // decoded board pixels should lie on a plane.
    auto geometry = [&](const sl::Triangulator& t) {
      const sl::TriangulatedView tv = t.triangulate(map, nullptr, 2);
      auto at = [&](const Eigen::Vector2f& p) {
        const std::size_t i = std::size_t(std::lround(p.y())) * map.width + std::lround(p.x());
        return tv.view.valid[i] ? Eigen::Vector3d(tv.view.points[i].cast<double>())
                                : Eigen::Vector3d::Constant(NAN);
      };
      std::vector<Eigen::Vector3d> pts;
      for (int y = 0; y < map.height; y += 2)
        for (int x = 0; x < map.width; x += 2)
          if (inside(quad, float(x), float(y)) && tv.view.valid[std::size_t(y) * map.width + x])
            pts.push_back(tv.view.points[std::size_t(y) * map.width + x].cast<double>());
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (const auto& p : pts) centroid += p;
      centroid /= double(pts.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const auto& p : pts) cov += (p - centroid) * (p - centroid).transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      const Eigen::Vector3d normal = es.eigenvectors().col(0);
      std::vector<double> residual;
      for (const auto& p : pts) residual.push_back(std::abs((p - centroid).dot(normal)));
      double ss = 0;
      for (double r : residual) ss += r * r;
      using sherd::bench::number_or_null;
      return json{{"long_span_mm", number_or_null((at(quad[1]) - at(quad[0])).norm())},
                  {"short_span_mm", number_or_null((at(quad[3]) - at(quad[0])).norm())},
                  {"distance_mm", centroid.norm()},
                  {"plane_rms_mm", std::sqrt(ss / double(residual.size()))}};
    };
    std::cout << json{{"bench", "structured_light"},
                      {"case", "decode_real"},
                      {"pose", static_cast<int>(pose)},
                      {"board_pixels", static_cast<double>(on_board)},
                      {"decoded_share_on_board", double(decoded) / double(on_board)},
                      {"decoded_share_frame", double(map.decoded_count()) / map.state.size()}}
                     .dump()
              << "\n";
    std::cout << json{{"bench", "structured_light"},
                      {"case", "board_geometry"},
                      {"pose", static_cast<int>(pose)},
                      {"truth_long_span_mm", (n - 1) * board.square_mm},
                      {"truth_short_span_mm", (m - 1) * board.square_mm},
                      {"ours", geometry(ours)},
                      {"reference_calibration", geometry(theirs)}}
                     .dump()
              << "\n";
  }

  // Speed: decode + triangulate the 1280×1024, 42-frame sequence (frames already in memory), two
  // threads; median of 7. Baseline in the same run: one thread.
  const auto frames = sl::read_sequence(dirs[0], "graycode_", patterns.frame_count());
  for (int threads : {1, 2}) {
    std::vector<double> decode_s, total_s;
    for (int rep = 0; rep < 7; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      const sl::DecodedMap map = sl::decode(patterns, frames, {40, 5}, threads);
      const auto t1 = std::chrono::steady_clock::now();
      const sl::TriangulatedView tv = ours.triangulate(map, &frames[patterns.white_frame()], threads);
      const auto t2 = std::chrono::steady_clock::now();
      decode_s.push_back(std::chrono::duration<double>(t1 - t0).count());
      total_s.push_back(std::chrono::duration<double>(t2 - t0).count());
    }
    std::cout << json{{"bench", "structured_light"},
                      {"case", "speed"},
                      {"frames", patterns.frame_count()},
                      {"width", frames[0].width},
                      {"height", frames[0].height},
                      {"threads", threads},
                      {"decode_s_median", sherd::bench::median(decode_s)},
                      {"decode_triangulate_s_median", sherd::bench::median(total_s)},
                      {"note", "shared 2-core machine under other builds"}}
                     .dump()
              << "\n";
  }
}
