#include "processing/fusion/fusion.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <unordered_map>

namespace sherd::fusion {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

void check_input(const std::vector<PosedView>& views, const Params& params) {
  if (!(params.voxel_mm > 0) || !(params.outlier_radius_voxels > 0) ||
      params.outlier_min_neighbours < 0 ||
      !(params.max_edge_mm > 0)) {
    throw InputError(fmt::format(
        "fusion: parameters out of range (voxel_mm {}, outlier_radius_voxels {}, "
        "outlier_min_neighbours {}, max_edge_mm {}): sizes must be positive and neighbours ≥ 0; "
        "fix the fusion parameters",
        params.voxel_mm, params.outlier_radius_voxels, params.outlier_min_neighbours,
        params.max_edge_mm));
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    const OrganisedView* view = views[i].view;
    if (view == nullptr) {
      throw InputError(fmt::format("fusion: view {} has no data; pass every captured view", i));
    }
    if (!views[i].pose.matrix().allFinite()) {
      throw InputError(fmt::format(
          "fusion: view {} has a non-finite pose; check its registration (and the scanner "
          "calibration and turntable angle it was seeded with)",
          i));
    }
    view->check("fusion", i);
  }
}

// The normal of a cell from its organised neighbours (cross product of the horizontal and vertical
// differences), for views whose scanner gave none: the grid already says which points are
// neighbours, so no neighbour search (PCL NormalEstimation) is needed. Zero where the cell has no
// usable neighbours.
Vec3f grid_normal(const OrganisedView& view, int x, int y, float max_edge_mm) {
  const auto at = [&](int cx, int cy) -> const Vec3f* {
    if (cx < 0 || cy < 0 || cx >= view.width || cy >= view.height) return nullptr;
    const std::size_t k = static_cast<std::size_t>(cy) * view.width + cx;
    return view.valid[k] ? &view.points[k] : nullptr;
  };
  const Vec3f& centre = *at(x, y);
  const auto difference = [&](int dx, int dy) -> Vec3f {
    const Vec3f* forward = at(x + dx, y + dy);
    const Vec3f* backward = at(x - dx, y - dy);
    const auto usable = [&](const Vec3f* p) {
      return p != nullptr && (*p - centre).norm() <= max_edge_mm;
    };
    const Vec3f& f = usable(forward) ? *forward : centre;
    const Vec3f& b = usable(backward) ? *backward : centre;
    return f - b;
  };
  const Vec3f n = difference(1, 0).cross(difference(0, 1));
  const float length = n.norm();
  return length > 0 ? Vec3f(n / length) : Vec3f::Zero();
}

// Every valid cell of every view, in the world frame, in the order OrganisedView::to_mesh numbers
// its vertices (view by view, cells row-major), so that vertex k of view v's triangulation is
// point first_point[v] + k.
struct Points {
  std::vector<Vec3f> position, normal;
  std::vector<Rgb8> colour;
  std::vector<std::uint32_t> view;
  std::vector<std::size_t> first_point;  // per view, plus the total at the end
  std::vector<Vec3f> scanner_centre;     // per view, world frame
};

Points world_points(const std::vector<PosedView>& views, float max_edge_mm) {
  Points out;
  std::size_t total = 0;
  for (const auto& v : views) total += v.view->valid_count();
  out.position.reserve(total);
  out.normal.reserve(total);
  out.colour.reserve(total);
  out.view.reserve(total);
  for (std::size_t v = 0; v < views.size(); ++v) {
    const OrganisedView& view = *views[v].view;
    const Eigen::Matrix3f rotation = views[v].pose.linear().cast<float>();
    const Vec3f translation = views[v].pose.translation().cast<float>();
    const bool has_normals = !view.normals.empty();
    const bool has_colours = !view.colours.empty();
    out.first_point.push_back(out.position.size());
    out.scanner_centre.push_back(translation);
    for (int y = 0; y < view.height; ++y) {
      for (int x = 0; x < view.width; ++x) {
        const std::size_t c = static_cast<std::size_t>(y) * view.width + x;
        if (!view.valid[c]) continue;
        const Vec3f& p = view.points[c];
        Vec3f n = has_normals ? view.normals[c] : grid_normal(view, x, y, max_edge_mm);
        // Without a usable normal, facing the scanner is all that is known of the surface.
        if (!n.allFinite() || !(n.norm() > 0)) n = -p;
        // Outward is towards the scanner (the origin of its frame), whatever sign it delivered.
        if (n.dot(p) > 0) n = -n;
        out.position.push_back(rotation * p + translation);
        out.normal.push_back(rotation * n.normalized());
        // Mid grey where the scanner gave no colour: neutral for rendering and segmentation.
        out.colour.push_back(has_colours ? view.colours[c] : Rgb8{128, 128, 128});
        out.view.push_back(static_cast<std::uint32_t>(v));
      }
    }
  }
  out.first_point.push_back(out.position.size());
  return out;
}

struct Voxels {
  std::vector<std::uint32_t> of_point;  // voxel index of each point
  std::vector<Eigen::Vector3d> position_sum;
  std::vector<Vec3f> normal_sum;
  std::vector<std::array<std::uint32_t, 3>> colour_sum;
  std::vector<std::uint32_t> count;

