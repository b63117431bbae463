// Tests for the glTF 2.0 writers (.glb, .gltf): an independent reader written here (GLB header
// and chunks, a small JSON parser, base64, accessors) checks the layout, the frame, positions
// against the translation, exact min/max, unit normals, indices, winding, alignment and errors.
#include <gtest/gtest.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>
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
  return (terralod::test::process_temp_dir("gltf") / name).string();
}

std::string read_bytes(const std::string& path) { return terralod::test::slurp(path); }

// ---------------------------------------------------------------------------------------------
// A minimal JSON parser: objects, arrays, strings (with \" \\ \/ \uXXXX < 0x80), numbers
// (strtod), true, false, null. Throws std::runtime_error on anything else.

struct Json {
  enum Kind { Null, Bool, Number, String, Array, Object } kind = Null;
  double number = 0;
  bool boolean = false;
  std::string string;
  std::vector<Json> array;
  std::map<std::string, Json> object;

  bool has(const std::string& k) const { return kind == Object && object.count(k) != 0; }
  const Json& operator[](const std::string& k) const {
    if (!has(k)) throw std::runtime_error("JSON: no member '" + k + "'");
    return object.at(k);
  }
  const Json& operator[](std::size_t i) const {
    if (kind != Array || i >= array.size()) throw std::runtime_error("JSON: no element " + std::to_string(i));
    return array[i];
  }
  std::size_t size() const { return kind == Array ? array.size() : object.size(); }
  double num() const {
    if (kind != Number) throw std::runtime_error("JSON: not a number");
    return number;
  }
  std::uint64_t u64() const {
    const double v = num();
    if (v < 0 || v != std::floor(v)) throw std::runtime_error("JSON: not a non-negative integer");
    return std::uint64_t(v);
  }
  const std::string& str() const {
    if (kind != String) throw std::runtime_error("JSON: not a string");
    return string;
  }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& text) : s_(text) {}
  Json parse_document() {
    Json v = value();
    skip_space();
    if (i_ != s_.size()) fail("text after the value");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("JSON at " + std::to_string(i_) + ": " + what);
  }
  void skip_space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t')) ++i_;
  }
  bool eat(char c) {
    skip_space();
    if (i_ < s_.size() && s_[i_] == c) return ++i_, true;
    return false;
  }
  void expect(char c) {
    if (!eat(c)) fail(std::string("expected '") + c + "'");
  }
  std::string string_literal() {
    expect('"');
    std::string out;
    while (true) {
      if (i_ >= s_.size()) fail("unterminated string");
      const char c = s_[i_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in a string");
      if (c != '\\') {
        out += c;
        continue;
      }
      if (i_ >= s_.size()) fail("unterminated escape");
      const char e = s_[i_++];
      if (e == '"' || e == '\\' || e == '/') {
        out += e;
      } else if (e == 'n') {
        out += '\n';
      } else if (e == 'u' && i_ + 4 <= s_.size()) {
        const unsigned long code = std::stoul(s_.substr(i_, 4), nullptr, 16);
        if (code >= 0x80) fail("\\u escape beyond ASCII");
        out += char(code);
        i_ += 4;
      } else {
        fail("unsupported escape");
      }
    }
  }
  Json value() {
    skip_space();
    if (i_ >= s_.size()) fail("unexpected end");
    Json v;
    const char c = s_[i_];
    if (c == '{') {
      v.kind = Json::Object;
      ++i_;
      if (eat('}')) return v;
      do {
        skip_space();
        std::string key = string_literal();
        expect(':');
        if (v.object.count(key)) fail("duplicate key " + key);
        v.object[key] = value();
      } while (eat(','));
      expect('}');
    } else if (c == '[') {
      v.kind = Json::Array;
      ++i_;
      if (eat(']')) return v;
      do v.array.push_back(value());
      while (eat(','));
      expect(']');
    } else if (c == '"') {
      v.kind = Json::String;
      v.string = string_literal();
    } else if (s_.compare(i_, 4, "true") == 0 || s_.compare(i_, 5, "false") == 0) {
      v.kind = Json::Bool;
      v.boolean = s_[i_] == 't';
      i_ += v.boolean ? 4 : 5;
    } else if (s_.compare(i_, 4, "null") == 0) {
      i_ += 4;
    } else {
      // JSON's number grammar: -?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?
      const std::size_t start = i_;
      if (s_[i_] == '-') ++i_;
      auto digits = [&] {
        const std::size_t d = i_;
        while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
        if (i_ == d) fail("bad number");
      };
      if (i_ < s_.size() && s_[i_] == '0')
        ++i_;
      else
        digits();
      if (i_ < s_.size() && s_[i_] == '.') ++i_, digits();
      if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
        ++i_;
        if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
        digits();
      }
      v.kind = Json::Number;
      v.number = std::strtod(s_.substr(start, i_ - start).c_str(), nullptr);
    }
    return v;
  }

  const std::string& s_;
  std::size_t i_ = 0;
};

