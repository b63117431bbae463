// Tests for the PLY/OBJ mesh writers and their read-back: exact values, units, winding, errors.
// The readers' own tests (ascii / big-endian PLY, OBJ forms) are in test_mesh_reader.cpp, the
// glTF writer's in test_gltf_writer.cpp.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "tiny_mesh_fixture.hpp"

namespace {

namespace fs = std::filesystem;
using namespace terralod::pm;

std::string tmp_path(const std::string& name) {
  return (terralod::test::process_temp_dir("mesh_io") / name).string();
}

// The tiny 3 x 2 fixture drawn in tiny_mesh_fixture.hpp.
using Fixture = terralod::test::TinyMeshFixture;

double signed_area_xy(const TriangleMeshData& m, const std::array<std::uint32_t, 3>& t) {
  const auto& a = m.positions[t[0]];
  const auto& b = m.positions[t[1]];
  const auto& c = m.positions[t[2]];
  return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
}

/// Minimal OBJ parser for "v x y z" and "f a b c" lines (1-based).
TriangleMeshData parse_obj(const std::string& path) {
  TriangleMeshData m;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "v") {
      std::array<std::string, 3> s;
      ls >> s[0] >> s[1] >> s[2];
      m.positions.push_back({std::strtod(s[0].c_str(), nullptr), std::strtod(s[1].c_str(), nullptr),
                             std::strtod(s[2].c_str(), nullptr)});
    } else if (tag == "f") {
      std::uint32_t a, b, c;
      ls >> a >> b >> c;
      m.triangles.push_back({a - 1, b - 1, c - 1});
    }
  }
  return m;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// ---------------------------------------------------------------------------------------------

TEST(MeshIo, PlySampleUnitsRoundTripExactly) {
  const Fixture f;
  const std::string path = tmp_path("tiny.ply");
  write_mesh(f.mesh, f.hf, path, Units::Samples);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const std::string text = read_text(path);
  EXPECT_EQ(text.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(text.find("element vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
                      "element face 2\nproperty list uchar int vertex_indices\nend_header\n"),
            std::string::npos);
  const std::size_t header = text.find("end_header\n") + 11;
  EXPECT_EQ(text.size(), header + 4 * 24 + 2 * 13);

  const TriangleMeshData m = read_ply(path);
  const std::vector<std::array<double, 3>> expected = {
      {0, 0, 10.5}, {1, 0, 11.25}, {1, 1, -3.0}, {0, 1, 0.1}};
  ASSERT_EQ(m.positions.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(m.positions[i], expected[i]) << i;
  ASSERT_EQ(m.triangles, f.mesh.triangles) << "sample units keep the mesh's own winding";
  for (const auto& t : m.triangles) EXPECT_GT(signed_area_xy(m, t), 0.0);
  fs::remove(path);
}

TEST(MeshIo, ObjSampleUnitsRoundTripExactly) {
  const Fixture f;
  const std::string path = tmp_path("tiny.obj");
  write_mesh(f.mesh, f.hf, path, Units::Samples);
  const TriangleMeshData m = parse_obj(path);
  const TriangleMeshData expected = mesh_positions(f.mesh, f.hf, Units::Samples);
  EXPECT_EQ(m.positions, expected.positions) << "shortest round-trip decimals read back exactly";
  EXPECT_EQ(m.triangles, expected.triangles);
  EXPECT_NE(read_text(path).find("v 1 1 -3\n"), std::string::npos);
  EXPECT_NE(read_text(path).find("v 0 1 0.1\n"), std::string::npos);
  EXPECT_NE(read_text(path).find("f 1 3 4\n"), std::string::npos);
  fs::remove(path);
}

TEST(MeshIo, WorldUnitsFlipWindingWhenTheTransformMirrors) {
  Fixture f;
  // North-up raster: row grows southwards, determinant < 0.
  f.hf.transform = GridTransform::north_up(/*x0=*/500000.0, /*y0=*/4900000.0, /*dx=*/30.0, /*dy=*/90.0);
  ASSERT_LT(f.hf.transform.determinant(), 0.0);
  for (const char* ext : {"ply", "obj"}) {
    const std::string path = tmp_path(std::string("world.") + ext);
    write_mesh(f.mesh, f.hf, path, Units::World);
    const TriangleMeshData m = std::string(ext) == "ply" ? read_ply(path) : parse_obj(path);
    ASSERT_EQ(m.positions.size(), 4u);
    for (std::size_t i = 0; i < 4; ++i) {
      const std::uint32_t s = f.mesh.vertices[i];
      const auto [x, y] = f.hf.transform.to_world(double(s % 3), double(s / 3));
      EXPECT_EQ(m.positions[i][0], x);
      EXPECT_EQ(m.positions[i][1], y);
      EXPECT_EQ(m.positions[i][2], f.hf[s]);
    }
    ASSERT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 2, 1}));
    EXPECT_EQ(m.triangles[1], (std::array<std::uint32_t, 3>{0, 3, 2}));
    for (const auto& t : m.triangles) EXPECT_GT(signed_area_xy(m, t), 0.0) << "CCW seen from +z";
    fs::remove(path);
  }
  // A transform with positive determinant keeps the winding.
  f.hf.transform = GridTransform{/*x0=*/5, /*xc=*/2, /*xr=*/0.5, /*y0=*/-1, /*yc=*/0.25, /*yr=*/3};
  ASSERT_GT(f.hf.transform.determinant(), 0.0);
  const TriangleMeshData m = mesh_positions(f.mesh, f.hf, Units::World);
  EXPECT_EQ(m.triangles, f.mesh.triangles);
  for (const auto& t : m.triangles) EXPECT_GT(signed_area_xy(m, t), 0.0);
}