  std::size_t size() const { return count.size(); }
  Vec3f centroid(std::uint32_t k) const { return (position_sum[k] / count[k]).cast<float>(); }
};

// Why a hash of voxel keys rather than pcl::VoxelGrid: the ownership below needs, for every input
// point, the voxel it fell in; VoxelGrid's leaf layout for that is a dense array over the whole
// bounding box (hundreds of MB for a vessel at 1 mm), the hash holds only occupied voxels.
Voxels voxelise(const Points& points, double voxel_mm) {
  Voxels voxels;
  const std::size_t n = points.position.size();
  voxels.of_point.resize(n);
  std::unordered_map<std::uint64_t, std::uint32_t> index_of_key;
  index_of_key.reserve(n / 2);
  // 21 bits per axis: ±1 048 576 voxels, a kilometre at 1 mm.
  constexpr std::int64_t kHalfRange = 1 << 20;
  const double inverse = 1.0 / voxel_mm;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3f& p = points.position[i];
    std::uint64_t key = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const auto cell = static_cast<std::int64_t>(std::floor(p[axis] * inverse)) + kHalfRange;
      if (cell < 0 || cell >= 2 * kHalfRange) {
        throw InputError(fmt::format(
            "fusion: a point of view {} lies {:.0f} mm from the world origin, beyond the voxel "
            "grid; check the view's pose and units (millimetres expected)",
            points.view[i], p.norm()));
      }
      key = (key << 21) | static_cast<std::uint64_t>(cell);
    }
    const auto [it, added] =
        index_of_key.try_emplace(key, static_cast<std::uint32_t>(voxels.count.size()));
    if (added) {
      voxels.position_sum.emplace_back(Eigen::Vector3d::Zero());
      voxels.normal_sum.emplace_back(Vec3f::Zero());
      voxels.colour_sum.push_back({0, 0, 0});
      voxels.count.push_back(0);
    }
    const std::uint32_t k = it->second;
    voxels.of_point[i] = k;
    voxels.position_sum[k] += p.cast<double>();
    voxels.normal_sum[k] += points.normal[i];
    const Rgb8& c = points.colour[i];
    voxels.colour_sum[k][0] += c.r;
    voxels.colour_sum[k][1] += c.g;
    voxels.colour_sum[k][2] += c.b;
    ++voxels.count[k];
  }
  return voxels;
}

// Per voxel: the view that saw it most frontally, by the |cos| of the voxel's mean normal with the
// ray to the view's scanner: a property of the geometry, far steadier than each point's own
// (noisy) grid normal, so the seams between owners are clean lines.
std::vector<std::uint32_t> owners(const Points& points, const Voxels& voxels) {
  std::vector<std::uint32_t> owner(voxels.size(), kNone);
  std::vector<float> owner_cosine(voxels.size(), -1.f);
  for (std::size_t i = 0; i < points.position.size(); ++i) {
    const std::uint32_t k = voxels.of_point[i];
    const Vec3f ray = (points.scanner_centre[points.view[i]] - voxels.centroid(k)).normalized();
    const float cosine = std::abs(voxels.normal_sum[k].normalized().dot(ray));
    if (cosine > owner_cosine[k]) {
      owner_cosine[k] = cosine;
      owner[k] = points.view[i];
    }
  }
  return owner;
}

// Voxels whose centroid PCL's RadiusOutlierRemoval rejects (see Params).
std::vector<std::uint8_t> outlier_voxels(const Voxels& voxels, const Params& params) {
  std::vector<std::uint8_t> outlier(voxels.size(), 0);
  auto centroids = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  centroids->resize(voxels.size());
  for (std::uint32_t k = 0; k < voxels.size(); ++k) {
    (*centroids)[k].getVector3fMap() = voxels.centroid(k);
  }
  pcl::RadiusOutlierRemoval<pcl::PointXYZ> filter(/*extract_removed_indices=*/true);
  filter.setInputCloud(centroids);
  filter.setRadiusSearch(params.outlier_radius_voxels * params.voxel_mm);
  filter.setMinNeighborsInRadius(params.outlier_min_neighbours);
  pcl::Indices kept;
  filter.filter(kept);
  for (const auto k : *filter.getRemovedIndices()) outlier[k] = 1;
  return outlier;
}