std::string base64_decode(const std::string& in) {
  auto sextet = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    throw std::runtime_error(std::string("base64: bad character ") + c);
  };
  if (in.size() % 4 != 0) throw std::runtime_error("base64: length not a multiple of 4");
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 4) {
    const int pad = (in[i + 3] == '=') + (in[i + 2] == '=');
    if (pad && i + 4 != in.size()) throw std::runtime_error("base64: padding inside");
    std::uint32_t v = 0;
    for (int k = 0; k < 4; ++k)
      v = (v << 6) | std::uint32_t(k >= 4 - pad ? 0 : sextet(in[i + std::size_t(k)]));
    out += char(v >> 16);
    if (pad < 2) out += char((v >> 8) & 0xff);
    if (pad < 1) out += char(v & 0xff);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The glTF reader: the JSON, the buffer, and typed access to accessors.

std::uint32_t u32_at(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);  // little-endian host, as the writer
  return v;
}

struct Gltf {
  Json json;
  std::string buffer;  // buffers[0]'s bytes (the BIN chunk without its padding check)
  std::size_t json_chunk_length = 0, bin_chunk_offset = 0, bin_chunk_length = 0;

  /// Accessor `i` read element by element as doubles (count x components).
  std::vector<double> accessor(std::size_t i, int* component_type = nullptr,
                               std::string* type = nullptr) const {
    const Json& a = json["accessors"][i];
    const Json& view = json["bufferViews"][a["bufferView"].u64()];
    EXPECT_EQ(view["buffer"].u64(), 0u);
    const std::uint64_t view_offset = view.has("byteOffset") ? view["byteOffset"].u64() : 0;
    const std::uint64_t offset = a.has("byteOffset") ? a["byteOffset"].u64() : 0;
    const int ct = int(a["componentType"].u64());
    const std::string& t = a["type"].str();
    const std::size_t comps = t == "SCALAR" ? 1 : t == "VEC3" ? 3 : 0;
    const std::size_t csize = ct == 5126 || ct == 5125 ? 4 : ct == 5123 ? 2 : 0;
    EXPECT_GT(comps * csize, 0u) << "unexpected accessor type " << t << " / " << ct;
    EXPECT_EQ(offset % 4, 0u) << "accessor " << i << " byteOffset alignment";
    EXPECT_EQ((view_offset + offset) % csize, 0u) << "accessor " << i << " component alignment";
    EXPECT_EQ(view_offset % 4, 0u) << "bufferView alignment";
    EXPECT_FALSE(view.has("byteStride")) << "tightly packed";
    const std::uint64_t count = a["count"].u64();
    EXPECT_LE(offset + count * comps * csize, view["byteLength"].u64())
        << "accessor " << i << " fits its view";
    EXPECT_LE(view_offset + view["byteLength"].u64(), buffer.size()) << "view fits the buffer";
    std::vector<double> out;
    out.reserve(count * comps);
    for (std::uint64_t k = 0; k < count * comps; ++k) {
      const std::size_t at = std::size_t(view_offset + offset + k * csize);
      if (at + csize > buffer.size()) throw std::runtime_error("accessor beyond the buffer");
      if (ct == 5126) {
        float f;
        std::memcpy(&f, buffer.data() + at, 4);
        out.push_back(f);
      } else if (ct == 5125) {
        out.push_back(u32_at(buffer, at));
      } else {
        std::uint16_t s;
        std::memcpy(&s, buffer.data() + at, 2);
        out.push_back(s);
      }
    }
    if (component_type) *component_type = ct;
    if (type) *type = t;
    return out;
  }
};

