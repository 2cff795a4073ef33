// read_model / write_ply / write_view / read_view against hand-built files (written byte by byte
// here, not by the code under test), hand-computed normals and the shared real data.
#include "processing/io/model_io.h"

#include "core/errors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>

namespace fs = std::filesystem;
using sherd::Mesh;
using sherd::Vec3f;
using sherd::io::read_model;
using sherd::io::Units;

namespace {

const fs::path kData = SHERD_SHARED_DATA;

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("sherd_io_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
                                                  ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream(file, std::ios::binary) << text;
}

template <typename T>
void put(std::string& bytes, T value) {
  bytes.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// The unit tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1), faces wound counter-clockwise seen
// from outside. Area-weighted vertex normals, by hand: at the origin the three axis faces (area
// 1/2 each, normals -x, -y, -z) give -(1,1,1)/√3; at (1,0,0) the faces -y, -z (area 1/2) and
// the slanted face ((1,1,1)/√3, area √3/2) sum to (1/2, 0, 0) → +x; likewise +y and +z.
const Vec3f kTetraPoints[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const int kTetraFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
const Vec3f kTetraNormals[4] = {-Vec3f::Ones().normalized(), Vec3f::UnitX(), Vec3f::UnitY(), Vec3f::UnitZ()};

void expect_tetrahedron(const Mesh& mesh, float scale = 1.0f) {
  ASSERT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 4u);
  ASSERT_TRUE(mesh.vertices.has_normals());
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(mesh.vertices.points[i].isApprox(kTetraPoints[i] * scale, 1e-6f) ||
                (i == 0 && mesh.vertices.points[i].norm() < 1e-6f))
        << "vertex " << i << ": " << mesh.vertices.points[i].transpose();
    EXPECT_NEAR(mesh.vertices.normals[i].dot(kTetraNormals[i]), 1.0f, 1e-5f) << "vertex " << i;
  }
  for (int f = 0; f < 4; ++f) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(mesh.triangles[f][c], static_cast<std::uint32_t>(kTetraFaces[f][c]));
  }
}

std::string tetra_ply_ascii(const std::string& eol) {
  std::string s = "ply" + eol + "format ascii 1.0" + eol + "element vertex 4" + eol + "property float x" + eol +
                  "property float y" + eol + "property float z" + eol + "element face 4" + eol +
                  "property list uchar int vertex_indices" + eol + "end_header" + eol;
  for (const auto& p : kTetraPoints) s += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + eol;
  for (const auto& f : kTetraFaces) s += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + eol;
  return s;
}

std::string tetra_ply_binary() {
  std::string s =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& p : kTetraPoints) put(s, p.x()), put(s, p.y()), put(s, p.z());
  for (const auto& f : kTetraFaces) {
    put(s, std::uint8_t{3});
    for (int c = 0; c < 3; ++c) put(s, static_cast<std::int32_t>(f[c]));
  }
  return s;
}

std::string tetra_stl_binary() {
  std::string s(80, ' ');
  put(s, std::uint32_t{4});
  for (const auto& f : kTetraFaces) {
    for (int k = 0; k < 3; ++k) put(s, 0.0f);  // facet normal: readers recompute it
    for (int c = 0; c < 3; ++c) {
      const Vec3f& p = kTetraPoints[f[c]];
      put(s, p.x()), put(s, p.y()), put(s, p.z());
    }
    put(s, std::uint16_t{0});
  }
  return s;
}

std::string tetra_stl_ascii() {
  std::string s = "solid tetra\n";
  for (const auto& f : kTetraFaces) {
    s += " facet normal 0 0 0\n  outer loop\n";
    for (int c = 0; c < 3; ++c) {
      const Vec3f& p = kTetraPoints[f[c]];
      s += "   vertex " + std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
    }
    s += "  endloop\n endfacet\n";
  }
  return s + "endsolid tetra\n";
}

// Unit cube [0,1]³ as 6 outward-wound quads: 8 vertices, 12 triangles once fanned.
const char* kCubeObj =
    "# unit cube\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

// Corner normals of the triangulated cube are not exactly diagonal (a corner touches one or two
// triangles of each face), but each points into the corner's own octant.
void expect_cube(const Mesh& mesh) {
  ASSERT_EQ(mesh.vertices.size(), 8u);
  ASSERT_EQ(mesh.triangles.size(), 12u);
  ASSERT_TRUE(mesh.vertices.has_normals());
  const Vec3f centre = Vec3f::Constant(0.5f);
  for (std::size_t i = 0; i < 8; ++i) {
    const Vec3f corner = mesh.vertices.points[i] - centre;
    EXPECT_NEAR(corner.cwiseAbs().maxCoeff(), 0.5f, 1e-6f);
    for (int a = 0; a < 3; ++a) EXPECT_GT(mesh.vertices.normals[i][a] * corner[a], 0.0f) << "corner " << i;
    EXPECT_NEAR(mesh.vertices.normals[i].norm(), 1.0f, 1e-5f);
  }
}