Cloud voxel_cloud(const Voxels& voxels, const std::vector<std::uint8_t>& outlier) {
  Cloud cloud;
  for (std::uint32_t k = 0; k < voxels.size(); ++k) {
    if (outlier[k]) continue;
    const Vec3f n = voxels.normal_sum[k];
    if (!(n.norm() > 0)) continue;  // normals cancel out: no side of the surface to speak of
    const float count = static_cast<float>(voxels.count[k]);
    cloud.points.push_back(voxels.centroid(k));
    cloud.normals.push_back(n.normalized());
    const auto& c = voxels.colour_sum[k];
    cloud.colours.push_back({static_cast<std::uint8_t>(std::lround(c[0] / count)),
                             static_cast<std::uint8_t>(std::lround(c[1] / count)),
                             static_cast<std::uint8_t>(std::lround(c[2] / count))});
  }
  return cloud;
}

// A view's organised triangulation (vertices numbered as OrganisedView::to_mesh numbers them:
// its valid cells, row-major) with its isolated dropouts closed, and which vertices lie where its
// surface ends.
struct ViewSurface {
  std::vector<Triangle> triangles;
  std::vector<std::uint8_t> border;  // per vertex
};

ViewSurface organised_surface(const OrganisedView& view, float max_edge_mm) {
  ViewSurface surface;
  surface.triangles = view.to_mesh(max_edge_mm).triangles;
  const int w = view.width, h = view.height;
  std::vector<std::uint32_t> vertex_of_cell(view.cells(), kNone);
  std::uint32_t vertices = 0;
  for (std::size_t c = 0; c < view.cells(); ++c) {
    if (view.valid[c]) vertex_of_cell[c] = vertices++;
  }
  const auto cell = [&](int x, int y) { return static_cast<std::size_t>(y) * w + x; };
  const float max_edge_sq = max_edge_mm * max_edge_mm;
  const auto close = [&](std::size_t a, std::size_t b) {
    return (view.points[a] - view.points[b]).squaredNorm() <= max_edge_sq;
  };

  // A single dropped cell among close valid neighbours is a measurement lost, not a hole in the
  // object (the scanner's dropouts: 1 % of cells): bridged by a fan over the hexagon of cells
  // the grid's triangles around it span (listed in to_mesh's winding), it stays part of this
  // view's surface instead of a pinhole that another view's surface must patch (a double layer)
  // or that nothing patches (a speck of background on the plate).
  std::vector<std::uint8_t> covered(view.valid.begin(), view.valid.end());
  constexpr std::array<std::array<int, 2>, 6> kHexagon{
      {{0, -1}, {-1, 0}, {-1, 1}, {0, 1}, {1, 0}, {1, -1}}};
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      if (view.valid[cell(x, y)]) continue;
      std::array<std::size_t, 6> ring{};
      bool closable = true;
      for (std::size_t k = 0; k < 6 && closable; ++k) {
        ring[k] = cell(x + kHexagon[k][0], y + kHexagon[k][1]);
        closable = view.valid[ring[k]] != 0;
      }
      // The fan's edges: the ring and the diagonals from its first cell.
      for (std::size_t k = 0; k < 6 && closable; ++k) {
        closable = close(ring[k], ring[(k + 1) % 6]) && (k < 2 || close(ring[0], ring[k]));
      }
      if (!closable) continue;
      for (std::size_t k = 1; k + 1 < 6; ++k) {
        surface.triangles.push_back(
            {vertex_of_cell[ring[0]], vertex_of_cell[ring[k]], vertex_of_cell[ring[k + 1]]});
      }
      covered[cell(x, y)] = 1;
    }
  }

  // Where the surface ends: a valid cell with a neighbour (of eight) outside the image, not
  // covered, or across a depth jump.
  surface.border.assign(vertices, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t c = cell(x, y);
      if (!view.valid[c]) continue;
      bool ends = false;
      for (int dy = -1; dy <= 1 && !ends; ++dy) {
        for (int dx = -1; dx <= 1 && !ends; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) {
            ends = true;
            continue;
          }
          const std::size_t n = cell(nx, ny);
          ends = !covered[n] || (view.valid[n] && !close(c, n));
        }
      }
      surface.border[vertex_of_cell[c]] = ends;
    }
  }
  return surface;
}