/// Reads a .glb, checking the container layout on the way (EXPECTs).
Gltf read_glb(const std::string& path) {
  const std::string b = read_bytes(path);
  Gltf g;
  if (b.size() < 20) throw std::runtime_error(path + ": too short for a GLB");
  EXPECT_EQ(b.compare(0, 4, "glTF"), 0) << "magic";
  EXPECT_EQ(u32_at(b, 4), 2u) << "version";
  EXPECT_EQ(u32_at(b, 8), b.size()) << "header length = file size";
  EXPECT_EQ(b.size() % 4, 0u);
  const std::uint32_t json_len = u32_at(b, 12);
  EXPECT_EQ(b.compare(16, 4, "JSON"), 0) << "first chunk type";
  EXPECT_EQ(json_len % 4, 0u) << "JSON chunk padded to 4";
  if (20 + std::size_t(json_len) > b.size()) throw std::runtime_error(path + ": JSON chunk beyond the file");
  std::string text = b.substr(20, json_len);
  const std::size_t last = text.find_last_not_of(' ');
  EXPECT_GT(last + 1 + 4, text.size()) << "at most 3 padding spaces";
  g.json = JsonParser(text).parse_document();
  g.json_chunk_length = json_len;
  const std::size_t bin = 20 + json_len;
  if (bin == b.size()) return g;  // no BIN chunk
  EXPECT_EQ(bin % 4, 0u) << "BIN chunk aligned";
  const std::uint32_t bin_len = u32_at(b, bin);
  EXPECT_EQ(b.compare(bin + 4, 4, std::string("BIN\0", 4)), 0) << "second chunk type";
  EXPECT_EQ(bin_len % 4, 0u) << "BIN chunk padded to 4";
  EXPECT_EQ(bin + 8 + bin_len, b.size()) << "BIN chunk ends the file";
  const std::uint64_t byte_length = g.json["buffers"][0]["byteLength"].u64();
  EXPECT_FALSE(g.json["buffers"][0].has("uri")) << "a GLB buffer has no uri";
  EXPECT_LE(byte_length, bin_len);
  EXPECT_GT(byte_length + 4, bin_len) << "at most 3 padding bytes";
  for (std::size_t k = bin + 8 + byte_length; k < b.size(); ++k)
    EXPECT_EQ(b[k], '\0') << "BIN padding is zeros";
  g.buffer = b.substr(bin + 8, byte_length);
  g.bin_chunk_offset = bin;
  g.bin_chunk_length = bin_len;
  return g;
}

/// Reads a .gltf with its buffer as a base64 data URI.
Gltf read_gltf(const std::string& path) {
  Gltf g;
  g.json = JsonParser(read_bytes(path)).parse_document();
  const std::string& uri = g.json["buffers"][0]["uri"].str();
  const std::string prefix = "data:application/octet-stream;base64,";
  EXPECT_EQ(uri.rfind(prefix, 0), 0u) << uri.substr(0, 60);
  g.buffer = base64_decode(uri.substr(prefix.size()));
  EXPECT_EQ(g.buffer.size(), g.json["buffers"][0]["byteLength"].u64());
  return g;
}

struct Decoded {
  std::vector<std::array<double, 3>> positions;  // as stored (relative to the translation)
  std::vector<std::array<double, 3>> normals;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::array<double, 3> translation{};
  int index_type = 0;
};

