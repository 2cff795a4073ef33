// PCL's k-d tree does the neighbour searches, in 3-D and in the top view.
#include "processing/segmentation/voxel_graph.h"

#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>

namespace sherd::segmentation::detail {

Voxels voxelise(const std::vector<Vec3f>& points, const std::vector<std::uint32_t>& candidates,
                double leaf) {
  // Voxel key per candidate (21 bits per axis, offset to stay positive), then runs of equal keys.
  auto key_of = [&](const Vec3f& p) {
    auto cell = [&](float v) {
      return static_cast<std::uint64_t>(
          std::clamp<long long>(std::llround(std::floor(v / leaf)) + (1 << 20), 0, (1 << 21) - 1));
    };
    return cell(p.x()) << 42 | cell(p.y()) << 21 | cell(p.z());
  };
  Voxels voxels;
  voxels.keyed.reserve(candidates.size());
  for (auto i : candidates) voxels.keyed.emplace_back(key_of(points[i]), i);
  std::sort(voxels.keyed.begin(), voxels.keyed.end());
  const auto& keyed = voxels.keyed;
  for (std::size_t k = 0; k < keyed.size();) {
    std::size_t end = k;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (; end < keyed.size() && keyed[end].first == keyed[k].first; ++end) {
      sum += points[keyed[end].second].cast<double>();
    }
    voxels.centres.push_back((sum / static_cast<double>(end - k)).cast<float>());
    voxels.begin.push_back(k);
    k = end;
  }
  voxels.begin.push_back(keyed.size());
  return voxels;
}

double point_spacing(const Voxels& voxels, double leaf) {
  if (voxels.centres.empty()) return 0.0;
  const double per_voxel = static_cast<double>(voxels.keyed.size()) / voxels.centres.size();
  return leaf / std::sqrt(per_voxel);
}

std::vector<std::vector<std::uint32_t>> neighbourhoods(const Voxels& voxels, double radius) {
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->reserve(voxels.centres.size());
  for (const auto& c : voxels.centres) cloud->push_back({c.x(), c.y(), c.z()});
  pcl::search::KdTree<pcl::PointXYZ> tree(false);  // unsorted results: order is not needed
  tree.setInputCloud(cloud);
  std::vector<std::vector<std::uint32_t>> near(voxels.centres.size());
  std::vector<int> found;
  std::vector<float> distances;
  for (std::size_t v = 0; v < near.size(); ++v) {
    tree.radiusSearch((*cloud)[v], radius, found, distances);
    near[v].reserve(found.size());
    for (auto n : found) {
      if (static_cast<std::size_t>(n) != v) near[v].push_back(static_cast<std::uint32_t>(n));
    }
  }
  return near;
}

std::vector<std::vector<std::uint32_t>> components(const Graph& near,
                                                   const std::vector<std::uint32_t>& among,
                                                   const std::vector<std::uint8_t>& allowed) {
  std::vector<std::vector<std::uint32_t>> found;
  std::vector<std::uint8_t> seen(near.size(), 0);
  for (auto seed : among) {
    if (seen[seed] || (!allowed.empty() && !allowed[seed])) continue;
    std::vector<std::uint32_t> members{seed};
    seen[seed] = 1;
    for (std::size_t k = 0; k < members.size(); ++k) {
      for (auto n : near[members[k]]) {
        if (seen[n] || (!allowed.empty() && !allowed[n])) continue;
        seen[n] = 1;
        members.push_back(n);
      }
    }
    found.push_back(std::move(members));
  }
  return found;
}

void geodesic_from(const Graph& near, const std::vector<Vec3f>& centres,
                   const std::vector<std::uint32_t>& cluster,
                   const std::vector<std::pair<std::uint32_t, int>>& sources,
                   std::vector<float>& distance, std::vector<int>& tag,
                   std::vector<std::uint8_t>& inside, const std::vector<int>* region) {
  using Item = std::pair<float, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  for (auto v : cluster) distance[v] = std::numeric_limits<float>::infinity(), tag[v] = -1;
  for (auto v : cluster) inside[v] = 1;
  for (auto [v, t] : sources) distance[v] = 0.0f, tag[v] = t, queue.emplace(0.0f, v);
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > distance[v]) continue;
    for (auto n : near[v]) {
      if (!inside[n] || (region != nullptr && (*region)[n] != (*region)[v])) continue;
      const float through = d + (centres[n] - centres[v]).norm();
      if (through < distance[n]) {
        distance[n] = through;
        tag[n] = tag[v];
        queue.emplace(through, n);
      }
    }
  }
  for (auto v : cluster) inside[v] = 0;
}