// Per voxel: whether its owner's surface ends inside it (see ViewSurface). There the owner may not
// cover all of the voxel, so the other views keep their triangles too and no crack opens (an
// overlap of a voxel). Hands each view's triangles out in `triangles`.
std::vector<std::uint8_t> voxels_where_owner_ends(const std::vector<PosedView>& views,
                                                  const Points& points, const Voxels& voxels,
                                                  const std::vector<std::uint32_t>& owner,
                                                  float max_edge_mm,
                                                  std::vector<std::vector<Triangle>>& triangles) {
  std::vector<std::uint8_t> owner_ends(voxels.size(), 0);
  for (std::size_t v = 0; v < views.size(); ++v) {
    const std::size_t first = points.first_point[v];
    if (first == points.first_point[v + 1]) continue;
    ViewSurface surface = organised_surface(*views[v].view, max_edge_mm);
    for (std::size_t k = 0; k < surface.border.size(); ++k) {
      const std::uint32_t voxel = voxels.of_point[first + k];
      if (surface.border[k] && owner[voxel] == v) owner_ends[voxel] = 1;
    }
    triangles[v] = std::move(surface.triangles);
  }
  return owner_ends;
}

}  // namespace

Result fuse_views(const std::vector<PosedView>& views, const Params& params) {
  check_input(views, params);
  Result result;
  for (const auto& v : views) result.views_used += v.view->valid_count() > 0;
  const Points points = world_points(views, params.max_edge_mm);
  result.input_points = points.position.size();
  if (points.position.empty()) {
    throw ProcessingError(fmt::format(
        "fusion: none of the {} views has a valid point; check that the object is in the "
        "scanner's field of view and lit by the projector, then scan again",
        views.size()));
  }
  const Voxels voxels = voxelise(points, params.voxel_mm);
  const std::vector<std::uint32_t> owner = owners(points, voxels);
  const std::vector<std::uint8_t> outlier = outlier_voxels(voxels, params);
  result.cloud = voxel_cloud(voxels, outlier);

  // The mesh: each view's triangles near the voxels it owns, on its own measured points.
  Mesh& mesh = result.mesh;
  std::vector<std::uint32_t> vertex_of_point(points.position.size(), kNone);
  const auto vertex = [&](std::size_t i) {
    if (vertex_of_point[i] == kNone) {
      vertex_of_point[i] = static_cast<std::uint32_t>(mesh.vertices.points.size());
      mesh.vertices.points.push_back(points.position[i]);
      // The voxel's mean normal is far less noisy than the grid normal of one cell; where the
      // voxel mixes two sides of a thin edge (they disagree), the cell's own is the better guess.
      const Vec3f own = points.normal[i];
      const Vec3f mean = voxels.normal_sum[voxels.of_point[i]].normalized();
      mesh.vertices.normals.push_back(mean.dot(own) > 0.5f ? mean : own);
      mesh.vertices.colours.push_back(points.colour[i]);
    }
    return vertex_of_point[i];
  };
  std::vector<std::vector<Triangle>> triangles(views.size());
  const std::vector<std::uint8_t> owner_ends =
      voxels_where_owner_ends(views, points, voxels, owner, params.max_edge_mm, triangles);
  const auto owned_by = [&](std::size_t i, std::uint32_t v) {
    return owner[voxels.of_point[i]] == v;
  };
  const auto may_keep = [&](std::size_t i, std::uint32_t v) {
    return owned_by(i, v) || owner_ends[voxels.of_point[i]];
  };
  for (std::uint32_t v = 0; v < views.size(); ++v) {
    const std::size_t first = points.first_point[v];
    for (const Triangle& t : triangles[v]) {
      const std::size_t a = first + t[0], b = first + t[1], c = first + t[2];
      if (outlier[voxels.of_point[a]] || outlier[voxels.of_point[b]] ||
          outlier[voxels.of_point[c]]) {
        continue;
      }
      if (!may_keep(a, v) && !may_keep(b, v) && !may_keep(c, v)) continue;
      mesh.triangles.push_back({vertex(a), vertex(b), vertex(c)});
    }
  }
  // Owned points outside any kept triangle (isolated cells) are still surface that was seen.
  for (std::size_t i = 0; i < points.position.size(); ++i) {
    const bool is_outlier = outlier[voxels.of_point[i]] != 0;
    result.outliers_removed += is_outlier;
    if (!is_outlier && owned_by(i, points.view[i])) vertex(i);
    if (!is_outlier && vertex_of_point[i] == kNone) ++result.overlap_points_dropped;
  }
  return result;
}

}  // namespace sherd::fusion