std::size_t header_count(const fs::path& file, const std::string& key) {
  std::ifstream in(file, std::ios::binary);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(key, 0) == 0) return std::stoul(line.substr(key.size()));
  }
  return 0;
}

}  // namespace

TEST(IoRead, PlyAsciiLfAndCrlf) {
  TempDir dir;
  write_text(dir / "lf.ply", tetra_ply_ascii("\n"));
  write_text(dir / "crlf.ply", tetra_ply_ascii("\r\n"));
  expect_tetrahedron(read_model(dir / "lf.ply"));
  expect_tetrahedron(read_model(dir / "crlf.ply"));
}

TEST(IoRead, PlyBinaryAndMetres) {
  TempDir dir;
  write_text(dir / "t.ply", tetra_ply_binary());
  expect_tetrahedron(read_model(dir / "t.ply"));
  expect_tetrahedron(read_model(dir / "t.ply", Units::Metres), 1000.0f);
}

TEST(IoRead, OffWithCommentsAndCountsOnTheirOwnLine) {
  TempDir dir;
  std::string off = "OFF\n# a tetrahedron\n4 4 6\n";
  for (const auto& p : kTetraPoints) off += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
  for (const auto& f : kTetraFaces) off += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + " 255 0 0\n";
  write_text(dir / "t.off", off);
  expect_tetrahedron(read_model(dir / "t.off"));
}

TEST(IoRead, ColourOffKeepsVertexColours) {
  TempDir dir;
  write_text(dir / "c.off", "COFF 3 1 0\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2\n");
  const Mesh mesh = read_model(dir / "c.off");
  ASSERT_TRUE(mesh.vertices.has_colours());
  EXPECT_EQ(mesh.vertices.colours[0], (sherd::Rgb8{255, 0, 0}));
  EXPECT_EQ(mesh.vertices.colours[2], (sherd::Rgb8{0, 0, 255}));
  for (const auto& n : mesh.vertices.normals) EXPECT_NEAR(n.z(), 1.0f, 1e-6f);  // CCW in the xy plane
}

TEST(IoRead, ObjCubeOfQuads) {
  TempDir dir;
  write_text(dir / "cube.obj", kCubeObj);
  expect_cube(read_model(dir / "cube.obj"));
}

TEST(IoRead, StlBinaryAndAsciiMergeCorners) {
  TempDir dir;
  write_text(dir / "b.stl", tetra_stl_binary());
  write_text(dir / "a.stl", tetra_stl_ascii());
  for (const auto* name : {"b.stl", "a.stl"}) {
    const Mesh mesh = read_model(dir / name);
    ASSERT_EQ(mesh.vertices.size(), 4u) << name;  // 12 triangle corners merged into 4 vertices
    ASSERT_EQ(mesh.triangles.size(), 4u) << name;
    for (std::size_t i = 0; i < 4; ++i) {
      const Vec3f& p = mesh.vertices.points[i];
      for (int k = 0; k < 4; ++k) {
        if ((p - kTetraPoints[k]).norm() < 1e-6f) {
          EXPECT_NEAR(mesh.vertices.normals[i].dot(kTetraNormals[k]), 1.0f, 1e-5f);
        }
      }
    }
  }
}

TEST(IoRead, PcdAsciiWithoutFacesGetsOutwardEstimatedNormals) {
  // A sphere of radius 50 mm sampled on a Fibonacci lattice: the estimated, propagated normals
  // must be the outward radial directions.
  TempDir dir;
  constexpr int kCount = 2000;
  std::string pcd = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " + std::to_string(kCount) +
                    "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(kCount) + "\nDATA ascii\n";
  const Vec3f centre(10, -20, 30);
  for (int i = 0; i < kCount; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / kCount, r = std::sqrt(1 - z * z);
    const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
    const Vec3f p = centre + 50.0f * Vec3f(r * std::cos(phi), r * std::sin(phi), z);
    pcd += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
  }
  write_text(dir / "sphere.pcd", pcd);
  const Mesh mesh = read_model(dir / "sphere.pcd");
  ASSERT_EQ(mesh.vertices.size(), static_cast<std::size_t>(kCount));
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3f radial = (mesh.vertices.points[i] - centre).normalized();
    ASSERT_GT(mesh.vertices.normals[i].dot(radial), 0.99f) << "point " << i;
  }
}

