// Model files in and out. PCL parses PLY/PCD/OBJ (and STL through VTK); OFF is read by hand
// because PCL has no OFF reader. Everything is converted to sherd::Mesh in millimetres with
// unit outward normals.
#include "processing/io/model_io.h"

#include "core/errors.h"

#include <fmt/format.h>
#include <pcl/PCLPointCloud2.h>
#include <pcl/PolygonMesh.h>
#include <pcl/common/io.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/features/normal_3d.h>
#include <pcl/io/obj_io.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/io/vtk_lib_io.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <numeric>
#include <queue>
#include <sstream>

namespace sherd::io {
namespace {

namespace fs = std::filesystem;

constexpr int kNormalNeighbours = 16;  // k of the k-nearest-neighbour plane fit and orientation graph
// The comment line that carries a raw view's capture time inside the PCD header (PCL's reader
// skips '#' lines). Kept in the one file so that the atomic rename commits point data and time
// together; the header's VIEWPOINT fields hold a pose, not a time.
constexpr const char* kTimestampTag = "# sherdscan timestamp_ns ";

[[noreturn]] void fail(const fs::path& file, const std::string& what, const std::string& what_to_do) {
  throw InputError(fmt::format("{}: {}; {}", file.string(), what, what_to_do));
}

std::string lower_extension(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool has_field(const pcl::PCLPointCloud2& cloud, const std::string& name) {
  return pcl::getFieldIndex(cloud, name) >= 0;
}

// ---------------------------------------------------------------------------------------------
// Conversion from PCL's generic containers.

// Polygons of any size become triangle fans; the corner order (the winding) is kept.
void append_polygon(const std::vector<std::uint32_t>& corners, std::size_t vertex_count,
                    const fs::path& file, std::vector<Triangle>& triangles) {
  for (auto v : corners) {
    if (v >= vertex_count) {
      fail(file, fmt::format("corrupt: a face refers to vertex {} of {}", v, vertex_count),
           "re-export the model");
    }
  }
  for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
    triangles.push_back({corners[0], corners[k], corners[k + 1]});
  }
}

// Every attribute the station uses, in one PCL point type; absent ones stay zero.
pcl::PointCloud<pcl::PointXYZRGBNormal> to_points(const pcl::PCLPointCloud2& blob) {
  pcl::PointCloud<pcl::PointXYZRGBNormal> cloud;
  // The conversion warns once per attribute the file lacks ("Failed to find match for field");
  // absent attributes are expected here, so warnings are muted for the call.
  const auto verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);
  pcl::fromPCLPointCloud2(blob, cloud);
  pcl::console::setVerbosityLevel(verbosity);
  return cloud;
}

Mesh mesh_from_pcl(const pcl::PCLPointCloud2& blob, const std::vector<pcl::Vertices>& polygons,
                   const fs::path& file) {
  if (!has_field(blob, "x") || !has_field(blob, "y") || !has_field(blob, "z")) {
    fail(file, "no x/y/z coordinates in the file", "give a file with vertex positions");
  }
  const auto cloud = to_points(blob);
  const bool with_normals = has_field(blob, "normal_x");
  const bool with_colours = has_field(blob, "rgb") || has_field(blob, "rgba");

  Mesh mesh;
  mesh.vertices.points.reserve(cloud.size());
  for (const auto& p : cloud) mesh.vertices.points.emplace_back(p.x, p.y, p.z);
  if (with_normals) {
    for (const auto& p : cloud) mesh.vertices.normals.emplace_back(p.normal_x, p.normal_y, p.normal_z);
  }
  if (with_colours) {
    for (const auto& p : cloud) mesh.vertices.colours.push_back({p.r, p.g, p.b});
  }
  for (const auto& polygon : polygons) {
    append_polygon({polygon.vertices.begin(), polygon.vertices.end()}, cloud.size(), file,
                   mesh.triangles);
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Readers per format. Each returns the raw mesh in file units or throws InputError.

Mesh read_ply(const fs::path& file) {
  pcl::PolygonMesh polygon_mesh;
  pcl::PLYReader reader;
  if (reader.read(file.string(), polygon_mesh) < 0) {
    fail(file, "corrupt or truncated PLY", "re-export the file as PLY 1.0");
  }
  // A range_grid PLY comes back organised (one cell per grid cell, NaN where the scanner saw
  // nothing): the faces, if any, still index the vertex list, so only keep them when unorganised.
  const bool organised = polygon_mesh.cloud.height > 1;
  if (organised && !polygon_mesh.polygons.empty()) {
    fail(file, "PLY with both a range_grid and faces", "export either the range grid or the mesh");
  }
  return mesh_from_pcl(polygon_mesh.cloud, polygon_mesh.polygons, file);
}

// PCL's PCDReader::read trusts the header: on a header without points or a truncated binary
// block it reads past the end of its memory map and crashes. So the header is read first and the
// data block's size checked against the file's size before PCL reads the body.
void check_pcd_body(const fs::path& file) {
  pcl::PCLPointCloud2 header;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0, data_type = 0;
  unsigned int data_offset = 0;
  const auto what_to_do = "re-export the file as PCD 0.7";
  if (pcl::PCDReader().readHeader(file.string(), header, origin, orientation, version, data_type, data_offset) < 0) {
    fail(file, "corrupt PCD header", what_to_do);
  }
  const std::uint64_t points = std::uint64_t{header.width} * header.height;
  if (header.fields.empty() || points == 0 || header.point_step == 0) {
    fail(file, "PCD header announces no points or no fields", what_to_do);
  }
  const std::uint64_t file_size = fs::file_size(file);
  enum : int { kAscii = 0, kBinary = 1, kBinaryCompressed = 2 };
  if (data_type == kBinary && data_offset + points * header.point_step > file_size) {
    fail(file, fmt::format("truncated PCD: {} points announced, data ends early", points), what_to_do);
  }
  if (data_type == kBinaryCompressed) {
    // The compressed block starts with its compressed and uncompressed sizes (uint32 each).
    std::uint32_t compressed_size = 0;
    std::ifstream in(file, std::ios::binary);
    in.seekg(data_offset);
    in.read(reinterpret_cast<char*>(&compressed_size), sizeof compressed_size);
    if (!in || data_offset + 8 + std::uint64_t{compressed_size} > file_size) {
      fail(file, "truncated compressed PCD", what_to_do);
    }
  }
}

pcl::PCLPointCloud2 read_pcd_blob(const fs::path& file) {
  check_pcd_body(file);
  pcl::PCLPointCloud2 blob;
  if (pcl::PCDReader().read(file.string(), blob) < 0) {
    fail(file, "corrupt or truncated PCD", "re-export the file as PCD 0.7");
  }
  return blob;
}

Mesh read_pcd(const fs::path& file) { return mesh_from_pcl(read_pcd_blob(file), {}, file); }

Mesh read_obj(const fs::path& file) {
  pcl::PolygonMesh polygon_mesh;
  if (pcl::io::loadOBJFile(file.string(), polygon_mesh) < 0) {
    fail(file, "corrupt OBJ", "re-export the file as Wavefront OBJ");
  }
  // PCL's OBJ reader pairs 'vn' lines with 'v' lines by order; when their counts differ its
  // normal fields are meaningless, so they are dropped and recomputed from the faces.
  Mesh mesh = mesh_from_pcl(polygon_mesh.cloud, polygon_mesh.polygons, file);
  std::ifstream in(file);
  std::size_t v_lines = 0, vn_lines = 0;
  for (std::string line; std::getline(in, line);) {
    v_lines += line.rfind("v ", 0) == 0;
    vn_lines += line.rfind("vn ", 0) == 0;
  }
  if (vn_lines != v_lines) mesh.vertices.normals.clear();
  return mesh;
}

Mesh read_stl(const fs::path& file) {
  pcl::PolygonMesh polygon_mesh;
  // Goes through vtkSTLReader, which merges the duplicated corners of STL's triangle soup.
  if (pcl::io::loadPolygonFileSTL(file.string(), polygon_mesh) == 0 &&
      polygon_mesh.cloud.width * polygon_mesh.cloud.height == 0) {
    fail(file, "corrupt STL or no triangles", "re-export the file as STL");
  }
  return mesh_from_pcl(polygon_mesh.cloud, polygon_mesh.polygons, file);
}

// OFF: "[C][N]OFF", counts "V F E", V vertex lines (x y z [nx ny nz] [r g b [a]]), F face lines
// "n i1 … in [colour]". '#' starts a comment. Written by hand: PCL has no OFF reader.
Mesh read_off(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open", "check the path and permissions");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    line = line.substr(0, line.find('#'));
    if (line.find_first_not_of(" \t\r") != std::string::npos) lines.push_back(std::move(line));
  }
  std::size_t next = 0;
  auto corrupt = [&](const std::string& what) -> void {
    fail(file, fmt::format("corrupt OFF ({})", what), "re-export the file as OFF");
  };
  if (lines.empty()) corrupt("no header");
  std::istringstream header(lines[next++]);
  std::string keyword;
  header >> keyword;
  const auto off_pos = keyword.rfind("OFF");
  if (off_pos == std::string::npos || off_pos + 3 != keyword.size()) corrupt("no OFF keyword");
  const std::string prefix = keyword.substr(0, off_pos);
  if (prefix.find_first_not_of("CN") != std::string::npos) corrupt("unsupported " + keyword);
  const bool with_colours = prefix.find('C') != std::string::npos;
  const bool with_normals = prefix.find('N') != std::string::npos;

  long long vertex_count = -1, face_count = -1;
  if (!(header >> vertex_count >> face_count)) {  // counts may sit on their own line
    if (next >= lines.size()) corrupt("no counts");
    std::istringstream counts(lines[next++]);
    counts >> vertex_count >> face_count;
  }
  if (vertex_count < 0 || face_count < 0) corrupt("bad vertex/face counts");
  if (lines.size() - next < static_cast<std::size_t>(vertex_count + face_count)) {
    corrupt(fmt::format("truncated: {} vertices and {} faces announced, {} lines present",
                        vertex_count, face_count, lines.size() - next));
  }

  Mesh mesh;
  auto& v = mesh.vertices;
  for (long long i = 0; i < vertex_count; ++i) {
    std::istringstream row(lines[next++]);
    Vec3f p, n = Vec3f::Zero();
    if (!(row >> p.x() >> p.y() >> p.z())) corrupt(fmt::format("vertex {} unreadable", i));
    v.points.push_back(p);
    if (with_normals) {
      if (!(row >> n.x() >> n.y() >> n.z())) corrupt(fmt::format("normal {} unreadable", i));
      v.normals.push_back(n);
    }
    if (with_colours) {
      float rgb[3];
      if (!(row >> rgb[0] >> rgb[1] >> rgb[2])) corrupt(fmt::format("colour {} unreadable", i));
      // OFF colours are either 0–255 integers or 0–1 floats.
      const bool unit_range = std::max({rgb[0], rgb[1], rgb[2]}) <= 1.0f;
      auto channel = [&](float c) {
        return static_cast<std::uint8_t>(std::clamp(unit_range ? c * 255.0f : c, 0.0f, 255.0f) + 0.5f);
      };
      v.colours.push_back({channel(rgb[0]), channel(rgb[1]), channel(rgb[2])});
    }
  }
  for (long long f = 0; f < face_count; ++f) {
    std::istringstream row(lines[next++]);
    long long corner_count = 0;
    if (!(row >> corner_count) || corner_count < 3) corrupt(fmt::format("face {} unreadable", f));
    std::vector<std::uint32_t> corners(static_cast<std::size_t>(corner_count));
    for (auto& c : corners) {
      long long index = -1;
      if (!(row >> index) || index < 0) corrupt(fmt::format("face {} unreadable", f));
      c = static_cast<std::uint32_t>(std::min<long long>(index, std::numeric_limits<std::uint32_t>::max()));
    }
    append_polygon(corners, v.size(), file, mesh.triangles);
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Normals.

// Area-weighted vertex normals: the cross product of two edges is twice the triangle's area
// times its normal, so summing them weights each face by its area. Counter-clockwise winding
// seen from outside gives outward normals. Vertices on no face keep a zero normal.
std::vector<Vec3f> face_normals(const Mesh& mesh) {
  std::vector<Vec3f> sum(mesh.vertices.size(), Vec3f::Zero());
  const auto& p = mesh.vertices.points;
  for (const auto& t : mesh.triangles) {
    const Vec3f n = (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
    for (auto v : t) sum[v] += n;
  }
  for (auto& n : sum) {
    const float length = n.norm();
    n = length > 0.0f ? Vec3f(n / length) : Vec3f::Zero();
  }
  return sum;
}

// Normals for the vertices whose `normals[i]` is zero: a plane fit to the k nearest neighbours
// (pcl::computePointNormal), then a consistent sign. A plane fit gives the normal's line, not its
// sign; the sign is propagated over the k-nearest-neighbour graph, always next across the edge
// whose normals are closest to parallel (Hoppe et al. 1992, a maximum spanning tree on |n_i·n_j|),
// so that it does not flip across thin walls or sharp edges. Propagation starts from the vertices
// whose normals are already known (file or faces). A component with none starts from its point
// farthest from the model's centroid: there the surface touches the sphere about the centroid
// that encloses it, so the outward normal is the one pointing away from the centroid.
void fill_normals(const std::vector<Vec3f>& points, std::vector<Vec3f>& normals) {
  const std::size_t n = points.size();
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->reserve(n);
  for (const auto& p : points) cloud->push_back({p.x(), p.y(), p.z()});
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(cloud);
  const int k = static_cast<int>(std::min<std::size_t>(kNormalNeighbours, n));

  std::vector<pcl::Indices> neighbours(n);
  std::vector<bool> known(n);
  std::vector<float> distances;
  for (std::size_t i = 0; i < n; ++i) {
    tree.nearestKSearch(static_cast<int>(i), k, neighbours[i], distances);
    known[i] = normals[i] != Vec3f::Zero();
    if (known[i]) continue;
    Eigen::Vector4f plane;
    float curvature = 0.0f;
    if (neighbours[i].size() >= 3 && pcl::computePointNormal(*cloud, neighbours[i], plane, curvature)) {
      normals[i] = plane.head<3>().normalized();
    }
    if (!normals[i].allFinite() || normals[i] == Vec3f::Zero()) normals[i] = Vec3f::UnitZ();
  }

  Vec3f centroid = Vec3f::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<float>(n);
  std::vector<std::uint32_t> seeds(n);
  std::iota(seeds.begin(), seeds.end(), 0u);
  std::sort(seeds.begin(), seeds.end(), [&](auto a, auto b) {
    return (points[a] - centroid).squaredNorm() > (points[b] - centroid).squaredNorm();
  });

  struct Edge {
    float alignment;  // |n_from · n_to|: the frontier is expanded across the most parallel first
    std::uint32_t from, to;
    bool operator<(const Edge& o) const { return alignment < o.alignment; }
  };
  std::priority_queue<Edge> frontier;
  std::vector<bool> oriented = known;
  auto expand = [&](std::uint32_t from) {
    for (auto to : neighbours[from]) {
      if (!oriented[to]) {
        frontier.push({std::abs(normals[from].dot(normals[to])), from, static_cast<std::uint32_t>(to)});
      }
    }
  };
  for (std::uint32_t i = 0; i < n; ++i) {
    if (known[i]) expand(i);
  }
  std::size_t next_seed = 0;
  for (std::size_t done = std::count(known.begin(), known.end(), true); done < n;) {
    if (frontier.empty()) {
      while (oriented[seeds[next_seed]]) ++next_seed;
      const auto seed = seeds[next_seed];
      if ((points[seed] - centroid).dot(normals[seed]) < 0.0f) normals[seed] = -normals[seed];
      oriented[seed] = true;
      ++done;
      expand(seed);
      continue;
    }
    const auto edge = frontier.top();
    frontier.pop();
    if (oriented[edge.to]) continue;
    if (normals[edge.from].dot(normals[edge.to]) < 0.0f) normals[edge.to] = -normals[edge.to];
    oriented[edge.to] = true;
    ++done;
    expand(edge.to);
  }
}

void ensure_normals(Mesh& mesh) {
  auto& v = mesh.vertices;
  if (v.has_normals()) {
    // Normals from the file: normalised; unusable ones (zero, non-finite) are recomputed.
    for (auto& n : v.normals) {
      const float length = n.norm();
      n = std::isfinite(length) && length > 0.0f ? Vec3f(n / length) : Vec3f::Zero();
    }
  } else {
    v.normals = face_normals(mesh);
  }
  if (std::any_of(v.normals.begin(), v.normals.end(), [](const Vec3f& n) { return n == Vec3f::Zero(); })) {
    fill_normals(v.points, v.normals);
  }
}

// NaN points (e.g. empty cells of a range grid) are dropped with the faces that use them.
Mesh drop_non_finite(const Mesh& mesh) {
  std::vector<std::uint32_t> keep;
  keep.reserve(mesh.vertices.size());
  for (std::uint32_t i = 0; i < mesh.vertices.size(); ++i) {
    if (mesh.vertices.points[i].allFinite()) keep.push_back(i);
  }
  return keep.size() == mesh.vertices.size() ? mesh : mesh.subset(keep);
}

// Writes through a temporary file in the same directory, then renames: a reader (or a crash)
// sees either the old file or the complete new one.
template <typename WriteFn>
void write_atomically(const fs::path& file, WriteFn&& write_to) {
  const fs::path temp = file.string() + ".partial";
  std::error_code ec;
  if (!write_to(temp)) {
    fs::remove(temp, ec);
    fail(file, "cannot write", "check that the directory exists, is writable and has space");
  }
  fs::rename(temp, file, ec);
  if (ec) {
    fs::remove(temp, ec);
    fail(file, "cannot rename the finished temporary file into place", "check the directory's permissions");
  }
}

pcl::PointXYZRGBNormal to_pcl_point(const Vec3f& p, const Vec3f& n, Rgb8 c) {
  pcl::PointXYZRGBNormal q;
  q.x = p.x(), q.y = p.y(), q.z = p.z();
  q.normal_x = n.x(), q.normal_y = n.y(), q.normal_z = n.z();
  q.r = c.r, q.g = c.g, q.b = c.b, q.a = 255;
  q.curvature = 0.0f;
  return q;
}

}  // namespace

Mesh read_model(const fs::path& file, Units units) {
  std::error_code ec;
  if (!fs::exists(file, ec)) fail(file, "no such file", "check the path");
  if (!fs::is_regular_file(file, ec)) fail(file, "not a regular file", "give a model file");
  if (fs::file_size(file, ec) == 0) fail(file, "empty file", "re-export the model");

  const std::string ext = lower_extension(file);
  Mesh mesh;
  if (ext == ".ply") {
    mesh = read_ply(file);
  } else if (ext == ".pcd") {
    mesh = read_pcd(file);
  } else if (ext == ".obj") {
    mesh = read_obj(file);
  } else if (ext == ".off") {
    mesh = read_off(file);
  } else if (ext == ".stl") {
    mesh = read_stl(file);
  } else {
    fail(file, fmt::format("unknown format '{}'", ext), "give a .ply, .obj, .off, .stl or .pcd file");
  }
  if (mesh.empty()) fail(file, "contains no points", "give a file with at least one vertex");
  mesh = drop_non_finite(mesh);
  if (mesh.empty()) fail(file, "contains no finite points (all NaN/inf)", "check the exporter");
  if (units == Units::Metres) {
    for (auto& p : mesh.vertices.points) p *= 1000.0f;
  }
  ensure_normals(mesh);
  return mesh;
}

void write_ply(const fs::path& file, const Mesh& mesh) {
  const auto& v = mesh.vertices;
  pcl::PolygonMesh polygon_mesh;
  // The PCL point type decides which PLY properties are written; pick the one that carries
  // exactly the attributes the mesh has.
  if (v.has_normals() && v.has_colours()) {
    pcl::PointCloud<pcl::PointXYZRGBNormal> cloud;
    for (std::size_t i = 0; i < v.size(); ++i) cloud.push_back(to_pcl_point(v.points[i], v.normals[i], v.colours[i]));
    pcl::toPCLPointCloud2(cloud, polygon_mesh.cloud);
  } else if (v.has_normals()) {
    pcl::PointCloud<pcl::PointNormal> cloud;
    for (std::size_t i = 0; i < v.size(); ++i) {
      pcl::PointNormal q;
      q.x = v.points[i].x(), q.y = v.points[i].y(), q.z = v.points[i].z();
      q.normal_x = v.normals[i].x(), q.normal_y = v.normals[i].y(), q.normal_z = v.normals[i].z();
      q.curvature = 0.0f;
      cloud.push_back(q);
    }
    pcl::toPCLPointCloud2(cloud, polygon_mesh.cloud);
  } else if (v.has_colours()) {
    pcl::PointCloud<pcl::PointXYZRGB> cloud;
    for (std::size_t i = 0; i < v.size(); ++i) {
      pcl::PointXYZRGB q(v.colours[i].r, v.colours[i].g, v.colours[i].b);
      q.x = v.points[i].x(), q.y = v.points[i].y(), q.z = v.points[i].z();
      cloud.push_back(q);
    }
    pcl::toPCLPointCloud2(cloud, polygon_mesh.cloud);
  } else {
    pcl::PointCloud<pcl::PointXYZ> cloud;
    for (const auto& p : v.points) cloud.push_back({p.x(), p.y(), p.z()});
    pcl::toPCLPointCloud2(cloud, polygon_mesh.cloud);
  }
  for (const auto& t : mesh.triangles) {
    pcl::Vertices face;
    for (auto v : t) face.vertices.push_back(static_cast<pcl::index_t>(v));
    polygon_mesh.polygons.push_back(std::move(face));
  }
  write_atomically(file, [&](const fs::path& temp) {
    return pcl::io::savePLYFileBinary(temp.string(), polygon_mesh) == 0;
  });
}

void write_view(const fs::path& file, const OrganisedView& view) {
  const std::size_t cells = view.cells();
  if (view.width <= 0 || view.height <= 0 || view.points.size() != cells || view.valid.size() != cells ||
      (!view.normals.empty() && view.normals.size() != cells) ||
      (!view.colours.empty() && view.colours.size() != cells)) {
    fail(file, fmt::format("inconsistent view ({} x {} grid, {} points, {} valid flags)", view.width,
                           view.height, view.points.size(), view.valid.size()),
         "fill one entry per grid cell");
  }
  // A packed blob (no alignment padding): PCL's binary PCD body is the fields back to back, and
  // its header generator describes exactly the fields listed here.
  pcl::PCLPointCloud2 blob;
  blob.width = static_cast<std::uint32_t>(view.width);
  blob.height = static_cast<std::uint32_t>(view.height);
  blob.is_dense = false;
  std::uint32_t offset = 0;
  for (const char* name : {"x", "y", "z", "normal_x", "normal_y", "normal_z", "rgb"}) {
    const auto type = std::string_view(name) == "rgb" ? pcl::PCLPointField::UINT32 : pcl::PCLPointField::FLOAT32;
    blob.fields.push_back({name, offset, type, 1});
    offset += 4;
  }
  blob.point_step = offset;
  blob.row_step = blob.point_step * blob.width;
  blob.data.resize(std::size_t{blob.row_step} * blob.height);
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < cells; ++i) {
    const Vec3f p = view.valid[i] ? view.points[i] : Vec3f::Constant(kNaN);
    const Vec3f n = !view.valid[i] ? Vec3f::Constant(kNaN) : view.normals.empty() ? Vec3f::Zero() : view.normals[i];
    const Rgb8 c = view.colours.empty() ? Rgb8{} : view.colours[i];
    const float values[6] = {p.x(), p.y(), p.z(), n.x(), n.y(), n.z()};
    const std::uint32_t rgb = 0xff000000u | std::uint32_t{c.r} << 16 | std::uint32_t{c.g} << 8 | c.b;
    std::uint8_t* out = blob.data.data() + i * blob.point_step;
    std::memcpy(out, values, sizeof values);
    std::memcpy(out + sizeof values, &rgb, sizeof rgb);
  }
  // PCL generates the header; the timestamp goes in as a comment line right after PCL's own
  // first comment line.
  std::string header = pcl::PCDWriter().generateHeaderBinary(blob, Eigen::Vector4f::Zero(),
                                                             Eigen::Quaternionf::Identity());
  const auto first_line_end = header.find('\n') + 1;
  header.insert(first_line_end, fmt::format("{}{}\n", kTimestampTag, view.timestamp_ns));
  header += "DATA binary\n";  // PCDWriter::writeBinary appends this line itself, after the header
  write_atomically(file, [&](const fs::path& temp) {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out << header;
    out.write(reinterpret_cast<const char*>(blob.data.data()), static_cast<std::streamsize>(blob.data.size()));
    out.flush();
    return static_cast<bool>(out);
  });
}

OrganisedView read_view(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) fail(file, "no such view file", "check the path");
  if (fs::file_size(file, ec) == 0) fail(file, "empty view file", "re-acquire the view");
  const pcl::PCLPointCloud2 blob = read_pcd_blob(file);
  if (blob.height <= 1 || !has_field(blob, "x") || !has_field(blob, "normal_x") || !has_field(blob, "rgb")) {
    fail(file, "not an organised XYZ+RGB+normal view", "give a view written by sherdscan");
  }
  const auto cloud = to_points(blob);

  OrganisedView view;
  view.width = static_cast<int>(cloud.width);
  view.height = static_cast<int>(cloud.height);
  for (const auto& p : cloud) {
    const Vec3f point(p.x, p.y, p.z);
    view.points.push_back(point);
    view.normals.emplace_back(p.normal_x, p.normal_y, p.normal_z);
    view.colours.push_back({p.r, p.g, p.b});
    view.valid.push_back(point.allFinite() ? 1 : 0);
  }
  std::ifstream in(file, std::ios::binary);
  for (std::string line; std::getline(in, line) && line.rfind("DATA", 0) != 0;) {
    if (line.rfind(kTimestampTag, 0) == 0) {
      try {
        view.timestamp_ns = std::stoll(line.substr(std::string(kTimestampTag).size()));
      } catch (const std::exception&) {
        fail(file, "unreadable timestamp line '" + line + "'", "re-acquire the view");
      }
    }
  }
  return view;
}

}  // namespace sherd::io