/// The one mesh of the file through scene 0 -> node 0 -> mesh 0 -> primitive 0, checking the
/// JSON fields the writer promises.
Decoded decode(const Gltf& g) {
  const Json& j = g.json;
  EXPECT_EQ(j["asset"]["version"].str(), "2.0");
  EXPECT_EQ(j["asset"]["generator"].str(), "terralod");
  EXPECT_EQ(j["scene"].u64(), 0u);
  EXPECT_EQ(j["scenes"][0]["nodes"].size(), 1u);
  const Json& node = j["nodes"][j["scenes"][0]["nodes"][0].u64()];
  Decoded d;
  for (std::size_t k = 0; k < 3; ++k) d.translation[k] = node["translation"][k].num();
  const Json& mesh = j["meshes"][node["mesh"].u64()];
  EXPECT_EQ(mesh["primitives"].size(), 1u);
  const Json& prim = mesh["primitives"][0];
  EXPECT_EQ(prim["mode"].u64(), 4u) << "triangles";
  const std::size_t pa = prim["attributes"]["POSITION"].u64(), na = prim["attributes"]["NORMAL"].u64(),
                    ia = prim["indices"].u64();
  int ct = 0;
  std::string type;
  const std::vector<double> p = g.accessor(pa, &ct, &type);
  EXPECT_EQ(ct, 5126);
  EXPECT_EQ(type, "VEC3");
  const std::vector<double> n = g.accessor(na, &ct, &type);
  EXPECT_EQ(ct, 5126);
  EXPECT_EQ(type, "VEC3");
  const std::vector<double> idx = g.accessor(ia, &d.index_type, &type);
  EXPECT_EQ(type, "SCALAR");
  EXPECT_EQ(j["bufferViews"][j["accessors"][pa]["bufferView"].u64()]["target"].u64(), 34962u);
  EXPECT_EQ(j["bufferViews"][j["accessors"][na]["bufferView"].u64()]["target"].u64(), 34962u);
  EXPECT_EQ(j["bufferViews"][j["accessors"][ia]["bufferView"].u64()]["target"].u64(), 34963u);
  for (std::size_t i = 0; i + 2 < p.size(); i += 3) d.positions.push_back({p[i], p[i + 1], p[i + 2]});
  for (std::size_t i = 0; i + 2 < n.size(); i += 3) d.normals.push_back({n[i], n[i + 1], n[i + 2]});
  for (std::size_t i = 0; i + 2 < idx.size(); i += 3)
    d.triangles.push_back({std::uint32_t(idx[i]), std::uint32_t(idx[i + 1]), std::uint32_t(idx[i + 2])});

  // min / max of POSITION: required, and exactly the stored floats' extremes.
  const Json& acc = j["accessors"][pa];
  for (std::size_t k = 0; k < 3; ++k) {
    double lo = INFINITY, hi = -INFINITY;
    for (const auto& q : d.positions) lo = std::min(lo, q[k]), hi = std::max(hi, q[k]);
    EXPECT_EQ(acc["min"][k].num(), lo) << "min " << k;
    EXPECT_EQ(acc["max"][k].num(), hi) << "max " << k;
  }
  return d;
}

/// glTF (x, z, -y) of a position in our frame.
std::array<double, 3> gltf_of(const std::array<double, 3>& p) { return {p[0], p[2], -p[1]}; }

/// Checks positions (stored + translation = expected within float rounding of the stored
/// value), indices, and unit normals of a decoded file against the mesh that was written.
void expect_matches(const Decoded& d, const TriangleMeshData& m) {
  ASSERT_EQ(d.positions.size(), m.positions.size());
  ASSERT_EQ(d.normals.size(), m.positions.size());
  EXPECT_EQ(d.triangles, m.triangles);
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    const auto want = gltf_of(m.positions[i]);
    for (std::size_t k = 0; k < 3; ++k) {
      const double rel = want[k] - d.translation[k];
      // float rounding of the relative coordinate: half an ulp, 2^-24 relative.
      EXPECT_LE(std::abs(d.positions[i][k] - rel), std::abs(rel) * 0x1p-24 + 1e-300)
          << "vertex " << i << " axis " << k;
      // and back in doubles: the same bound plus the rounding of the sum.
      EXPECT_LE(std::abs(d.positions[i][k] + d.translation[k] - want[k]),
                std::abs(rel) * 0x1p-24 + std::abs(want[k]) * 0x1p-52)
          << "vertex " << i << " axis " << k;
    }
    const auto& n = d.normals[i];
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6) << "normal " << i;
  }
}