TEST(MeshIo, ExtractedTerrainMeshRoundTrips) {
  TerrainOptions opt;
  opt.width = 65;
  opt.height = 49;
  const Heightfield hf = generate_terrain(opt);
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  const TriangleMesh mesh = pm.extract(/*max_error=*/5.0);
  ASSERT_GT(mesh.triangles.size(), 2u);
  const std::string path = tmp_path("terrain.ply");
  write_mesh(mesh, hf, path, Units::World);
  const TriangleMeshData back = read_ply(path);
  const TriangleMeshData expected = mesh_positions(mesh, hf, Units::World);
  EXPECT_EQ(back.positions, expected.positions);
  EXPECT_EQ(back.triangles, expected.triangles);
  double area = 0.0;
  for (const auto& t : back.triangles) {
    EXPECT_GT(signed_area_xy(back, t), 0.0);
    area += signed_area_xy(back, t);
  }
  // The mesh covers the whole grid: (W-1)(H-1) cells of 30 m x 30 m.
  EXPECT_NEAR(area, 64.0 * 48.0 * 30.0 * 30.0, 1e-6 * area);
  fs::remove(path);
}

TEST(MeshIo, ErrorsNameTheFile) {
  const Fixture f;
  const std::string bad_ext = tmp_path("mesh.stl");
  try {
    write_mesh(f.mesh, f.hf, bad_ext, Units::Samples);
    ADD_FAILURE() << "unknown extension accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(bad_ext + ": ", 0), 0u) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad_ext));

  const std::string no_dir = tmp_path("missing_dir/mesh.ply");
  try {
    write_mesh(f.mesh, f.hf, no_dir, Units::Samples);
    ADD_FAILURE() << "write into a missing folder succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(no_dir + ": ", 0), 0u) << e.what();
  }
  EXPECT_FALSE(fs::exists(no_dir + ".tmp"));

  const std::string missing = tmp_path("nothing_here.ply");
  try {
    read_ply(missing);
    ADD_FAILURE() << "missing file read";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ": cannot open", 0), 0u) << e.what();
  }
}

TEST(MeshIo, ReadPlyRejectsEveryTruncationAndForeignFormats) {
  const Fixture f;
  const std::string path = tmp_path("whole.ply");
  write_mesh(f.mesh, f.hf, path, Units::Samples);
  const std::string whole = read_text(path);
  const std::string cut = tmp_path("cut.ply");
  for (std::size_t len = 0; len < whole.size(); ++len) {
    std::ofstream(cut, std::ios::binary) << whole.substr(0, len);
    EXPECT_THROW(read_ply(cut), std::runtime_error) << "prefix of " << len << " bytes";
  }
  // Binary data under an ascii header (ascii itself is read: test_mesh_reader.cpp).
  std::string ascii = whole;
  ascii.replace(ascii.find("binary_little_endian"), 20, "ascii");
  std::ofstream(cut, std::ios::binary) << ascii;
  EXPECT_THROW(read_ply(cut), std::runtime_error);
  std::string foreign = whole;
  foreign.replace(foreign.find("binary_little_endian"), 20, "binary_middle_endian");
  std::ofstream(cut, std::ios::binary) << foreign;
  try {
    read_ply(cut);
    ADD_FAILURE() << "unknown PLY format accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not supported"), std::string::npos) << e.what();
  }
  // A face index beyond the vertices.
  std::string bad = whole;
  bad[bad.size() - 4] = 9;  // last index of the last face
  std::ofstream(cut, std::ios::binary) << bad;
  EXPECT_THROW(read_ply(cut), std::runtime_error);
  // A vertex count far larger than the file.
  std::string huge = whole;
  huge.replace(huge.find("element vertex 4"), 16, "element vertex 4000000000");
  std::ofstream(cut, std::ios::binary) << huge;
  EXPECT_THROW(read_ply(cut), std::runtime_error);
  fs::remove(cut);
  fs::remove(path);
}

TEST(MeshIo, ReadsFloatVerticesAndExtraProperties) {
  // Other tools write float coordinates, extra properties and uint indices.
  std::string ply =
      "ply\nformat binary_little_endian 1.0\ncomment from elsewhere\nelement vertex 3\n"
      "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
      "element face 1\nproperty uchar flags\nproperty list uchar uint vertex_indices\nend_header\n";
  auto put = [&ply](const void* p, std::size_t n) { ply.append(static_cast<const char*>(p), n); };
  const float v[3][3] = {{0, 0, 1.5f}, {2, 0, 2.5f}, {0, 3, -1}};
  for (const auto& p : v) {
    put(p, 12);
    ply.push_back(char(200));
  }
  ply.push_back(char(7));
  ply.push_back(char(3));
  const std::uint32_t idx[3] = {0, 1, 2};
  put(idx, 12);
  const std::string path = tmp_path("foreign.ply");
  std::ofstream(path, std::ios::binary) << ply;
  const TriangleMeshData m = read_ply(path);
  ASSERT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.positions[1], (std::array<double, 3>{2, 0, 2.5}));
  EXPECT_EQ(m.positions[2], (std::array<double, 3>{0, 3, -1}));
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  fs::remove(path);
}

}  // namespace
