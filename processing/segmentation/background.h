// Background removal: the plate (RANSAC plane), the frame, the scanning volume and the
// background colour. Internal to processing/segmentation.
#pragma once

#include <cstdint>
#include <vector>

#include "core/types.h"
#include "processing/segmentation/segmentation.h"

namespace sherd::segmentation::detail {

// The largest side (mm) of the axis-aligned box around the points `indices`.
double largest_side(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& indices);

// Fits the dominant plane by RANSAC on a regular subsample, then takes every point within the
// distance of it. Accepted as support only when its inliers span plane_min_extent_mm. Returns
// the removed points (none when no support was found).
std::vector<std::uint32_t> remove_support_plane(const std::vector<Vec3f>& points,
                                                const Params& params,
                                                std::vector<std::uint8_t>& keep);

// The bound on a black background's HSV value (0–1) that this scan's plate `plate` shows, at most
// `black_max_value` (see kPlateValueMargin in background.cpp).
double black_bound_of_plate(const std::vector<Rgb8>& colours,
                            const std::vector<std::uint32_t>& plate, double black_max_value);

// Clears keep[] for the holding frame's points, by its geometry (see kFrameTopMaxTiltDeg in
// background.cpp); none when Params::frame_height_mm is 0.
void remove_frame(const std::vector<Vec3f>& points, const Params& params,
                  std::vector<std::uint8_t>& keep);

// The point lies outside the configured scanning volume (Params::volume_radius_mm and heights).
bool outside_volume(const Vec3f& p, const Params& params);

// Background colour is judged per point, then smoothed over the neighbourhood: a point of
// background colour whose neighbourhood is mostly object-coloured is a dark speck on the object
// (a shaded fracture edge, a stain, 8-bit noise on a near-black shade), not background. Dropping
// such points cut holes into dark sherds (tray benchmark: per-point recall median 0.9953 without
// this, 0.998 with it). A region of background colour wider than the neighbourhood — a plate, a
// frame's plinth — stays background, even where an object touches it.
std::vector<std::uint32_t> without_background_colour(const Mesh& fused,
                                                     const std::vector<std::uint32_t>& candidates,
                                                     const Params& params);

}  // namespace sherd::segmentation::detail
