#include "core/types.h"

#include "core/errors.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>

namespace sherd {

void Cloud::append(const Cloud& other) {
  const bool keep_normals = (empty() || has_normals()) && other.has_normals();
  const bool keep_colours = (empty() || has_colours()) && other.has_colours();
  points.insert(points.end(), other.points.begin(), other.points.end());
  if (keep_normals) {
    normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  } else {
    normals.clear();
  }
  if (keep_colours) {
    colours.insert(colours.end(), other.colours.begin(), other.colours.end());
  } else {
    colours.clear();
  }
}

Cloud Cloud::subset(const std::vector<std::uint32_t>& indices) const {
  Cloud out;
  out.points.reserve(indices.size());
  for (auto i : indices) out.points.push_back(points[i]);
  if (has_normals()) {
    out.normals.reserve(indices.size());
    for (auto i : indices) out.normals.push_back(normals[i]);
  }
  if (has_colours()) {
    out.colours.reserve(indices.size());
    for (auto i : indices) out.colours.push_back(colours[i]);
  }
  return out;
}

void Cloud::transform(const Pose& pose) {
  const Eigen::Matrix3f rotation = pose.linear().cast<float>();
  const Eigen::Vector3f translation = pose.translation().cast<float>();
  for (auto& p : points) p = rotation * p + translation;
  for (auto& n : normals) n = rotation * n;
}

Mesh Mesh::subset(const std::vector<std::uint32_t>& vertex_indices) const {
  constexpr auto kDropped = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> new_index(vertices.size(), kDropped);
  for (std::uint32_t k = 0; k < vertex_indices.size(); ++k) new_index[vertex_indices[k]] = k;
  Mesh out;
  out.vertices = vertices.subset(vertex_indices);
  for (const auto& t : triangles) {
    const Triangle mapped{new_index[t[0]], new_index[t[1]], new_index[t[2]]};
    if (mapped[0] != kDropped && mapped[1] != kDropped && mapped[2] != kDropped) {
      out.triangles.push_back(mapped);
    }
  }
  return out;
}

Box3 Box3::of(const Cloud& cloud) {
  Box3 box;
  if (cloud.empty()) return box;
  box.min = Vec3d::Constant(std::numeric_limits<double>::infinity());
  box.max = -box.min;
  for (const auto& p : cloud.points) {
    box.min = box.min.cwiseMin(p.cast<double>());
    box.max = box.max.cwiseMax(p.cast<double>());
  }
  return box;
}

std::size_t OrganisedView::valid_count() const {
  std::size_t n = 0;
  for (auto v : valid) n += v != 0;
  return n;
}

Mesh OrganisedView::to_mesh(float max_edge_mm) const {
  Mesh mesh;
  std::vector<std::uint32_t> vertex_of_cell(cells(), std::numeric_limits<std::uint32_t>::max());
  const bool with_normals = normals.size() == cells();
  const bool with_colours = colours.size() == cells();
  for (std::size_t i = 0; i < cells(); ++i) {
    if (!valid[i]) continue;
    vertex_of_cell[i] = static_cast<std::uint32_t>(mesh.vertices.points.size());
    mesh.vertices.points.push_back(points[i]);
    if (with_normals) mesh.vertices.normals.push_back(normals[i]);
    if (with_colours) mesh.vertices.colours.push_back(colours[i]);
  }
  const float max_edge_sq = max_edge_mm * max_edge_mm;
  auto close = [&](std::size_t a, std::size_t b) {
    return (points[a] - points[b]).squaredNorm() <= max_edge_sq;
  };
  auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
    if (valid[a] && valid[b] && valid[c] && close(a, b) && close(b, c) && close(a, c)) {
      mesh.triangles.push_back({vertex_of_cell[a], vertex_of_cell[b], vertex_of_cell[c]});
    }
  };
  for (int y = 0; y + 1 < height; ++y) {
    for (int x = 0; x + 1 < width; ++x) {
      const std::size_t i00 = static_cast<std::size_t>(y) * width + x;
      const std::size_t i01 = i00 + 1, i10 = i00 + width, i11 = i10 + 1;
      add(i00, i10, i01);
      add(i01, i10, i11);
    }
  }
  return mesh;
}

void OrganisedView::check(std::string_view part, std::size_t index) const {
  const std::size_t n = cells();
  const bool sizes_ok = width >= 0 && height >= 0 && points.size() == n && valid.size() == n &&
                        (normals.empty() || normals.size() == n) &&
                        (colours.empty() || colours.size() == n);
  if (!sizes_ok) {
    throw InputError(fmt::format(
        "{}: view {} is corrupt ({}x{} grid but {} points, {} validity flags, {} normals, {} "
        "colours); re-capture or re-read the raw view",
        part, index, width, height, points.size(), valid.size(), normals.size(), colours.size()));
  }
  for (std::size_t c = 0; c < n; ++c) {
    if (valid[c] && !points[c].allFinite()) {
      throw InputError(fmt::format(
          "{}: view {} cell {} (row {}, column {}) is marked valid but its point is not finite; "
          "re-capture or re-read the raw view",
          part, index, c, c / width, c % width));
    }
  }
}

}  // namespace sherd
