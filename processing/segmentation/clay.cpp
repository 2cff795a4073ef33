#include "processing/segmentation/clay.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sherd::segmentation::detail {

float off_clay_line(const Vec3f& clay, const Vec3f& face) {
  const Eigen::Vector2f c = hue(clay), to_grey = Eigen::Vector2f(1.0f, 1.0f) - c;
  const float t = std::clamp((hue(face) - c).dot(to_grey) / to_grey.squaredNorm(), -0.1f, 1.0f);
  return (hue(face) - c - t * to_grey).norm();
}

namespace {

bool fracture_face_of(const Vec3f& clay_rgb, const Vec3f& face_rgb, double face_width_mm,
                      double max_off_clay_line, double max_face_width_mm) {
  return face_width_mm <= max_face_width_mm && greyer(hue(face_rgb), hue(clay_rgb)) &&
         off_clay_line(clay_rgb, face_rgb) < max_off_clay_line;
}

// Peaks of the histogram of hues `h` (bins of kHueBin, Gaussian-smoothed), as hues. The histogram
// spans the central 99 % of the hues on each axis, and at most kHueMaxBins bins from its low end:
// a few voxels of odd colour, or a part of very little red (hues far above 1), must not make it
// huge; fired clays lie between about 0.3 and 1. Measured on the test of a clay sherd against a
// blue object (TwoClays.ASherdAndABlueObjectTouchingAreTwo): unbounded 7.3 s and 1.5 GB resident,
// bounded 0.08 s and 73 MB, the same two sherds.
constexpr int kHueMaxBins = 512;
std::vector<Eigen::Vector2f> hue_peaks(const std::vector<Eigen::Vector2f>& h) {
  auto range = [&](int axis) {
    std::vector<float> values(h.size());
    for (std::size_t k = 0; k < h.size(); ++k) values[k] = h[k][axis];
    const float low = quantile_of(values, 0.005);
    return std::pair(low, std::min(quantile_of(values, 0.995), low + (kHueMaxBins - 1) * kHueBin));
  };
  const auto [x0, x1] = range(0);
  const auto [y0, y1] = range(1);
  const int pad = static_cast<int>(std::ceil(3 * kHueSmoothBins));
  const int nx = static_cast<int>((x1 - x0) / kHueBin) + 1 + 2 * pad;
  const int ny = static_cast<int>((y1 - y0) / kHueBin) + 1 + 2 * pad;
  auto at = [nx](int i, int j) { return static_cast<std::size_t>(j) * nx + i; };
  std::vector<float> counts(static_cast<std::size_t>(nx) * ny, 0.0f);
  for (const auto& v : h) {
    const int i = pad + static_cast<int>(std::floor((v.x() - x0) / kHueBin));
    const int j = pad + static_cast<int>(std::floor((v.y() - y0) / kHueBin));
    if (i >= 0 && j >= 0 && i < nx && j < ny) counts[at(i, j)] += 1.0f;
  }
  std::vector<float> kernel(2 * pad + 1);
  for (int d = -pad; d <= pad; ++d)
    kernel[d + pad] = std::exp(-0.5f * d * d / (kHueSmoothBins * kHueSmoothBins));
  // Separable smoothing: along i (di = 1), then along j (dj = 1).
  auto smooth = [&](const std::vector<float>& in, int di, int dj) {
    std::vector<float> out(in.size(), 0.0f);
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        for (int d = -pad; d <= pad; ++d) {
          const int ii = i + d * di, jj = j + d * dj;
          if (ii >= 0 && jj >= 0 && ii < nx && jj < ny)
            out[at(i, j)] += kernel[d + pad] * in[at(ii, jj)];
        }
      }
    }
    return out;
  };
  const std::vector<float> density = smooth(smooth(counts, 1, 0), 0, 1);
  std::vector<Eigen::Vector2f> peaks;
  for (int j = 1; j + 1 < ny; ++j) {
    for (int i = 1; i + 1 < nx; ++i) {
      const float here = density[at(i, j)];
      bool peak = here > 0.0f;
      // Higher than the neighbours before it, at least as high as those after: one bin of a
      // plateau.
      for (int n = 0; n < 9 && peak; ++n) {
        const float there = density[at(i + n % 3 - 1, j + n / 3 - 1)];
        peak = n == 4 || (n < 4 ? here > there : here >= there);
      }
      if (peak)
        peaks.emplace_back(x0 + (i - pad + 0.5f) * kHueBin, y0 + (j - pad + 0.5f) * kHueBin);
    }
  }
  return peaks;
}

