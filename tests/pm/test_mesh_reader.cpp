// Tests for the mesh readers (read_mesh, read_ply in ascii / little- / big-endian, read_obj):
// round trips through files written by hand here, OBJ's face forms, and malformed files of each
// kind, whose errors name the file and the line or record.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/pm/mesh_io.hpp"

namespace {

namespace fs = std::filesystem;
using namespace terralod::pm;

std::string tmp_path(const std::string& name) {
  fs::create_directories(TERRALOD_TEST_TMP);
  return std::string(TERRALOD_TEST_TMP) + "/mesh_reader_" + name;
}

void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

/// The message of the std::runtime_error that read_mesh(path) throws ("" and a failure if none).
std::string read_error(const std::string& path) {
  try {
    (void)read_mesh(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << path << " was read without an error";
  return "";
}

/// Expects read_mesh(path) to fail with a message that starts with "<path>: " and contains each
/// of `parts`.
void expect_error(const std::string& path, const std::vector<std::string>& parts) {
  const std::string msg = read_error(path);
  EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
  for (const std::string& p : parts)
    EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
}

/// Writes `bytes` to `path`, then expect_error(path, parts).
void expect_file_error(const std::string& path, const std::string& bytes,
                       const std::vector<std::string>& parts) {
  write_file(path, bytes);
  expect_error(path, parts);
}

/// `s` with its first occurrence of `what` replaced by `with` (std::out_of_range when absent).
std::string replaced(std::string s, const std::string& what, const std::string& with) {
  return s.replace(s.find(what), what.size(), with);
}

/// `s` with the byte `from_end` bytes before its end set to `value`.
std::string with_byte(std::string s, std::size_t from_end, char value) {
  s[s.size() - from_end] = value;
  return s;
}

std::string g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// The fixture: a square fan of 4 triangles around a centre vertex, with coordinates that are
// not exact in decimal (so the ascii forms must print 17 digits) and UTM-sized:
//
//   v3 ---- v2
//   |  \  / |
//   |   v4  |       triangles (0,1,4) (1,2,4) (2,3,4) (3,0,4), CCW seen from +z
//   |  /  \ |
//   v0 ---- v1
TriangleMeshData fixture() {
  TriangleMeshData m;
  m.positions = {{500000.125, 4899910.7, 10.5},
                 {500030.1, 4899910.7, 11.25},
                 {500030.1, 4900000.3, -3.0},
                 {500000.125, 4900000.3, 0.1},
                 {500015.0, 4899955.0, 1e-7}};
  m.triangles = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
  return m;
}

std::string ascii_ply(const TriangleMeshData& m, const std::string& eol = "\n") {
  std::string s = "ply" + eol + "format ascii 1.0" + eol + "comment written by hand" + eol +
                  "element vertex " + std::to_string(m.positions.size()) + eol + "property double x" + eol +
                  "property double y" + eol + "property double z" + eol + "property uchar red" + eol +
                  "element face " + std::to_string(m.triangles.size()) + eol +
                  "property list uchar int vertex_indices" + eol + "element edge 1" + eol +
                  "property list uchar int vertex_pair" + eol + "end_header" + eol;
  for (const auto& p : m.positions) s += g17(p[0]) + " " + g17(p[1]) + "  " + g17(p[2]) + " 200" + eol;
  for (const auto& t : m.triangles)
    s += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + "\t" + std::to_string(t[2]) + eol;
  s += "2 0 1" + eol;  // the edge element: skipped
  return s;
}

template <class T>
void put(std::string& out, T v, bool big_endian) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big_endian) std::reverse(b, b + sizeof(T));  // the test host is little-endian
  out.append(b, sizeof(T));
}

/// Binary PLY with float64 x y z, a float32 extra property, and "list uchar uint" faces.
std::string binary_ply(const TriangleMeshData& m, bool big_endian) {
  std::string s = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex " + std::to_string(m.positions.size()) +
                  "\nproperty float64 x\nproperty float64 y\nproperty float64 z\nproperty float confidence\n"
                  "element face " +
                  std::to_string(m.triangles.size()) +
                  "\nproperty list uint8 uint32 vertex_indices\nend_header\n";
  for (const auto& p : m.positions) {
    for (double v : p) put(s, v, big_endian);
    put(s, 0.5f, big_endian);
  }
  for (const auto& t : m.triangles) {
    put(s, std::uint8_t(3), big_endian);
    for (std::uint32_t v : t) put(s, v, big_endian);
  }
  return s;
}

std::string obj_text(const TriangleMeshData& m) {
  std::string s = "# written by hand\n";
  for (const auto& p : m.positions) s += "v " + g17(p[0]) + " " + g17(p[1]) + " " + g17(p[2]) + "\n";
  for (const auto& t : m.triangles)
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) +
         "\n";
  return s;
}