/// The Y component of (b - a) x (c - a) in glTF axes: twice the area of triangle t projected
/// on the ground plane, positive when t is CCW seen from +Y (right-hand rule).
double up_cross(const Decoded& d, const std::array<std::uint32_t, 3>& t) {
  const auto &a = d.positions[t[0]], &b = d.positions[t[1]], &c = d.positions[t[2]];
  const double ux = b[0] - a[0], uz = b[2] - a[2], vx = c[0] - a[0], vz = c[2] - a[2];
  return uz * vx - ux * vz;  // Y component of (u x v)
}

// The tiny 3 x 2 fixture of tiny_mesh_fixture.hpp:
//
//   row 0:  s0 = 10.5   s1 = 11.25   s2 = 12
//   row 1:  s3 = 0.1    s4 = -3      s5 = 1e-7
//
// Mesh: vertices {s0, s1, s4, s3}, triangles (0,1,2) and (0,2,3), CCW in (col,row), with a
// north-up transform x = 500000 + 30 col, y = 4900000 - 90 row (UTM-sized, determinant < 0,
// so the world writer flips to (0,2,1), (0,3,2)). World positions:
//   v0 (500000, 4900000, 10.5)   v1 (500030, 4900000, 11.25)
//   v2 (500030, 4899910, -3)     v3 (500000, 4899910, 0.1)
// glTF (x, z, -y): v0 (500000, 10.5, -4900000) ... ; bounding box x [500000, 500030],
// y [-3, 11.25], z [-4900000, -4899910]; centre (500015, 4.125, -4899955) = the translation.
struct Fixture : terralod::test::TinyMeshFixture {
  Fixture() {
    hf.transform = GridTransform::north_up(/*x0=*/500000.0, /*y0=*/4900000.0, /*dx=*/30.0, /*dy=*/90.0);
  }
};

// ---------------------------------------------------------------------------------------------

TEST(GltfWriter, GlbOfTheTinyFixtureByHand) {
  const Fixture f;
  const std::string path = tmp_path("tiny.glb");
  write_mesh(f.mesh, f.hf, path, Units::World);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const Gltf g = read_glb(path);
  const Decoded d = decode(g);
  EXPECT_EQ(d.translation, (std::array<double, 3>{500015.0, 4.125, -4899955.0}));
  // Relative positions, all exact in float: v0 = (-15, 6.375, -45), v2 = (15, -7.125, 45).
  ASSERT_EQ(d.positions.size(), 4u);
  EXPECT_EQ(d.positions[0], (std::array<double, 3>{-15, 6.375, -45}));
  EXPECT_EQ(d.positions[1], (std::array<double, 3>{15, 7.125, -45}));
  EXPECT_EQ(d.positions[2], (std::array<double, 3>{15, -7.125, 45}));
  EXPECT_EQ(d.positions[3], (std::array<double, 3>{-15, double(float(0.1 - 4.125)), 45}));
  EXPECT_EQ(d.triangles, (std::vector<std::array<std::uint32_t, 3>>{{0, 2, 1}, {0, 3, 2}}));
  EXPECT_EQ(d.index_type, 5123) << "4 vertices: UNSIGNED_SHORT";
  // Buffer: 4 x 12 positions + 4 x 12 normals + 6 x 2 indices = 108 bytes, BIN chunk 108.
  EXPECT_EQ(g.buffer.size(), 108u);
  EXPECT_EQ(g.bin_chunk_length, 108u);
  expect_matches(d, mesh_positions(f.mesh, f.hf, Units::World));
  for (const auto& t : d.triangles) EXPECT_GT(up_cross(d, t), 0.0) << "CCW seen from +Y";
  for (const auto& n : d.normals) EXPECT_GT(n[1], 0.0) << "normals point up";
  const Json& comments = g.json["asset"]["extras"]["comments"];
  ASSERT_EQ(comments.size(), 3u);
  EXPECT_EQ(comments[2].str(), "error_bound 0.75");
  fs::remove(path);
}