// How long (mm) `region` borders the rest of `part` (region within part): the bands of voxels
// either side with a neighbour on the other (see border_length_mm). `mark` is scratch space, all
// zero, sized for all voxels.
double border_with_rest_mm(const Graph& near, const std::vector<std::uint32_t>& part,
                           const std::vector<std::uint32_t>& region, double radius,
                           std::vector<std::uint8_t>& mark) {
  for (auto v : part) mark[v] = 1;
  for (auto v : region) mark[v] = 2;
  std::size_t band_in = 0, band_out = 0;
  for (auto v : part) {
    const std::uint8_t other = mark[v] == 2 ? 1 : 2;
    const bool beside = std::any_of(near[v].begin(), near[v].end(),
                                    [&](std::uint32_t n) { return mark[n] == other; });
    if (beside) ++(mark[v] == 2 ? band_in : band_out);
  }
  for (auto v : part) mark[v] = 0;
  return border_length_mm(band_in, band_out, radius);
}

}  // namespace

Eigen::Vector2f hue(const Vec3f& rgb) {
  return Eigen::Vector2f(rgb.y(), rgb.z()) / std::max(rgb.x(), 1.0f);
}

bool greyer(const Eigen::Vector2f& h, const Eigen::Vector2f& clay) {
  return (h - clay).dot(Eigen::Vector2f(1.0f, 1.0f) - clay) > 0.0f;
}

float off_either_line(const Vec3f& a, const Vec3f& b) {
  return std::min(off_clay_line(a, b), off_clay_line(b, a));
}

std::vector<Vec3f> colour_sums(const std::vector<std::vector<std::uint32_t>>& parts,
                               const std::vector<Vec3f>& voxel_rgb) {
  std::vector<Vec3f> colour(parts.size(), Vec3f::Zero());
  for (std::size_t p = 0; p < parts.size(); ++p) {
    for (auto v : parts[p]) colour[p] += voxel_rgb[v];
  }
  return colour;
}

bool of_one_clay(const Vec3f& a_rgb, double a_width_mm, const Vec3f& b_rgb, double b_width_mm,
                 double same_hue, double face_off_clay_line, double max_face_width_mm) {
  return (hue(a_rgb) - hue(b_rgb)).norm() < same_hue ||
         fracture_face_of(b_rgb, a_rgb, a_width_mm, face_off_clay_line, max_face_width_mm) ||
         fracture_face_of(a_rgb, b_rgb, b_width_mm, face_off_clay_line, max_face_width_mm);
}

float face_offset_of(const Eigen::Vector2f& clay, const Eigen::Vector2f& h) {
  const Eigen::Vector2f d = h - clay;
  if (d.norm() < kSameHue) return d.norm();
  const Eigen::Vector2f to_grey = (Eigen::Vector2f(1.0f, 1.0f) - clay).normalized();
  const float along = d.dot(to_grey);
  const float across = std::abs(d.x() * to_grey.y() - d.y() * to_grey.x());
  const bool face = along > 0.0f && across < kFaceMaxAcross && across < kFaceCone * along;
  return face ? across : std::numeric_limits<float>::infinity();
}