void expect_same(const TriangleMeshData& got, const TriangleMeshData& want) {
  EXPECT_EQ(got.positions, want.positions) << "17 digits and binary doubles read back exactly";
  EXPECT_EQ(got.triangles, want.triangles);
}

// ---------------------------------------------------------------------------------------------
// Round trips

TEST(MeshReader, RoundTripsThroughEveryEncoding) {
  const TriangleMeshData m = fixture();
  const std::string ascii = tmp_path("ascii.ply"), ascii_crlf = tmp_path("ascii_crlf.ply"),
                    be = tmp_path("be.ply"), le = tmp_path("le.ply"), le_ours = tmp_path("ours.ply"),
                    obj = tmp_path("hand.obj"), obj_ours = tmp_path("ours.obj");
  write_file(ascii, ascii_ply(m));
  write_file(ascii_crlf, ascii_ply(m, "\r\n"));
  write_file(be, binary_ply(m, /*big_endian=*/true));
  write_file(le, binary_ply(m, /*big_endian=*/false));
  write_file(obj, obj_text(m));
  write_mesh(m, le_ours);
  write_mesh(m, obj_ours);
  for (const std::string& path : {ascii, ascii_crlf, be, le, le_ours, obj, obj_ours}) {
    SCOPED_TRACE(path);
    expect_same(read_mesh(path), m);
    fs::remove(path);
  }
}

TEST(MeshReader, ExtensionChoosesTheReader) {
  const TriangleMeshData m = fixture();
  const std::string upper = tmp_path("UPPER.OBJ");
  write_file(upper, obj_text(m));
  expect_same(read_mesh(upper), m);
  // A PLY named .obj is read as OBJ: none of its lines is an OBJ statement, no vertex is read.
  const std::string ply_as_obj = tmp_path("ply_inside.obj");
  write_file(ply_as_obj, ascii_ply(m));
  expect_error(ply_as_obj, {"no vertices ('v' lines)"});
  const std::string glb = tmp_path("mesh.glb");
  write_file(glb, "glTF");
  expect_error(glb, {"cannot read this mesh format", ".ply or .obj"});
  expect_error(tmp_path("no_extension"), {".ply or .obj"});
  for (const std::string& p : {upper, ply_as_obj, glb}) fs::remove(p);
}

// ---------------------------------------------------------------------------------------------
// OBJ forms

TEST(MeshReader, ObjFaceFormsNegativeIndicesAndPolygons) {
  // Vertices v1..v6 (1-based), z = the number:
  //   v1 (0,0)  v2 (1,0)  v3 (1,1)  v4 (0,1)  v5 (2,0)  v6 (2,1) (with a colour)
  // Faces, by hand (0-based triangles):
  //   f 1 2 3 4            quad     -> (0,1,2) (0,2,3)
  //   f 2/1 5/2 6/3        a/b      -> (1,4,5)
  //   f 2/1/1 6/3/1 3/2/1  a/b/c    -> (1,5,2)
  //   f 2//1 6//1 3//1     a//c     -> (1,5,2)
  //   f -5 -2 -1 -4 -3     after 6 vertices: -1 = v6, so v2 v5 v6 v3 v4: a pentagon fan
  //                                 -> (1,4,5) (1,5,2) (1,2,3)
  const std::string text =
      "# comment line\n"
      "mtllib terrain.mtl\n"
      "o terrain\n"
      "v 0 0 1\n"
      "v 1 0 2   # a comment after values\n"
      "v\t1 1 3\n"
      "v 0 1 4 1.0\n"  // w
      "vt 0 0\nvt 1 0\nvt 1 1\n"
      "vn 0 0 1\n"
      "g ground\n"
      "s off\n"
      "usemtl grass\n"
      "f 1 2 3 4\n"
      "\n"
      "v 2 0 5\r\n"  // CRLF
      "v 2 1 6 0.2 0.4 0.6\n"
      "f 2/1 5/2 6/3\n"
      "f 2/1/1 6/3/1 3/2/1\n"
      "f 2//1 6//1 3//1\n"
      "f -5 -2 -1 -4 -3\n"
      "l 1 2\n"
      "p 1\n";
  const std::string path = tmp_path("forms.obj");
  write_file(path, text);
  const TriangleMeshData m = read_mesh(path);
  const std::vector<std::array<double, 3>> positions = {{0, 0, 1}, {1, 0, 2}, {1, 1, 3},
                                                        {0, 1, 4}, {2, 0, 5}, {2, 1, 6}};
  EXPECT_EQ(m.positions, positions);
  const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {0, 2, 3}, {1, 4, 5}, {1, 5, 2},
                                                               {1, 5, 2}, {1, 4, 5}, {1, 5, 2}, {1, 2, 3}};
  EXPECT_EQ(m.triangles, triangles);
  fs::remove(path);
}