TEST(GltfWriter, NormalsOfAPlaneByHand) {
  // The plane z = 0.5 x + 2 over a 2 x 2 square, two triangles CCW from above:
  //   v0 (0,0)  v1 (2,0)  v2 (2,2)  v3 (0,2);  triangles (0,1,2), (0,2,3).
  // Normal in our frame: (-0.5, 0, 1) / sqrt(1.25); in glTF (x, z, -y): (-0.5, 1, 0) / sqrt(1.25).
  TriangleMeshData m;
  m.positions = {{0, 0, 2}, {2, 0, 3}, {2, 2, 3}, {0, 2, 2}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  const std::string path = tmp_path("plane.glb");
  write_mesh(m, path);
  const Decoded d = decode(read_glb(path));
  expect_matches(d, m);
  const double s = 1.0 / std::sqrt(1.25);
  for (const auto& n : d.normals) {
    EXPECT_NEAR(n[0], -0.5 * s, 1e-7);
    EXPECT_NEAR(n[1], s, 1e-7);
    EXPECT_NEAR(n[2], 0.0, 1e-7);
  }
  // Area weighting: a fold where one triangle is 3 times larger than the other. Shared vertex
  // 0 gets (big normal x 3 + small normal) / |..|, not the plain average.
  //   big:   (0,0,0) (3,0,0) (0,1,0)         flat, cross = (0, 0, 3)
  //   small: (0,0,0) (0,1,0) (-1,0,1)        cross((0,1,0), (-1,0,1)) = (1, 0, 1)
  // Sum (1, 0, 4) / sqrt(17); glTF (1, 4, 0) / sqrt(17).
  TriangleMeshData fold;
  fold.positions = {{0, 0, 0}, {3, 0, 0}, {0, 1, 0}, {-1, 0, 1}};
  fold.triangles = {{0, 1, 2}, {0, 2, 3}};
  write_mesh(fold, path);
  const Decoded e = decode(read_glb(path));
  expect_matches(e, fold);
  EXPECT_NEAR(e.normals[0][0], 1 / std::sqrt(17.0), 1e-7);
  EXPECT_NEAR(e.normals[0][1], 4 / std::sqrt(17.0), 1e-7);
  EXPECT_NEAR(e.normals[0][2], 0.0, 1e-7);
  EXPECT_NEAR(e.normals[3][0], 1 / std::sqrt(2.0), 1e-7) << "only the small triangle";
  EXPECT_NEAR(e.normals[3][1], 1 / std::sqrt(2.0), 1e-7);
  fs::remove(path);
}

TEST(GltfWriter, GeneratedTerrainInBothUnitsAndBothForms) {
  TerrainOptions opt;
  opt.width = 65;
  opt.height = 49;
  Heightfield hf = generate_terrain(opt);
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  const TriangleMesh mesh = pm.extract(/*max_error=*/5.0);
  ASSERT_GT(mesh.triangles.size(), 2u);
  const std::string glb = tmp_path("terrain.glb"), gltf = tmp_path("terrain.gltf");
  for (const Units units : {Units::World, Units::Samples}) {
    SCOPED_TRACE(units == Units::World ? "world" : "samples");
    write_mesh(mesh, pm.heightfield(), glb, units);
    write_mesh(mesh, pm.heightfield(), gltf, units);
    const TriangleMeshData expected = mesh_positions(mesh, pm.heightfield(), units);
    const Gltf gb = read_glb(glb), gt = read_gltf(gltf);
    EXPECT_EQ(gb.buffer, gt.buffer) << ".glb and .gltf hold the same buffer";
    const Decoded d = decode(gb);
    expect_matches(d, expected);
    expect_matches(decode(gt), expected);
    double area = 0;
    for (const auto& t : d.triangles) {
      EXPECT_GT(up_cross(d, t), 0.0) << "CCW seen from +Y";
      area += up_cross(d, t) / 2;
    }
    // The mesh covers the whole grid: 64 x 48 cells of 30 m (world) or 1 sample (samples).
    const double cell = units == Units::World ? 30.0 * 30.0 : 1.0;
    EXPECT_NEAR(area, 64.0 * 48.0 * cell, 1e-3 * area);
  }
  fs::remove(glb);
  fs::remove(gltf);
}

TEST(GltfWriter, IndexTypeSwitchesAbove65535Vertices) {
  // A strip of n vertices in two rows, CCW from above: 65534 vertices use uint16, 65536 uint32.
  for (const std::uint32_t n : {65534u, 65536u}) {
    TriangleMeshData m;
    const std::uint32_t half = n / 2;
    for (std::uint32_t i = 0; i < half; ++i) {
      m.positions.push_back({double(i), 0, 0});
      m.positions.push_back({double(i), 1, 0});
    }
    for (std::uint32_t i = 0; i + 1 < half; ++i) {
      m.triangles.push_back({2 * i, 2 * i + 2, 2 * i + 3});
      m.triangles.push_back({2 * i, 2 * i + 3, 2 * i + 1});
    }
    const std::string path = tmp_path("strip.glb");
    write_mesh(m, path);
    const Decoded d = decode(read_glb(path));
    EXPECT_EQ(d.index_type, n <= 65535u ? 5123 : 5125) << n << " vertices";
    EXPECT_EQ(d.triangles, m.triangles);
    for (const auto& t : d.triangles) ASSERT_GT(up_cross(d, t), 0.0);
    fs::remove(path);
  }
  // Exactly 65535 vertices: the largest index is 65534, never glTF's reserved 65535 (primitive
  // restart), so still uint16.
  TriangleMeshData m;
  for (std::uint32_t i = 0; i < 65535; ++i) m.positions.push_back({double(i % 256), double(i / 256), 0});
  m.triangles = {{0, 1, 65534}};
  const std::string path = tmp_path("edge.glb");
  write_mesh(m, path);
  const Decoded d = decode(read_glb(path));
  EXPECT_EQ(d.index_type, 5123);
  EXPECT_EQ(d.triangles, m.triangles);
  fs::remove(path);
}

TEST(GltfWriter, OddIndexCountsStayAligned) {
  // One triangle: 3 uint16 indices = 6 bytes; buffer 3 x 24 + 6 = 78 bytes, BIN chunk 80.
  TriangleMeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  const std::string path = tmp_path("one.glb");
  write_mesh(m, path);
  const Gltf g = read_glb(path);
  EXPECT_EQ(g.buffer.size(), 78u);
  EXPECT_EQ(g.bin_chunk_length, 80u);
  EXPECT_EQ(g.bin_chunk_offset % 4, 0u);
  expect_matches(decode(g), m);
  fs::remove(path);
}

TEST(GltfWriter, MeshWithoutTrianglesIsAnEmptyScene) {
  TriangleMeshData m;
  m.positions = {{1, 2, 3}};
  const std::string path = tmp_path("empty.glb");
  write_mesh(m, path);
  const Gltf g = read_glb(path);
  EXPECT_EQ(g.json["asset"]["version"].str(), "2.0");
  EXPECT_FALSE(g.json.has("meshes"));
  EXPECT_FALSE(g.json.has("buffers"));
  EXPECT_EQ(g.json["nodes"].size(), 1u);
  EXPECT_EQ(fs::file_size(path), 20u + g.json_chunk_length) << "no BIN chunk";
  fs::remove(path);
}

TEST(GltfWriter, ErrorsNameTheFile) {
  TriangleMeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  for (const char* name : {"missing_dir/mesh.glb", "missing_dir/mesh.gltf"}) {
    const std::string path = tmp_path(name);
    try {
      write_mesh(m, path);
      ADD_FAILURE() << "write into a missing folder succeeded";
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(path + ": cannot write", 0), 0u) << e.what();
    }
    EXPECT_FALSE(fs::exists(path + ".tmp"));
  }
  // JSON cannot hold a NaN bound.
  m.positions[1][2] = NAN;
  const std::string nan_path = tmp_path("nan.glb");
  try {
    write_mesh(m, nan_path);
    ADD_FAILURE() << "NaN written";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(nan_path + ": vertex 1 ", 0), 0u) << e.what();
  }
  EXPECT_FALSE(fs::exists(nan_path));
  // The extension decides; any case.
  m.positions[1][2] = 0;
  const std::string upper = tmp_path("UPPER.GLB");
  write_mesh(m, upper);
  EXPECT_EQ(read_bytes(upper).compare(0, 4, "glTF"), 0);
  fs::remove(upper);
  EXPECT_EQ(mesh_format_of("a/b.GlTf"), MeshFormat::Gltf);
  EXPECT_EQ(mesh_format_of("a.glb/b"), std::nullopt);
}

}  // namespace