int clays_of(const std::vector<Eigen::Vector2f>& h, const std::vector<std::uint32_t>& part,
             const Graph& near, const std::vector<Vec3f>& centres, double radius,
             const std::vector<Vec3f>& voxel_rgb, std::size_t min_region, std::vector<int>& clay_of,
             Eigen::Vector2f* main_clay) {
  std::vector<Eigen::Vector2f> peaks = hue_peaks(h);
  clay_of.assign(h.size(), 0);
  std::vector<std::size_t> held;
  while (true) {
    held.assign(peaks.size(), 0);
    for (std::size_t k = 0; k < h.size(); ++k) {
      int best = 0;
      for (int p = 1; p < static_cast<int>(peaks.size()); ++p) {
        if ((h[k] - peaks[p]).squaredNorm() < (h[k] - peaks[best]).squaredNorm()) best = p;
      }
      clay_of[k] = best;
      ++held[best];
    }
    const auto fewest = std::min_element(held.begin(), held.end()) - held.begin();
    if (peaks.size() <= 1 || held[fewest] >= min_region / 4) break;
    peaks.erase(peaks.begin() + fewest);
  }
  const int n = static_cast<int>(peaks.size());
  std::vector<Vec3f> rgb(n, Vec3f::Zero());  // colour sums: the peaks' hues as the voxels show them
  for (std::size_t k = 0; k < h.size(); ++k) rgb[clay_of[k]] += voxel_rgb[part[k]];
  auto face_offset = [&](int p, int q) { return face_offset_of(hue(rgb[q]), hue(rgb[p])); };
  // Of two peaks of one hue, the one holding fewer voxels is the other's face.
  auto face_of = [&](int p, int q) {
    if ((hue(rgb[p]) - hue(rgb[q])).norm() < kSameHue)
      return held[p] < held[q] || (held[p] == held[q] && p > q);
    return std::isfinite(face_offset(p, q));
  };
  std::vector<std::uint8_t> is_clay(n, 1);
  for (int p = 0; p < n; ++p) {
    for (int q = 0; q < n && is_clay[p]; ++q) is_clay[p] = q == p || !face_of(p, q);
  }
  // A face peak whose largest region could seed a sherd (min_region voxels) and is wider than a
  // wall is thick (kFaceMaxWidthMm) is no fracture face but a sherd of a clay that lies near
  // another's line to grey. Measured on bench_segmentation (100 trays each of seeds 1 / 1001 /
  // 5001 / 7001 / 9001 / 11001): of 145 face peaks with regions that large, 143 were 10–17.3 mm
  // wide; the second sherd of tray 5021 (merged with its neighbour, 0.005 off its clay's line)
  // 32.2 mm; a single sherd's hue spread in tray 7009 50.9 mm (its "clay" then too small to seed,
  // so no cut). Exact count of seed 5001 95 → 96 %, no other tray changed.
  // A narrower region is a sherd too when it is wider than kTouchingMinWidthMm and borders the
  // rest of the part along less than kFaceMinBorderShare of its length (its area over its width):
  // a fracture face runs along its sherd's surface for all its length, a sherd touches its
  // neighbour along a short stretch (see parts_without_neck).
  std::vector<std::uint8_t> mark;
  for (int p = 0; p < n; ++p) {
    if (is_clay[p] || held[p] < min_region) continue;
    mark.resize(near.size(), 0);
    for (std::size_t k = 0; k < h.size(); ++k) mark[part[k]] = clay_of[k] == p;
    std::vector<std::uint32_t> largest;
    for (auto& region : components(near, part, mark)) {
      if (region.size() > largest.size()) largest = std::move(region);
    }
    for (auto v : part) mark[v] = 0;
    if (largest.size() < min_region) continue;
    const double width = width_of(near, centres, largest, radius, mark);
    const double leaf = radius / kVoxelsPerTolerance;
    const double length = static_cast<double>(largest.size()) * leaf * leaf / width;
    is_clay[p] =
        width > kFaceMaxWidthMm ||
        (width > kTouchingMinWidthMm &&
         border_with_rest_mm(near, part, largest, radius, mark) < kFaceMinBorderShare * length);
  }
  // A clay peak between two others, within kSameHue of the segment joining them, is their
  // mixture: the voxels whose neighbourhood straddles the contact of two clays.
  auto between = [&](int p, int a, int b) {
    const Eigen::Vector2f ha = hue(rgb[a]), ab = hue(rgb[b]) - ha, ap = hue(rgb[p]) - ha;
    const float t = ap.dot(ab) / ab.squaredNorm();
    return t > 0.0f && t < 1.0f && (ap - t * ab).norm() < kSameHue;
  };
  std::vector<std::uint8_t> mixture(n, 0);
  for (int p = 0; p < n; ++p) {
    for (int a = 0; a < n && is_clay[p]; ++a) {
      for (int b = a + 1; b < n && is_clay[p]; ++b) {
        mixture[p] = a != p && b != p && is_clay[a] && is_clay[b] && between(p, a, b);
        is_clay[p] = !mixture[p];
      }
    }
  }
  std::vector<int> clay(n, -1);
  int clays = 0;
  for (int p = 0; p < n; ++p) {
    if (is_clay[p]) clay[p] = clays++;
  }
  for (int p = 0; p < n; ++p) {  // each face to the clay it fits best, else the nearest hue
    if (clay[p] >= 0 || mixture[p]) continue;
    float best_offset = std::numeric_limits<float>::infinity(), nearest = best_offset;
    for (int q = 0; q < n; ++q) {
      if (clay[q] < 0 || q == p) continue;
      const float offset = face_offset(p, q), distance = (hue(rgb[p]) - hue(rgb[q])).norm();
      if (offset < best_offset || (std::isinf(best_offset) && distance < nearest))
        clay[p] = clay[q], best_offset = std::min(offset, best_offset), nearest = distance;
    }
  }
  if (main_clay) {  // the clay peak holding the most voxels
    int most = -1;
    for (int p = 0; p < n; ++p) {
      if (is_clay[p] && (most < 0 || held[p] > held[most])) most = p;
    }
    *main_clay = hue(rgb[most]);
  }
  for (auto& c : clay_of) c = clay[c];
  return clays;
}

std::vector<Eigen::Vector2f> neighbourhood_hues(const std::vector<std::uint32_t>& part,
                                                const Graph& near,
                                                const std::vector<Vec3f>& voxel_rgb,
                                                std::vector<std::uint8_t>& mark) {
  for (auto v : part) mark[v] = 1;
  std::vector<Eigen::Vector2f> h(part.size());
  for (std::size_t k = 0; k < part.size(); ++k) {
    Vec3f sum = voxel_rgb[part[k]];
    for (auto n : near[part[k]]) {
      if (mark[n]) sum += voxel_rgb[n];
    }
    h[k] = hue(sum);
  }
  for (auto v : part) mark[v] = 0;
  return h;
}

}  // namespace sherd::segmentation::detail