TEST(MeshReader, NegativeIndicesAreRelativeToTheVerticesSoFar) {
  // Two quads, each written right after its own vertices with -4..-1: the second quad's -4 is
  // v5 (0-based 4), not v1.
  const std::string path = tmp_path("relative.obj");
  write_file(path,
             "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n"
             "v 2 0 0\nv 3 0 0\nv 3 1 0\nv 2 1 0\nf -4 -3 -2 -1\n");
  const TriangleMeshData m = read_mesh(path);
  const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  EXPECT_EQ(m.triangles, triangles);
  fs::remove(path);
}

// ---------------------------------------------------------------------------------------------
// Malformed files

TEST(MeshReader, MalformedAsciiPly) {
  const std::string good = ascii_ply(fixture());
  const std::string path = tmp_path("bad_ascii.ply");
  // Header: 13 lines; vertex records on lines 14..18, faces on 19..22, the edge on 23.
  auto with_line = [&](int number, const std::string& replacement) {
    std::string s = good;
    std::size_t at = 0;
    for (int i = 1; i < number; ++i) at = s.find('\n', at) + 1;
    s.replace(at, s.find('\n', at) - at, replacement);
    return s;
  };
  struct Case {
    std::string text;
    std::vector<std::string> parts;
  };
  const std::vector<Case> cases = {
      // truncated: the file ends before the last face, or inside the header
      {good.substr(0, good.find("3 3 0\t4")), {"truncated", "element face record 3 of 4"}},
      {good.substr(0, good.find("end_header")), {"no end_header"}},
      // a record cut short, a bad number, a value too many
      {with_line(15, "500030.1 4899910.7"), {"line 15", "element vertex record 1", "too few values"}},
      {with_line(16, "1 2 x3 200"), {"line 16", "element vertex record 2", "'x3'"}},
      {with_line(14, "1 2 3 200 7"), {"line 14", "1 values too many"}},
      {with_line(14, "1 2 nan 200"), {"vertex 0 ", "not finite"}},
      // bad indices
      {with_line(20, "3 1 2 9"), {"face 1 refers to vertex 9 of 5"}},
      {with_line(20, "3 1 -2 4"), {"line 20", "element face record 1", "vertex index -2"}},
      {with_line(21, "3 2 3.5 4"), {"line 21", "'3.5'"}},
      // bad counts: a quad, a list count beyond its line, a count of elements beyond the file
      {with_line(22, "4 3 0 4 1"), {"line 22", "element face record 3", "4 vertices"}},
      {with_line(22, "5 3 0 4"), {"line 22", "counts 5 values, the line has 3"}},
      {with_line(4, "element vertex 4000000000"), {"truncated", "element vertex declares 4000000000"}},
      {with_line(4, "element vertex -1"), {"line 4", "bad PLY element line"}},
      {with_line(2, "format ascii 2.0"), {"line 2", "version '2.0'"}},
      {with_line(2, "format binary_middle_endian 1.0"), {"line 2", "binary_middle_endian", "not supported"}},
      {good + "1 2 3\n", {"line 24", "data after the last element"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.parts.front());
    expect_file_error(path, c.text, c.parts);
  }
  fs::remove(path);
}

TEST(MeshReader, MalformedBigEndianPly) {
  const std::string good = binary_ply(fixture(), /*big_endian=*/true);
  const std::string path = tmp_path("bad_be.ply");
  // Every truncation fails (binary records have fixed sizes, the last byte included).
  for (std::size_t len = 0; len < good.size(); ++len) {
    write_file(path, good.substr(0, len));
    const std::string msg = read_error(path);
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << len << ": " << msg;
  }
  expect_file_error(path, good.substr(0, good.size() - 5), {"truncated", "element face record 3"});
  // The last index of the last face, big-endian: 9 instead of 4.
  expect_file_error(path, with_byte(good, 1, 9), {"face 3 refers to vertex 9 of 5"});
  // The last face's count: 4 corners, then 2.
  expect_file_error(path, with_byte(good, 13, 4), {"truncated", "element face record 3"});
  expect_file_error(path, with_byte(good, 13, 2), {"element face record 3 has 2 vertices"});
  // Counts far beyond the file are refused before allocating.
  expect_file_error(path, replaced(good, "element face 4", "element face 3000000000"),
                    {"truncated: element face needs at least 3000000000 x 1 bytes"});
  // A byte too many: the little-endian reading of a big-endian file would not notice, the
  // size check does.
  expect_file_error(path, good + "x", {"1 unexpected bytes after the last element"});
  fs::remove(path);
}

TEST(MeshReader, MalformedLittleEndianPly) {
  const std::string good = binary_ply(fixture(), /*big_endian=*/false);
  const std::string path = tmp_path("bad_le.ply");
  expect_file_error(path, good.substr(0, good.size() - 1), {"truncated", "element face record 3"});
  // The low byte of the last index.
  expect_file_error(path, with_byte(good, 4, 9), {"face 3 refers to vertex 9 of 5"});
  expect_file_error(path, replaced(good, "element vertex 5", "element vertex 4000000000"),
                    {"truncated: element vertex needs at least 4000000000 x 28 bytes"});
  expect_file_error(path, replaced(good, "list uint8 uint32", "list uint8 float"),
                    {"face indices must have an integer type"});
  expect_file_error(path, replaced(good, "property float64 z", "property float64 w"),
                    {"vertex element lacks x, y or z"});
  fs::remove(path);
}

TEST(MeshReader, MalformedObj) {
  const std::string path = tmp_path("bad.obj");
  const std::string v = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";  // lines 1..4
  struct Case {
    std::string text;
    std::vector<std::string> parts;
  };
  const std::vector<Case> cases = {
      // truncated lines
      {v + "f 1 2", {"line 5", "at least 3 corners, found 2"}},
      {v + "v 1 2\n", {"line 5", "needs x y z", "found 2"}},
      // bad indices: beyond the vertices so far, zero, too negative, a forward reference
      {v + "f 1 2 9\n", {"line 5", "'9' refers to vertex 9, but 4 vertices are defined before it"}},
      {v + "f 0 1 2\n", {"line 5", "'0' refers to vertex 0"}},
      {v + "f -5 1 2\n", {"line 5", "'-5'"}},
      {"v 0 0 0\nf 1 2 3\nv 1 0 0\nv 1 1 0\n", {"line 2", "'2' refers to vertex 2, but 1 vertices"}},
      // bad numbers and corner forms
      {v + "v 1 2 x\n", {"line 5", "'x' is not a finite number"}},
      {v + "v 1 2 inf\n", {"line 5", "'inf' is not a finite number"}},
      {v + "v 1 2 3 4 5 6 7 8\n", {"line 5", "found 8 values"}},
      {v + "f 1/1/1/1 2 3\n", {"line 5", "more than 3 parts"}},
      {v + "f 1/x 2 3\n", {"line 5", "'1/x' is not a, a/b, a/b/c or a//c"}},
      {v + "f 1/ 2 3\n", {"line 5", "'1/'"}},
      {v + "f 1/2/ 2 3\n", {"line 5", "'1/2/'"}},
      {v + "f a 2 3\n", {"line 5", "'a' does not start with a vertex index"}},
      {v + "f 99999999999999999999 2 3\n", {"line 5", "does not start with a vertex index"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.parts.back());
    expect_file_error(path, c.text, c.parts);
  }
  expect_error(tmp_path("missing.obj"), {"cannot open"});
  fs::remove(path);
}

}  // namespace