TEST(IoRead, NanPointsDroppedWithTheirFaces) {
  TempDir dir;
  write_text(dir / "nan.ply",
             "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\nnan nan nan\n0 1 0\n1 1 0\n3 0 1 3\n3 1 2 3\n");
  const Mesh mesh = read_model(dir / "nan.ply");
  EXPECT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 1u);  // the face through the NaN vertex is gone
  EXPECT_EQ(mesh.vertices.points[mesh.triangles[0][2]], Vec3f(0, 1, 0));

  write_text(dir / "allnan.pcd",
             "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
             "nan nan nan\nnan nan nan\n");
  EXPECT_THROW(read_model(dir / "allnan.pcd"), sherd::InputError);
}

TEST(IoRead, BadInputThrowsInputErrorNamingTheFile) {
  TempDir dir;
  std::string truncated = tetra_ply_binary();
  truncated.resize(truncated.size() - 30);
  write_text(dir / "truncated.ply", truncated);
  write_text(dir / "garbage.ply", std::string("\x01\x02garbage\x00\xff\xfe not a model", 24));
  write_text(dir / "garbage.pcd", "this is not a point cloud\n");
  write_text(dir / "garbage.stl", "solid x\n facet nonsense\n");
  write_text(dir / "garbage.obj", "\x7f\x45\x4c\x46 binary junk");
  write_text(dir / "empty.ply", "");
  write_text(dir / "truncated.off", "OFF\n4 4 0\n0 0 0\n1 0 0\n");
  write_text(dir / "badindex.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  write_text(dir / "model.xyz", "0 0 0\n");
  std::string truncated_pcd = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 100\nHEIGHT 1\nPOINTS 100\nDATA binary\n";
  truncated_pcd += std::string(40, '\0');
  write_text(dir / "truncated.pcd", truncated_pcd);
  for (const auto* name : {"truncated.ply", "garbage.ply", "garbage.pcd", "garbage.stl", "garbage.obj", "empty.ply",
                           "truncated.off", "badindex.off", "model.xyz", "truncated.pcd", "missing.ply"}) {
    try {
      read_model(dir / name);
      ADD_FAILURE() << name << " was accepted";
    } catch (const sherd::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

TEST(IoRead, BinaryPlyCutInsideTheVertexDataIsRefused) {
  // A real mesh written as binary PLY, then cut in the middle of its vertex block and of its
  // face block: both must be refused with InputError, not crash or come back short.
  TempDir dir;
  const Mesh bunny = read_model(kData / "stanford-bunny" / "reconstruction" / "bun_zipper_res4.ply");
  sherd::io::write_ply(dir / "whole.ply", bunny);
  const auto size = fs::file_size(dir / "whole.ply");
  for (const double fraction : {0.3, 0.9}) {
    fs::copy_file(dir / "whole.ply", dir / "cut.ply", fs::copy_options::overwrite_existing);
    fs::resize_file(dir / "cut.ply", static_cast<std::uintmax_t>(size * fraction));
    EXPECT_THROW(read_model(dir / "cut.ply"), sherd::InputError) << "cut at " << fraction;
  }
}

TEST(IoWrite, PlyRoundTripKeepsEverything) {
  TempDir dir;
  Mesh mesh;
  for (int i = 0; i < 4; ++i) {
    mesh.vertices.points.push_back(kTetraPoints[i] * 25.0f);
    mesh.vertices.normals.push_back(kTetraNormals[i]);
    mesh.vertices.colours.push_back({static_cast<std::uint8_t>(10 * i), 200, static_cast<std::uint8_t>(255 - i)});
  }
  for (const auto& f : kTetraFaces) mesh.triangles.push_back({std::uint32_t(f[0]), std::uint32_t(f[1]), std::uint32_t(f[2])});
  sherd::io::write_ply(dir / "out.ply", mesh);
  EXPECT_FALSE(fs::exists(dir / "out.ply.partial"));
  {
    std::ifstream in(dir / "out.ply", std::ios::binary);
    std::string header((std::istreambuf_iterator<char>(in)), {});
    EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  }
  const Mesh back = read_model(dir / "out.ply");
  ASSERT_EQ(back.vertices.size(), 4u);
  ASSERT_EQ(back.triangles, mesh.triangles);
  ASSERT_TRUE(back.vertices.has_colours());
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(back.vertices.points[i], mesh.vertices.points[i]);
    EXPECT_TRUE(back.vertices.normals[i].isApprox(mesh.vertices.normals[i], 1e-6f));
    EXPECT_EQ(back.vertices.colours[i], mesh.vertices.colours[i]);
  }

  // A bare cloud (no faces, no attributes) round-trips its points.
  Mesh cloud;
  cloud.vertices.points = {{1, 2, 3}, {4, 5, 6}, {7, 8, 10}, {-1, 0, 2}};
  sherd::io::write_ply(dir / "cloud.ply", cloud);
  const Mesh cloud_back = read_model(dir / "cloud.ply");
  EXPECT_EQ(cloud_back.vertices.points, cloud.vertices.points);
  EXPECT_TRUE(cloud_back.triangles.empty());
  EXPECT_THROW(sherd::io::write_ply(dir / "no_such_dir" / "x.ply", mesh), sherd::InputError);
}

TEST(IoWrite, ViewRoundTripKeepsGridInvalidCellsAndTimestamp) {
  TempDir dir;
  sherd::OrganisedView view;
  view.width = 4, view.height = 3;
  view.timestamp_ns = 1'732'240'000'123'456'789;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) {
      const bool valid = (x + y) % 3 != 0;
      view.points.push_back(valid ? Vec3f(x * 0.5f, y * 0.5f, 300.0f + x) : Vec3f::Constant(std::numeric_limits<float>::quiet_NaN()));
      view.normals.push_back(Vec3f(0, 0, -1));
      view.colours.push_back({static_cast<std::uint8_t>(x * 60), static_cast<std::uint8_t>(y * 100), 7});
      view.valid.push_back(valid ? 1 : 0);
    }
  }
  sherd::io::write_view(dir / "v.pcd", view);
  EXPECT_FALSE(fs::exists(dir / "v.pcd.partial"));
  const auto back = sherd::io::read_view(dir / "v.pcd");
  EXPECT_EQ(back.width, 4);
  EXPECT_EQ(back.height, 3);
  EXPECT_EQ(back.timestamp_ns, view.timestamp_ns);
  EXPECT_EQ(back.valid, view.valid);
  for (std::size_t i = 0; i < view.cells(); ++i) {
    if (view.valid[i]) {
      EXPECT_EQ(back.points[i], view.points[i]);
      EXPECT_EQ(back.normals[i], view.normals[i]);
      EXPECT_EQ(back.colours[i], view.colours[i]);
    } else {
      EXPECT_TRUE(std::isnan(back.points[i].x()));
    }
  }
  // It is a standard PCD: the generic reader sees exactly the valid cells.
  EXPECT_EQ(read_model(dir / "v.pcd").vertices.size(), view.valid_count());
  // Truncated views are refused, not half-read.
  fs::resize_file(dir / "v.pcd", fs::file_size(dir / "v.pcd") - 100);
  EXPECT_THROW(sherd::io::read_view(dir / "v.pcd"), sherd::InputError);
}

// The Stanford raw scans: range_grid PLYs; bun000 has CRLF line endings, top2 LF. Vertex
// counts from SOURCE.txt (= the files' 'element vertex' lines), Cyberware frame in metres.
TEST(IoRealData, StanfordBunnyRangeScans) {
  const fs::path dir = kData / "stanford-bunny" / "data";
  for (const auto& [name, count] : {std::pair{"bun000.ply", 40256u}, std::pair{"top2.ply", 38298u}}) {
    const Mesh mesh = read_model(dir / name, Units::Metres);
    EXPECT_EQ(mesh.vertices.size(), count) << name;
    const auto extent = sherd::Box3::of(mesh.vertices).extent();
    EXPECT_GT(extent.maxCoeff(), 100.0) << name;  // the bunny is ~15 cm across, now in mm
    EXPECT_LT(extent.maxCoeff(), 250.0) << name;
    EXPECT_TRUE(mesh.vertices.has_normals());
  }
}

TEST(IoRealData, StanfordBunnyZipperMesh) {
  const fs::path file = kData / "stanford-bunny" / "reconstruction" / "bun_zipper_res2.ply";
  const Mesh mesh = read_model(file);
  EXPECT_EQ(mesh.vertices.size(), header_count(file, "element vertex "));
  EXPECT_EQ(mesh.triangles.size(), header_count(file, "element face "));
}

TEST(IoRealData, PclTestCloudsInAllThreePcdEncodings) {
  const fs::path dir = kData / "pcl-test-clouds";
  // ascii with normals, binary with rgb + normals, binary_compressed: counts from the headers.
  for (const auto* name : {"bun0.pcd", "colored_cloud.pcd", "milk.pcd", "car6.pcd"}) {
    const Mesh mesh = read_model(dir / name);
    EXPECT_EQ(mesh.vertices.size(), header_count(dir / name, "POINTS ")) << name;
    for (const auto& n : mesh.vertices.normals) ASSERT_NEAR(n.norm(), 1.0f, 1e-4f) << name;
  }
  EXPECT_TRUE(read_model(dir / "colored_cloud.pcd").vertices.has_colours());
  // Organised, with NaN cells: fewer finite points than grid cells, all finite.
  const Mesh scene = read_model(dir / "table_scene_mug_stereo_textured.pcd", Units::Metres);
  EXPECT_LT(scene.vertices.size(), 640u * 480u);
  EXPECT_GT(scene.vertices.size(), 640u * 480u / 2);
  EXPECT_TRUE(scene.vertices.has_colours());
}