std::vector<std::pair<std::uint32_t, int>> boundary_of(const Graph& near,
                                                       const std::vector<Vec3f>& centres,
                                                       const std::vector<std::uint32_t>& region,
                                                       double radius,
                                                       std::vector<std::uint8_t>& inside) {
  for (auto v : region) inside[v] = 1;
  std::vector<std::pair<std::uint32_t, int>> boundary;
  for (auto v : region) {
    Vec3f mean = Vec3f::Zero();
    int count = 0;
    for (auto n : near[v]) {
      if (inside[n]) mean += centres[n], ++count;
    }
    if (count < 3 || (mean / static_cast<float>(count) - centres[v]).norm() > 0.25 * radius)
      boundary.emplace_back(v, 0);
  }
  for (auto v : region) inside[v] = 0;
  return boundary;
}

double width_of(const Graph& near, const std::vector<Vec3f>& centres,
                const std::vector<std::uint32_t>& region, double radius,
                std::vector<std::uint8_t>& inside) {
  std::vector<float> depth(near.size());
  std::vector<int> nearest(near.size());
  geodesic_from(near, centres, region, boundary_of(near, centres, region, radius, inside), depth,
                nearest, inside);
  double width = 0.0;
  for (auto v : region) width = std::max(width, 2.0 * depth[v]);
  return width;
}

void flood_from_cores(const Graph& near, const std::vector<std::uint32_t>& cluster,
                      const std::vector<std::pair<std::uint32_t, int>>& cores,
                      const std::vector<float>& depth, std::vector<int>& tag) {
  using Item = std::pair<float, std::uint32_t>;
  std::priority_queue<Item> queue;  // deepest first
  for (auto v : cluster) tag[v] = -1;
  for (auto [v, t] : cores) tag[v] = t, queue.emplace(depth[v], v);
  while (!queue.empty()) {
    const auto v = queue.top().second;
    queue.pop();
    for (auto n : near[v]) {
      if (tag[n] >= 0) continue;
      tag[n] = tag[v];
      queue.emplace(depth[n], n);
    }
  }
}

void add_once(std::vector<int>& parts, int part) {
  if (std::find(parts.begin(), parts.end(), part) == parts.end()) parts.push_back(part);
}

struct TopView::Tree {
  pcl::search::KdTree<pcl::PointXYZ> tree{false};  // unsorted results
  std::vector<float> distances;
};

TopView::TopView(const std::vector<Vec3f>& centres, std::vector<std::uint32_t> voxels)
    : voxel_at(std::move(voxels)) {
  build(centres);
}

TopView::TopView(const std::vector<std::vector<std::uint32_t>>& parts,
                 const std::vector<Vec3f>& centres, const std::vector<std::uint8_t>& chosen)
    : part_of(centres.size(), -1) {
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (!chosen[p]) continue;
    for (auto v : parts[p]) part_of[v] = static_cast<int>(p), voxel_at.push_back(v);
  }
  build(centres);
}

TopView::~TopView() = default;

void TopView::search(const Vec3f& centre, double radius, std::vector<int>& found) {
  tree_->tree.radiusSearch(pcl::PointXYZ(centre.x(), centre.y(), 0.0f), radius, found,
                           tree_->distances);
}

void TopView::build(const std::vector<Vec3f>& centres) {
  tree_ = std::make_unique<Tree>();
  auto flat = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  flat->reserve(voxel_at.size());
  for (auto v : voxel_at) flat->push_back({centres[v].x(), centres[v].y(), 0.0f});
  if (!flat->empty()) tree_->tree.setInputCloud(flat);
}

double border_length_mm(std::size_t band_ab, std::size_t band_ba, double radius) {
  const double leaf = radius / kVoxelsPerTolerance;
  return static_cast<double>(band_ab + band_ba) * leaf * leaf / (2.0 * radius);
}

std::vector<std::vector<std::uint32_t>> with_joined(std::vector<std::vector<std::uint32_t>> parts,
                                                    const std::vector<int>& joins) {
  std::vector<std::vector<std::uint32_t>> joined;
  std::vector<int> index(parts.size(), -1);
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (joins[p] < 0)
      index[p] = static_cast<int>(joined.size()), joined.push_back(std::move(parts[p]));
  }
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (joins[p] < 0) continue;
    auto& into = joined[index[joins[p]]];
    into.insert(into.end(), parts[p].begin(), parts[p].end());
  }
  return joined;
}

std::vector<std::vector<std::uint32_t>> with_joined(std::vector<std::vector<std::uint32_t>> parts,
                                                    Groups& group) {
  std::vector<int> joins(parts.size(), -1);
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const int root = group.root(static_cast<int>(p));
    if (root != static_cast<int>(p)) joins[p] = root;
  }
  return with_joined(std::move(parts), joins);
}

std::vector<std::vector<std::uint32_t>> points_of(
    const Voxels& voxels, const std::vector<std::vector<std::uint32_t>>& parts) {
  std::vector<std::vector<std::uint32_t>> found;
  for (const auto& part : parts) {
    std::vector<std::uint32_t> members;
    for (auto v : part) {
      for (std::size_t k = voxels.begin[v]; k < voxels.begin[v + 1]; ++k)
        members.push_back(voxels.keyed[k].second);
    }
    std::sort(members.begin(), members.end());
    found.push_back(std::move(members));
  }
  return found;
}

}  // namespace sherd::segmentation::detail
